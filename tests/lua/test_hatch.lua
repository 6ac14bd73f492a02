-- The hatch primitive and layers from Lua: counts and lengths against
-- analytic values, options, errors.
local t = require "gradus.testing"
local hatch = gradus.hatch

local function rect(x0, y0, x1, y1) return { { x0, y0, x1, y0, x1, y1, x0, y1 } } end
local function circle(cx, cy, r, n)
  local p = {}
  for i = 0, n - 1 do
    local a = 2 * math.pi * i / n
    p[#p + 1] = cx + r * math.cos(a); p[#p + 1] = cy + r * math.sin(a)
  end
  return { p }
end

t.test("square hatched along x: count and length", function()
  -- lines y = k*0.1 with 0.027 <= y < 1.027: k = 1..10, each 1 mm
  local l, rep = hatch.region(rect(0.013, 0.027, 1.013, 1.027), { spacing = 0.1, angle = 0 })
  local s = l:stats()
  t.eq(s.hatch.vectors, 10, "vectors") ; t.near(s.hatch.length, 10, 1e-9, "length")
  t.eq(rep.hatches, 10, "report")
  for _, b in ipairs(l:blocks()) do
    t.eq(b.kind, "hatch", "kind") ; t.eq(b.shape, "segments", "shape") ; t.eq(b.laser, 1, "laser")
    for i = 2, #b.points, 2 do t.near(b.points[i] / 0.1, math.floor(b.points[i] / 0.1 + 0.5), 1e-9, "on a line") end
  end
end)

t.test("layer: contour at b, hatch region, tostring", function()
  local l, rep = hatch.layer(rect(0.013, 0.027, 2.013, 2.027), { spacing = 0.1, angle = 0, z = 0.04 })
  t.near(l:z(), 0.04, 0, "z")
  local s = l:stats()
  t.eq(s.contour.blocks, 1, "one contour") ; t.eq(rep.contours, 1, "report contours")
  -- the distance-field offset cuts the corners by about a grid cell
  t.near(s.contour.length, 4 * 1.9, 0.05, "contour length (offset square 1.9 mm)")
  -- hatch region: the square offset by b = 0.05, 1.9 mm wide: 19 lines
  t.near(s.hatch.length, 19 * 1.9, 0.2, "hatch length")
  local b = l:blocks()[1]
  t.eq(b.shape, "closed", "closed") ; t.eq(b.dir, 1, "CCW outer")
  t.eq(b.points[1], b.points[#b.points - 1], "first point repeated")
  t.ok(tostring(l):match("^layer z=0.04: 1 contours %(7%.%d+ mm%), %d+ hatches"), tostring(l))
end)

t.test("contour chords follow the offset's arcs around the section's corners", function()
  -- a 2 mm square with a 0.6 mm square hole: the contour at b runs on quarter
  -- circles of radius b around the hole's corners, and turns a right angle
  -- at the outer square's; chords between two crossings of the grid (cell
  -- d/4) cut both (by 6.3 um before the offsets' chords were refined)
  local b, lo, hi = 0.025, 0.7, 1.3
  local sec = { { 0, 0, 2, 0, 2, 2, 0, 2 }, { lo, lo, lo, hi, hi, hi, hi, lo } }
  local l = hatch.layer(sec, { spacing = 0.05, beam_offset = b, angle = 0, z = 0.04 })
  local function dist(x, y) -- to the section's boundary, analytic
    local dx, dy = math.max(lo - x, 0, x - hi), math.max(lo - y, 0, y - hi)
    return math.min(math.sqrt(dx * dx + dy * dy), x, y, 2 - x, 2 - y)
  end
  local worst, n, on_arc = 0, 0, 0
  for _, bk in ipairs(l:blocks()) do
    if bk.kind == "contour" then
      local P = bk.points
      for q = 1, #P - 3, 2 do
        for s = 0, 3 do -- the vertex and three points inside the chord
          local x, y = P[q] + s / 4 * (P[q + 2] - P[q]), P[q + 1] + s / 4 * (P[q + 3] - P[q + 1])
          worst = math.max(worst, math.abs(dist(x, y) - b))
          n = n + 1
          if (x < lo or x > hi) and (y < lo or y > hi) and dist(x, y) < 0.5 then on_arc = on_arc + 1 end
        end
      end
    end
  end
  t.ok(on_arc >= 16, "points on the hole's corner arcs: " .. on_arc)
  -- the offsets' chord tolerance (0.5 um) and the crossings' (1 nm), rounding aside
  t.ok(worst <= 5.1e-4, ("contour %.3f um off the offset (%d points)"):format(worst * 1e3, n))
end)

t.test("angle sequence", function()
  t.near(hatch.angle(0), 45, 1e-12, "default first") ; t.near(hatch.angle(1), 112, 1e-12, "+67")
  t.near(hatch.angle(3, 45, 67), 246, 1e-12, "k=3") ; t.near(hatch.angle(5, 0, 90), 90, 1e-12, "90")
end)

t.test("patterns", function()
  local L = { { 0.01, 0.02, 2.01, 0.02, 2.01, 1.02, 1.01, 1.02, 1.01, 2.02, 0.01, 2.02 } }
  local z = hatch.region(L, { spacing = 0.1, angle = 0, pattern = "zigzag" })
  local bl = z:blocks()
  t.ok(#bl <= 3, "zigzag joins the L into few polylines, got " .. #bl)
  t.eq(bl[1].shape, "open", "open polylines") ; t.eq(bl[1].dir, 2, "dir 2")
  local isl = hatch.region(rect(0.003, 0.007, 4.003, 4.007), { spacing = 0.1, angle = 0, pattern = "island", island = 1 })
  local nx, ny = 0, 0
  for _, b in ipairs(isl:blocks()) do
    local p = b.points
    for i = 1, #p, 4 do
      if math.abs(p[i + 3] - p[i + 1]) < 1e-12 then nx = nx + 1 else ny = ny + 1 end
      local I = math.floor((p[i] + p[i + 2]) / 2)
      t.ok(p[i] >= I - 1e-9 and p[i] <= I + 1 + 1e-9 and p[i + 2] >= I - 1e-9 and p[i + 2] <= I + 1 + 1e-9,
        "vector within one island column")
    end
  end
  t.ok(nx > 0 and ny > 0, "both directions")
  t.near(isl:stats().hatch.length, 16 / 0.1, 2, "islands cover the square")
end)

t.test("min length and thin walls are counted", function()
  local _, rep = hatch.region({ { 0, 0.005, 1, 0.005, 0, 1.005 } }, { spacing = 0.1, angle = 0, min_length = 0.3 })
  t.eq(rep.dropped, 3, "dropped") ; t.eq(rep.hatches, 7, "kept")
  local sec = rect(0.013, 0.027, 2.013, 2.027)
  sec[2] = { 3, 0, 5, 0, 5, 0.06, 3, 0.06 }
  local l, r2 = hatch.layer(sec, { spacing = 0.1 })
  t.eq(r2.thin_walls, 1, "thin wall") ; t.eq(l:stats().thin_walls, 1, "layer counts it")
  t.ok(tostring(l):match("1 thin walls"), tostring(l))
  -- the strip (0.06 wide, b = 0.05) gets a centre line, tagged, reported
  local thin = {}
  for _, b in ipairs(l:blocks()) do if b.thin then thin[#thin + 1] = b end end
  t.eq(#thin, 1, "one thin-wall line") ; t.eq(r2.thin_scans, 1, "reported")
  t.eq(thin[1].kind, "contour", "kind") ; t.eq(thin[1].shape, "open", "shape") ; t.eq(thin[1].dir, 3, "dir")
  for q = 2, #thin[1].points, 2 do
    local x = thin[1].points[q - 1]
    -- on the axis, but where the medial axis forks into the end's corners
    t.near(thin[1].points[q], 0.03, (x > 3.05 and x < 4.95) and 1e-6 or 0.015, "on the strip's axis")
  end
  t.ok(r2.thin_length > 1.9 and r2.thin_length < 2, ("thin length %.4f"):format(r2.thin_length))
  t.eq(r2.contours, 1, "the square's contour only")
  local q = hatch.verify(sec, l, { track = 0.1, clip_lo = { 2.5, -1 }, clip_hi = { 6, 1 } })
  t.eq(q.thin_scans, 1, "verify: thin scan") ; t.eq(q.contour_points, 0, "no contour point in the strip's box")
  t.near(q.thin_length, r2.thin_length, 1e-9, "verify: thin length") ; t.eq(q.max_dev, 0, "not a deviation")
  -- thin_box: the strip lies outside the square's box, so it is not a wall there
  local _, r3 = hatch.layer(sec, { spacing = 0.1, thin_box = { 0, 0, 2.1, 2.1 } })
  t.eq(r3.thin_walls, 0, "strip outside thin_box ignored") ; t.eq(r3.contours, 1, "square still contoured")
  t.raises(function() hatch.layer(sec, { spacing = 0.1, thin_box = { 0, 0 } }) end, "thin_box")
  t.raises(function() hatch.layer(sec, { spacing = 0.1, thin_box = { 0, 0, 0 / 0, 1 } }) end, "thin_box must be")
  t.raises(function() hatch.layer(sec, { spacing = 0.1, thin_box = { 2, 0, 1, 1 } }) end, "x0 <= x1")
end)

t.test("verify", function()
  local disc = circle(0.011, 0.007, 1, 720)
  local l = hatch.layer(disc, { spacing = 0.1, angle = 45 })
  local q = hatch.verify(disc, l, { track = 0.1 })
  t.ok(q.pore < 0.005, "pore " .. q.pore) ; t.ok(q.overmelt < 0.01, "overmelt " .. q.overmelt)
  t.near(q.solid_area, math.pi, 0.03, "solid area")
  t.ok(q.max_dev < 0.02, "contour deviation " .. q.max_dev)
  local sq = rect(0.013, 0.027, 3.013, 3.027)
  local u = hatch.region(sq, { spacing = 0.3, angle = 0 })
  t.near(hatch.verify(sq, u, { track = 0.1 }).pore, 2 / 3, 0.02, "under-hatched")
end)

t.test("layers built by hand", function()
  local l = gradus.layer.new(0.1)
  l:add("hatch", "segments", { 0, 0, 1, 0, 0, 1, 1, 1 })
  l:add("contour", "closed", { 0, 0, 1, 0, 1, 1, 0, 1 }, 2)
  local s = l:stats()
  t.eq(s.hatch.vectors, 2, "two segments") ; t.near(s.hatch.length, 2, 1e-12, "length")
  t.near(s.contour.length, 4, 1e-12, "closed square closed automatically")
  local b = l:blocks()[2]
  t.eq(#b.points, 10, "first point repeated") ; t.eq(b.laser, 2, "laser") ; t.eq(b.dir, 1, "CCW")
  l:translate(1, 2)
  local x0, y0, x1, y1 = l:bounds()
  t.near(x0, 1, 0, "x0") ; t.near(y1, 3, 0, "y1")
  local m = gradus.layer.new(0.1):append(l):append(l, 10, 0)
  t.near(m:stats().hatch.length, 4, 1e-12, "appended twice")
end)

t.test("errors", function()
  local sq = rect(0, 0, 1, 1)
  t.raises(function() hatch.layer(sq, { spacing = -0.05 }) end, "spacing must be > 0, got %-0.05")
  t.raises(function() hatch.layer(sq, { spaceing = 0.1 }) end, "unknown option 'spaceing'")
  t.raises(function() hatch.layer(sq, { pattern = "spiral" }) end, "spiral")
  t.raises(function() hatch.layer(sq, { angle = 0 / 0 }) end, "angle")
  t.raises(function() hatch.layer(sq, { spacing = "x" }) end, "spacing")
  t.raises(function() hatch.verify(sq, gradus.layer.new(0), {}) end, "track")
  t.raises(function() hatch.layer({ { 0, 0, 1 } }) end, "ring 1")
  t.raises(function() gradus.layer.new(0):add("hatch", "segments", { 0, 0, 1 }) end, "pairs")
  t.raises(function() gradus.layer.new(0):add("laser", "open", { 0, 0, 1, 1 }) end, "laser")
end)

t.done()
