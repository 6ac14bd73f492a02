-- gradus.lattice: the whole pipeline from a table of options: a box (or a
-- domain) of graded TPMS cells to a CLI file, a manifest, stats and pictures.
-- recipes/lattice.lua reads the parameters of doc/contract.md section 7 and calls run().
local gradus = require "gradus"
local sequence = require "gradus.sequence"
local lasers = require "gradus.lasers"
local M = {}

-- The paper's eq. (8): graded half-thickness along the cell's local height.
M.EQ8 = "0.1*(2*sin(pi*(w+1)/4)+1)"

local strict = require "gradus.strict"
local part = require "gradus.part"
local SURFACES = { "primitive", "gyroid", "diamond", "iwp", "neovius", "frd", "fischer_koch_s", "lidinoid",
  "split_p", "octo" }
local FN = { ["function"] = true }

--- M.PARAMS: the parameters of the general recipe (doc/contract.md section
-- 7, plus a few): { name, default, spec } with the unit, one line of help
-- and the accepted range (gradus.strict.check). `gradus run RECIPE --help`,
-- help("name") and the checks of M.run all read this list.
M.PARAMS = {
  { "surface", "primitive", { choices = SURFACES, help = "TPMS surface of the cells" } },
  { "cell", 2.0, { n = 3, one = true, unit = "mm", min = 0.1, max = 100,
    help = "cell (voxel) size L, or Lx,Ly,Lz for a stretched cell" } },
  { "cells", "2,2,1", { n = 3, integer = true, min = 1, max = 100000, help = "cells along x, y, z" } },
  { "size", "", { n = 3, unit = "mm", min = 0.01, max = 100000, empty = true,
    help = "part size x, y, z instead of cells: the lattice is cut at the faces (empty: cells)" } },
  { "origin", "0,0,0", { n = 3, unit = "mm", min = -1000, max = 1000, help = "min corner x, y, z of the box of cells" } },
  { "level", 0.0, { min = -20, max = 20, help = "iso-level c of the TPMS (the surface phi = c)" } },
  { "kind", "sheet", { choices = { "sheet", "network" }, help = "sheet (a wall around the surface) or network (one side, grown)" } },
  { "thickness", M.EQ8, { kind = "expr", unit = "mm", min = 0.005, max = 10,
    help = "graded half-thickness T: a number or an expression in x, y, z, u, v, w, L, Lx, Ly, Lz, pi" } },
  { "inside", "", { kind = "expr", empty = true, unit = "mm", min = 0.005, max = 10,
    help = "inside half-thickness of an asymmetric sheet (empty: same as thickness)" } },
  { "layer", 0.04, { unit = "mm", min = 0.005, max = 1, help = "layer thickness t" } },
  { "hatch", 0.05, { unit = "mm", min = 0.005, max = 2, help = "hatch spacing d" } },
  { "beam_offset", "auto", { auto = "hatch/2", unit = "mm", min = 0, max = 1,
    help = "contour offset b inside the section boundary (at most cell/4, auto too)" } },
  { "angle", 45.0, { unit = "degrees", min = -360, max = 360, help = "hatch angle of layer 1" } },
  { "rotation", 67.0, { unit = "degrees", min = -360, max = 360, help = "hatch angle added per layer" } },
  { "pattern", "parallel", { choices = { "parallel", "zigzag", "island" },
    help = "parallel (joined across voxels), zigzag, island (per voxel)" } },
  { "alternate", true, { help = "reverse every other hatch vector" } },
  { "contours", 1, { integer = true, min = 0, max = 20, help = "contour scans per boundary" } },
  { "contour_first", true, { help = "contours before hatches" } },
  { "lasers", 1, { integer = true, min = 1, max = 16, help = "identical lasers (without a machine profile)" } },
  { "machine", "", { help = "machine profile YAML (lasers, fields, speeds); empty: `lasers` identical lasers" } },
  { "assign", "balance", { choices = { "balance", "zones" }, allow = FN, help = "laser assignment: balance (scan time) or zones" } },
  { "sequence", "raster", { choices = sequence.names, allow = FN, help = "order of the islands of a layer" } },
  { "kb", "", { help = "knowledge-base directory; empty: the default cache; off: compute every voxel directly" } },
  { "kb_store", "reused", { choices = { "all", "reused", "none" },
    help = "templates written to the knowledge base: all, reused (classes of more than one voxel) or none" } },
  { "format", "ascii", { choices = { "ascii", "binary", "binary-long", "ovf" },
    help = "output format: ascii CLI, binary CLI (short form when the part fits), binary-long CLI, ovf (Open Vector Format)" } },
  { "res", 40, { integer = true, min = 4, max = 400, help = "marching-cubes samples per cell edge for the surface H" } },
  { "mode", "exact", { choices = { "exact", "mesh" }, help = "closest points: exact (analytic) or mesh (the paper's)" } },
  { "slice_cell", "auto", { auto = "hatch/2", unit = "mm", min = 0.0005, max = 1,
    help = "grid step of the in-plane distance field (at most hatch/2, at least cell/4000)" } },
  { "quant", 0.001, { unit = "mm", min = 1e-6, max = 0.01, help = "thickness quantisation of template keys" } },
  { "threads", 2, { integer = true, min = 1, max = 64, help = "worker threads" } },
  { "layers", "", { help = "range a:b of layers to compute (empty: all)" } },
  { "pictures", "", { help = "layer numbers to draw as SVG/PNG, e.g. 24,25" } },
  { "split", false, { help = "also write one CLI per laser" } },
  { "verify", "", { help = "layer numbers to check against the true section (stats: quality)" } },
  { "min_length", 0.0, { unit = "mm", min = 0, max = 10, help = "hatch vectors shorter than this are dropped" } },
  { "domain", "", { allow = { userdata = true }, help = "design domain: an STL file of the part or an expression negative inside" } },
  { "skin", 0.0, { unit = "mm", min = 0, max = 10, help = "solid skin depth along the domain's boundary" } },
  { "domain_distance", true, { help = "make an expression domain a signed distance in mm (unless it is one already), so that skin is in mm whatever its scale; false: use the expression's values as they are" } },
  { "faces", true, { help = "contour the lattice where the box of cells cuts it" } },
  { "regions", "", { help = "build styles per region (skin, thin, downskin, upskin): a process profile with regions:, or default (Ti-6Al-4V); empty: none" } },
  { "qualify", false, { allow = FN, help = "verify every template built and qualify it (or a Lua rule)" } },
  -- design by density (gradus.density, doc/density.md): a target instead of thickness
  { "density", "", { kind = "expr", empty = true, min = 1e-6, max = 1, allow = FN,
    help = "relative density target in (0, 1): a number, an expression, a Lua function or a .vtk/.npy field file" } },
  { "porosity", "", { kind = "expr", empty = true, min = 0, max = 1, allow = FN,
    help = "porosity target (1 - density), same forms as density" } },
  { "density_origin", "0,0,0", { n = 3, unit = "mm", min = -1000, max = 1000, help = "origin of a .npy field file's grid" } },
  { "density_spacing", "", { help = "grid spacing of a .npy field file: d or dx,dy,dz (mm)" } },
  { "clamp", false, { help = "clamp density targets outside the reachable range (counted) instead of refusing them" } },
  { "track", "auto", { auto = "hatch", unit = "mm", min = 0.005, max = 2, help = "melt-track width: the thinnest wall or pore a density target may ask for" } },
}
-- fields of the parameter table that are not -D parameters
M.FIELDS = { rule = "p.rule(i, j, k, x, y, z) -> {surface=, thickness=, laser=, seq=, skip=} per voxel" }

