-- A build plate: several parts, each placed and turned, in one CLI.
--   gradus run recipes/plate.lua -D plate=recipes/plate.yaml -o out/plate.cli --stats out/plate.yaml
-- The plate file (doc/formats.md "Plate files") lists the parts: lattice
-- parameters or a recipe with its parameters, plus at: [x, y] and rotation:.
-- Writes the CLI, out/plate.manifest.yaml, the stats with per-part figures,
-- out/plate_plate.svg (the footprints) and a layer picture.
local plate = require "gradus.plate"
local file = gradus.param("plate", (gradus.root or ".") .. "/recipes/plate.yaml",
  { help = "the plate file (YAML): machine, layer, format and the list of parts" })
local out = gradus.output("out/plate.cli")
local st = plate.run { plate = file, output = out }
local names = {}
for _, p in ipairs(st.parts) do names[#names + 1] = ("%s %d layers"):format(p.name, p.layers) end
print(("%s: %d parts (%s), %d layers, %.1f mm3 solid, est. build %.0f s (%.0f s recoating)")
  :format(out, #st.parts, table.concat(names, ", "), st.layers, st.solid_volume_mm3, st.build_time_s, st.recoat_time_s))
