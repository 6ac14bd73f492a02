-- Measured toolpath quality (doc/contract.md s.5): for graded TPMS cells, sheet
-- and network, distance modes exact and mesh. A 3 x 3 block of 2 mm cells
-- (t = 0.04, d = 0.05, b = d/2, one contour) is placed through the
-- knowledge-base pipeline (`rows` rows of cells, default 2, so that there is
-- a cell face inside the block); on every `step`-th layer (default every
-- layer) the middle voxel is checked against the true section under
-- voxel-owned grading, built here independently of the templates and of the
-- engine's face-step code (gradus.steptruth): each of the nine voxels around
-- it has its own offset field (gradus.distance.offset with voxel = true:
-- u, v, w of a foot point relative to that voxel, clamped), and is the solid
-- only inside its own square; where the gradings of neighbours differ the
-- section steps on their face.
-- Layers within two of a cell face (z = k L: the first and last two of the
-- block, two on each side of an inner face) are reported apart ("face"):
--   pore     = solid area left unmelted / solid area (melt track width d), in the middle voxel
--   overmelt = melted area outside the solid / solid area
--   hatch out = hatch length outside the solid / hatch length, in the middle voxel
--              (exact: each vector cut where it crosses the true section's boundary)
--   dev      = | in-plane distance of each contour point of the middle voxel to the
--              true section boundary - b | (exact boundary, steps included; max, p99, mean):
--              the vertices and `chords` points evenly spaced inside every segment
--              (default 3: the laser follows the chord, not only its ends);
--              points more than `recheck` um off that boundary are measured again
--              on the voxels' own fields sampled every 0.1 um around the point
--              (gradus.steptruth.local_deviation), counted as `rechecked`
--   thin     = thin-wall centre lines (slivers narrower than 2b): scans and length,
--              not in dev (they follow a wall's middle, not the offset b)
-- Gradings (-D grading=): eq8 (sheets: the paper's eq. (8) in w; networks: 0.1 mm),
-- sine_u (0.1 + 0.04 sin(pi u): periodic across x, continuous at the faces),
-- step_x / step_y (0.06, 0.10, 0.14 mm by column / row of cells: steps at x / y faces).
--   gradus run recipes/quality.lua [-D step=1] [-D rows=2] [-D surfaces=primitive,gyroid,diamond]
--     [-D grading=eq8] [-D per_layer=true] (one line per checked layer) [-D sheet_thickness=EXPR]
local lattice = require "gradus.lattice"
local truth = require "gradus.steptruth"
local step = gradus.param("step", 1, { integer = true, min = 1, max = 50, help = "check every step-th layer" })
local nrows = gradus.param("rows", 2, { integer = true, min = 1, max = 10, help = "rows of cells along z in the block" })
local res = gradus.param("res", 40, { integer = true, min = 4, max = 400, help = "marching-cubes samples per cell edge" })
local surfaces = gradus.param("surfaces", "primitive,gyroid,diamond", { help = "TPMS names, comma-separated" })
local kinds = gradus.param("kinds", "sheet,network", { help = "sheet and/or network" })
local modes = gradus.param("modes", "exact,mesh", { help = "distance modes: exact and/or mesh" })
local per_layer = gradus.param("per_layer", false, { help = "one line per checked layer" })
local out = gradus.param("out", "", { help = "YAML file for the table (empty: none)" })
local grading = gradus.param("grading", "eq8", { help = "eq8, sine_u, step_x or step_y (see the top of the file)" })
local recheck = gradus.param("recheck", 1, { unit = "um", min = 0, max = 1000,
  help = "contour points off the reference by more than this are measured again on the voxels' own fields (0.1 um grid)" })
local recheck_max = gradus.param("recheck_max", 300, { integer = true, min = 0, max = 100000,
  help = "at most this many points a layer measured again (the worst first)" })
local chords = gradus.param("chords", 3, { integer = true, min = 0, max = 20,
  help = "points measured inside every contour segment, besides its vertices" })
local first = gradus.param("first", 1, { integer = true, min = 1, max = 500, help = "first layer checked" })
local last = gradus.param("last", 0, { integer = true, min = 0, max = 500, help = "last layer checked (0: the block's last)" })
local d, t, b, L = 0.05, 0.04, 0.025, 2.0
-- sheets: the paper's eq. (8), graded inside each cell (each voxel's own
-- grading: the thickness steps at the cell faces between layers); -D
-- sheet_thickness='0.1*(2*sin(pi*min(max(z,0),2)/4)+1)' is continuous across
-- them
local T = { sheet = gradus.param("sheet_thickness", "0.1*(2*sin(pi*(w+1)/4)+1)",
  { unit = "mm", help = "half-thickness of the sheets (expression)" }), network = "0.1" }

local STEPS = { 0.06, 0.10, 0.14 }
-- the thickness of voxel (i, j) of the block for a kind
local function thickness(kind, i, j)
  if grading == "eq8" then return T[kind] end
  if grading == "sine_u" then return "0.1 + 0.04*sin(pi*u)" end
  if grading == "step_x" then return STEPS[i + 1] end
  if grading == "step_y" then return STEPS[j + 1] end
  error(("bad option 'grading' (eq8, sine_u, step_x or step_y expected, got '%s')"):format(grading), 0)
end

local kbdir = os.tmpname()
os.remove(kbdir)
local function list(s) local o = {} for x in s:gmatch("[^,]+") do o[#o + 1] = x end return o end

local rows = {}
for _, surface in ipairs(list(surfaces)) do
  for _, kind in ipairs(list(kinds)) do
    for _, mode in ipairs(list(modes)) do
      local p = lattice.params()
      p.surface, p.kind, p.thickness, p.mode, p.res = surface, kind, tostring(thickness(kind, 1, 1)), mode, res
      p.rule = function(i, j) return { thickness = thickness(kind, i, j) } end
      p.cells, p.layer, p.hatch, p.contours, p.kb = ("3,3,%d"):format(nrows), t, d, 1, kbdir
      local keep, per = {}, math.floor(L / t + 0.5)
      for g = first, last > 0 and math.min(last, nrows * per) or nrows * per, step do keep[#keep + 1] = g end
      local function near_face(g) local r = (g - 1) % per return r < 2 or r >= per - 2 end
      -- run the pipeline without writing a CLI; keep the layers
      p.layers = ""
      p.pictures = table.concat(keep, ",")
      local _, kept = lattice.run(p, nil)
      -- the truth: each voxel's own field (fields[k][i][j]), built when a row is first checked
      local fields = {}
      local function row(k)
        if not fields[k] then
          fields[k] = {}
          for i = 0, 2 do
            for j = 0, 2 do
              fields[k][3 * j + i + 1] = { lo = { i * L, j * L }, hi = { (i + 1) * L, (j + 1) * L },
                field = gradus.distance.offset { surface = surface, cell = L, lo = { i * L, j * L, k * L },
                  hi = { (i + 1) * L, (j + 1) * L, (k + 1) * L }, res = res, thickness = thickness(kind, i, j),
                  kind = kind, mode = "exact", voxel = true } }
            end
          end
        end
        return fields[k]
      end
      local function blank() return { pore = 0, over = 0, hout = 0, rechecked = 0, recheck_left = 0, dev = 0, p99 = 0, devsum = 0, npts = 0, thin = 0, thin_length = 0, layers = 0 } end
      local worst = { interior = blank(), face = blank() }
      for _, g in ipairs(keep) do
        local layer = kept[g]
        local z = g * t - t / 2
        local V = row((g - 1) // per)
        -- inside the middle voxel the section is its own field's
        local sec = gradus.slice.field(V[5].field, z, { lo = { L, L }, hi = { 2 * L, 2 * L }, cell = d / 8 })
        local r = gradus.hatch.verify(sec, layer, { track = d, pixel = d / 20, offset = b, spacing = d, contours = 1,
          clip_lo = { L, L }, clip_hi = { 2 * L, 2 * L } })
        local E = truth.edges(V, z, { lo = { L - 0.15, L - 0.15 }, hi = { 2 * L + 0.15, 2 * L + 0.15 } }, d / 8)
        local pts = truth.points(layer, E, b, { L, L, 2 * L, 2 * L }, chords)
        -- points off the reference by more than `recheck`: measured again on the
        -- voxels' own fields, on a 0.1 um grid around the point (the reference's
        -- boundary is ill-conditioned where the field is nearly flat at zero)
        table.sort(pts, function(p1, p2) return math.abs(p1[3]) > math.abs(p2[3]) end)
        r.rechecked, r.recheck_left = 0, 0
        for _, q in ipairs(pts) do
          if math.abs(q[3]) <= recheck * 1e-3 then break end
          if r.rechecked >= recheck_max then r.recheck_left = r.recheck_left + 1
          else
            local ref, found = q[3], nil
            q[3], found = truth.local_deviation(V, z, q[1], q[2], b, { reach = math.max(0.002, math.abs(q[3]) + 0.001) })
            r.rechecked = r.rechecked + 1
            if per_layer then
              print(("    layer %d point (%.5f, %.5f): %+.3f um against the reference, %s%.3f um on the field")
                :format(g, q[1], q[2], ref * 1e3, found and "" or "no void within, at least +", q[3] * 1e3))
            end
          end
        end
        local devs, dsum = {}, 0
        for _, q in ipairs(pts) do devs[#devs + 1] = math.abs(q[3]); dsum = dsum + devs[#devs] end
        table.sort(devs)
        r.max_dev, r.p99_dev, r.contour_points = truth.quantile(devs, 1), truth.quantile(devs, 0.99), #devs
        r.mean_dev = #devs > 0 and dsum / #devs or 0
        local w = worst[near_face(g) and "face" or "interior"]
        w.layers = w.layers + 1
        w.pore = math.max(w.pore, r.pore)
        w.over = math.max(w.over, r.overmelt)
        r.hatch_out = r.hatch_length > 0 and r.hatch_outside / r.hatch_length or 0
        w.hout = math.max(w.hout, r.hatch_out)
        w.dev = math.max(w.dev, r.max_dev)
        w.p99 = math.max(w.p99, r.p99_dev)
        w.devsum = w.devsum + r.mean_dev * r.contour_points
        w.npts = w.npts + r.contour_points
        w.thin = w.thin + r.thin_scans
        w.rechecked, w.recheck_left = w.rechecked + r.rechecked, w.recheck_left + r.recheck_left
        w.thin_length = w.thin_length + r.thin_length
        if per_layer then
          print(("  layer %3d%s  pore %.4f%%  overmelt %.4f%%  hatch out %.4f%%  dev max %.3f um p99 %.3f um  thin %d (%.3f mm)  rechecked %d%s")
            :format(g, near_face(g) and "*" or " ", 100 * r.pore, 100 * r.overmelt, 100 * r.hatch_out, r.max_dev * 1000, r.p99_dev * 1000,
              r.thin_scans, r.thin_length, r.rechecked, r.recheck_left > 0 and (" (%d left)"):format(r.recheck_left) or ""))
        end
      end
      for _, where in ipairs { "interior", "face" } do
        local w = worst[where]
        rows[#rows + 1] = { surface = surface, kind = kind, mode = mode, grading = grading, layers = where, checked = w.layers, pore_max = w.pore,
          overmelt_max = w.over, hatch_outside_max = w.hout, dev_max_um = w.dev * 1000, dev_p99_um = w.p99 * 1000, dev_mean_um = w.npts > 0 and w.devsum / w.npts * 1000 or 0,
          thin_scans = w.thin, thin_length = w.thin_length, rechecked = w.rechecked, recheck_left = w.recheck_left }
        local r = rows[#rows]
        print(("%-10s %-8s %-6s %-7s %-8s layers %3d  pore max %.4f%%  overmelt max %.4f%%  hatch out max %.4f%%  contour dev max %.3f um p99 %.3f um mean %.3f um  thin %d (%.2f mm)  rechecked %d%s")
          :format(surface, kind, mode, grading, where, r.checked, 100 * r.pore_max, 100 * r.overmelt_max, 100 * r.hatch_outside_max, r.dev_max_um,
            r.dev_p99_um, r.dev_mean_um, r.thin_scans, r.thin_length, r.rechecked,
            r.recheck_left > 0 and (" (%d left)"):format(r.recheck_left) or ""))
      end
    end
  end
end
os.execute("rm -rf '" .. kbdir .. "'")
if out ~= "" then gradus.yaml.save(out, { quality = rows, date = os.date("!%Y-%m-%d"), step = step, res = res }) end
