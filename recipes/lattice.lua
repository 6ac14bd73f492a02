-- The general recipe: a box of graded TPMS cells to a CLI file.
--   gradus run recipes/lattice.lua -D cells=2,2,1 -o out.cli --stats out.yaml
-- Parameters (doc/contract.md section 7; `gradus run recipes/lattice.lua
-- --help` lists them with defaults, units and ranges): surface, cell, cells,
-- origin, level, kind, thickness, layer, hatch, beam_offset, angle, rotation,
-- pattern, contours, lasers, kb, format; and machine, assign, sequence, mode,
-- res, layers, pictures, split, threads; domain (an STL file of the part, or
-- an expression) and skin (mm); density or porosity (a target instead of
-- thickness, doc/density.md).
local lattice = require "gradus.lattice"
local p = lattice.params()
local out = gradus.output("out/lattice.cli")
local st = lattice.run(p, out)
-- scan length of every kind (contours, hatches, edges), in m, or in mm under a metre
local len = st.vectors.contour.length + st.vectors.hatch.length + st.vectors.edge.length
local scan = len >= 1000 and ("%.1f m"):format(len / 1000) or ("%.1f mm"):format(len)
print(("%s: %d layers, %d voxels, %d templates (%d built, %d from the knowledge base), %s of scan vectors, est. build %.0f s")
  :format(out, st.layers, st.voxels, st.templates.unique, st.templates.built, st.templates.reused, scan, st.build_time_s))