local DECL = {}
for _, d in ipairs(M.PARAMS) do DECL[d[1]] = d end

--- M.params([defaults]): the recipe parameters, each read with gradus.param
-- (so each is a -D name) and returned in a strict table: assigning or
-- reading a field that is not a parameter raises. defaults (optional)
-- replaces declared defaults: lattice.params{cells = "4,4,2"}.
function M.params(defaults)
  for k in pairs(defaults or {}) do
    if not DECL[k] then
      local names = {}
      for n in pairs(DECL) do names[#names + 1] = n end
      error(("lattice.params: unknown parameter '%s' in the defaults%s"):format(tostring(k), strict.suggest(tostring(k), names)), 2)
    end
  end
  local values = {}
  for _, d in ipairs(M.PARAMS) do
    local def = d[2]
    if defaults and defaults[d[1]] ~= nil then def = defaults[d[1]] end
    values[d[1]] = gradus.param(d[1], def, d[3])
  end
  local known = {}
  for k in pairs(DECL) do known[k] = true end
  for k in pairs(M.FIELDS) do known[k] = true end
  return strict.table(known, values, "the lattice recipe (lattice.params)")
end

-- Whether parameter k of the checked values q was asked for: given with -D,
-- or other than its default (the recipe's own, where it declared one).
local function given(q, k)
  local ctx = gradus._ctx
  if ctx and ctx.params and ctx.params[k] ~= nil then return true end
  local decl = ctx and ctx.decl and ctx.decl.by[k]
  local d0 = decl and decl.default or DECL[k][2]
  return strict.fmt(q[k]) ~= strict.fmt(strict.check(k, d0, DECL[k][3], DECL[k][2]))
end

-- The values of p, checked against the declarations (numbers finite and in
-- range, choices, vectors converted to tables) and against each other.
local function checked(p)
  local v = strict.values(p)
  local q = {}
  for k, x in pairs(v) do
    if not DECL[k] and not M.FIELDS[k] then
      local names = {}
      for n in pairs(DECL) do names[#names + 1] = n end
      error(("unknown parameter '%s'%s"):format(tostring(k), strict.suggest(tostring(k), names)), 0)
    end
    q[k] = x
  end
  for _, d in ipairs(M.PARAMS) do
    local k = d[1]
    if q[k] == nil then q[k] = d[2] end
    q[k] = strict.check(k, q[k], d[3], d[2])
  end
  local function rel(ok, fmt, ...) if not ok then error(fmt:format(...), 0) end end
  -- a stretched cell: the layer against Lz, the hatch and grid against the
  -- longest length, the beam offset against the shortest
  local C = part.lengths(q.cell)
  local lmin, lmax = math.min(C[1], C[2], C[3]), math.max(C[1], C[2], C[3])
  rel(q.layer <= C[3], "parameter 'layer' (%g mm) must not exceed the cell (%g mm)", q.layer, C[3])
  rel(lmax / q.hatch <= 2000, "parameter 'hatch' must be at least cell/2000 = %g mm for a cell of %g mm, got %g",
    lmax / 2000, lmax, q.hatch)
  if q.beam_offset ~= "auto" then
    rel(q.beam_offset <= lmin / 4, "parameter 'beam_offset' must be auto (hatch/2) or in [0, %g] mm (cell/4), got %g",
      lmin / 4, q.beam_offset)
  else -- the automatic offset obeys the same bound (a hatch in cm, or 1.5 for 0.15, would pass unseen)
    rel(q.hatch / 2 <= lmin / 4,
      "parameter 'hatch' (%g mm) makes the automatic beam offset hatch/2 = %g mm larger than cell/4 = %g mm: " ..
      "give a hatch of at most cell/2 = %g mm, or set beam_offset", q.hatch, q.hatch / 2, lmin / 4, lmin / 2)
  end
  if q.slice_cell ~= "auto" then
    rel(q.slice_cell <= q.hatch / 2 and q.slice_cell >= lmax / 4000,
      "parameter 'slice_cell' must be auto (hatch/2) or in [%g, %g] mm (cell/4000 .. hatch/2), got %g",
      lmax / 4000, q.hatch / 2, q.slice_cell)
  end
  -- size decides the cells: cells given as well would be ignored
  rel(q.size == "" or not given(q, "cells"),
    "parameters 'size' and 'cells' both given (size=%s, cells=%s): the part's size decides the cells; give one of them",
    strict.fmt(q.size), strict.fmt(q.cells))
  rel(not (type(q.cell) == "table" and (q.density ~= "" or q.porosity ~= "")),
    "parameter 'density'/'porosity': design by density needs a cubic cell (the density tables are for cubes), got cell=%s",
    strict.fmt(q.cell))
  return q
end

-- The output's path without its .cli or .ovf (any case): the manifest's and the pictures' base.
local function stem(path) return (path:gsub("%.[cC][lL][iI]$", ""):gsub("%.[oO][vV][fF]$", "")) end

local function parse_range(s, n)
  if s == "" then return 1, n end
  local a, b = s:match("^(%d+):(%d+)$")
  if not a then
    local one = tonumber(s)
    if one then return one, one end
    error(("bad layers '%s': expected a:b"):format(s), 3)
  end
  return tonumber(a), tonumber(b)
end

-- The design domain p.domain: a field, an expression, or the path of a
-- closed STL mesh (the part: its signed distance, gradus.mesh.solid), which
-- must overlap the box of cells; nil or "": none.
local function domain_of(d, origin, cells, cell, p)
  if d == nil or d == "" then return nil end
  local C = part.lengths(cell)
  if p and p.domain_distance and type(d) == "string" and not d:lower():match("%.stl$") then
    -- gradus.field.distance: closest points on the zero set within the band; an expression that is
    -- a distance over the part's box already (planes and spheres joined by min, max, abs) stays as it is
    local hi = {}
    for a = 1, 3 do hi[a] = origin[a] + cells[a] * C[a] end
    return gradus.field.distance(gradus.field.expr(d), { band = 2 * p.skin + 1, cell = math.min(C[1], C[2], C[3]),
      box = { origin[1], origin[2], origin[3], hi[1], hi[2], hi[3] } })
  end
  if type(d) == "string" and d:lower():match("%.stl$") then
    local ok, m = pcall(gradus.mesh.read, d)
    local mesh = m
    if ok then ok, m = pcall(gradus.mesh.solid, m) end
    if not ok then error(("bad domain '%s': %s"):format(d, tostring(m)), 3) end
    local lo, hi = mesh:bounds()
    for a = 1, 3 do
      if hi[a] <= origin[a] or lo[a] >= origin[a] + cells[a] * C[a] then
        error(("bad domain '%s': the part (%g, %g, %g)-(%g, %g, %g) mm lies outside the box of cells (%g, %g, %g)-(%g, %g, %g); set origin and cells")
          :format(d, lo[1], lo[2], lo[3], hi[1], hi[2], hi[3], origin[1], origin[2], origin[3],
            origin[1] + cells[1] * C[1], origin[2] + cells[2] * C[2], origin[3] + cells[3] * C[3]), 3)
      end
    end
    return m
  end
  return d
end

--- M.run(p, out): run the pipeline. p: params (see M.params) and optional
-- rules: p.rule(i, j, k, x, y, z) -> table {surface=, thickness=, laser=,
-- seq=, skip=} per voxel; p.qualify: true (verify every template built and
-- qualify it by the quality targets (doc/contract.md s.5)) or a function(quality) -> ok, reason that
-- adds the recipe's own rule (quality: pore, overmelt, max_dev mm, layers,
-- thin_walls, key); p.domain (a field, negative inside, an expression
-- or an STL file); p.skin (mm).
-- Writes the CLI to `out`, the manifest beside it, stats to --stats, and SVG
-- pictures of p.pictures layers. Returns the stats table.
-- The machine profile, or `lasers` identical lasers; a lasers count other
-- than the profile's is refused (it would be ignored).
local function machine_of(p)
  if p.machine == "" then return lasers.default(p.lasers) end
  local machine = lasers.load(p.machine)
  if given(p, "lasers") and p.lasers ~= #machine.lasers then
    error(("parameters 'lasers' and 'machine' both given (lasers=%d, machine=%s with %d): the profile's lasers are used; give one of them")
      :format(p.lasers, p.machine, #machine.lasers), 3)
  end
  return machine
end

-- Every voxel of the box into the job: its spec (spec_of(surface,
-- thickness, inside)), laser (the rule's, the zones', or any that reaches
-- it) and sequence key; a voxel the rule skips stays empty.
local function place_voxels(job, p, machine, cells, origin, spec_of)
  local seqf = sequence.get(p.sequence)
  local nx, ny, nz = cells[1], cells[2], cells[3]
  local C = part.lengths(p.cell)
  local Lx, Ly, Lz = C[1], C[2], C[3]
  local zone
  if #machine.lasers > 1 and p.assign == "zones" then
    zone = lasers.zones(machine, origin[1], origin[1] + nx * Lx)
  end
  for k = 0, nz - 1 do
    for j = 0, ny - 1 do
      for i = 0, nx - 1 do
        local x0, y0, z0 = origin[1] + i * Lx, origin[2] + j * Ly, origin[3] + k * Lz
        local r = p.rule and p.rule(i, j, k, x0, y0, z0) or {}
        if not r.skip then
          local laser = r.laser
          if laser == nil and zone then laser = zone(x0, y0, x0 + Lx, y0 + Ly) + 1 end
          if laser == nil and type(p.assign) == "function" then laser = p.assign(i, j, k, x0, y0, z0) end
          if laser ~= nil then
            local l = machine.lasers[laser]
            if not l then
              error(("voxel (%d, %d, %d): laser %s does not exist (the machine '%s' has %d)")
                :format(i, j, k, tostring(laser), machine.name, #machine.lasers), 0)
            end
            if not lasers.reaches(l, x0, y0, x0 + Lx, y0 + Ly) then
              error(("laser fields of '%s' do not cover the part: laser %d (%s), chosen for voxel (%d, %d, %d), does not reach [%.3f, %.3f] x [%.3f, %.3f] mm")
                :format(machine.name, laser, l.name or "?", i, j, k, x0, x0 + Lx, y0, y0 + Ly), 0)
            end
          else
            lasers.reach(machine, x0, y0, x0 + Lx, y0 + Ly) -- errors if nobody reaches
          end
          job:voxel(i, j, k, {
            spec = spec_of(r.surface or p.surface, r.thickness or p.thickness, r.inside or p.inside),
            laser = laser,
            seq = r.seq or seqf(i, j, k, nx, ny),
          })
        else
          job:voxel(i, j, k, { spec = 0 }) -- empty (voxels start with the first spec)
        end
      end
    end
  end
end

-- The layers to compute (first, last), to keep (pictures and checks) and
-- to check (verify), from p.layers, p.pictures and p.verify over a job of
-- `total` layers (`cut`: the part's own count, a size cutting the box, and
-- a range past it is cut back to it). A
-- picture or check of a layer the job does not have is refused (it would
-- be skipped unseen); one outside layers=a:b is skipped (the tasks of a
-- split job share the parameters).
local function layer_choice(p, total, cut)
  local first, last = parse_range(p.layers, total)
  if cut and last > total then last = total end
  if first < 1 then error(("bad layers '%s': layers are numbered from 1"):format(tostring(p.layers)), 3) end
  local function layer_list(name)
    local list = {}
    for item in tostring(p[name]):gmatch("[^,]+") do
      local g = tonumber(item)
      if not g or g ~= math.floor(g) then
        error(("bad %s '%s': layer numbers a,b,c expected"):format(name, tostring(p[name])), 4)
      end
      if g < 1 or g > total then
        error(("bad %s '%s': layer %d is not one of the job's %d layers"):format(name, tostring(p[name]), g, total), 4)
      end
      list[#list + 1] = g
    end
    return list
  end
  local keep, checks = layer_list("pictures"), layer_list("verify")
  for _, g in ipairs(checks) do keep[#keep + 1] = g end
  return first, last, keep, checks
end

-- The output's format: OVF for a .ovf output; its extension and format=
-- must agree (an OVF file named .cli would go to a machine as CLI).
local function output_format(p, out)
  local ext = out and out:lower():match("%.(%w+)$")
  if ext == "ovf" and given(p, "format") and p.format ~= "ovf" then
    error(("parameter 'format' (%s) and the output %s disagree: a .ovf file is Open Vector Format; name it .cli or drop format")
      :format(p.format, out), 3)
  end
  if ext == "cli" and p.format == "ovf" then
    error(("parameter 'format' (ovf) and the output %s disagree: Open Vector Format goes to a .ovf file"):format(out), 3)
  end
  return ext == "ovf" and "ovf" or p.format
end

-- SVG (and PNG) pictures of the kept layers beside the output; their paths.
local function pictures(out, keep, kept)
  local pics = {}
  for _, g in ipairs(keep) do
    if kept[g] and out then
      local base = stem(out or "out/layer")
      local path = ("%s_layer%d.svg"):format(base, g)
      gradus.svg.layer(path, kept[g], { title = ("layer %d, z = %.3f mm"):format(g, kept[g]:z()), jumps = true })
      pics[#pics + 1] = path
      if gradus.png then
        local png = ("%s_layer%d.png"):format(base, g)
        gradus.png.layer(png, kept[g], { width = 900, title = ("layer %d"):format(g), jumps = false })
        pics[#pics + 1] = png
      end
    end
  end
  return pics
end

-- Quality of the checked layers on voxel (0,0,k): the vectors against the
-- true section (the graded offset field sliced directly, 4x finer grid).
local function layer_quality(p, st, kept, checks, origin)
  local C = part.lengths(p.cell)
  local Lx, Ly, Lz = C[1], C[2], C[3]
  local d, b = p.hatch, st.effective.beam_offset
  local q = { pore_max = 0, overmelt_max = 0, contour_dev_max_mm = 0, layers = {} }
  local truths = {}
  for _, g in ipairs(checks) do
    if kept[g] then
      local zm = origin[3] + g * p.layer - p.layer / 2
      local k = math.floor((zm - origin[3]) / Lz)
      if not truths[k] then
        truths[k] = gradus.distance.offset { surface = p.surface, cell = { Lx, Ly, Lz }, origin = origin,
          lo = { origin[1], origin[2], origin[3] + k * Lz }, hi = { origin[1] + Lx, origin[2] + Ly, origin[3] + (k + 1) * Lz },
          res = p.res, thickness = tonumber(p.thickness) or p.thickness, kind = p.kind, mode = "exact", level = p.level }
      end
      local m = b + p.contours * d + 0.1
      local sec = gradus.slice.field(truths[k], zm, { lo = { origin[1] - m, origin[2] - m },
        hi = { origin[1] + Lx + m, origin[2] + Ly + m }, cell = d / 8 })
      local r = gradus.hatch.verify(sec, kept[g], { track = d, pixel = d / 20, offset = b, spacing = d,
        contours = math.max(1, p.contours), clip_lo = { origin[1], origin[2] }, clip_hi = { origin[1] + Lx, origin[2] + Ly } })
      q.pore_max = math.max(q.pore_max, r.pore)
      q.overmelt_max = math.max(q.overmelt_max, r.overmelt)
      q.contour_dev_max_mm = math.max(q.contour_dev_max_mm, r.max_dev)
      q.layers[#q.layers + 1] = { layer = g, pore = r.pore, overmelt = r.overmelt, contour_dev_max_mm = r.max_dev }
    end
  end
  return q
end

local function run(p, out)
  strict.action()
  p = checked(p)
  local format = output_format(p, out)
  local box = part.box(p)
  local cells, origin = box.cells, p.origin
  gradus.place.check_size(cells, p.cell) -- before the domain's mesh and the voxels' loops over that box
  local domain = box.domain(domain_of(p.domain, origin, cells, p.cell, p))
  if not domain and p.skin > 0 then
    error(("parameter 'skin' (%g mm) is a solid band along the domain's boundary, and there is no domain: "
      .. "give domain= (an STL file or an expression) or a size= that cuts cells"):format(p.skin), 2)
  end
  local machine = machine_of(p)
  local rg = require("gradus.regions").load(p.regions) -- nil without regions
  if rg then
    require("gradus.regions").fit(rg, p)
    machine = require("gradus.regions").machine(rg, machine)
  end
  local job = gradus.place.job {
    cell = p.cell, origin = origin, cells = cells, layer = p.layer, hatch = p.hatch,
    beam_offset = p.beam_offset ~= "auto" and p.beam_offset or nil, contours = p.contours,
    contour_first = p.contour_first, angle = p.angle, rotation = p.rotation, pattern = p.pattern,
    alternate = p.alternate, res = p.res, mode = p.mode, quant = p.quant, threads = p.threads,
    slice_cell = p.slice_cell ~= "auto" and p.slice_cell or nil, min_length = p.min_length,
    faces = p.faces, verify = p.qualify and true or false,
  }
  job:machine(machine)
  if rg then require("gradus.regions").job(rg, job) end
  local specs = {}
  local dens = require("gradus.density").prepare(p, origin, cells, out)
  local function spec_of(surface, thickness, inside)
    local key = surface .. "|" .. thickness .. "|" .. (inside or "")
    if not specs[key] then
      specs[key] = job:spec(dens and dens:spec(surface) or { surface = surface, level = p.level, kind = p.kind,
        thickness = thickness, inside = inside ~= "" and inside or nil })
    end
    return specs[key]
  end
  place_voxels(job, p, machine, cells, origin, spec_of)
  if domain then job:domain(domain, { skin = p.skin or 0 }) end
  if dens then
    local C = part.lengths(p.cell)
    local Lx, Ly, Lz = C[1], C[2], C[3]
    dens:check(function(i, j, k)
      local r = p.rule and p.rule(i, j, k, origin[1] + i * Lx, origin[2] + j * Ly, origin[3] + k * Lz) or {}
      return not r.skip and (r.surface or p.surface) or nil
    end)
  end
  local first, last, keep, checks = layer_choice(p, box.layers or job:layers(), box.layers ~= nil)
  local kb = p.kb
  if kb == "" then kb = nil end
  if out then gradus.mkdir(gradus.dirname(out)) end
  local styles = {}
  for l, las in ipairs(machine.lasers) do
    for kindi, kind in ipairs({ "contour", "hatch", "edge" }) do
      styles[#styles + 1] = { id = (l - 1) * 3 + kindi, label = las.name .. "-" .. kind, laser = las.name,
        kind = kind, power = las[kind].power, speed = las[kind].speed, jump_speed = machine.jump_speed }
    end
  end
  if rg then require("gradus.regions").styles(rg, machine, styles, p.hatch) end
  local st, kept = job:run {
    output = out, format = format, styles = styles, name = out and out:match("([^/]+)$"),
    jump_delay = machine.jump_delay, polygon_delay = machine.polygon_delay, kb = kb ~= "off" and (kb or true) or false,
    direct = kb == "off", first = first, last = last, keep = keep, split = p.split, kb_store = p.kb_store,
    extent = box.hi,
    quiet = gradus.quiet(), qualify = type(p.qualify) == "function" and p.qualify or nil,
  }
  if st.templates.unqualified > 0 and not gradus.quiet() then
    io.stderr:write(("gradus: %d template(s) not qualified (%s)\n"):format(st.templates.unqualified,
      st.templates.unqualified_reason or ""))
  end
  st.warnings = lasers.warnings(machine, st, { origin = origin, cells = cells, cell = p.cell, assign = p.assign })
  for _, w in ipairs(st.warnings) do
    if not gradus.quiet() then io.stderr:write("gradus: warning: " .. w .. "\n") end
  end
  if #st.warnings == 0 then st.warnings = nil end
  -- manifest: every build style with laser, kind, power, speed
  if out then
    gradus.yaml.save(stem(out) .. ".manifest.yaml", {
      cli = out, format = format, form = st.form, units_mm = st.units, layers = st.layers, machine = machine.name,
      styles = styles,
    })
  end
  st.pictures = pictures(out, keep, kept)
  if #checks > 0 then st.quality = layer_quality(p, st, kept, checks, origin) end
  if dens and dens.target and out then
    st.density = dens:measure(gradus.outputs.stage(out), domain, p.beam_offset ~= "auto" and p.beam_offset or p.hatch / 2, p.layer)
  end
  st.parameters = {}
  for k, v in pairs(p) do
    if type(v) ~= "function" and type(v) ~= "userdata" then st.parameters[k] = v end
  end
  -- the values the job used, not "auto" or "" (default cache, default machine)
  st.parameters.beam_offset = st.effective.beam_offset
  st.parameters.slice_cell = st.effective.slice_cell
  if p.track == "auto" then st.parameters.track = p.hatch end
  if kb == nil then st.parameters.kb = gradus.kb.default_dir() end
  if p.machine == "" then st.parameters.machine = machine.name end
  st.parameters.layers = ("%d:%d"):format(first, last)
  gradus.write_stats(st)
  return st, kept
end
-- one job: CLI, manifest, pictures and stats are renamed into place together
function M.run(p, out) return gradus.outputs.job(run, p, out) end

return M
