-- Voxel-owned grading at part scale: a gyroid sheet graded in w (T = 0.06 +
-- 0.03 w, L = 2) in one voxel. Its first layer's section area (the job's
-- template, direct) against an independent fine-grid classification of the
-- whole-block field under the rule (u, v, w of the foot point relative to the
-- voxel holding the point, clamped), and against the earlier wrap rule,
-- which the part's first layer must not follow.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"

local TH, LAYER = "0.06+0.03*w", 0.04

local function job_area(layer)
  local p = lattice.params()
  p.cells, p.surface, p.thickness, p.kb, p.res = "1,1,1", "gyroid", TH, "off", 40
  p.layers = ("%d:%d"):format(layer, layer)
  local st = lattice.run(p, nil)
  return st.solid_volume_mm3 / LAYER
end

-- area of {g < 0} in the voxel square at height z, on an N x N grid of cell centres
local function grid_area(thickness, z, N)
  local f = gradus.distance.offset { surface = "gyroid", lo = { 0, 0, 0 }, hi = { 2, 2, 2 }, margin = 0.3,
    res = 40, thickness = thickness }
  local h = 2 / N
  local s = f:sample2 { z = z, lo = { h / 2, h / 2 }, hi = { 2 - h / 2, 2 - h / 2 }, n = { N, N } }
  local n = 0
  for i = 1, N * N do if s[i] < 0 then n = n + 1 end end
  return n * h * h
end

t.test("first layer of a w-graded gyroid sheet: area under the voxel-owned rule, not the wrap rule", function()
  local z, N = LAYER / 2, 300
  local a_job = job_area(1)
  local a_rule = grid_area(TH, z, N)
  -- the earlier rule: w of the foot point's own cell, wrapping (feet below z = 0 read the top's T)
  local a_wrap = grid_area(function(x, y, zq) return 0.06 + 0.03 * ((zq % 2) - 1) end, z, N)
  print(("  info: layer 1 section area: job %.5f mm^2, rule (grid %d^2) %.5f, wrap rule %.5f"):format(a_job, N,
    a_rule, a_wrap))
  -- grid classification error: at most the boundary length times h/2 (boundary below 20 mm here)
  t.near(a_job, a_rule, 20 * (2 / N) / 2 * 0.5, "job vs the rule's fine grid")
  t.ok(math.abs(a_wrap - a_rule) > 0.02, ("the wrap rule differs by only %.4f mm^2"):format(math.abs(a_wrap - a_rule)))
end)

t.done()
