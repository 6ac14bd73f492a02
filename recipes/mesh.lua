-- mesh.lua: mesh a TPMS block (or a sphere) by marching cubes and write it.
-- gradus run recipes/mesh.lua -D surface=primitive -D res=40 -D out=out/p.stl
local surface = gradus.param("surface", "primitive")
local cell = tonumber(gradus.param("cell", 2))
local cells = {}
for c in tostring(gradus.param("cells", "1,1,1")):gmatch("[^,]+") do cells[#cells + 1] = tonumber(c) end
local level = tonumber(gradus.param("level", 0))
local res = tonumber(gradus.param("res", 40))
local out = gradus.param("out", "out/mesh.stl")
local m
if surface == "sphere" then
  local R = tonumber(gradus.param("radius", 3))
  m = gradus.mc(string.format("sqrt(x*x+y*y+z*z)-%.17g", R),
                {lo={-1.1*R,-1.1*R,-1.1*R}, hi={1.1*R,1.1*R,1.1*R}, res=res, refine=true})
else
  local f = gradus.field.tpms(surface, {cell=cell, level=level})
  local hi = {cells[1]*cell, cells[2]*cell, cells[3]*cell}
  m = gradus.mc(f, {lo={0,0,0}, hi=hi, n={res*cells[1]+1, res*cells[2]+1, res*cells[3]+1}, refine=true})
end
local nv, nf = m:counts()
print(string.format("%s: %d vertices, %d faces, area %.4f mm^2, volume %.4f mm^3", surface, nv, nf, m:area(), m:volume()))
m:write(out)
print("wrote " .. out)
