-- Direct slicing: analytic rings (circle, annulus, sphere section), their
-- orientation and nesting, points on the true boundary after refinement, the
-- in-plane offset of a circle, the eq. (7) resolution rule.
local t = require "gradus.testing"

t.test("circle section: area, orientation, points on the circle", function()
  local r = gradus.slice.field("sqrt(x^2+y^2) - 1.5", 0, { lo = { -2, -2 }, hi = { 2, 2 }, cell = 0.05 })
  t.eq(r:count(), 1, "one ring")
  local ring = r:ring(1)
  t.ok(ring.area > 0, "outer ring counter-clockwise")
  local n = #ring // 2
  local chord = 0
  for q = 1, #ring, 2 do
    t.near(math.sqrt(ring[q] ^ 2 + ring[q + 1] ^ 2), 1.5, 1e-6, "point on the circle")
    local q2 = q + 2 > #ring and 1 or q + 2
    chord = math.max(chord, math.sqrt((ring[q2] - ring[q]) ^ 2 + (ring[q2 + 1] - ring[q + 1]) ^ 2))
  end
  -- inscribed polygon: area between pi R^2 (1 - chord^2/(4R^2)) and pi R^2
  local A = math.pi * 1.5 ^ 2
  t.ok(r:area() <= A + 1e-9 and r:area() >= A * (1 - chord ^ 2 / (4 * 1.5 ^ 2)), ("area %.6f vs %.6f"):format(r:area(), A))
  t.ok(n > 50, "ring points")
end)

t.test("annulus: outer CCW, hole CW with its parent", function()
  local r = gradus.slice.field("max(1 - sqrt(x^2+y^2), sqrt(x^2+y^2) - 2)", 0, { lo = { -3, -3 }, hi = { 3, 3 }, cell = 0.05 })
  t.eq(r:count(), 2, "two rings")
  local outer, hole
  for i = 1, 2 do
    local ring = r:ring(i)
    if ring.area > 0 then outer = i else hole = i end
  end
  t.ok(outer and hole, "one outer, one hole")
  t.eq(r:ring(hole).parent, outer, "the hole's parent is the outer ring")
  t.near(r:area(), math.pi * (4 - 1), 0.01, "annulus area")
  t.ok(r:contains(1.5, 0) and not r:contains(0, 0) and not r:contains(2.5, 0), "even-odd inside test")
end)

t.test("sphere section at a height is the circle of radius sqrt(R^2 - z^2)", function()
  local r = gradus.slice.field("sqrt(x^2+y^2+z^2) - 3", 1.8, { lo = { -3.5, -3.5 }, hi = { 3.5, 3.5 }, cell = 0.05 })
  local ring = r:ring(1)
  for q = 1, #ring, 2 do t.near(math.sqrt(ring[q] ^ 2 + ring[q + 1] ^ 2), 2.4, 1e-6, "radius 2.4") end
end)

t.test("in-plane offset of a circle is the circle of radius R - b", function()
  local r = gradus.slice.field("sqrt(x^2+y^2) - 1.5", 0, { lo = { -2, -2 }, hi = { 2, 2 }, cell = 0.0125 })
  local o = gradus.slice.offset(r, 0.025, { cell = 0.0125 })
  -- the offset is taken from the polygonal section, whose chords lie inside the circle by at most
  -- s^2/(8R) (s the longest chord): that bounds the radius error
  local sec, s = r:ring(1), 0
  for q = 1, #sec - 2, 2 do s = math.max(s, math.sqrt((sec[q + 2] - sec[q]) ^ 2 + (sec[q + 3] - sec[q + 1]) ^ 2)) end
  local tol = s ^ 2 / (8 * 1.5) + 1e-7
  local ring = o:ring(1)
  for q = 1, #ring, 2 do t.near(math.sqrt(ring[q] ^ 2 + ring[q + 1] ^ 2), 1.475, tol, "offset radius") end
  t.eq(gradus.slice.offset(r, 1.6, { cell = 0.0125 }):count(), 0, "an offset wider than the disc leaves nothing")
end)

t.test("eq. (7): a grid coarser than d/2 is refused", function()
  t.eq(gradus.slice.max_cell(0.05), 0.025, "d/2")
  t.raises(function() gradus.slice.field("x", 0, { lo = { 0, 0 }, hi = { 1, 1 }, hatch = 0.05, cell = 0.04 }) end, "eq. 7")
end)

t.done()
