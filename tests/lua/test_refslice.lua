-- The reference slicer of the quality measurements (gradus.refslice, under
-- gradus.steptruth) against analytic boundaries: its own error must be far
-- below the 1 um the contours are held to. Base cell d/8 = 6.25 um as in
-- recipes/quality.lua; every check is on the segments' end points and chord
-- midpoints, against the exact curve.
local t = require "gradus.testing"
local refslice = require "gradus.refslice"
local truth = require "gradus.steptruth"
local CELL = 0.05 / 8

-- the largest distance of the segments' end points and midpoints to a
-- boundary given as a distance function dist(x, y), and the total length
local function off(E, dist)
  local worst, len = 0, 0
  for _, e in ipairs(E) do
    worst = math.max(worst, dist(e[1], e[2]), dist(e[3], e[4]), dist(0.5 * (e[1] + e[3]), 0.5 * (e[2] + e[4])))
    len = len + math.sqrt((e[3] - e[1]) ^ 2 + (e[4] - e[2]) ^ 2)
  end
  return worst, len
end

t.test("circle of radius 28 um: vertices and chords within 0.02 um (plain marching squares: 0.1 um off)", function()
  local r, z, c = 0.03, 0.01, 0.5
  local rho = math.sqrt(r * r - z * z)
  local f = gradus.field.sphere(r, { center = { c, c, 0 } })
  local function dist(x, y) return math.abs(math.sqrt((x - c) ^ 2 + (y - c) ^ 2) - rho) end
  local E = refslice.boundary(f, z, { 0.4013, 0.4007 }, { 0.6, 0.6 }, { cell = CELL })
  local worst, len = off(E, dist)
  t.ok(worst <= 2e-5, ("%.4g um off the circle"):format(worst * 1e3))
  t.near(len, 2 * math.pi * rho, 1e-5, "perimeter")
  -- the same grid without chords (the engine's slicer with chords off)
  local sec = gradus.slice.field(f, z, { lo = { 0.4013, 0.4007 }, hi = { 0.6, 0.6 }, cell = CELL })
  local R, raw = sec:ring(1), {}
  for k = 1, #R, 2 do raw[#raw + 1] = { R[k], R[k + 1], R[(k + 1) % #R + 1], R[(k + 2) % #R + 1] } end
  local w0 = off(raw, dist)
  t.ok(w0 > 1e-4, ("plain chords %.3g um off (the check can fail)"):format(w0 * 1e3))
end)

t.test("a 20 degree corner between grid nodes: the tip within 0.05 um, every point on the edges", function()
  -- solid: the wedge above both lines through the tip (x0, y0), opening up
  local x0, y0, a = 0.50317, 0.50123, math.rad(10)
  local n1x, n1y, n2x, n2y = -math.cos(a), math.sin(a), math.cos(a), math.sin(a)
  local f = gradus.field.expr(("max(%.17g*(x-%.17g) + %.17g*(y-%.17g), %.17g*(x-%.17g) + %.17g*(y-%.17g))")
    :format(-n1x, x0, -n1y, y0, -n2x, x0, -n2y, y0))
  -- f < 0 inside: -n . (p - tip) < 0 for both normals n pointing into the solid
  local function dist(x, y)
    local dx, dy = x - x0, y - y0
    local d1, d2 = math.abs(-n1x * dx - n1y * dy), math.abs(-n2x * dx - n2y * dy)
    if dy < 0 then return math.sqrt(dx * dx + dy * dy) end
    return math.min(d1, d2)
  end
  local E = refslice.boundary(f, 0, { 0.45, 0.45 }, { 0.6, 0.6 }, { cell = CELL })
  local worst = off(E, dist)
  local tip = math.huge
  for _, e in ipairs(E) do tip = math.min(tip, math.sqrt((e[1] - x0) ^ 2 + (e[2] - y0) ^ 2)) end
  t.ok(worst <= 2e-5, ("%.4g um off the edges"):format(worst * 1e3))
  t.ok(tip <= 5e-5, ("tip %.3g um away"):format(tip * 1e3))
end)

-- a void sliver between a jump of f (the line y = 0: below it f = -0.05,
-- solid) and the line y = 0.05 x (above it solid): 0 < y < 0.05 x, x > 0,
-- narrower than the base cell up to x = 125 um, as where a graded thickness
-- jumps across the medial surface
t.test("a sliver narrower than the grid along a jump of f: found to its tip", function()
  local th = 0.05
  local f = gradus.field.lua(function(x, y)
    if y < 0 then return -0.05 end
    return (th * x - y) / math.sqrt(1 + th * th)
  end)
  local function dist(x, y)
    if x < 0 then return math.sqrt(x * x + y * y) end
    return math.min(math.abs(y), math.abs(th * x - y) / math.sqrt(1 + th * th))
  end
  local lo, hi = { -0.0503, -0.0501 }, { 0.15, 0.05 }
  local E = refslice.boundary(f, 0, lo, hi, { cell = CELL })
  local worst = off(E, dist)
  local tip = math.huge
  for _, e in ipairs(E) do tip = math.min(tip, math.sqrt(e[1] ^ 2 + e[2] ^ 2)) end
  t.ok(worst <= 2e-5, ("%.4g um off the sliver's sides"):format(worst * 1e3))
  t.ok(tip <= 5e-4, ("tip found %.3g um away"):format(tip * 1e3))
  -- the plain grid loses the tip by tens of micrometres
  local sec = gradus.slice.field(f, 0, { lo = lo, hi = hi, cell = CELL })
  local tip0 = math.huge
  for i = 1, sec:count() do
    local R = sec:ring(i)
    for k = 1, #R, 2 do
      if R[k] > lo[1] + 1e-9 and R[k] < hi[1] - 1e-9 and math.abs(R[k + 1]) < 0.01 then tip0 = math.min(tip0, R[k]) end
    end
  end
  t.ok(tip0 > 0.01, ("plain grid: tip at x = %.3g um (the check can fail)"):format(tip0 * 1e3))
end)

t.test("two voxels, discs of radius 0.3 | 0.2 across x = 1: the step on the face, exact", function()
  local c = 1.0
  local V = {
    { lo = { 0.5, 0.5 }, hi = { 1, 1.5 }, field = gradus.field.sphere(0.3, { center = { c, c, 0 } }) },
    { lo = { 1, 0.5 }, hi = { 1.5, 1.5 }, field = gradus.field.sphere(0.2, { center = { c, c, 0 } }) },
  }
  local function dist(x, y)
    local r = math.sqrt((x - c) ^ 2 + (y - c) ^ 2)
    local d = x < c and math.abs(r - 0.3) or math.abs(r - 0.2)
    if math.abs(x - c) < 1e-12 and math.abs(y - c) >= 0.2 and math.abs(y - c) <= 0.3 then d = 0 end
    return math.min(d, math.sqrt((x - c) ^ 2 + math.min((math.abs(y - c) - 0.2) ^ 2, (math.abs(y - c) - 0.3) ^ 2)))
  end
  local E = truth.edges(V, 0, { lo = { 0.5, 0.5 }, hi = { 1.5, 1.5 } }, CELL)
  local worst, len = off(E, dist)
  local face = 0
  for _, e in ipairs(E) do
    if e[1] == c and e[3] == c then face = face + math.abs(e[4] - e[2]) end
  end
  t.ok(worst <= 2e-5, ("%.4g um off the stepped boundary"):format(worst * 1e3))
  t.near(face, 0.2, 1e-7, "the step's length on the face")
  t.near(len, math.pi * 0.3 + math.pi * 0.2 + 0.2, 1e-5, "the boundary's length")
end)
-- steptruth.local_deviation: the distance from a contour point to the
-- nearest void on the voxels' own fields, measured on a 0.1 um grid: against a
-- circle, and against a crease of the field touching zero (a void sliver
-- 0.67 um wide at x = 0 tapering to a tip at x = 1.667 um along y = 0: the
-- kind of horn a thick sheet's distance makes along its medial surface,
-- where slicers are ill-conditioned); across a voxel face the point's voxel
-- is the one whose square holds each sample.
t.test("local deviation: a circle, a thin crease's tip, a face", function()
  local b = 0.025
  local circle = gradus.field.expr("sqrt(x^2 + y^2) - 0.3") -- void outside
  local V = { { lo = { -1, -1 }, hi = { 1, 1 }, field = circle } }
  local dev, found = truth.local_deviation(V, 0, 0.3 - b - 0.0007, 0, b)
  t.ok(found, "void found")
  t.near(dev, 0.0007, 5e-5, "circle: 0.7 um farther than b")
  local crease = gradus.field.expr("0.0001 - 0.3*abs(y) - 0.06*x") -- void along y = 0 for x < 1.667 um
  local tip = 0.0001 / 0.06
  V = { { lo = { -1, -1 }, hi = { 1, 1 }, field = crease } }
  dev, found = truth.local_deviation(V, 0, tip + 0.02, 0.003, b)
  t.ok(found, "crease: void found")
  t.near(dev, math.sqrt(0.02 ^ 2 + 0.003 ^ 2) - b, 1.5e-4, "crease: the tip within 0.15 um")
  dev, found = truth.local_deviation(V, 0, tip + 0.03, 0, b, { reach = 0.002 })
  t.ok(not found and dev == 0.002, "no void within b + reach: the reach as a lower bound")
  -- the same crease owned only left of x = 0: right of it a solid voxel (-1); the nearest void is
  -- the crease at x < 0, 0.02 mm from a point at (0.02, 0)
  V = { { lo = { -1, -1 }, hi = { 0, 1 }, field = crease }, { lo = { 0, -1 }, hi = { 1, 1 }, field = gradus.field.constant(-1) } }
  dev = truth.local_deviation(V, 0, 0.02, 0, b)
  t.near(dev, 0.02 - b, 1.5e-4, "face: the void ends on the face")
  t.raises(function() truth.local_deviation(V, 0, 0, 0, b, { h = 0 }) end, "bad option 'h'")
  t.raises(function() truth.local_deviation(V, 0, 0, 0, b, { reach = -1 }) end, "bad option 'reach'")
end)

t.done()
