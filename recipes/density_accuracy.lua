-- Accuracy of design by density, measured from the CLI (doc/density.md).
--   gradus run recipes/density_accuracy.lua [-D surfaces=gyroid,diamond] [-D kinds=sheet,network]
--     [-D fractions=0.1,0.5,0.9] [-D graded=true] [-o out/density_accuracy.md]
-- Uniform targets: one cell (L = 2 mm), beam offset 0, layer 0.02 mm, at the
-- given fractions of each surface's reachable range; the achieved density is
-- the contour area per layer times the layer thickness (gradus.density.measure).
-- graded=true adds a gyroid sheet graded along z over 4 cells, compared per
-- quarter of the height with the target's mean there.
local lattice = require "gradus.lattice"
local density = require "gradus.density"
local list = function(s)
  local t = {}
  for item in tostring(s):gmatch("[^,]+") do t[#t + 1] = item end
  return t
end
local surfaces = gradus.param("surfaces", "all", { help = "surfaces to measure, comma-separated (all: the whole catalogue)" })
local kinds = list(gradus.param("kinds", "sheet,network", { help = "sheet, network or both" }))
local fractions = list(gradus.param("fractions", "0.05,0.5,0.95"))
local graded = gradus.param("graded", true)
local out = gradus.output("out/density_accuracy.md")
local dir = out:gsub("%.md$", "")
local base = lattice.params()
surfaces = list(surfaces == "all" and table.concat(gradus.field.surfaces(), ",") or surfaces)
local function run(over, name)
  local p = {}
  for k, v in pairs(base) do p[k] = v end
  p.cell, p.cells, p.layer, p.beam_offset, p.pictures, p.kb = 2, "1,1,1", 0.02, 0, "", "off"
  for k, v in pairs(over) do p[k] = v end
  local st = lattice.run(p, dir .. "/" .. name .. ".cli")
  return st
end
local rows = { "| surface | kind | reachable | target | achieved | difference |", "|---|---|---|---|---|---|" }
local worst = 0
for _, s in ipairs(surfaces) do
  for _, kind in ipairs(kinds) do
    local t = density.get { surface = s, kind = kind, cell = 2, track = base.hatch, kb = base.kb }
    local lo, hi = t:range()
    if lo <= hi then
      for _, f in ipairs(fractions) do
        local target = lo + tonumber(f) * (hi - lo)
        local ok, st = pcall(run, { surface = s, kind = kind, density = ("%.6f"):format(target) }, s .. "_" .. kind .. "_" .. f)
        if ok then
          local a = st.density.voxels[1].achieved
          worst = math.max(worst, math.abs(a - target))
          rows[#rows + 1] = ("| %s | %s | %.4f..%.4f | %.4f | %.4f | %+.4f |"):format(s, kind, lo, hi, target, a, a - target)
        else
          rows[#rows + 1] = ("| %s | %s | %.4f..%.4f | %.4f | failed: %s | |"):format(s, kind, lo, hi, target, tostring(st):gsub("|", "/"))
        end
        io.stderr:write(rows[#rows] .. "\n")
      end
    else
      rows[#rows + 1] = ("| %s | %s | nothing reachable | | | |"):format(s, kind)
    end
  end
end
rows[#rows + 1] = ""
rows[#rows + 1] = ("Largest |achieved - target|: %.4f"):format(worst)
if graded then
  -- a z-graded gyroid sheet over 4 cells: density 0.15 at the bottom to 0.45 at the top
  local expr = "0.15+0.3*z/8"
  local st = run({ surface = "gyroid", kind = "sheet", cells = "1,1,4", density = expr }, "graded")
  rows[#rows + 1] = ""
  rows[#rows + 1] = "| quarter of the height (cell) | target mean | achieved | difference |"
  rows[#rows + 1] = "|---|---|---|---|"
  for _, v in ipairs(st.density.voxels) do
    rows[#rows + 1] = ("| %d (z %g..%g mm) | %.4f | %.4f | %+.4f |"):format(v.k + 1, 2 * v.k, 2 * v.k + 2, v.target, v.achieved, v.diff)
  end
end
gradus.write_file(out, table.concat(rows, "\n") .. "\n")
print(out)
