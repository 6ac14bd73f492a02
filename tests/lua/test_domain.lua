-- A part given as an STL file as the design domain (gradus.mesh.solid, the
-- lattice recipe's domain=FILE.stl) and the solid skin along its boundary,
-- checked against the analytic sphere the STL approximates.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local C, R = { 4, 4, 1 }, 1.2 -- the sphere part, mm, in a box of 4 x 4 x 1 cells of 2 mm
local HATCH = 0.05

-- The sphere as a closed STL (marching cubes, vertices refined onto the
-- sphere: every face is a chord, so the mesh lies inside the sphere).
local function sphere_stl(path, res)
  local m = gradus.mc(("sqrt((x-%g)^2+(y-%g)^2+(z-%g)^2)-%g"):format(C[1], C[2], C[3], R),
    { lo = { C[1] - 1.5, C[2] - 1.5, C[3] - 1.5 }, hi = { C[1] + 1.5, C[2] + 1.5, C[3] + 1.5 }, res = res, refine = true })
  m:write(path)
  return m
end
local STL = tmp .. "/sphere.stl"
sphere_stl(STL, 24)

local function params(o)
  local p = lattice.params()
  p.cells, p.thickness, p.kb, p.res, p.mode, p.hatch = "4,4,1", "0.08", "off", 20, "mesh", HATCH
  for k, v in pairs(o) do p[k] = v end
  return p
end

local function escape(s) return (s:gsub("%p", "%%%0")) end

t.test("gradus.mesh.solid: signed distance of an STL sphere, errors of an open mesh", function()
  local f = gradus.mesh.read(STL):solid()
  t.near(f:eval(C[1], C[2], C[3]), -R, 0.01, "centre")
  t.near(f:eval(C[1] + 2, C[2], C[3]), 2 - R, 0.01, "outside")
  t.eq(f:lipschitz(), 1, "a distance: Lipschitz bound 1")
  local open = gradus.mc("sqrt(x*x+y*y+z*z)-1", { lo = { -2, -2, 0 }, hi = { 2, 2, 2 }, res = 10 })
  t.raises(function() gradus.mesh.solid(open) end, "not closed %(open boundary edges, used by one face%): %d+ edges, e%.g%. %(")
end)

t.test("domain=FILE.stl: no scan point outside the part; voxels wholly outside produce nothing", function()
  local st, kept = lattice.run(params { domain = STL, layer = 0.1, pictures = "5,10,15" }, nil)
  -- only the 2 x 2 voxels around the sphere's axis are cut by it; the other 12 are skipped
  t.eq(st.voxels, 4, "voxels computed")
  t.eq(st.trimmed_voxels, 4, "voxels trimmed")
  local worst, n = -math.huge, 0
  for _, g in ipairs({ 5, 10, 15 }) do
    local zm = g * 0.1 - 0.05
    for _, b in ipairs(kept[g]:blocks()) do
      for q = 1, #b.points, 2 do
        local r = math.sqrt((b.points[q] - C[1]) ^ 2 + (b.points[q + 1] - C[2]) ^ 2 + (zm - C[3]) ^ 2)
        worst = math.max(worst, r - R)
        n = n + 1
      end
    end
  end
  t.ok(n > 100, "scan points on the checked layers: " .. n)
  t.ok(worst <= 1e-3, ("a scan point lies %.4g mm outside the sphere"):format(worst))
end)

-- Length of the segment inside the disc (cx, cy, r).
local function in_disc(x0, y0, x1, y1, r)
  local dx, dy, fx, fy = x1 - x0, y1 - y0, x0 - C[1], y0 - C[2]
  local a, b, c = dx * dx + dy * dy, 2 * (dx * fx + dy * fy), fx * fx + fy * fy - r * r
  local disc = b * b - 4 * a * c
  if a == 0 or disc <= 0 then return 0 end
  local t1 = math.max(0, (-b - math.sqrt(disc)) / (2 * a))
  local t2 = math.min(1, (-b + math.sqrt(disc)) / (2 * a))
  return math.max(0, t2 - t1) * math.sqrt(a)
end

local function seg_dist(px, py, x0, y0, x1, y1)
  local dx, dy = x1 - x0, y1 - y0
  local u = ((px - x0) * dx + (py - y0) * dy) / (dx * dx + dy * dy)
  u = math.max(0, math.min(1, u))
  return math.sqrt((x0 + u * dx - px) ^ 2 + (y0 + u * dy - py) ^ 2)
end

-- The equator layer (25, z = 0.98) of the sphere part with the given skin:
-- the fraction of points at depth `depth` under the section's boundary that
-- lie within half a hatch spacing of a hatch vector, and the hatch length
-- in the annulus r1 < r < r2 times the spacing (the area it fills).
local function equator(skin, depth, r1, r2)
  local _, kept = lattice.run(params { domain = STL, skin = skin, layers = "25:25", pictures = "25" }, nil)
  local segs = {}
  for _, b in ipairs(kept[25]:blocks()) do
    if b.kind == "hatch" then
      for q = 1, #b.points - 3, 4 do segs[#segs + 1] = { b.points[q], b.points[q + 1], b.points[q + 2], b.points[q + 3] } end
    end
  end
  local rs = math.sqrt(R * R - (0.98 - C[3]) ^ 2)
  local covered, N = 0, 90
  for k = 1, N do
    local a = 2 * math.pi * k / N
    local px, py = C[1] + (rs - depth) * math.cos(a), C[2] + (rs - depth) * math.sin(a)
    local best = math.huge
    for _, s in ipairs(segs) do best = math.min(best, seg_dist(px, py, s[1], s[2], s[3], s[4])) end
    if best <= HATCH / 2 + 1e-3 then covered = covered + 1 end
  end
  local len = 0
  for _, s in ipairs(segs) do len = len + in_disc(s[1], s[2], s[3], s[4], r2) - in_disc(s[1], s[2], s[3], s[4], r1) end
  return covered / N, len * HATCH, rs
end

t.test("skin: a solid band of the given depth under the STL part's surface", function()
  local s = 0.3
  local rs = math.sqrt(R * R - 0.02 ^ 2)
  local r1, r2 = rs - s + 0.05, rs - 0.1 -- inside the band, clear of its contours
  local area = math.pi * (r2 * r2 - r1 * r1)
  local cov, filled = equator(s, s / 2, r1, r2)
  t.eq(cov, 1, "every point at depth s/2 is hatched")
  t.near(filled, area, 0.15 * area, "hatched area of the band vs the analytic annulus")
  -- a point deeper than the skin is in the lattice again: not all hatched
  local cov0, filled0 = equator(0, s / 2, r1, r2)
  t.ok(cov0 < 0.7, ("without a skin the band is lattice only, yet %.0f%% of it is hatched"):format(100 * cov0))
  t.ok(filled0 < 0.7 * area, ("without a skin: %.3g of %.3g mm^2 hatched"):format(filled0, area))
end)

t.test("domain=FILE.stl errors name the file", function()
  local open = gradus.mc("sqrt(x*x+y*y+z*z)-1", { lo = { -2, -2, 0 }, hi = { 2, 2, 2 }, res = 10 })
  local path = tmp .. "/open.stl"
  open:write(path)
  t.raises(function() lattice.run(params { domain = path }, nil) end, "bad domain '" .. escape(path) .. "': solid: the mesh is not closed")
  -- a binary STL cut short
  local h = io.open(STL, "rb")
  local bytes = h:read("a")
  h:close()
  local cut = tmp .. "/cut.stl"
  h = io.open(cut, "wb")
  h:write(bytes:sub(1, 84 + 50 * 3 + 20))
  h:close()
  t.raises(function() lattice.run(params { domain = cut }, nil) end, "bad domain '" .. escape(cut) .. "': .*cut%.stl")
  -- text that is no STL
  local junk = tmp .. "/junk.stl"
  h = io.open(junk, "w")
  h:write("solid junk\n  facet normal 0 0 1\n    outer loop\n      vertex 0 0 zero\n")
  h:close()
  t.raises(function() lattice.run(params { domain = junk }, nil) end, "bad domain '" .. escape(junk) .. "': .*junk%.stl:%d")
  t.raises(function() lattice.run(params { domain = tmp .. "/missing.stl" }, nil) end, "missing%.stl")
  t.raises(function() lattice.run(params { domain = STL, origin = "20,0,0" }, nil) end,
    "sphere%.stl': the part %(2%.8.*%) mm lies outside the box of cells %(20, 0, 0%)%-%(28, 8, 2%); set origin and cells")
end)

-- The contour pieces of layer g lying on the line x = v (axis 1) or y = v
-- (axis 2), within 1e-6 mm, as intervals along it.
local function on_line(layer, axis, v)
  local iv = {}
  for x0, y0, x1, y1 in t.segments(layer, "contour") do
    local a0, a1, s0, s1 = x0, x1, y0, y1
    if axis == 2 then a0, a1, s0, s1 = y0, y1, x0, x1 end
    if math.abs(a0 - v) < 1e-6 and math.abs(a1 - v) < 1e-6 and s0 ~= s1 then
      iv[#iv + 1] = { math.min(s0, s1), math.max(s0, s1) }
    end
  end
  table.sort(iv, function(a, b) return a[1] < b[1] end)
  return iv
end

t.test("a contour along a voxel face is scanned once, by the voxel it bounds", function()
  -- a square part whose contour (the domain's boundary moved in by the beam
  -- offset) runs along the voxel faces x, y = 2 and 6: each voxel's template
  -- holds it on its side; before, both voxels of a face scanned it (the part's
  -- outline twice at beam offset 0, the sides at 2 twice at 0.025)
  for _, c in ipairs({ { 2, 0 }, { 2.025, 0.025 } }) do
    local dom = ("max(abs(x-4),abs(y-4))-%g"):format(c[1])
    local _, kept = lattice.run(params { domain = dom, skin = 0.3, beam_offset = c[2], layers = "10:10",
      pictures = "10", mode = "exact" }, nil)
    for axis = 1, 2 do
      for _, v in ipairs({ 2, 6 }) do
        local iv, len, reach = on_line(kept[10], axis, v), 0, 2
        for _, s in ipairs(iv) do
          t.ok(s[1] >= reach - 1e-6, ("%s, %s = %g: pieces overlap at %.6f"):format(dom, axis == 1 and "x" or "y", v, s[1]))
          t.ok(s[1] <= reach + 1e-6, ("%s, %s = %g: a gap from %.6f to %.6f"):format(dom, axis == 1 and "x" or "y", v, reach, s[1]))
          reach = math.max(reach, s[2])
          len = len + s[2] - s[1]
        end
        t.near(len, 4, 1e-5, ("%s: contour length on %s = %g (the side, once)"):format(dom, axis == 1 and "x" or "y", v))
      end
    end
  end
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
