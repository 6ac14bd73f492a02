-- A gyroid network whose thickness steps by column across x faces (0.06,
-- 0.10, 0.14 mm; 3 x 3 x 1 cells of 2 mm, res 40), layer 38. Before the fix,
-- the step's reflex corner at (4, 2.35) lay exactly on a node of the contour
-- offset's grid and the section's ring repeated it; the in-plane distance then
-- read "outside" on the grid line below the corner and the middle voxel's
-- contour took a spurious point there, 2 b below the corner, ending 25 um
-- from its neighbour's (closed only by the melt-track rule). The cause has a
-- unit test of its own (tests/c/test_polydist.c: repeated_corner_points);
-- this one checks the whole layer against the true section
-- (gradus.steptruth: each voxel's own offset field, cut to its square):
-- every contour closed and oriented, every contour point at the beam offset b
-- from the true boundary within 1 um (before: 25 um).
local t = require "gradus.testing"
local truth = require "gradus.steptruth"
local L, d, lt, b, RES, G = 2, 0.05, 0.04, 0.025, 40, 38
local T = { 0.06, 0.10, 0.14 }

t.test("gyroid network 0.06 | 0.10 | 0.14 across x, layer 38: contours closed, at b from the true boundary", function()
  local j = gradus.place.job { cell = L, cells = { 3, 3, 1 }, layer = lt, hatch = d, res = RES, threads = 2 }
  local sp = {}
  for i = 1, 3 do sp[i] = j:spec { surface = "gyroid", kind = "network", thickness = T[i] } end
  for i = 0, 2 do for k = 0, 2 do j:voxel(i, k, 0, { spec = sp[i + 1] }) end end
  local _, kept = j:run { kb = false, keep = { G } }
  local layer, z = kept[G], G * lt - lt / 2
  local V = {}
  for k = 0, 2 do
    for i = 0, 2 do
      V[#V + 1] = { lo = { i * L, k * L }, hi = { (i + 1) * L, (k + 1) * L },
        field = gradus.distance.offset { surface = "gyroid", cell = L, lo = { i * L, k * L, 0 },
          hi = { (i + 1) * L, (k + 1) * L, L }, res = RES, thickness = T[i + 1], kind = "network", mode = "exact", voxel = true } }
    end
  end
  local open = 0
  for _, bk in ipairs(layer:blocks()) do
    if bk.kind == "contour" and bk.shape ~= "closed" and not bk.thin then open = open + 1 end
  end
  t.eq(open, 0, "every contour closed")
  local rep = t.contour_check(layer, { field = truth.field(V), z = z, box = { 0, 0, 3 * L, 3 * L }, offset = b })
  t.ok(rep.loops > 0 and #rep.bad == 0, ("%d loops, %d badly oriented"):format(rep.loops, #rep.bad))
  local devs = truth.deviations(layer, truth.edges(V, z, { lo = { 0, 0 }, hi = { 3 * L, 3 * L } }, d / 8), b)
  local worst = truth.quantile(devs, 1)
  print(("  info: %d loops, %d contour points, deviation max %.3g um"):format(rep.loops, #devs, worst * 1e3))
  t.ok(#devs > 100 and worst <= 1e-3, ("contour deviation max %.3g um over %d points"):format(worst * 1e3, #devs))
end)
t.done()
