-- The paper's Fig. 20: graded voxels assembled along z. A column of `n` P
-- cells (default 4) whose half-thickness grows from cell to cell along the
-- part's height; each cell is a different voxel class, so each gets its own
-- template; the column's toolpaths are the templates stacked. Pictures of a
-- layer in the lowest and in the highest cell show the grading.
local lattice = require "gradus.lattice"
local n = gradus.param("n", 4, { integer = true, min = 1, max = 100, help = "cells in the column" })
local p = lattice.params()
p.cells = ("1,1,%d"):format(n)
-- T rises linearly with the global height z: 0.05 mm at the bottom to 0.15 mm at the top
p.thickness = gradus.param("thickness", ("0.05 + 0.1*z/%g"):format(n * p.cell))
local per = math.floor(p.cell / p.layer + 0.5)
p.pictures = gradus.param("pictures", ("%d,%d"):format(per // 2, (n - 1) * per + per // 2))
local out = gradus.output("out/paper_assembly.cli")
local st = lattice.run(p, out)
print(("Fig. 20 column: %d cells, %d layers, %d voxel classes (templates), pictures %s"):format(n, st.layers,
  st.templates.unique, table.concat(st.pictures, " ")))
