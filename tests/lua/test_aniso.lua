-- Stretched (anisotropic) cells, cell=Lx,Ly,Lz (issue 19): the surface is the
-- TPMS stretched, H = {phi(2 pi x/Lx, 2 pi y/Ly, 2 pi z/Lz) = 0}, and the
-- half-thickness stays a true distance in mm: the solid is {dist(p, H) <=
-- T(q)} with the Euclidean distance to the stretched surface. Checked
-- against truth computed here in Lua, independently of the engine: the
-- closest point of the analytic stretched P surface by its own projection
-- iteration. A cube given as L,L,L is the job of cell=L (same bytes); the
-- layer count and header follow Lz; bad cells are refused by name.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local function params(o) return t.lattice_params({ kb = "off", res = 30, threads = 2 }, o) end

-- The stretched P surface of a cell Lx x Ly x Lz at the origin (the cell's
-- centre is the TPMS origin), its gradient, and the closest point of p on it:
-- q <- p - ((phi(q) + grad(q).(p - q)) / |grad(q)|^2) grad(q), whose fixed
-- point has phi(q) = 0 and p - q along the normal.
local LX, LY, LZ = 3, 2, 2.5
local W = { 2 * math.pi / LX, 2 * math.pi / LY, 2 * math.pi / LZ }
local function phi(x, y, z)
  local X, Y, Z = W[1] * (x - LX / 2), W[2] * (y - LY / 2), W[3] * (z - LZ / 2)
  return math.cos(X) + math.cos(Y) + math.cos(Z),
    -W[1] * math.sin(X), -W[2] * math.sin(Y), -W[3] * math.sin(Z)
end
local function closest(px, py, pz)
  local qx, qy, qz = px, py, pz
  for _ = 1, 200 do
    local f, gx, gy, gz = phi(qx, qy, qz)
    local s = (f + gx * (px - qx) + gy * (py - qy) + gz * (pz - qz)) / (gx * gx + gy * gy + gz * gz)
    local nx, ny, nz = px - s * gx, py - s * gy, pz - s * gz
    local step = math.abs(nx - qx) + math.abs(ny - qy) + math.abs(nz - qz)
    qx, qy, qz = nx, ny, nz
    if step < 1e-13 then break end
  end
  return qx, qy, qz, math.sqrt((px - qx) ^ 2 + (py - qy) ^ 2 + (pz - qz) ^ 2)
end

-- The graded half-thickness at foot point q: u relative to the voxel [0, Lx]
local T0, T1 = 0.06, 0.02
local THICK = ("%g+%g*u"):format(T0, T1)
-- of the voxel that owns the point p (voxel-owned grading)
local function T(qx, px)
  local c = (math.floor((px or qx) / LX) + 0.5) * LX
  return T0 + T1 * math.max(-1, math.min(1, 2 * (qx - c) / LX))
end

