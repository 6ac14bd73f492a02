-- A bone-scaffold-like cylinder designed by porosity: a gyroid sheet lattice
-- graded from 60 % porosity at the core to 80 % at the rim, trimmed to a
-- cylinder of radius R; the stats compare the achieved porosity of every
-- voxel inside the cylinder (from the CLI's contours) with its target, and a
-- plot (SVG, PNG) shows target against achieved.
--   gradus run recipes/density.lua [-D surface=gyroid] [-D cells=6,6,2] [-o out/density.cli] [--stats out/density.yaml]
-- Every lattice parameter (recipes/lattice.lua) can be given; these are the
-- recipe's own defaults.
local lattice = require "gradus.lattice"
local density = require "gradus.density"
local p = lattice.params { surface = "gyroid", cell = 2.0, cells = "6,6,2", layer = 0.04 }
local R = gradus.param("radius", 6.0)     -- cylinder radius, mm
local core = gradus.param("core", 0.6)    -- porosity on the axis
local rim = gradus.param("rim", 0.8)      -- porosity at radius R
local n = {}
for item in tostring(p.cells):gmatch("[^,]+") do n[#n + 1] = tonumber(item) end
local cx, cy = n[1] * p.cell / 2, n[2] * p.cell / 2
local r = ("sqrt((x-%g)^2+(y-%g)^2)"):format(cx, cy)
if p.porosity == "" and p.density == "" then
  p.porosity = ("%g+%g*min(%s/%g,1)"):format(core, rim - core, r, R)
end
if p.domain == "" then p.domain = ("%s-%g"):format(r, R) end
local out = gradus.output("out/density.cli")
local st = lattice.run(p, out)
local d = st.density
local pics = density.plot(out:gsub("%.cli$", "") .. "_plot.png", d,
  ("%s %s, porosity %g (core) to %g (rim): target vs achieved per voxel"):format(p.surface, p.kind, core, rim))
print(("%s: %d layers, %d voxels; porosity per voxel inside the cylinder (%d compared, %d cut by it): error min %+.4f mean %+.4f max %+.4f; plot %s")
  :format(out, st.layers, st.voxels, d.compared, d.partial, d.error and d.error.min or 0, d.error and d.error.mean or 0,
    d.error and d.error.max or 0, table.concat(pics, ", ")))
