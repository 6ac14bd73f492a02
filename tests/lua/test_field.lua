-- gradus.field: expressions against the same formula in Lua, the TPMS
-- catalogue, gradients, combinations, sampling and error messages.
local t = require "gradus.testing"
local field = gradus.field

t.test("expression field equals the Lua formula at random points", function()
  local f = field.expr("sin(x)*cos(y) - z^2/3 + max(x, y) + atan(y, x) + -x^2")
  local ref = function(x, y, z)
    return math.sin(x) * math.cos(y) - z ^ 2 / 3 + math.max(x, y) + math.atan(y, x) + -(x ^ 2)
  end
  math.randomseed(7)
  local xs, ys, zs = {}, {}, {}
  for i = 1, 300 do
    local x, y, z = math.random() * 10 - 5, math.random() * 10 - 5, math.random() * 10 - 5
    xs[i], ys[i], zs[i] = x, y, z
    t.near(f:eval(x, y, z), ref(x, y, z), 1e-12, "eval at point " .. i)
  end
  local vs = f:eval_many(xs, ys, zs)
  t.eq(#vs, 300, "eval_many length")
  for i = 1, 300 do t.near(vs[i], ref(xs[i], ys[i], zs[i]), 1e-12, "eval_many " .. i) end
end)

t.test("tpms catalogue values and names", function()
  local names = field.surfaces()
  t.eq(#names, 10, "ten surfaces")
  local p = field.tpms("primitive", {cell = 2, origin = {1, 1, 1}})
  t.near(p:eval(2, 2, 2), 3, 1e-12, "cell centre")
  t.near(p:eval(1, 1, 1), -3, 1e-12, "cell corner")
  t.near(field.tpms("primitive"):eval(1, 1, 1), 3, 1e-12, "default cell 2 from 0")
  t.near(field.tpms("primitive", {level = 1}):eval(1, 1, 1), 2, 1e-12, "level")
  local err = t.raises(function() field.tpms("schwartz") end, "schwartz")
  for _, n in ipairs(names) do t.ok(err:find(n, 1, true), "error lists " .. n) end
  t.raises(function() field.tpms("gyroid", {cell = -1}) end, "cell size must be > 0, got %-1")
  t.ok(tostring(p):find("primitive%(L=2"), "tostring " .. tostring(p))
end)

t.test("gradients", function()
  local g = field.tpms("gyroid", {cell = 3})
  local h = 1e-5
  for _, p in ipairs({{0.1, 0.7, -1.3}, {2, 1, 0.5}, {-4, 3.3, 2.2}}) do
    local x, y, z = p[1], p[2], p[3]
    local gx, gy, gz = g:grad(x, y, z)
    t.near(gx, (g:eval(x + h, y, z) - g:eval(x - h, y, z)) / (2 * h), 1e-6, "gx")
    t.near(gy, (g:eval(x, y + h, z) - g:eval(x, y - h, z)) / (2 * h), 1e-6, "gy")
    t.near(gz, (g:eval(x, y, z + h) - g:eval(x, y, z - h)) / (2 * h), 1e-6, "gz")
    t.ok(math.sqrt(gx * gx + gy * gy + gz * gz) <= g:lipschitz(), "within the bound")
  end
  local s = field.sphere(2, {center = {1, 0, 0}})
  local gx, gy, gz = s:grad(1, 3, 4)
  t.near(gx, 0, 1e-6, "sphere gx") ; t.near(gy, 0.6, 1e-6, "sphere gy") ; t.near(gz, 0.8, 1e-6, "sphere gz")
end)

t.test("conveniences and combinations", function()
  local s = field.sphere(3)
  t.near(s:eval(0, 0, 0), -3, 1e-15, "sphere centre")
  t.near(s:eval(0, 4, 0), 1, 1e-15, "sphere outside")
  t.near(field.cylinder(2):eval(3, 4, 100), 3, 1e-15, "cylinder")
  t.near(field.constant(2.5):eval(1, 2, 3), 2.5, 0, "constant")
  local a, b = field.expr("x"), field.expr("y")
  t.near(field.min(a, b):eval(1, 2, 0), 1, 0, "min")
  t.near(field.max(a, "y"):eval(1, 2, 0), 2, 0, "max with a string")
  t.near(a:union(5):eval(7, 0, 0), 5, 0, "union with a number")
  t.near(a:intersect(b):eval(7, 0, 0), 7, 0, "intersect")
  t.near(field.blend(a, b, 0.25):eval(4, 8, 0), 5, 1e-15, "blend")
  t.near(a:negate():eval(4, 0, 0), -4, 0, "negate")
  t.near(s:translate(1, 2, 3):eval(1, 2, 3), -3, 1e-15, "translate")
  t.near(s:translate({0, 0, 10}):eval(0, 0, 10), -3, 1e-15, "translate table")
  t.near(s:scale(2):eval(6, 0, 0), 0, 1e-15, "scale")
  t.raises(function() s:scale(0) end, "scale must be > 0")
  t.ok(field.min(a, b):describe():find("min%(expr%(x%), expr%(y%)%)"), "describe")
end)

t.test("Lua function fields", function()
  local f = field.lua(function(x, y, z) return x * y - z end)
  t.near(f:eval(2, 3, 1), 5, 0, "eval")
  local gx, gy, gz = f:grad(2, 3, 1)
  t.near(gx, 3, 1e-6, "fd gx") ; t.near(gy, 2, 1e-6, "fd gy") ; t.near(gz, -1, 1e-6, "fd gz")
  local u = field.min(function(x) return x end, "y")
  t.near(u:eval(-1, 0, 0), -1, 0, "function through gr_to_field")
  local bad = field.lua(function(x) if x > 1 then error("too big") end return 0 end)
  t.raises(function() bad:eval(2, 0, 0) end, "too big")
  local err = t.raises(function() bad:eval(2, 0.5, 0) end)
  t.ok(err:find("x=2, y=0.5, z=0", 1, true), "names the point: " .. err)
  t.raises(function() field.lua(function() return "a" end):eval(0, 0, 0) end, "expected a number")
  -- called from inside a coroutine
  local co = coroutine.wrap(function() return f:eval(1, 1, 1) end)
  t.near(co(), 0, 0, "inside a coroutine")
end)

t.test("expression errors", function()
  t.raises(function() field.expr("sin(x") end, "expression 'sin%(x' col 6: expected '%)'")
  local err = t.raises(function() field.expr("x + q") end, "unknown name 'q'")
  t.ok(err:find("x, y, z", 1, true), "lists the variables: " .. err)
  t.raises(function() field.expr("log(x)"):eval(-1, 0, 0) end, "gave nan at x=%-1, y=0, z=0")
  t.raises(function() field.min({}, 1) end, "field, number, expression string or function expected")
end)

t.test("sampling", function()
  local f = field.expr("x + 10*y + 100*z")
  local g = f:sample{lo = {0, 0, 0}, hi = {1, 2, 3}, n = {3, 3, 4}}
  t.eq(g.nx, 3, "nx") ; t.eq(g.ny, 3, "ny") ; t.eq(g.nz, 4, "nz") ; t.eq(#g, 36, "count")
  -- i=2, j=1, k=3 -> x=1, y=1, z=3
  t.near(g[1 + 2 + 3 * (1 + 3 * 3)], 1 + 10 + 300, 1e-12, "value at (1,1,3)")
  local s = f:sample2{z = 0.5, lo = {-1, -1}, hi = {1, 1}, n = {5, 2}}
  t.eq(#s, 10, "2-D count")
  t.near(s[1], -1 - 10 + 50, 1e-12, "first") ; t.near(s[10], 1 + 10 + 50, 1e-12, "last")
  t.raises(function() f:sample{lo = {0, 0, 0}, hi = {1, 1, 1}, n = {2000, 2000, 2000}} end, "61035 MB")
  t.raises(function() f:sample{lo = {0, 0, 0}, hi = {1, 1, 1}, n = {1, 2, 2}} end, "got 1")
end)

t.done()