-- Two voxels along x of the stretched P sheet graded along u (so that the
-- sheet steps at their shared face x = Lx), layer 0.1: 25 layers, layer 13's
-- mid-height is the cell's centre z = Lz/2. share = false: every class
-- alone instead of the shared closest-point table; mode = mesh: the mesh's
-- closest points (the paper's).
local B = 0.025 -- beam offset (hatch/2)
local function run(name, o)
  local j = gradus.place.job { cell = { LX, LY, LZ }, cells = { 2, 1, 1 }, layer = 0.1, hatch = 0.05, res = 30,
    threads = 2, share = o.share, mode = o.mode }
  local s = j:spec { surface = "primitive", thickness = THICK }
  for i = 0, 1 do j:voxel(i, 0, 0, { spec = s }) end
  local out = tmp .. "/" .. name .. ".cli"
  local st = j:run { output = out, kb = false }
  return st, gradus.cli.read(out).layers
end
local ST, LAYERS = run("shared", {})

-- Contour vertices of a layer away from the voxel's faces, each with the
-- in-plane normal pointing out of the solid (the solid lies left of a contour).
local function contour_points(layer, margin)
  local pts = {}
  for _, b in ipairs(layer:blocks()) do
    local p, n = b.points, #b.points // 2
    if b.kind == "contour" and n >= 3 then
      for i = 2, n - 1 do
        local x, y = p[2 * i - 1], p[2 * i]
        local dx, dy = p[2 * i + 1] - p[2 * i - 3], p[2 * i + 2] - p[2 * i - 2]
        local len = math.sqrt(dx * dx + dy * dy)
        local xf = x % LX -- across the voxel, away from its faces
        if len > 0 and xf > margin and xf < LX - margin and y > margin and y < LY - margin then
          pts[#pts + 1] = { x, y, dy / len, -dx / len }
        end
      end
    end
  end
  return pts
end

t.test("cell=2,2,2 writes the same file as cell=2", function()
  local a, b = tmp .. "/a.cli", tmp .. "/b.cli"
  lattice.run(params { cells = "1,1,1", layer = 0.1, thickness = "0.08", hatch = 0.1, res = 20 }, a)
  lattice.run(params { cells = "1,1,1", layer = 0.1, thickness = "0.08", hatch = 0.1, res = 20, cell = "2,2,2" }, b)
  local fa, fb = io.open(a):read("a"), io.open(b):read("a")
  t.ok(#fa > 1000 and fa == fb, "byte-identical CLI files")
end)

t.test("cell=2,2,3, cells=1,1,2, layer 0.05: 120 layers, header 2 x 2 x 6 mm", function()
  local job = gradus.place.job { cell = { 2, 2, 3 }, cells = { 1, 1, 2 }, layer = 0.05 }
  t.eq(job:layers(), 120, "the job's layers: 2 x 3 / 0.05")
  local st = lattice.run(params { cell = "2,2,3", size = "2,2,6", layer = 0.05, thickness = "0.1", hatch = 0.1,
    res = 20, layers = "119:120" }, nil)
  t.eq(st.layers_total, 120, "size=2,2,6: 120 layers")
  local out = tmp .. "/h.cli"
  lattice.run(params { cell = "2,2,3", cells = "1,1,2", layer = 0.05, thickness = "0.1", hatch = 0.1, res = 20 }, out)
  local cli = gradus.cli.read(out)
  t.eq(#cli.layers, 120, "layers in the file")
  t.near(cli.layers[120]:z(), 6, 1e-6, "top layer at 6 mm")
  for a, v in ipairs({ 0, 0, 0, 2, 2, 6 }) do t.near(cli.header.dimension[a], v, 1e-6, "header dimension " .. a) end
end)

-- Largest | dist(p, H) - T(q) | over the contour points of a few layers,
-- each shifted out by b (on the section's boundary), and their count.
local function deviation(layers)
  local worst, n = 0, 0
  for _, g in ipairs { 4, 7, 10, 13, 20 } do
    local z = layers[g]:z() - 0.05
    for _, c in ipairs(contour_points(layers[g], 0.15)) do
      local px, py = c[1] + B * c[3], c[2] + B * c[4]
      local qx, _, _, d = closest(px, py, z)
      worst = math.max(worst, math.abs(d - T(qx, px)))
      n = n + 1
    end
  end
  return worst, n
end

t.test("a stretched P sheet: every contour point shifted out by b is T(q) from the stretched surface", function()
  t.eq(#LAYERS, 25, "25 layers of 0.1 mm in Lz = 2.5")
  local worst, n = deviation(LAYERS)
  t.ok(n > 1000, ("contour points checked: %d"):format(n))
  t.ok(worst < 5e-4, ("max | dist(p, H) - T(q) | = %.3g mm over %d points"):format(worst, n))
end)

t.test("the same without the shared closest points, and in mesh mode", function()
  local st, layers = run("alone", { share = false })
  t.eq(st.vectors.contour.count, ST.vectors.contour.count, "contour vectors as with the shared table")
  local worst = 0
  for g = 1, #layers do
    local a, b = {}, {}
    for _, bl in ipairs(LAYERS[g]:blocks()) do for _, v in ipairs(bl.points) do a[#a + 1] = v end end
    for _, bl in ipairs(layers[g]:blocks()) do for _, v in ipairs(bl.points) do b[#b + 1] = v end end
    t.eq(#a, #b, "coordinates of layer " .. g)
    for q = 1, #a do worst = math.max(worst, math.abs(a[q] - b[q])) end
  end
  t.ok(worst <= 1e-5, ("shared and alone differ by %.3g mm"):format(worst))
  local _, mesh = run("mesh", { mode = "mesh" })
  local dev, n = deviation(mesh)
  t.ok(n > 1000 and dev < 0.005, ("mesh mode: max | dist(p, H) - T(q) | = %.3g mm over %d points"):format(dev, n))
end)

t.test("a stretched P sheet at the cell's mid-height: the wall is 2 T(q) thick across the surface", function()
  -- at z = Lz/2 the surface's normal is horizontal: the wall's section is
  -- q +- T(q) n, and the contours run at q +- (T(q) - b) n
  local z = LAYERS[13]:z() - 0.05
  t.near(z, LZ / 2, 1e-9, "layer 13 at the cell's centre")
  local segs = {}
  for _, b in ipairs(LAYERS[13]:blocks()) do
    if b.kind == "contour" then
      for i = 1, #b.points // 2 - 1 do segs[#segs + 1] = { table.unpack(b.points, 2 * i - 1, 2 * i + 2) } end
    end
  end
  local function to_contours(x, y)
    local best = math.huge
    for _, s in ipairs(segs) do
      local dx, dy = s[3] - s[1], s[4] - s[2]
      local u = math.max(0, math.min(1, ((x - s[1]) * dx + (y - s[2]) * dy) / (dx * dx + dy * dy)))
      best = math.min(best, math.sqrt((s[1] + u * dx - x) ^ 2 + (s[2] + u * dy - y) ^ 2))
    end
    return best
  end
  local worst, n = 0, 0
  for i = 0, 120 do
    local x = LX * i / 120
    local cx = math.cos(W[1] * (x - LX / 2))
    if cx < -0.05 then -- cos X + cos Y = -1 has a solution
      for _, sgn in ipairs { -1, 1 } do
        local Y = sgn * math.acos(-1 - cx)
        local y = LY / 2 + Y / W[2]
        local _, gx, gy = phi(x, y, z)
        local gn = math.sqrt(gx * gx + gy * gy)
        if y > 0.2 and y < LY - 0.2 and x > 0.2 and x < LX - 0.2 then
          local w = T(x) - B
          for _, s in ipairs { -1, 1 } do
            worst = math.max(worst, to_contours(x + s * w * gx / gn, y + s * w * gy / gn))
            n = n + 1
          end
        end
      end
    end
  end
  t.ok(n >= 40, ("points checked: %d"):format(n))
  t.ok(worst < 5e-4, ("the contours pass within %.3g mm of q +- (T - b) n (%d points)"):format(worst, n))
end)

t.test("section area of a layer against a fine-grid classification of dist(p, H) - T(q)", function()
  local z, h, area = 0.65, 0.01, 0
  local lip = math.sqrt(W[1] ^ 2 + W[2] ^ 2 + W[3] ^ 2) -- |grad phi| <= lip: dist >= |phi| / lip
  for i = 0, LX / h - 1 do
    for j = 0, LY / h - 1 do
      local x, y = (i + 0.5) * h, (j + 0.5) * h
      if math.abs(phi(x, y, z)) / lip < T0 + T1 + h then
        local qx, _, _, d = closest(x, y, z)
        area = area + math.max(0, math.min(1, 0.5 - (d - T(qx, x)) / h)) -- pixel coverage
      end
    end
  end
  area = area * h * h
  local st = lattice.run(params { surface = "primitive", cell = ("%g,%g,%g"):format(LX, LY, LZ), cells = "1,1,1",
    layer = 0.1, hatch = 0.05, thickness = THICK, layers = "7:7" }, nil)
  local got = st.solid_volume_mm3 / 0.1
  t.ok(area > 0.5, ("brute-force area %g mm^2"):format(area))
  t.near(got, area, 0.003 * area, "section area of layer 7 (mm^2)")
end)

t.test("bad cells: refused by name with the accepted range, no output", function()
  local out = tmp .. "/bad.cli"
  for _, c in ipairs { "2,0,2", "2,2", "a,b,c", "2,nan,2", "2,2,200" } do
    t.raises(function() lattice.run(params { cell = c }, out) end,
      "parameter 'cell' must be a number or 3 numbers in %[0.1, 100%] mm", "cell=" .. c)
  end
  t.raises(function() lattice.run(params { cell = "2,2,1", layer = 0.04, density = "0.2" }, out) end,
    "needs a cubic cell", "density-graded stretched cells")
  t.ok(not io.open(out), "no output")
  t.raises(function() gradus.place.job { cell = { 2, 2 } } end, "bad option 'cell' %(3 numbers expected, got 2%)")
  t.raises(function() gradus.place.job { cell = { 2, 0 / 0, 2 } } end,
    "bad option 'cell' %(finite numbers in %[0.001, 1000%] mm expected, got %-?nan%)")
  t.raises(function() gradus.place.job { cell = { 2, 2, 0 } } end, "bad option 'cell'.*got 0%)")
end)

t.test("a process profile's voxel and a plate part's cell take Lx,Ly,Lz", function()
  local prof = tmp .. "/prof.yaml"
  gradus.write_file(prof, "voxel: [2, 2, 3]\nlayer: 0.05\n")
  local v = require("gradus.profiles").process(prof).voxel
  t.ok(type(v) == "table" and v[1] == 2 and v[2] == 2 and v[3] == 3, "voxel: [2, 2, 3] is a stretched cell")
  gradus.write_file(prof, "voxel: 2,2,2\n")
  t.eq(require("gradus.profiles").process(prof).voxel, 2, "voxel: 2,2,2 is the cube 2")
  gradus.write_file(prof, "voxel: 2,0,2\n")
  t.raises(function() require("gradus.profiles").process(prof) end, "prof.yaml:1:%d+: parameter 'voxel' must be a number or 3 numbers")
  local plate = tmp .. "/plate.yaml"
  gradus.write_file(plate, "layer: 0.05\nplate: {lo: [0, 0], hi: [100, 100]}\nparts:\n  - name: s\n    at: [50, 50]\n    cell: 2,2,3\n    cells: 1,2,2\n")
  local d = require("gradus.plate").load(plate)
  local b = d.parts[1].box
  t.ok(b[1] == 2 and b[2] == 4 and b[3] == 6, ("the part's box 2 x 4 x 6 mm, got %s"):format(table.concat(b, " x ")))
end)

t.test("the stretched job reports its lengths; gradus.field.tpms stretched is the formula", function()
  local job = gradus.place.job { cell = { 3, 2, 2.5 }, cells = { 1, 1, 1 }, layer = 0.1 }
  t.ok(tostring(job):find("3%.0+ x 2%.0+ x 2%.5"), tostring(job))
  local f = gradus.field.tpms("primitive", { cell = { LX, LY, LZ } })
  for _, p in ipairs { { 0.3, 0.7, 1.9 }, { 2.1, 1.5, 0.2 } } do
    t.near(f:eval(p[1], p[2], p[3]), (phi(p[1], p[2], p[3])), 1e-12, "gradus.field.tpms stretched")
  end
  t.eq(ST.layers, 25, "the shared run: 25 layers")
end)

t.done()
