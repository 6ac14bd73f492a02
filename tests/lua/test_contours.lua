-- Orientation of every closed contour, checked on the field (t.contour_check):
-- signed area against the declared direction and the solid on the left, on
-- the paper's graded column (P sheet, eq. 8, 1 x 1 x 3 cells: local layer 31
-- of each cell and the layers next to every cell face), a continuously graded
-- gyroid sheet and a demo-like P lattice; closed contours shorter than the
-- melt track are dropped and counted in the stats, never written.
local t = require "gradus.testing"
local B, D, LAYER = 0.025, 0.05, 0.04

-- a job of cells c (2 mm voxels), every voxel one spec; returns stats, kept layers, the exact field
local function run(surface, th, c, keep)
  local j = gradus.place.job { cell = 2, cells = c, layer = LAYER, hatch = D, beam_offset = B, res = 40, threads = 2 }
  local s = j:spec { surface = surface, thickness = th }
  for k = 0, c[3] - 1 do
    for jj = 0, c[2] - 1 do
      for i = 0, c[1] - 1 do j:voxel(i, jj, k, { spec = s }) end
    end
  end
  local out = os.tmpname()
  local st, layers = j:run { output = out, format = "ascii", kb = false, keep = keep }
  os.remove(out)
  local f = gradus.distance.offset { surface = surface, lo = { 0, 0, 0 }, hi = { 2 * c[1], 2 * c[2], 2 * c[3] },
    cell = 2, thickness = th, res = 40 }
  return st, layers, f
end

-- every closed contour of the kept layers: oriented, longer than the track
local function check_all(name, c, keep, layers, f)
  local loops, worst = 0, math.huge
  for _, g in ipairs(keep) do
    local l = layers[g]
    local r = t.contour_check(l, { field = f, z = l:z() - LAYER / 2, box = { 0, 0, 2 * c[1], 2 * c[2] }, offset = B })
    loops = loops + r.loops
    t.eq(#r.bad, 0, ("%s layer %d: %s"):format(name, g, r.bad[1] and r.bad[1].why or ""))
    for _, b in ipairs(l:blocks()) do
      if b.kind == "contour" and b.shape == "closed" then
        local len, P = 0, b.points
        for k = 1, #P // 2 - 1 do len = len + math.sqrt((P[2 * k + 1] - P[2 * k - 1]) ^ 2 + (P[2 * k + 2] - P[2 * k]) ^ 2) end
        worst = math.min(worst, len)
      end
    end
  end
  t.ok(loops >= #keep, name .. ": too few closed contours checked (" .. loops .. ")")
  t.ok(worst >= D, ("%s: a closed contour of %.4f mm, shorter than the track %g mm, was written"):format(name, worst, D))
  print(("  info: %s: %d closed contours on %d layers, shortest %.3f mm"):format(name, loops, #keep, worst))
end

t.test("the check itself: a contour with the solid on its right is caught, its reverse passes", function()
  local f = gradus.field.sphere(0.5, { center = { 1, 1, 0 } })
  local ring = {}
  for k = 0, 63 do
    local a = 2 * math.pi * k / 64
    ring[#ring + 1] = 1 + (0.5 - B) * math.cos(a)
    ring[#ring + 1] = 1 + (0.5 - B) * math.sin(a)
  end
  local rev = {}
  for k = #ring // 2, 1, -1 do rev[#rev + 1] = ring[2 * k - 1]; rev[#rev + 1] = ring[2 * k] end
  local good, bad = gradus.layer.new(0.04), gradus.layer.new(0.04)
  good:add("contour", "closed", ring)
  bad:add("contour", "closed", rev)
  local o = { field = f, z = 0, box = { 0, 0, 2, 2 }, offset = B }
  local rg, rb = t.contour_check(good, o), t.contour_check(bad, o)
  t.eq(#rg.bad, 0, "outer contour counter-clockwise: " .. (rg.bad[1] and rg.bad[1].why or ""))
  t.eq(#rb.bad, 1, "the same contour clockwise (solid on its right)")
  t.ok(rb.bad[1].why:find("solid on the right"), rb.bad[1].why)
  -- a hole: the solid outside a circle, the contour clockwise passes
  local hole = gradus.layer.new(0.04)
  local ringh = {}
  for k = #ring // 2, 1, -1 do
    local a = 2 * math.pi * (k - 1) / 64
    ringh[#ringh + 1] = 1 + (0.5 + B) * math.cos(a)
    ringh[#ringh + 1] = 1 + (0.5 + B) * math.sin(a)
  end
  hole:add("contour", "closed", ringh)
  t.eq(#t.contour_check(hole, { field = f:negate(), z = 0, box = { 0, 0, 2, 2 }, offset = B }).bad, 0, "hole clockwise")
end)

t.test("paper's graded column (P sheet, eq. 8): every closed contour oriented, faces included", function()
  local c = { 1, 1, 3 }
  -- local layer 31 of each cell, and the first two and last two layers of each cell
  local keep = { 1, 2, 31, 49, 50, 51, 52, 81, 99, 100, 101, 102, 131, 149, 150 }
  local st, layers, f = run("primitive", "0.1*(2*sin(pi*(w+1)/4)+1)", c, keep)
  t.eq(st.layers, 150, "layers")
  check_all("column", c, keep, layers, f)
end)

t.test("continuously graded gyroid sheet: oriented contours, the corner's short loop dropped and counted", function()
  local c = { 2, 2, 1 }
  local keep = { 1, 2, 12, 25, 38, 47, 48, 49, 50 }
  local st, layers, f = run("gyroid", "0.05+0.03*z", c, keep)
  check_all("gyroid", c, keep, layers, f)
  local cs = st.contours
  t.ok(cs and cs.dropped_short >= 1, "a short loop at the box's corner is counted (layer 48)")
  t.ok(cs.dropped_short_length > 0 and cs.dropped_short_length < cs.dropped_short * D,
    ("dropped length %.4f mm for %d loops"):format(cs.dropped_short_length, cs.dropped_short))
  print(("  info: gyroid: %d closed contours shorter than %g mm dropped, %.4f mm"):format(cs.dropped_short, D,
    cs.dropped_short_length))
end)

t.test("demo-like P lattice graded in z: oriented contours", function()
  local c = { 2, 2, 1 }
  local keep = { 1, 2, 13, 25, 37, 49, 50 }
  local _, layers, f = run("primitive", "0.06+0.02*z", c, keep)
  check_all("lattice", c, keep, layers, f)
end)

t.done()
