-- The paper's case study (section 4): the graded Schwarz P cell of Table 1
-- (L = 2 mm, t = 40 um, d = 50 um) with the thickness of eq. (8), H meshed at
-- resolution 150, and the toolpaths of its figures:
--   Fig. 16: parallel vectors rotated 90 degrees per layer, island (unjoined)
--            and continuous (joined across voxels) modes, on 2 x 2 cells;
--   Fig. 17: contour + parallel vectors rotated 67 degrees from 45, layers 24, 25.
local lattice = require "gradus.lattice"
local profile = require("gradus.profiles").process(gradus.root .. "/recipes/profiles/paper.yaml")
local dir = gradus.param("dir", "out/paper_p", { help = "output directory" })

-- the profile's values are the defaults; faces = false: the paper's voxel
-- templates, hatched up to the cell's sides, no side contours
local defaults = { cell = profile.voxel, layer = profile.layer, hatch = profile.hatch,
  beam_offset = profile.beam_offset, thickness = lattice.EQ8, res = 150, faces = false }

local function run(name, over)
  local p = lattice.params(defaults)
  for k, v in pairs(over) do p[k] = v end
  local out = dir .. "/" .. name .. ".cli"
  local st = lattice.run(p, out)
  print(("%-22s %3d layers  %5.2f m contours  %6.2f m hatches  pictures: %s"):format(name, st.layers,
    st.vectors.contour.length / 1000, st.vectors.hatch.length / 1000, table.concat(st.pictures, " ")))
  return st
end

run("fig16_island", { cells = "2,2,1", pattern = "island", angle = 0, rotation = 90, contours = 0, pictures = "24,25" })
run("fig16_continuous", { cells = "2,2,1", pattern = "parallel", angle = 0, rotation = 90, contours = 0, pictures = "24,25" })
run("fig17_contour_parallel", { cells = "1,1,1", pattern = "parallel", angle = 45, rotation = 67, contours = 1, pictures = "24,25" })
