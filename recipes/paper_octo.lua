-- The paper's OCTO case (Figs. 18, 19): the O,C-TO cell (SPEC.md s.2) with the
-- half-thickness of eq. (9) (half of eq. 8), hatched with the three
-- strategies of Fig. 18, all with a 90-degree rotation from the x axis:
--   island with parallel vectors, parallel vectors (joined), island with
--   contour + parallel vectors (combined). Pictures of layers 24 and 25.
local lattice = require "gradus.lattice"
local profile = gradus.yaml.load(gradus.root .. "/recipes/profiles/paper.yaml")
local dir = gradus.param("dir", "out/paper_octo")
local EQ9 = "0.05*(2*sin(pi*(w+1)/4)+1)"
local function run(name, over)
  local p = lattice.params()
  p.surface = "octo"
  p.cell, p.layer, p.hatch, p.beam_offset = profile.voxel, profile.layer, profile.hatch, profile.beam_offset
  p.thickness = EQ9
  p.cells = "2,2,1"
  p.angle, p.rotation = 0, 90
  p.pictures = "24,25"
  for k, v in pairs(over) do p[k] = v end
  local st = lattice.run(p, dir .. "/" .. name .. ".cli")
  print(("%-26s %3d layers  %5.2f m contours  %6.2f m hatches  %s"):format(name, st.layers,
    st.vectors.contour.length / 1000, st.vectors.hatch.length / 1000, table.concat(st.pictures, " ")))
end
run("fig18a_island_parallel", { pattern = "island", contours = 0 })
run("fig18b_parallel", { pattern = "parallel", contours = 0 })
run("fig18c_island_combined", { pattern = "island", contours = 1 })
