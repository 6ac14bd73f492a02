-- Design by density through the lattice recipe: targets as expressions,
-- field files and Lua functions; achieved density measured from the CLI's
-- contours; infeasible targets refused with the reachable range, or clamped.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local density = require "gradus.density"
density.RES = 48 -- coarse calibration for speed (a few 1e-4 in rho)
local tmp = t.tmpdir()

local function params(o)
  local p = lattice.params()
  p.surface, p.cells, p.kb, p.layer, p.beam_offset, p.hatch = "gyroid", "1,1,1", tmp .. "/kb", 0.04, 0, 0.05
  for k, v in pairs(o) do p[k] = v end
  return p
end

-- a VTK legacy ASCII grid of constant value v over [-1, 3]^3 mm
local function vtk(path, v)
  local lines = { "# vtk DataFile Version 3.0", "porosity", "ASCII", "DATASET STRUCTURED_POINTS",
    "DIMENSIONS 3 3 3", "ORIGIN -1 -1 -1", "SPACING 2 2 2", "POINT_DATA 27", "SCALARS p double 1", "LOOKUP_TABLE default" }
  for _ = 1, 27 do lines[#lines + 1] = tostring(v) end
  gradus.write_file(path, table.concat(lines, "\n") .. "\n")
end

t.test("uniform density target met within 0.003 (gyroid sheet, from the CLI)", function()
  local st = lattice.run(params { density = "0.3" }, tmp .. "/u.cli")
  t.eq(st.density.compared, 1, "voxels compared")
  t.near(st.density.voxels[1].achieved, 0.3, 0.003, "achieved density")
  t.near(st.density.error.max_abs, math.abs(st.density.voxels[1].diff), 1e-12, "summary")
  -- the calibration is cached in the knowledge base directory
  local f = io.open(tmp .. "/kb/density/gyroid_level0_res48.density")
  t.ok(f, "cache file written")
  if f then f:close() end
end)

t.test("porosity from a VTK field file", function()
  vtk(tmp .. "/p.vtk", 0.7)
  local st = lattice.run(params { porosity = tmp .. "/p.vtk" }, tmp .. "/f.cli")
  t.eq(st.density.what, "porosity", "reported as porosity")
  t.near(st.density.voxels[1].target, 0.7, 1e-9, "target porosity")
  t.near(st.density.voxels[1].achieved, 0.7, 0.003, "achieved porosity")
end)

t.test("thickness from a VTK field file equals the same thickness as an expression", function()
  vtk(tmp .. "/t.vtk", 0.1)
  local a = lattice.run(params { thickness = tmp .. "/t.vtk", layer = 0.1, kb = "off" }, tmp .. "/t1.cli")
  local b = lattice.run(params { thickness = "0.1", layer = 0.1, kb = "off" }, tmp .. "/t2.cli")
  t.ok(a.solid_volume_mm3 > 0, "solid")
  -- the two thicknesses differ by the interpolation's rounding, which can
  -- tip a crossing between the nodes' cubic and a solve on the surface:
  -- each is within the crossing tolerance (10 nm) of the true section, so
  -- the solids differ by at most that over the sheet's two walls (their
  -- area: the volume over T)
  local walls = a.solid_volume_mm3 / 0.1
  t.near(a.solid_volume_mm3, b.solid_volume_mm3, walls * 1e-5, "same solid (to the crossing tolerance)")
  t.ok(not a.density, "no density stats")
end)

t.test("infeasible targets: refused with the reachable range, or clamped and counted", function()
  t.raises(function() lattice.run(params { density = "0.01" }, tmp .. "/bad.cli") end,
    "density 0.01 at x=[%d.]+ y=[%d.]+ z=[%d.]+: gyroid sheet, L=2 mm, reachable 0%.0%d+%.%.0%.9%d+ with a 0%.05 mm track")
  t.ok(not io.open(tmp .. "/bad.cli"), "no CLI left behind")
  t.raises(function() lattice.run(params { density = "0.3", porosity = "0.7" }, tmp .. "/bad.cli") end, "not both")
  local st = lattice.run(params { density = "0.01", clamp = true, layer = 0.1 }, tmp .. "/c.cli")
  t.eq(st.density.clamped_voxels, 1, "clamped voxels counted")
end)

t.test("a Lua function target becomes a grid the workers can read", function()
  local fn = function(x, y, z) return 0.2 + 0.01 * x + 0.02 * y + 0.03 * z end
  local d = density.prepare(params { density = fn }, { 0, 0, 0 }, { 1, 1, 1 }, tmp .. "/fn.cli")
  t.ok(d.src.field, "a field")
  local v = d.src.field:eval(0.3, 1.1, 1.7)
  t.near(v, fn(0.3, 1.1, 1.7), 1e-9, "linear function reproduced")
  local spec = d:spec("gyroid")
  t.ok(spec.target == d.src.field and spec.density_table, "spec carries table and target")
end)

t.test("gradus.distance.offset with a density table", function()
  local tb = density.get { surface = "gyroid", cell = 2, track = 0.05 }
  local g = gradus.distance.offset { surface = "gyroid", cell = 2, thickness = "0.4", density_table = tb }
  local T = tb:thickness(0.4)
  t.near(tb:rho(T), 0.4, 1e-9, "round trip")
  -- on the gyroid surface (phi = 0 at the cell centre), g = 0 - T
  t.near(g:eval(1, 1, 1), -T, 1e-6, "field value on H is -T(rho)")
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
