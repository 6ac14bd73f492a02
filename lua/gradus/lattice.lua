-- gradus.lattice: the whole pipeline from a table of options: a box (or a
-- domain) of graded TPMS cells to a CLI file, a manifest, stats and pictures.
-- recipes/lattice.lua reads the SPEC.md section 7 parameters and calls run().
local gradus = require "gradus"
local sequence = require "gradus.sequence"
local lasers = require "gradus.lasers"
local M = {}

-- The paper's eq. (8): graded half-thickness along the cell's local height.
M.EQ8 = "0.1*(2*sin(pi*(w+1)/4)+1)"

local function vec(name, v, n)
  if type(v) == "number" then
    local t = {}
    for i = 1, n do t[i] = v end
    return t
  end
  if type(v) == "string" then
    local t = {}
    for item in v:gmatch("[^,]+") do
      local x = tonumber(item)
      if not x then error(("bad %s '%s': %d numbers 'a,b,c' expected"):format(name, v, n), 3) end
      t[#t + 1] = x
    end
    v = t
  end
  if type(v) ~= "table" or #v ~= n then
    error(("bad %s: %d numbers expected, got %s"):format(name, n, tostring(v)), 3)
  end
  return v
end

--- M.params(): the recipe parameters of SPEC.md section 7 (plus a few), each
-- read with gradus.param and checked.
function M.params()
  local P = gradus.param
  local p = {
    surface = P("surface", "primitive"),
    cell = P("cell", 2.0),
    cells = P("cells", "2,2,1"),
    origin = P("origin", "0,0,0"),
    level = P("level", 0.0),
    kind = P("kind", "sheet"),
    thickness = P("thickness", M.EQ8),
    inside = P("inside", ""),
    layer = P("layer", 0.04),
    hatch = P("hatch", 0.05),
    beam_offset = P("beam_offset", -1.0),
    angle = P("angle", 45.0),
    rotation = P("rotation", 67.0),
    pattern = P("pattern", "parallel"),
    alternate = P("alternate", true),
    contours = P("contours", 1),
    contour_first = P("contour_first", true),
    lasers = P("lasers", 1),
    machine = P("machine", ""),
    assign = P("assign", "balance"),
    sequence = P("sequence", "raster"),
    kb = P("kb", ""),
    format = P("format", "ascii"),
    res = P("res", 40),
    mode = P("mode", "exact"),
    slice_cell = P("slice_cell", -1.0),
    quant = P("quant", 0.001),
    threads = P("threads", 2),
    layers = P("layers", ""),
    pictures = P("pictures", ""),
    split = P("split", false),
    verify = P("verify", ""),
    min_length = P("min_length", 0.0),
    domain = P("domain", ""),
    skin = P("skin", 0.0),
    faces = P("faces", true),
    qualify = P("qualify", false),
  }
  return p
end

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
local function domain_of(d, origin, cells, L)
  if d == nil or d == "" then return nil end
  if type(d) == "string" and d:lower():match("%.stl$") then
    local ok, m = pcall(gradus.mesh.read, d)
    local mesh = m
    if ok then ok, m = pcall(gradus.mesh.solid, m) end
    if not ok then error(("bad domain '%s': %s"):format(d, tostring(m)), 3) end
    local lo, hi = mesh:bounds()
    for a = 1, 3 do
      if hi[a] <= origin[a] or lo[a] >= origin[a] + cells[a] * L then
        error(("bad domain '%s': the part (%g, %g, %g)-(%g, %g, %g) mm lies outside the box of cells (%g, %g, %g)-(%g, %g, %g); set origin and cells")
          :format(d, lo[1], lo[2], lo[3], hi[1], hi[2], hi[3], origin[1], origin[2], origin[3],
            origin[1] + cells[1] * L, origin[2] + cells[2] * L, origin[3] + cells[3] * L), 3)
      end
    end
    return m
  end
  return d
end

--- M.run(p, out): run the pipeline. p: params (see M.params) and optional
-- rules: p.rule(i, j, k, x, y, z) -> table {surface=, thickness=, laser=,
-- seq=, skip=} per voxel; p.qualify: true (verify every template built and
-- qualify it by the SPEC targets) or a function(quality) -> ok, reason that
-- adds the recipe's own rule (quality: pore, overmelt, max_dev mm, layers,
-- thin_walls, key); p.domain (a field, negative inside, an expression
-- or an STL file); p.skin (mm).
-- Writes the CLI to `out`, the manifest beside it, stats to --stats, and SVG
-- pictures of p.pictures layers. Returns the stats table.
function M.run(p, out)
  local cells = vec("cells", p.cells, 3)
  for a = 1, 3 do
    if cells[a] < 1 or cells[a] ~= math.floor(cells[a]) then
      error(("bad cells '%s': positive whole numbers expected"):format(tostring(p.cells)), 2)
    end
  end
  local origin = vec("origin", p.origin, 3)
  local domain = domain_of(p.domain, origin, cells, p.cell)
  if p.kind ~= "sheet" and p.kind ~= "network" then
    error(("bad kind '%s' (sheet or network)"):format(tostring(p.kind)), 2)
  end
  local machine
  if p.machine ~= "" then
    machine = lasers.load(p.machine)
  else
    machine = lasers.default(p.lasers)
  end
  local job = gradus.place.job {
    cell = p.cell, origin = origin, cells = cells, layer = p.layer, hatch = p.hatch,
    beam_offset = p.beam_offset >= 0 and p.beam_offset or nil, contours = p.contours,
    contour_first = p.contour_first, angle = p.angle, rotation = p.rotation, pattern = p.pattern,
    alternate = p.alternate, res = p.res, mode = p.mode, quant = p.quant, threads = p.threads,
    slice_cell = p.slice_cell > 0 and p.slice_cell or nil, min_length = p.min_length,
    faces = p.faces, verify = p.qualify and true or false,
  }
  job:machine(machine)
  local specs = {}
  local function spec_of(surface, thickness, inside)
    local key = surface .. "|" .. thickness .. "|" .. (inside or "")
    if not specs[key] then
      specs[key] = job:spec { surface = surface, level = p.level, kind = p.kind, thickness = thickness,
        inside = inside ~= "" and inside or nil }
    end
    return specs[key]
  end
  local seqf = sequence.get(p.sequence)
  local nx, ny, nz = cells[1], cells[2], cells[3]
  local L = p.cell
  local zone
  if #machine.lasers > 1 and p.assign == "zones" then
    zone = lasers.zones(machine, origin[1], origin[1] + nx * L)
  elseif p.assign ~= "balance" and p.assign ~= "zones" and type(p.assign) ~= "function" then
    error(("bad assign '%s' (balance, zones or a Lua function)"):format(tostring(p.assign)), 2)
  end
  for k = 0, nz - 1 do
    for j = 0, ny - 1 do
      for i = 0, nx - 1 do
        local x0, y0, z0 = origin[1] + i * L, origin[2] + j * L, origin[3] + k * L
        local r = p.rule and p.rule(i, j, k, x0, y0, z0) or {}
        if not r.skip then
          local laser = r.laser
          if laser == nil and zone then laser = zone(x0, y0, x0 + L, y0 + L) + 1 end
          if laser == nil and type(p.assign) == "function" then laser = p.assign(i, j, k, x0, y0, z0) end
          if laser ~= nil then
            local l = machine.lasers[laser]
            if not l then
              error(("voxel (%d, %d, %d): laser %s does not exist (the machine '%s' has %d)")
                :format(i, j, k, tostring(laser), machine.name, #machine.lasers), 0)
            end
            if not lasers.reaches(l, x0, y0, x0 + L, y0 + L) then
              error(("laser fields of '%s' do not cover the part: laser %d (%s), chosen for voxel (%d, %d, %d), does not reach [%.3f, %.3f] x [%.3f, %.3f] mm")
                :format(machine.name, laser, l.name or "?", i, j, k, x0, x0 + L, y0, y0 + L), 0)
            end
          else
            lasers.reach(machine, x0, y0, x0 + L, y0 + L) -- errors if nobody reaches
          end
          job:voxel(i, j, k, {
            spec = spec_of(r.surface or p.surface, r.thickness or p.thickness, r.inside or p.inside),
            laser = laser,
            seq = r.seq or seqf(i, j, k, nx, ny),
          })
        end
      end
    end
  end
  if domain then job:domain(domain, { skin = p.skin or 0 }) end
  local first, last = parse_range(p.layers, job:layers())
  local keep = {}
  for item in tostring(p.pictures):gmatch("[^,]+") do keep[#keep + 1] = tonumber(item) end
  local checks = {}
  for item in tostring(p.verify):gmatch("[^,]+") do
    local g = tonumber(item)
    if not g then error(("bad verify '%s': layer numbers a,b,c expected"):format(tostring(p.verify)), 2) end
    checks[#checks + 1] = g
    keep[#keep + 1] = g
  end
  local kb = p.kb
  if kb == "" then kb = nil end
  if out then gradus.mkdir(gradus.dirname(out)) end
  local format = (out and out:lower():match("%.ovf$")) and "ovf" or p.format
  local styles = {}
  for l, las in ipairs(machine.lasers) do
    for kindi, kind in ipairs({ "contour", "hatch", "edge" }) do
      styles[#styles + 1] = { id = (l - 1) * 3 + kindi, label = las.name .. "-" .. kind, laser = las.name,
        kind = kind, power = las[kind].power, speed = las[kind].speed, jump_speed = machine.jump_speed }
    end
  end
  local st, kept = job:run {
    output = out, format = format, styles = styles, name = out and out:match("([^/]+)$"),
    jump_delay = machine.jump_delay, polygon_delay = machine.polygon_delay, kb = kb ~= "off" and (kb or true) or false,
    direct = kb == "off", first = first, last = last, keep = keep, split = p.split,
    quiet = gradus.quiet(), qualify = type(p.qualify) == "function" and p.qualify or nil,
  }
  if st.templates.unqualified > 0 and not gradus.quiet() then
    io.stderr:write(("gradus: %d template(s) not qualified (%s)\n"):format(st.templates.unqualified,
      st.templates.unqualified_reason or ""))
  end
  -- manifest: every build style with laser, kind, power, speed
  if out then
    gradus.yaml.save((out:gsub("%.cli$", ""):gsub("%.ovf$", "")) .. ".manifest.yaml", {
      cli = out, format = format, form = st.form, units_mm = st.units, layers = st.layers, machine = machine.name,
      styles = styles,
    })
  end
  local pics = {}
  for _, g in ipairs(keep) do
    if kept[g] and out then
      local base = (out or "out/layer"):gsub("%.cli$", "")
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
  st.pictures = pics
  -- quality of the checked layers on voxel (0,0,k): the vectors against the
  -- true section (the graded offset field sliced directly, 4x finer grid)
  if #checks > 0 then
    local L, d, b = p.cell, p.hatch, p.beam_offset >= 0 and p.beam_offset or p.hatch / 2
    local q = { pore_max = 0, overmelt_max = 0, contour_dev_max_mm = 0, layers = {} }
    local truths = {}
    for _, g in ipairs(checks) do
      if kept[g] then
        local zm = origin[3] + g * p.layer - p.layer / 2
        local k = math.floor((zm - origin[3]) / L)
        if not truths[k] then
          truths[k] = gradus.distance.offset { surface = p.surface, cell = L, origin = origin,
            lo = { origin[1], origin[2], origin[3] + k * L }, hi = { origin[1] + L, origin[2] + L, origin[3] + (k + 1) * L },
            res = p.res, thickness = tonumber(p.thickness) or p.thickness, kind = p.kind, mode = "exact", level = p.level }
        end
        local m = b + p.contours * d + 0.1
        local sec = gradus.slice.field(truths[k], zm, { lo = { origin[1] - m, origin[2] - m },
          hi = { origin[1] + L + m, origin[2] + L + m }, cell = d / 8 })
        local r = gradus.hatch.verify(sec, kept[g], { track = d, pixel = d / 20, offset = b, spacing = d,
          contours = math.max(1, p.contours), clip_lo = { origin[1], origin[2] }, clip_hi = { origin[1] + L, origin[2] + L } })
        q.pore_max = math.max(q.pore_max, r.pore)
        q.overmelt_max = math.max(q.overmelt_max, r.overmelt)
        q.contour_dev_max_mm = math.max(q.contour_dev_max_mm, r.max_dev)
        q.layers[#q.layers + 1] = { layer = g, pore = r.pore, overmelt = r.overmelt, contour_dev_max_mm = r.max_dev }
      end
    end
    st.quality = q
  end
  st.parameters = {}
  for k, v in pairs(p) do
    if type(v) ~= "function" and type(v) ~= "userdata" then st.parameters[k] = v end
  end
  gradus.write_stats(st)
  return st, kept
end

return M
