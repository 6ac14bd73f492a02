-- gradus.distance: network offsets of the cylinder x^2 + y^2 = 9 by 1 mm,
-- sliced: the sections are bounded by circles of radius 4 (side -1) and 2
-- (side +1); bad options raise naming the option.
local t = require "gradus.testing"

local function cyl() return gradus.field.expr("sqrt(x^2 + y^2) - 3") end
local function offset(side, extra)
  local o = {surface = cyl(), cell = 10, lo = {-5, -5, -1}, hi = {5, 5, 1}, res = 40,
             thickness = 1, kind = "network", side = side, mode = "exact"}
  for k, v in pairs(extra or {}) do o[k] = v end
  return gradus.distance.offset(o)
end

-- the radii of ring i's vertices: min, max
local function radii(rings, i)
  local r = rings:ring(i)
  local lo, hi = math.huge, -math.huge
  for j = 1, #r, 2 do
    local rr = math.sqrt(r[j] ^ 2 + r[j + 1] ^ 2)
    lo, hi = math.min(lo, rr), math.max(hi, rr)
  end
  return lo, hi
end

t.test("side -1: the section is the disc of radius 4", function()
  local g = offset(-1)
  local s = gradus.slice.field(g, 0.3, {lo = {-5, -5}, hi = {5, 5}, cell = 0.1})
  t.ok(s:count() == 1, "one ring, got " .. s:count())
  local lo, hi = radii(s, 1)
  t.near(lo, 4, 1e-4, "min radius")
  t.near(hi, 4, 1e-4, "max radius")
  t.near(s:area(), math.pi * 16, 0.05, "area of the disc (polygon)")
  t.ok(s:contains(0, 0) and s:contains(3.9, 0) and not s:contains(4.1, 0), "contains")
end)

t.test("side +1: the section has a hole of radius 2", function()
  local g = offset(1)
  local s = gradus.slice.field(g, -0.4, {lo = {-5, -5}, hi = {5, 5}, cell = 0.1})
  t.ok(s:count() == 2, "outer window boundary and the hole, got " .. s:count())
  local best = math.huge
  local found
  for i = 1, s:count() do
    local lo, hi = radii(s, i)
    if hi < best then best, found = hi, {lo, hi} end
  end
  t.near(found[1], 2, 1e-4, "hole min radius")
  t.near(found[2], 2, 1e-4, "hole max radius")
  t.ok(not s:contains(0, 0) and not s:contains(1.9, 0) and s:contains(2.1, 0), "contains")
end)

t.test("graded thickness x/6 + 1 (eq. 5)", function()
  local g = offset(-1, {thickness = "x/6 + 1"})
  for i = 0, 11 do
    local th = 2 * math.pi * i / 12 + 0.1
    local r = 3 + 3 * math.cos(th) / 6 + 1
    t.near(g:eval(r * math.cos(th), r * math.sin(th), 0), 0, 1e-6, "g at theta " .. th)
  end
end)

t.test("bad options name the option", function()
  t.raises(function() gradus.distance.offset{cell = 2, lo = {0, 0, 0}, hi = {1, 1, 1}} end, "surface")
  t.raises(function() offset(-1, {thickness = -0.1}) end, "thickness")
  t.raises(function() offset(-1, {thickness = 6}) end, "thickness")
  t.raises(function() offset(-1, {thickness = "x/6 +"}) end, "thickness")
  t.raises(function() offset(-1, {thickness = {}}) end, "thickness")
  t.raises(function() offset(-1, {kind = "foam"}) end, "kind")
  t.raises(function() offset(-1, {mode = "fast"}) end, "mode")
  t.raises(function() offset(-1, {cell = -2}) end, "cell")
  t.raises(function() offset(-1, {res = 1}) end, "res")
  t.raises(function() gradus.distance.offset{surface = "nosuch", lo = {0, 0, 0}, hi = {1, 1, 1}} end, "nosuch")
end)

t.test("closest point of a sphere mesh", function()
  local m = gradus.mc("sqrt(x*x+y*y+z*z)-3", {lo = {-4, -4, -4}, hi = {4, 4, 4}, res = 40, refine = true})
  local qx, qy, qz, d, tri = gradus.distance.closest(m, 5, 0, 0)
  t.near(d, 2, 0.01, "distance")
  t.near(qx, 3, 0.01, "qx")
  t.near(math.sqrt((5 - qx) ^ 2 + qy ^ 2 + qz ^ 2), d, 1e-12, "|p - q| = d")
  local nv, nf = m:counts()
  t.ok(math.type(tri) == "integer" and tri >= 1 and tri <= nf, "triangle index 1-based")
end)

t.test("a thickness whose offset sheets touch is reported with where", function()
  local _, w = gradus.distance.offset { surface = "primitive", cell = 2, thickness = 0.6, res = 30 }
  t.ok(w and w:find("touch near x="), "warning for T = 0.6 in a 2 mm P cell: " .. tostring(w))
  local _, w2 = gradus.distance.offset { surface = "primitive", cell = 2, thickness = 0.1, res = 30 }
  t.eq(w2, nil, "no warning for T = 0.1")
end)

t.test("a Lua function thickness T(x, y, z) of the closest point", function()
  local g = gradus.distance.offset { surface = gradus.field.expr("sqrt(x^2+y^2)-3"), cell = 12, lo = { -6, -6, -0.5 },
    hi = { 6, 6, 0.5 }, res = 40, kind = "network", thickness = function(x, y, z) return x / 6 + 1 end }
  -- eq. (5): at q = (3, 0, 0) T = 1.5, so the offset is at radius 4.5; at q = (-3, 0, 0) T = 0.5
  t.near(g:eval(4.5, 0, 0), 0, 1e-6, "zero at radius 3 + T(q)")
  t.near(g:eval(-2.5, 0, 0), -1, 1e-6, "sd - T inside")
  t.raises(function() gradus.distance.offset { surface = "primitive", thickness = function() return -1 end } end,
    "bad option 'thickness'")
end)

t.done()
