-- The paper's offset examples (section 3.3) as pictures in doc/ (or -D dir=):
--   Fig. 8: the cylinder x^2 + y^2 - 9 with offsets r = +-1 (circles of radius 2 and 4);
--   Fig. 9: deformed circles, eq. (5): offsets +-(x/6 + 1);
--   Fig. 15: the graded P cell (eq. 8) - standard, inside and outside offset surfaces as meshes.
-- Each offset is the zero set of the variable distance field built on the
-- marching-cubes mesh H of the base surface, sliced at z = 0.
local dir = gradus.param("dir", "out/paper_offsets", { help = "output directory" })
local res = gradus.param("res", 60, { integer = true, min = 4, max = 400, help = "marching-cubes samples" })
local mode = gradus.param("mode", "exact", { choices = { "exact", "mesh" }, help = "closest points" })
gradus.mkdir(dir)
local base = gradus.field.expr("sqrt(x^2+y^2) - 3") -- the cylinder of radius 3 (its zero set is x^2+y^2-9 = 0)
local win = { lo = { -5.5, -5.5 }, hi = { 5.5, 5.5 }, cell = 0.02 }

-- draw rings as a layer of closed contours (laser 1: base, laser 2: offsets)
local function picture(path, title, sets)
  local l = gradus.layer.new(0)
  for k, rings in ipairs(sets) do
    for i = 1, rings:count() do
      local pts = rings:ring(i)
      pts[#pts + 1] = pts[1]
      pts[#pts + 1] = pts[2]
      l:add("contour", "closed", pts, k)
    end
  end
  gradus.svg.layer(path, l, { title = title, width = 600, track = 0.04 })
  return path
end

local function offsets(thickness)
  local out = {}
  for _, side in ipairs({ -1, 1 }) do
    local g = gradus.distance.offset { surface = base, cell = 12, lo = { -6, -6, -0.5 }, hi = { 6, 6, 0.5 }, res = res,
      thickness = thickness, kind = "network", side = side, mode = mode }
    out[#out + 1] = gradus.slice.field(g, 0, win)
  end
  return out
end

local H = gradus.slice.field(base, 0, win)
local o8 = offsets(1)
-- radius of the smallest ring (by |area|) of a set: the offset circle
local function radius(rings)
  local best = math.huge
  for i = 1, rings:count() do best = math.min(best, math.abs(rings:ring(i).area)) end
  return math.sqrt(best / math.pi)
end
print(("Fig. 8: base circle radius %.5f (3); offset circles %.5f (4) and %.5f (2)")
  :format(radius(H), radius(o8[1]), radius(o8[2])))
print("  " .. picture(dir .. "/fig8_cylinder_offsets.svg", "Fig. 8: x^2+y^2-9, offsets r = +-1", { H, o8[1], o8[2] }))
local o9 = offsets("x/6 + 1")
print("  " .. picture(dir .. "/fig9_deformed_circles.svg", "Fig. 9: offsets +-(x/6 + 1), eq. (5)", { H, o9[1], o9[2] }))

-- Fig. 15: graded P offset surfaces as meshes
local P = gradus.field.tpms("primitive", { cell = 2 })
local T = "0.1*(2*sin(pi*(w+1)/4)+1)"
local meshes = {
  standard = P,
  inside = gradus.distance.offset { surface = P, cell = 2, res = res, thickness = T, kind = "network", side = 1, mode = mode },
  outside = gradus.distance.offset { surface = P, cell = 2, res = res, thickness = T, kind = "network", side = -1, mode = mode },
}
for _, name in ipairs({ "standard", "inside", "outside" }) do
  local m = gradus.mc(meshes[name], { lo = { 0, 0, 0 }, hi = { 2, 2, 2 }, res = res + 1, refine = true })
  local path = ("%s/fig15_p_%s.stl"):format(dir, name)
  m:write(path)
  local nv, nf = m:counts()
  print(("Fig. 15 %-8s surface: %6d vertices, %6d faces -> %s"):format(name, nv, nf, path))
end
