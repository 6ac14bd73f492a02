-- True-distance domains (issue 19): a domain expression of any scale is made a
-- signed distance in mm near its boundary (gradus.field.distance, the
-- lattice recipe's domain=), so the skin has its depth in mm. Checked
-- against analytic truth: the distance to a cylinder and to an ellipsoid,
-- and the skin band of a cylinder part, whose contours must lie at radius
-- R - b and R - s + b (b the beam offset, s the skin) within 1 um, closed,
-- whichever way the cylinder is written (a squared form or a distance) and
-- for an STL cylinder.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local R, S, B, D = 4, 0.3, 0.025, 0.05 -- cylinder radius about (5, 5), skin, beam offset, hatch (mm)
local SQUARED, DIST = "(x-5)^2+(y-5)^2-16", "sqrt((x-5)^2+(y-5)^2)-4"

t.test("gradus.field.distance: signed distance to a cylinder given squared, at any scale", function()
  for _, src in ipairs { SQUARED, "1000*((x-5)^2+(y-5)^2-16)", "0.001*((x-5)^2+(y-5)^2-16)" } do
    local d = gradus.field.distance(src, { band = 1.5, cell = 2 })
    for _, r in ipairs { 3.1, 3.5, 3.7, 3.95, 4, 4.02, 4.3, 4.9 } do
      local a = 0.3 + r -- any direction
      t.near(d:eval(5 + r * math.cos(a), 5 + r * math.sin(a), 0.7), r - R, 1e-9, ("%s at r = %g"):format(src, r))
    end
    -- beyond the band only the sign is asked for (a bound of at least the band)
    t.ok(d:eval(5.5, 5, 0) <= -1, src .. ": deep inside")
    t.ok(d:eval(12, 5, 0) >= 1, src .. ": far outside")
  end
end)

t.test("gradus.field.distance: an ellipsoid, against the closest of dense surface samples", function()
  local a, b, c = 3, 2, 1
  local d = gradus.field.distance(("x^2/%g+y^2/%g+z^2/%g-1"):format(a * a, b * b, c * c), { band = 0.6, cell = 2 })
  local pts = { { 3.2, 0.3, 0.1 }, { 1.0, 1.7, 0.4 }, { 0.5, 0.4, 0.8 }, { 2.0, -1.2, 0.5 }, { -2.5, 0.2, -0.3 } }
  for _, p in ipairs(pts) do
    -- brute force: the nearest of a dense parametric sampling, refined locally
    local best, bu, bv = math.huge, 0, 0
    local N = 400
    for i = 0, N do
      local u = math.pi * i / N
      for k = 0, 2 * N - 1 do
        local v = math.pi * k / N
        local x, y, z = a * math.sin(u) * math.cos(v), b * math.sin(u) * math.sin(v), c * math.cos(u)
        local q = (x - p[1]) ^ 2 + (y - p[2]) ^ 2 + (z - p[3]) ^ 2
        if q < best then best, bu, bv = q, u, v end
      end
    end
    local h = math.pi / N
    for _ = 1, 40 do
      for _, du in ipairs { -h, h } do
        local x, y, z = a * math.sin(bu + du) * math.cos(bv), b * math.sin(bu + du) * math.sin(bv), c * math.cos(bu + du)
        local q = (x - p[1]) ^ 2 + (y - p[2]) ^ 2 + (z - p[3]) ^ 2
        if q < best then best, bu = q, bu + du end
      end
      for _, dv in ipairs { -h, h } do
        local x, y, z = a * math.sin(bu) * math.cos(bv + dv), b * math.sin(bu) * math.sin(bv + dv), c * math.cos(bu)
        local q = (x - p[1]) ^ 2 + (y - p[2]) ^ 2 + (z - p[3]) ^ 2
        if q < best then best, bv = q, bv + dv end
      end
      h = h * 0.7
    end
    local inside = p[1] ^ 2 / (a * a) + p[2] ^ 2 / (b * b) + p[3] ^ 2 / (c * c) < 1
    local truth = (inside and -1 or 1) * math.sqrt(best)
    t.ok(math.abs(truth) < 0.6, "the sample point lies within the band")
    t.near(d:eval(p[1], p[2], p[3]), truth, 1e-6, ("ellipsoid at (%g, %g, %g)"):format(p[1], p[2], p[3]))
  end
end)

t.test("gradus.field.distance: a distance stays itself, NaN from the domain names the domain", function()
  local s = gradus.field.sphere(1)
  local d = gradus.field.distance(s, { band = 1, cell = 2 })
  t.near(d:eval(1.5, 0.2, 0.1), s:eval(1.5, 0.2, 0.1), 1e-9, "sphere: distance in the band unchanged")
  t.near(d:eval(3, 0, 0), s:eval(3, 0, 0), 1e-6, "sphere: the estimate beyond the band")
  t.raises(function() gradus.field.distance("sqrt(x-5)", { band = 1, cell = 2 }):eval(1, 1, 1) end,
    "domain: expression 'sqrt%(x%-5%)' gave nan at x=1, y=1, z=1")
end)

-- The skin band alone: a P network at level -2.9 is small blobs at the cell
-- corners (z = 0, 2): the layer at z = 0.98 holds no lattice, so its section
-- is the annulus R - S <= r <= R of the skin. Returns the layer and stats.
local function ring(domain, as_dist, layer)
  local p = lattice.params()
  layer = layer or 25
  if as_dist ~= nil then p.domain_distance = as_dist end
  p.surface, p.kind, p.level, p.thickness = "primitive", "network", -2.9, "0.05"
  p.cells, p.kb, p.layers, p.pictures, p.hatch = "5,5,1", "off", layer .. ":" .. layer, tostring(layer), D
  p.domain, p.skin = domain, S
  local st, kept = lattice.run(p, nil)
  return kept[layer], st
end

-- contours of a layer: {closed, dir, rmin, rmax, area} each; hatch length
local function measure(l)
  local cs, hl = {}, 0
  for _, b in ipairs(l:blocks()) do
    local P = b.points
    if b.kind == "contour" then
      local rmin, rmax, area = math.huge, -math.huge, 0
      for k = 1, #P - 1, 2 do
        local r = math.sqrt((P[k] - 5) ^ 2 + (P[k + 1] - 5) ^ 2)
        rmin, rmax = math.min(rmin, r), math.max(rmax, r)
        if k + 3 <= #P then area = area + 0.5 * (P[k] * P[k + 3] - P[k + 2] * P[k + 1]) end
      end
      local closed = b.shape == "closed" and P[1] == P[#P - 1] and P[2] == P[#P]
      cs[#cs + 1] = { closed = closed, dir = b.dir, rmin = rmin, rmax = rmax, area = area }
    elseif b.kind == "hatch" then
      for q = 1, #P - 3, 4 do hl = hl + math.sqrt((P[q + 2] - P[q]) ^ 2 + (P[q + 3] - P[q + 1]) ^ 2) end
    end
  end
  table.sort(cs, function(u, v) return u.rmax < v.rmax end)
  return cs, hl
end

local function check_ring(name, l, tol)
  local cs, hl = measure(l)
  t.eq(#cs, 2, name .. ": two contours, the skin's inner and outer")
  if #cs ~= 2 then return end
  local inner, outer = cs[1], cs[2]
  t.ok(inner.closed and outer.closed, name .. ": both contours closed")
  t.near(inner.rmin, R - S + B, tol, name .. ": inner contour, nearest point")
  t.near(inner.rmax, R - S + B, tol, name .. ": inner contour, farthest point")
  t.near(outer.rmin, R - B, tol, name .. ": outer contour, nearest point")
  t.near(outer.rmax, R - B, tol, name .. ": outer contour, farthest point")
  local annulus = math.pi * ((R - B) ^ 2 - (R - S + B) ^ 2)
  t.near(math.abs(outer.area) - math.abs(inner.area), annulus, 1e-3 * annulus, name .. ": area between the contours")
  t.ok(outer.area > 0 and inner.area < 0, name .. ": outer counter-clockwise, inner clockwise")
  t.near(hl * D, annulus, 0.03 * annulus, name .. ": hatched area (length x spacing)")
  return hl
end

-- a domain expression is used as given; gradus.field.distance makes a smooth one a distance in mm
local function as_distance(expr) return gradus.field.distance(gradus.field.expr(expr), { band = 2 * S + 1, cell = 2 }) end

t.test("skin of a cylinder domain written squared (made a distance) or as a distance: the same band, depth in mm (1 um)", function()
  local l1, st1 = ring(as_distance(SQUARED))
  local h1 = check_ring("squared", l1, 1e-3)
  local l2 = ring(DIST)
  local h2 = check_ring("distance", l2, 1e-3)
  -- the hatch regions of both lie within the offsets' chord tolerance (0.5 um) of the same offset,
  -- and a vector's end moves with them (more where its line grazes the boundary); the offsets'
  -- grids may differ where the edge checks decide otherwise on values a few ulps apart. A band of
  -- another depth (1 % off, say) changes the hatch length by about as much.
  t.near(h1, h2, 1e-3 * h2, "hatch length of both forms")
  local l3 = ring(SQUARED) -- the lattice recipe does the same by default (domain_distance=true)
  local h3 = check_ring("squared, by default", l3, 1e-3)
  t.near(h3, h1, 1e-3 * h1, "hatch length of the squared form by default")
  -- domain_distance=false: the expression's own values, 8 times the distance near r = 4, so the
  -- band is about 0.3/8 mm deep: narrower than two beam offsets, hardly anything to hatch
  local _, h4 = measure(ring(SQUARED, false))
  t.ok(h4 < 0.2 * h1, ("domain_distance=false keeps the values (hatch %.2f mm against %.2f mm)"):format(h4, h1))
  t.eq(st1.trimmed_voxels, 24, "the centre voxel (corners 2.6 mm inside) is an ordinary voxel")
end)

-- the squared cylinder cut by the planes z = 0.4 and z = 1.6: the max of terms of different
-- scales, whose larger value is not the nearer boundary (at r = 3.7, z = 0.98 the caps' term
-- -0.58 wins over the wall's -2.31, though the wall is 0.3 mm away and the caps 0.58 mm)
local CAPPED = "max((x-5)^2+(y-5)^2-16, abs(z-1)-0.6)"

t.test("skin of a squared cylinder cut by planes: the wall's band in mm mid-height, solid under the cap", function()
  check_ring("capped, z = 0.98", ring(CAPPED, nil, 25), 1e-3)
  local cs, hl = measure(ring(CAPPED, nil, 36)) -- z = 1.42: 0.18 mm under the cap, all skin
  t.eq(#cs, 1, "under the cap: one contour, the disk's")
  if cs[1] then t.near(cs[1].rmin, R - B, 1e-3, "under the cap: the disk's contour at R - b") end
  local disk = math.pi * (R - B) ^ 2
  t.near(hl * D, disk, 0.03 * disk, "under the cap: the whole disk hatched")
end)

t.test("gradus.field.distance of the capped cylinder: exact away from its rims, within 0.04 mm at them", function()
  local d = gradus.field.distance(CAPPED, { band = 1.6, cell = 2, box = { 0, 0, 0, 10, 10, 2 } })
  local far, near = 0, 0
  for k = 0, 3999 do -- a deterministic spread of points inside and outside, within 0.5 mm of the wall
    local r, a, z = 3.5 + (k * 0.618034) % 1, k * 2.39996, 0.2 + 1.6 * ((k * 0.414214) % 1)
    local dr, dz = r - R, math.abs(z - 1) - 0.6
    local truth = (dr > 0 or dz > 0) and math.sqrt(math.max(dr, 0) ^ 2 + math.max(dz, 0) ^ 2) or math.max(dr, dz)
    local err = math.abs(d:eval(5 + r * math.cos(a), 5 + r * math.sin(a), z) - truth)
    -- the rims (r = 4, z = 0.4 or 1.6) are edges that no projection reaches and the mesh cuts:
    -- the points whose closest point is a rim (outside, dr > 0 and dz > 0) and those near one
    if (dr > 0 and dz > 0) or math.sqrt(dr ^ 2 + dz ^ 2) < 0.1 then near = math.max(near, err) else far = math.max(far, err) end
  end
  t.ok(far < 1e-6, ("closest point on the wall or a cap, 0.1 mm or more from the rims: max error %.2g mm"):format(far))
  t.ok(near < 0.04, ("closest point a rim, or near one: max error %.3f mm"):format(near))
end)

t.test("skin of an STL cylinder: depth in mm (within the facets' chord error)", function()
  local stl = tmp .. "/cyl.stl"
  local m = gradus.mc("max(sqrt((x-5)^2+(y-5)^2)-4,max(z-2.6,-0.6-z))",
    { lo = { 0.5, 0.5, -1 }, hi = { 9.5, 9.5, 3 }, res = 72, refine = true })
  m:write(stl)
  local l = ring(stl)
  -- facets are chords of the circle: the mesh lies inside it by at most the sagitta of a
  -- 0.25 mm edge, (0.25/2)^2 / (2 R) = 2 um; marching cubes adds cut corners of the same order
  check_ring("STL", l, 0.002)
end)

local function seg_dist(px, py, x0, y0, x1, y1)
  local dx, dy = x1 - x0, y1 - y0
  local u = math.max(0, math.min(1, ((px - x0) * dx + (py - y0) * dy) / (dx * dx + dy * dy)))
  return math.sqrt((x0 + u * dx - px) ^ 2 + (y0 + u * dy - py) ^ 2)
end

t.test("gyroid in a squared cylinder with a skin: every contour closed across voxel borders, the band hatched", function()
  local p = lattice.params()
  -- layer 31 (z = 1.22): the gyroid grazes the skin's inner side at a voxel border (x = 2.8, y = 2),
  -- where a 16 um excursion of the contour across the border was left open before
  p.surface = "gyroid"
  p.cells, p.kb, p.layers, p.pictures, p.hatch = "5,5,1", "off", "31:31", "31", D
  p.domain, p.skin = as_distance(SQUARED), S
  local _, kept = lattice.run(p, nil)
  for _, g in ipairs { 31 } do
    local open, closed, rmax, segs = 0, 0, 0, {}
    for _, b in ipairs(kept[g]:blocks()) do
      local P = b.points
      if b.kind == "contour" then
        if b.shape == "closed" and P[1] == P[#P - 1] and P[2] == P[#P] then closed = closed + 1 else open = open + 1 end
        for k = 1, #P - 1, 2 do rmax = math.max(rmax, math.sqrt((P[k] - 5) ^ 2 + (P[k + 1] - 5) ^ 2)) end
      elseif b.kind == "hatch" then
        for q = 1, #P - 3, 4 do segs[#segs + 1] = { P[q], P[q + 1], P[q + 2], P[q + 3] } end
      end
    end
    t.eq(open, 0, ("layer %d: contour polylines not closed"):format(g))
    t.ok(closed >= 2, ("layer %d: %d closed contours"):format(g, closed))
    t.near(rmax, R - B, 1e-3, ("layer %d: the outer contour at R - b"):format(g))
    -- every point at half the skin's depth is hatched (within half a spacing of a vector)
    local miss = 0
    for k = 1, 120 do
      local a = 2 * math.pi * k / 120
      local px, py, best = 5 + (R - S / 2) * math.cos(a), 5 + (R - S / 2) * math.sin(a), math.huge
      for _, sg in ipairs(segs) do best = math.min(best, seg_dist(px, py, sg[1], sg[2], sg[3], sg[4])) end
      if best > D / 2 + 1e-6 then miss = miss + 1 end
    end
    t.eq(miss, 0, ("layer %d: points at depth s/2 left unhatched"):format(g))
  end
end)

t.test("a domain empty inside the box of cells, or NaN from the domain, is refused", function()
  local p = lattice.params()
  p.cells, p.kb, p.layers, p.mode, p.res = "2,2,1", "off", "1:1", "mesh", 20
  p.domain = "(x-50)^2+y^2-1"
  t.raises(function() lattice.run(p, tmp .. "/empty.cli") end, "domain.*empty")
  t.ok(io.open(tmp .. "/empty.cli") == nil, "no output written")
  p.domain = "sqrt(x-1)-0.5" -- NaN where x < 1
  t.raises(function() lattice.run(p, tmp .. "/nan.cli") end, "domain: expression 'sqrt%(x%-1%)%-0%.5' gave nan at x=")
  t.ok(io.open(tmp .. "/nan.cli") == nil, "no output written")
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
