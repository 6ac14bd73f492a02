-- An L-shaped bracket as a closed STL mesh, the STL part of the example
-- plate (recipes/plate.yaml):
--   gradus run recipes/plate_bracket.lua -o recipes/plate_bracket.stl
-- Its profile in the x-z plane (mm) is extruded along y from 0 to `depth`:
-- a foot `length` long and `foot` thick, an upright `wall` thick and
-- `height` tall. Written as ASCII STL, every triangle facing outwards.
local length = gradus.param("length", 12.0, { unit = "mm", min = 1, max = 500, help = "foot length (x)" })
local depth = gradus.param("depth", 6.0, { unit = "mm", min = 1, max = 500, help = "depth (y)" })
local height = gradus.param("height", 8.0, { unit = "mm", min = 1, max = 500, help = "upright height (z)" })
local foot = gradus.param("foot", 3.0, { unit = "mm", min = 0.5, max = 500, help = "foot thickness (z)" })
local wall = gradus.param("wall", 3.0, { unit = "mm", min = 0.5, max = 500, help = "upright thickness (x)" })
local out = gradus.output("recipes/plate_bracket.stl")
if foot >= height or wall >= length then error("foot must be below height and wall below length", 0) end

-- the profile, counter-clockwise in (x, z); vertex 4 (wall, foot) is the
-- inner corner, which sees every other vertex: the caps are fans from it
local P = { { 0, 0 }, { length, 0 }, { length, foot }, { wall, foot }, { wall, height }, { 0, height } }
local tris = {}
local function tri(a, b, c, n) -- a, b, c: {x, y, z}; flipped if not facing n
  local u = { b[1] - a[1], b[2] - a[2], b[3] - a[3] }
  local v = { c[1] - a[1], c[2] - a[2], c[3] - a[3] }
  local w = { u[2] * v[3] - u[3] * v[2], u[3] * v[1] - u[1] * v[3], u[1] * v[2] - u[2] * v[1] }
  if w[1] * n[1] + w[2] * n[2] + w[3] * n[3] < 0 then b, c = c, b end
  tris[#tris + 1] = { n, a, b, c }
end
local function at(p, y) return { p[1], y, p[2] } end
for i = 1, #P do
  local a, b = P[i], P[i % #P + 1]
  local n = { b[2] - a[2], 0, -(b[1] - a[1]) } -- outward for a CCW profile
  local len = math.sqrt(n[1] ^ 2 + n[3] ^ 2)
  n = { n[1] / len, 0, n[3] / len }
  tri(at(a, 0), at(b, 0), at(b, depth), n)
  tri(at(a, 0), at(b, depth), at(a, depth), n)
end
for _, i in ipairs({ 5, 6, 1, 2 }) do
  local a, b, c = P[4], P[i], P[i % #P + 1]
  tri(at(a, 0), at(b, 0), at(c, 0), { 0, -1, 0 })
  tri(at(a, depth), at(b, depth), at(c, depth), { 0, 1, 0 })
end
local lines = { "solid bracket" }
for _, t in ipairs(tris) do
  lines[#lines + 1] = ("  facet normal %g %g %g\n    outer loop"):format(t[1][1], t[1][2], t[1][3])
  for k = 2, 4 do lines[#lines + 1] = ("      vertex %g %g %g"):format(t[k][1], t[k][2], t[k][3]) end
  lines[#lines + 1] = "    endloop\n  endfacet"
end
lines[#lines + 1] = "endsolid bracket\n"
gradus.write_file(out, table.concat(lines, "\n"))
print(("%s: %d triangles, %g x %g x %g mm"):format(out, #tris, length, depth, height))
