local t = require "gradus.testing"
local R = 3
t.test("sphere mesh closed, area and volume", function()
  local m = gradus.mc("sqrt(x*x+y*y+z*z)-3", {lo={-4,-4,-4}, hi={4,4,4}, res=60, refine=true})
  local topo = m:topology()
  t.ok(topo.boundary_edges == 0 and topo.nonmanifold_edges == 0 and topo.euler == 2, "closed sphere")
  t.near(m:area(), 4*math.pi*R*R, 0.01*4*math.pi*R*R, "area")
  t.near(m:volume(), 4/3*math.pi*R^3, 0.01*4/3*math.pi*R^3, "volume")
  local lo, hi = m:bounds()
  t.near(hi[1], R, 0.05, "bounds")
end)
t.test("write and read back", function()
  local m = gradus.mc("sqrt(x*x+y*y+z*z)-3", {lo={-4,-4,-4}, hi={4,4,4}, res=20})
  local nv, nf = m:counts()
  for _, ext in ipairs({"stl", "ply", "obj"}) do
    local p = os.tmpname() .. "." .. ext
    m:write(p)
    local r = gradus.mesh.read(p)
    local rv, rf = r:counts()
    t.ok(rv == nv and rf == nf, ext .. " counts")
    os.remove(p)
  end
end)
t.test("errors", function()
  t.raises(function() gradus.mc("x", {lo={0,0,0}, hi={1,1,1}, res=1}) end, ">= 2")
  t.raises(function() gradus.mesh.read("/nonexistent/x.stl") end, "nonexistent")
end)
t.done()
