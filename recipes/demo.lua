-- The demo job (make demo): a 4 x 4 x 2 block of 2 mm Schwarz P sheet cells
-- whose wall thickens with height, two lasers balanced by scan time, a
-- binary CLI with its manifest and stats, and pictures of two layers.
local lattice = require "gradus.lattice"
-- the lattice recipe's parameters with the demo's own defaults; the
-- half-thickness grows from 0.06 mm at the bottom to 0.14 mm at the top (z in mm)
local p = lattice.params { cells = "4,4,2", thickness = "0.06 + 0.02*z", lasers = 2, format = "binary",
  pictures = "25,75" }
local out = gradus.output("out/demo.cli")
local st = lattice.run(p, out)
print(("demo: %s: %d layers, %d voxels in %d classes, %.2f m contours + %.2f m hatches, %d pictures, %.2f s")
  :format(out, st.layers, st.voxels, st.templates.unique, st.vectors.contour.length / 1000,
    st.vectors.hatch.length / 1000, #st.pictures, st.seconds.total))
for _, pic in ipairs(st.pictures) do print("  picture: " .. pic) end
