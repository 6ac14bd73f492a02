-- Steps at x and y faces (engine/facestep.c): two voxels side by side with
-- different thickness. Under voxel-owned grading the solid is each voxel's
-- own section cut at the shared face, so it steps exactly on the face plane.
-- Checked against an independent truth (gradus.steptruth): each voxel's
-- offset field (gradus.distance.offset, constant thickness) cut to its voxel
-- and united, and for distances the exact boundary (each voxel's section
-- sliced over its own square, the face parts where one side only is solid):
--  - every contour is closed and oriented (t.contour_check on the truth);
--  - where a contour runs along the face (segments parallel to it within
--    2 b of it), it lies on the plane face -+ b within 1 um, and there is such
--    a run;
--  - verify() on the truth: pores <= 0.5 %, overmelt <= 1 %; the contour's
--    distance to the truth's boundary is b within 1 um at p99 (every point).
-- Templates through the knowledge-base path and kb=off (direct), exact mode.
local t = require "gradus.testing"
local truth = require "gradus.steptruth"
local L, d, lt, b = 2, 0.05, 0.04, 0.025
local RES = 30

-- the part: voxels (0,0) and (1,0) (axis "x") or (0,0) and (0,1) (axis "y")
local function run(c, direct, keep)
  local nx, ny = c.axis == "x" and 2 or 1, c.axis == "y" and 2 or 1
  local j = gradus.place.job { cell = L, cells = { nx, ny, 1 }, layer = lt, hatch = d, res = RES, threads = 2 }
  local sa = j:spec { surface = c.surface, kind = c.kind, thickness = c.T[1] }
  local sb = j:spec { surface = c.surface, kind = c.kind, thickness = c.T[2] }
  j:voxel(0, 0, 0, { spec = sa })
  j:voxel(nx - 1, ny - 1, 0, { spec = sb })
  local _, kept = j:run { kb = false, direct = direct, keep = keep }
  return kept, { nx * L, ny * L }
end

-- the truth (gradus.steptruth): the first voxel's field where the
-- coordinate is below L, the second's from L on
local function voxels(c, hi)
  local V = {}
  for v = 1, 2 do
    local lo, top = { 0, 0 }, { hi[1], hi[2] }
    local ax = c.axis == "x" and 1 or 2
    if v == 1 then top[ax] = L else lo[ax] = L end
    V[v] = { lo = lo, hi = top, field = gradus.distance.offset { surface = c.surface, cell = L, lo = { 0, 0, 0 },
      hi = { hi[1], hi[2], L }, res = RES, thickness = c.T[v], kind = c.kind, mode = "exact" } }
  end
  return V
end

-- contour segments parallel to the face within 2 b of it: their distance to
-- the face's offset planes (worst) and their total length
local function step_runs(layer, c)
  local ax = c.axis == "x" and 1 or 2
  local worst, len = 0, 0
  for x0, y0, x1, y1 in t.segments(layer, "contour") do
    local a0, a1, s0, s1 = x0, x1, y0, y1
    if ax == 2 then a0, a1, s0, s1 = y0, y1, x0, x1 end
    local l = math.abs(s1 - s0)
    if l > 2e-3 and math.abs(a1 - a0) < 1e-6 * l and math.abs(a0 - L) < 2 * b then
      worst = math.max(worst, math.abs(math.abs(a0 - L) - b))
      len = len + l
    end
  end
  return worst, len
end

local cases = {
  { name = "P sheet 0.06 | 0.12 across an x face", surface = "primitive", kind = "sheet", T = { 0.06, 0.12 }, axis = "x",
    layers = { 13, 25 } },
  { name = "gyroid network 0.05 | 0.15 across a y face", surface = "gyroid", kind = "network", T = { 0.05, 0.15 },
    axis = "y", layers = { 7, 30 } },
}

for _, c in ipairs(cases) do
  for _, direct in ipairs { false, true } do
    t.test(("%s (%s)"):format(c.name, direct and "kb=off, direct" or "templates"), function()
      local kept, hi = run(c, direct, c.layers)
      local V = voxels(c, hi)
      local F = truth.field(V)
      local total_run = 0
      for _, g in ipairs(c.layers) do
        local layer, z = kept[g], g * lt - lt / 2
        local open = 0
        for _, bk in ipairs(layer:blocks()) do
          if bk.kind == "contour" and bk.shape ~= "closed" and not bk.thin then open = open + 1 end
        end
        t.eq(open, 0, ("layer %d: every contour closed"):format(g))
        local rep = t.contour_check(layer, { field = F, z = z, box = { 0, 0, hi[1], hi[2] }, offset = b })
        t.ok(rep.loops > 0 and #rep.bad == 0, ("layer %d: %d loops, %d badly oriented"):format(g, rep.loops, #rep.bad))
        local worst, len = step_runs(layer, c)
        total_run = total_run + len
        t.ok(worst <= 1e-3, ("layer %d: contour along the step %.3g um off the plane face -+ b"):format(g, worst * 1e3))
        local sec = gradus.slice.field(F, z, { lo = { 0, 0 }, hi = hi, cell = d / 8 })
        local r = gradus.hatch.verify(sec, layer, { track = d, pixel = d / 20, offset = b, spacing = d, contours = 1 })
        t.ok(r.pore <= 0.005, ("layer %d: pore %.3f %%"):format(g, 100 * r.pore))
        t.ok(r.overmelt <= 0.01, ("layer %d: overmelt %.3f %%"):format(g, 100 * r.overmelt))
        local devs = truth.deviations(layer, truth.edges(V, z, { lo = { 0, 0 }, hi = hi }, d / 8), b)
        local p99, n, dmax = truth.quantile(devs, 0.99), #devs, truth.quantile(devs, 1)
        print(("  info: layer %d: %d loops, step run %.3f mm (%.3g um off), pore %.3f %%, overmelt %.3f %%, dev p99 %.3g um max %.3g um")
          :format(g, rep.loops, len, worst * 1e3, 100 * r.pore, 100 * r.overmelt, p99 * 1e3, dmax * 1e3))
        t.ok(n > 100 and p99 <= 1e-3, ("layer %d: contour deviation p99 %.3g um (max %.3g, %d points)")
          :format(g, p99 * 1e3, dmax * 1e3, n))
      end
      t.ok(total_run > 0.02, ("the contours run along the step (%.3f mm over the layers)"):format(total_run))
    end)
  end
end
t.done()
