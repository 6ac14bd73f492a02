-- Measured toolpath quality (doc/contract.md s.5): for graded P, gyroid and diamond
-- cells, sheet and network, distance modes exact and mesh. A 3 x 3 block of
-- 2 mm cells (t = 0.04, d = 0.05, b = d/2, one contour) is placed through the
-- knowledge-base pipeline; on every `step`-th layer the middle voxel is
-- checked against the true section (the graded offset field of the whole
-- block sliced directly at the layer's mid-plane on a fine grid):
--   pore     = solid area left unmelted / solid area (melt track width d)
--   overmelt = melted area outside the solid / solid area
--   dev      = | in-plane distance of each contour point to the true section boundary - b |
--   thin     = thin-wall centre lines (slivers narrower than 2b): scans and length,
--              not in dev (they follow a wall's middle, not the offset b)
--   gradus run recipes/quality.lua [-D step=5] [-D surfaces=primitive,gyroid,diamond]
--     [-D per_layer=true] (one line per checked layer) [-D sheet_thickness=EXPR]
local lattice = require "gradus.lattice"
local step = gradus.param("step", 5, { integer = true, min = 1, max = 50, help = "check every step-th layer" })
local res = gradus.param("res", 40, { integer = true, min = 4, max = 400, help = "marching-cubes samples per cell edge" })
local surfaces = gradus.param("surfaces", "primitive,gyroid,diamond", { help = "TPMS names, comma-separated" })
local kinds = gradus.param("kinds", "sheet,network", { help = "sheet and/or network" })
local modes = gradus.param("modes", "exact,mesh", { help = "distance modes: exact and/or mesh" })
local per_layer = gradus.param("per_layer", false, { help = "one line per checked layer" })
local out = gradus.param("out", "", { help = "YAML file for the table (empty: none)" })
local d, t, b, L = 0.05, 0.04, 0.025, 2.0
-- sheets: the paper's eq. (8), graded inside each cell (w wraps at the cell's
-- faces, so the thickness jumps there: see doc/quality.md); -D
-- sheet_thickness='0.1*(2*sin(pi*min(max(z,0),2)/4)+1)' is the same inside
-- the block and continuous across its faces
local T = { sheet = gradus.param("sheet_thickness", "0.1*(2*sin(pi*(w+1)/4)+1)",
  { unit = "mm", help = "half-thickness of the sheets (expression)" }), network = "0.1" }

local kbdir = os.tmpname()
os.remove(kbdir)
local function list(s) local o = {} for x in s:gmatch("[^,]+") do o[#o + 1] = x end return o end

local rows = {}
for _, surface in ipairs(list(surfaces)) do
  for _, kind in ipairs(list(kinds)) do
    for _, mode in ipairs(list(modes)) do
      local p = lattice.params()
      p.surface, p.kind, p.thickness, p.mode, p.res = surface, kind, T[kind], mode, res
      p.cells, p.layer, p.hatch, p.contours, p.kb = "3,3,1", t, d, 1, kbdir
      local keep = {}
      for g = 3, math.floor(L / t + 0.5), step do keep[#keep + 1] = g end
      p.pictures = ""
      local job_keep = table.concat(keep, ",")
      -- run the pipeline without writing a CLI; keep the layers
      p.layers = ""
      local st, kept = (function()
        p.pictures = job_keep
        return lattice.run(p, nil)
      end)()
      local truth = gradus.distance.offset { surface = surface, cell = L, lo = { 0, 0, 0 }, hi = { 3 * L, 3 * L, L },
        res = res, thickness = T[kind], kind = kind, mode = "exact" }
      local worst = { pore = 0, over = 0, dev = 0, devsum = 0, npts = 0, above = 0, thin = 0, thin_length = 0 }
      for _, g in ipairs(keep) do
        local layer = kept[g]
        local z = g * t - t / 2
        local sec = gradus.slice.field(truth, z, { lo = { L - 0.3, L - 0.3 }, hi = { 2 * L + 0.3, 2 * L + 0.3 }, cell = d / 8 })
        local r = gradus.hatch.verify(sec, layer, { track = d, pixel = d / 20, offset = b, spacing = d, contours = 1,
          clip_lo = { L, L }, clip_hi = { 2 * L, 2 * L } })
        worst.pore = math.max(worst.pore, r.pore)
        worst.over = math.max(worst.over, r.overmelt)
        worst.dev = math.max(worst.dev, r.max_dev)
        worst.devsum = worst.devsum + r.mean_dev * r.contour_points
        worst.npts = worst.npts + r.contour_points
        worst.thin = worst.thin + r.thin_scans
        worst.thin_length = worst.thin_length + r.thin_length
        if per_layer then
          print(("  layer %2d  pore %.4f%%  overmelt %.4f%%  dev max %.3f um  thin %d (%.3f mm)")
            :format(g, 100 * r.pore, 100 * r.overmelt, r.max_dev * 1000, r.thin_scans, r.thin_length))
        end
      end
      rows[#rows + 1] = { surface = surface, kind = kind, mode = mode, layers = #keep, pore_max = worst.pore,
        overmelt_max = worst.over, dev_max_um = worst.dev * 1000, dev_mean_um = worst.npts > 0 and worst.devsum / worst.npts * 1000 or 0,
        thin_scans = worst.thin, thin_length = worst.thin_length }
      local r = rows[#rows]
      print(("%-10s %-8s %-6s layers %2d  pore max %.4f%%  overmelt max %.4f%%  contour dev max %.3f um mean %.3f um  thin %d (%.2f mm)")
        :format(surface, kind, mode, r.layers, 100 * r.pore_max, 100 * r.overmelt_max, r.dev_max_um, r.dev_mean_um,
          r.thin_scans, r.thin_length))
    end
  end
end
os.execute("rm -rf '" .. kbdir .. "'")
if out ~= "" then gradus.yaml.save(out, { quality = rows, date = os.date("!%Y-%m-%d"), step = step, res = res }) end
