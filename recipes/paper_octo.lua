-- The paper's OCTO case (Figs. 18, 19): the O,C-TO cell (doc/contract.md s.2) with the
-- half-thickness of eq. (9) (half of eq. 8), hatched with the three
-- strategies of Fig. 18, all with a 90-degree rotation from the x axis:
--   island with parallel vectors, parallel vectors (joined), island with
--   contour + parallel vectors (combined). Pictures of layers 24 and 25.
local lattice = require "gradus.lattice"
local profile = require("gradus.profiles").process(gradus.root .. "/recipes/profiles/paper.yaml")
local dir = gradus.param("dir", "out/paper_octo", { help = "output directory" })
local EQ9 = "0.05*(2*sin(pi*(w+1)/4)+1)"
local function run(name, over)
  local p = lattice.params { cell = profile.voxel, layer = profile.layer, hatch = profile.hatch,
    beam_offset = profile.beam_offset, pictures = "24,25" }
  p.surface, p.thickness, p.cells, p.angle, p.rotation = "octo", EQ9, "2,2,1", 0, 90
  for k, v in pairs(over) do p[k] = v end
  local st = lattice.run(p, dir .. "/" .. name .. ".cli")
  print(("%-26s %3d layers  %5.2f m contours  %6.2f m hatches  %s"):format(name, st.layers,
    st.vectors.contour.length / 1000, st.vectors.hatch.length / 1000, table.concat(st.pictures, " ")))
end
run("fig18a_island_parallel", { pattern = "island", contours = 0 })
run("fig18b_parallel", { pattern = "parallel", contours = 0 })
run("fig18c_island_combined", { pattern = "island", contours = 1 })
