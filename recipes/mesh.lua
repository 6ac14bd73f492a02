-- mesh.lua: mesh a TPMS block (or a sphere) by marching cubes and write it;
-- with `thickness`, mesh the graded offset surface instead (paper Fig. 15).
--   gradus run recipes/mesh.lua -D surface=primitive -D res=40 -D out=out/p.stl
--   gradus run recipes/mesh.lua -D thickness='0.1*(2*sin(pi*(w+1)/4)+1)' -D kind=sheet -D mode=exact
-- kind: sheet (both offset surfaces, the wall's boundary), outside (the +T
-- offset surface alone), inside (the -T one). Formats by extension: .stl .ply .obj
local surface = gradus.param("surface", "primitive", { help = "a TPMS name, or sphere" })
local cell = gradus.param("cell", 2.0, { unit = "mm", min = 0.1, max = 100, help = "cell size L" })
local cells = gradus.param("cells", { 1, 1, 1 }, { n = 3, integer = true, min = 1, max = 100, help = "cells along x, y, z" })
local level = gradus.param("level", 0.0, { min = -20, max = 20, help = "iso-level of the TPMS" })
local res = gradus.param("res", 40, { integer = true, min = 2, max = 400, help = "samples per cell edge" })
local thickness = gradus.param("thickness", "", { unit = "mm", help = "half-thickness (number or expression); empty: the surface itself" })
local kind = gradus.param("kind", "sheet", { choices = { "sheet", "outside", "inside" }, help = "which offset surface" })
local mode = gradus.param("mode", "exact", { choices = { "exact", "mesh" }, help = "closest points" })
local out = gradus.param("out", gradus.output("out/mesh.stl"), { help = "mesh file: .stl .ply .obj" })
local R = gradus.param("radius", 3.0, { unit = "mm", min = 0.01, max = 1000, help = "radius of the sphere (surface=sphere)" })
local m
if surface == "sphere" then
  m = gradus.mc(string.format("sqrt(x*x+y*y+z*z)-%.17g", R),
    { lo = { -1.1 * R, -1.1 * R, -1.1 * R }, hi = { 1.1 * R, 1.1 * R, 1.1 * R }, res = res, refine = true })
else
  local f = gradus.field.tpms(surface, { cell = cell, level = level })
  local hi = { cells[1] * cell, cells[2] * cell, cells[3] * cell }
  if thickness ~= "" then
    local kinds = { sheet = { "sheet", -1 }, outside = { "network", -1 }, inside = { "network", 1 } }
    local k = kinds[kind]
    if not k then error(("kind must be sheet, outside or inside, got '%s'"):format(kind)) end
    f = gradus.distance.offset { surface = f, cell = cell, lo = { 0, 0, 0 }, hi = hi, res = res,
      thickness = tonumber(thickness) or thickness, kind = k[1], side = k[2], mode = mode }
  end
  m = gradus.mc(f, { lo = { 0, 0, 0 }, hi = hi, n = { res * cells[1] + 1, res * cells[2] + 1, res * cells[3] + 1 }, refine = true })
end
local nv, nf = m:counts()
print(string.format("%s%s: %d vertices, %d faces, area %.4f mm^2", surface,
  thickness ~= "" and (" " .. kind .. " offset") or "", nv, nf, m:area()))
m:write(out)
print("wrote " .. out)
