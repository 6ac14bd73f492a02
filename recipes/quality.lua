-- Measured toolpath quality (doc/contract.md s.5): for graded P, gyroid and diamond
-- cells, sheet and network, distance modes exact and mesh. A 3 x 3 block of
-- 2 mm cells (t = 0.04, d = 0.05, b = d/2, one contour) is placed through the
-- knowledge-base pipeline (`rows` rows of cells, default 2, so that there is
-- a cell face inside the block); on every `step`-th layer (default every
-- layer) the middle voxel is checked against the true section: the graded
-- offset field of the whole block under voxel-owned grading (the thickness
-- of a point reads u, v, w of its foot point relative to the voxel that
-- holds the point, clamped: gradus.distance.offset of the block, not the
-- templates), sliced directly at the layer's mid-plane on a fine grid.
-- Layers within two of a cell face (z = k L: the first and last two of the
-- block, two on each side of an inner face) are reported apart ("face"):
--   pore     = solid area left unmelted / solid area (melt track width d)
--   overmelt = melted area outside the solid / solid area
--   dev      = | in-plane distance of each contour point to the true section boundary - b |
--   thin     = thin-wall centre lines (slivers narrower than 2b): scans and length,
--              not in dev (they follow a wall's middle, not the offset b)
--   gradus run recipes/quality.lua [-D step=1] [-D rows=2] [-D surfaces=primitive,gyroid,diamond]
--     [-D per_layer=true] (one line per checked layer) [-D sheet_thickness=EXPR]
local lattice = require "gradus.lattice"
local step = gradus.param("step", 1, { integer = true, min = 1, max = 50, help = "check every step-th layer" })
local nrows = gradus.param("rows", 2, { integer = true, min = 1, max = 10, help = "rows of cells along z in the block" })
local res = gradus.param("res", 40, { integer = true, min = 4, max = 400, help = "marching-cubes samples per cell edge" })
local surfaces = gradus.param("surfaces", "primitive,gyroid,diamond", { help = "TPMS names, comma-separated" })
local kinds = gradus.param("kinds", "sheet,network", { help = "sheet and/or network" })
local modes = gradus.param("modes", "exact,mesh", { help = "distance modes: exact and/or mesh" })
local per_layer = gradus.param("per_layer", false, { help = "one line per checked layer" })
local out = gradus.param("out", "", { help = "YAML file for the table (empty: none)" })
local d, t, b, L = 0.05, 0.04, 0.025, 2.0
-- sheets: the paper's eq. (8), graded inside each cell (each voxel's own
-- grading: the thickness steps at the cell faces between layers); -D
-- sheet_thickness='0.1*(2*sin(pi*min(max(z,0),2)/4)+1)' is continuous across
-- them
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
      p.cells, p.layer, p.hatch, p.contours, p.kb = ("3,3,%d"):format(nrows), t, d, 1, kbdir
      local keep, per = {}, math.floor(L / t + 0.5)
      for g = 1, nrows * per, step do keep[#keep + 1] = g end
      local function near_face(g) local r = (g - 1) % per return r < 2 or r >= per - 2 end
      p.pictures = ""
      local job_keep = table.concat(keep, ",")
      -- run the pipeline without writing a CLI; keep the layers
      p.layers = ""
      local st, kept = (function()
        p.pictures = job_keep
        return lattice.run(p, nil)
      end)()
      local truth = gradus.distance.offset { surface = surface, cell = L, lo = { 0, 0, 0 }, hi = { 3 * L, 3 * L, nrows * L },
        res = res, thickness = T[kind], kind = kind, mode = "exact" }
      local function blank() return { pore = 0, over = 0, dev = 0, devsum = 0, npts = 0, thin = 0, thin_length = 0, layers = 0 } end
      local worst = { interior = blank(), face = blank() }
      for _, g in ipairs(keep) do
        local layer = kept[g]
        local z = g * t - t / 2
        local sec = gradus.slice.field(truth, z, { lo = { L - 0.3, L - 0.3 }, hi = { 2 * L + 0.3, 2 * L + 0.3 }, cell = d / 8 })
        local r = gradus.hatch.verify(sec, layer, { track = d, pixel = d / 20, offset = b, spacing = d, contours = 1,
          clip_lo = { L, L }, clip_hi = { 2 * L, 2 * L } })
        local w = worst[near_face(g) and "face" or "interior"]
        w.layers = w.layers + 1
        w.pore = math.max(w.pore, r.pore)
        w.over = math.max(w.over, r.overmelt)
        w.dev = math.max(w.dev, r.max_dev)
        w.devsum = w.devsum + r.mean_dev * r.contour_points
        w.npts = w.npts + r.contour_points
        w.thin = w.thin + r.thin_scans
        w.thin_length = w.thin_length + r.thin_length
        if per_layer then
          print(("  layer %3d%s  pore %.4f%%  overmelt %.4f%%  dev max %.3f um  thin %d (%.3f mm)")
            :format(g, near_face(g) and "*" or " ", 100 * r.pore, 100 * r.overmelt, r.max_dev * 1000, r.thin_scans, r.thin_length))
        end
      end
      for _, where in ipairs { "interior", "face" } do
        local w = worst[where]
        rows[#rows + 1] = { surface = surface, kind = kind, mode = mode, layers = where, checked = w.layers, pore_max = w.pore,
          overmelt_max = w.over, dev_max_um = w.dev * 1000, dev_mean_um = w.npts > 0 and w.devsum / w.npts * 1000 or 0,
          thin_scans = w.thin, thin_length = w.thin_length }
        local r = rows[#rows]
        print(("%-10s %-8s %-6s %-8s layers %3d  pore max %.4f%%  overmelt max %.4f%%  contour dev max %.3f um mean %.3f um  thin %d (%.2f mm)")
          :format(surface, kind, mode, where, r.checked, 100 * r.pore_max, 100 * r.overmelt_max, r.dev_max_um, r.dev_mean_um,
            r.thin_scans, r.thin_length))
      end
    end
  end
end
os.execute("rm -rf '" .. kbdir .. "'")
if out ~= "" then gradus.yaml.save(out, { quality = rows, date = os.date("!%Y-%m-%d"), step = step, res = res }) end
