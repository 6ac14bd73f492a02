-- gradus.plate: a build plate of several parts in one CLI (doc/api/plate.md).
--
--   plate.load(file) -> the checked plate description (errors: file:line:col)
--   plate.run{plate = file | description, output = "plate.cli", keep = false}
--       -> stats: each part runs as its own job (the lattice recipe with its
--       parameters, or its own recipe) into a temporary CLI in its own
--       coordinates; the engine (gradus.cli.plate) rotates and translates it
--       onto the plate and merges every part layer by layer into one CLI.
--       Writes the CLI, a manifest, the stats (--stats) and pictures, all
--       renamed into place together (gradus.outputs): nothing on error.
local gradus = require "gradus"
local strict = require "gradus.strict"
local lasers = require "gradus.lasers"
local M = {}

local function set(list) local t = {} for _, k in ipairs(list) do t[k] = true end return t end

-- keys of the plate file and of a part (besides the lattice parameters)
M.PLATE_KEYS = set { "name", "machine", "plate", "layer", "format", "kb", "threads", "res", "picture_layer", "regions", "parts" }
M.PLACE_KEYS = set { "name", "at", "rotation", "recipe", "params" }
-- lattice parameters a part may not set: the plate decides them
M.PLATE_OWNED = set { "machine", "lasers", "format", "split", "layers", "pictures", "verify", "origin", "kb", "threads",
  "regions" }

local function where(d, t, k)
  local pos = d.marks and d.marks[t] and d.marks[t][k]
  return d.file .. (pos and (":" .. pos) or "")
end

local function fail(d, t, k, fmt, ...)
  error(("%s: " .. fmt):format(where(d, t, k), ...), 0)
end

local function is_num(v) return type(v) == "number" and v == v and v ~= math.huge and v ~= -math.huge end

local function dir_of(path) return path:match("^(.*)/[^/]*$") or "." end
local function rel(base, p) if p:sub(1, 1) == "/" then return p end return dir_of(base) .. "/" .. p end

-- A YAML value as the string a -D parameter would give.
local function raw(v)
  if type(v) == "table" then
    local s = {}
    for i, x in ipairs(v) do s[i] = tostring(x) end
    return table.concat(s, ",")
  end
  return tostring(v)
end

local FILE_KEYS = set { "domain", "density", "porosity" }

local function lattice_decls()
  local decl = {}
  for _, d in ipairs(require("gradus.lattice").PARAMS) do decl[d[1]] = d end
  return decl
end

-- One part of the plate file, checked: placement, recipe or lattice keys.
local function load_part(d, t, i, layer, decl)
  local key = d.parts_list
  if type(t) ~= "table" or t[1] ~= nil then fail(d, key, i, "part %d must be a mapping of keys", i) end
  local name = t.name ~= nil and tostring(t.name) or ("part" .. i)
  local part = { name = name, index = i, table = t, params = {} }
  if t.at == nil then fail(d, key, i, "part '%s': at: [x, y] (mm) is missing", name) end
  if type(t.at) ~= "table" or #t.at ~= 2 or not is_num(t.at[1]) or not is_num(t.at[2]) then
    fail(d, t, "at", "part '%s': at must be [x, y] in mm (two numbers), got %s", name, raw(t.at))
  end
  part.at = { t.at[1], t.at[2] }
  local rot = t.rotation == nil and 0 or t.rotation
  if not is_num(rot) then fail(d, t, "rotation", "part '%s': rotation must be a number (degrees), got '%s'", name, raw(rot)) end
  part.rotation = rot
  if t.recipe ~= nil then
    for k in pairs(t) do
      if not M.PLACE_KEYS[k] then
        fail(d, t, k, "part '%s': unknown key '%s' in a recipe part (its parameters go under params:); known keys: at, name, params, recipe, rotation", name, tostring(k))
      end
    end
    part.recipe = rel(d.file, tostring(t.recipe))
    if gradus.fs.kind(part.recipe) ~= "file" then fail(d, t, "recipe", "part '%s': recipe file %s not found", name, part.recipe) end
    if t.params ~= nil and (type(t.params) ~= "table" or t.params[1] ~= nil) then
      fail(d, t, "params", "part '%s': params must be a mapping of parameter: value", name)
    end
    for k, v in pairs(t.params or {}) do part.params[k] = raw(v) end
    part.pos = t.params or t
    if t.params and t.params.layer ~= nil and tonumber(t.params.layer) ~= layer then
      fail(d, t.params, "layer", "part '%s': layer %s differs from the plate's layer thickness %g mm", name, raw(t.params.layer), layer)
    end
    return part
  end
  if t.params ~= nil then fail(d, t, "params", "part '%s': params: is for recipe parts; give lattice parameters as keys of the part", name) end
  for k, v in pairs(t) do
    if not M.PLACE_KEYS[k] then
      local dd = decl[k]
      if not dd or M.PLATE_OWNED[k] then
        local names = {}
        for n in pairs(decl) do if not M.PLATE_OWNED[n] then names[#names + 1] = n end end
        for n in pairs(M.PLACE_KEYS) do names[#names + 1] = n end
        table.sort(names)
        local why = k == "origin" and " (a part is placed with at: [x, y] and rotation:)"
          or M.PLATE_OWNED[k] and (" ('%s' is set for the whole plate)"):format(k) or strict.suggest(tostring(k), names)
        fail(d, t, k, "unknown key '%s' in part '%s'%s", tostring(k), name, why)
      end
      local ok, res = pcall(strict.check, k, type(v) == "table" and raw(v) or v, dd[3], dd[2])
      if not ok then fail(d, t, k, "part '%s': %s", name, tostring(res)) end
      part.params[k] = raw(v)
      local f = type(v) == "string" and FILE_KEYS[k] and v:lower():match("%.(%w+)$")
      if f == "stl" or f == "vtk" or f == "npy" then -- files are relative to the plate file
        part.params[k] = rel(d.file, v)
        if gradus.fs.kind(part.params[k]) ~= "file" then
          fail(d, t, k, "part '%s': %s file %s not found", name, k, part.params[k])
        end
      end
    end
  end
  if t.layer ~= nil and t.layer ~= layer then
    fail(d, t, "layer", "part '%s': layer %s differs from the plate's layer thickness %g mm", name, raw(t.layer), layer)
  end
  -- the box in the part's own coordinates (gradus.part): the rotated box is the footprint
  local cell = part.params.cell and strict.check("cell", part.params.cell, decl.cell[3], decl.cell[2]) or decl.cell[2]
  local C = require("gradus.part").lengths(cell) -- a stretched cell: Lx, Ly, Lz
  local size = {}
  if part.params.size and part.params.size ~= "" then
    for x in part.params.size:gmatch("[^,]+") do size[#size + 1] = tonumber(x) end
  else
    local cells = part.params.cells or decl.cells[2]
    for x in cells:gmatch("[^,]+") do size[#size + 1] = tonumber(x) * C[#size + 1] end
  end
  part.box = size
  part.pos = t
  return part
end

--- M.load(file) -> {file=, name=, machine=, plate={lo={x,y}, hi={x,y}}, layer=, format=, parts={...}}
function M.load(file)
  if type(file) ~= "string" then error("bad argument #1 to 'plate.load' (file name expected)", 2) end
  local t, marks = gradus.yaml.load(file, { marks = true })
  local d = { file = file, marks = marks }
  if type(t) ~= "table" or t[1] ~= nil then error(("%s: a plate file must be a mapping (name, machine, plate, layer, format, parts)"):format(file), 0) end
  strict.check_keys(t, M.PLATE_KEYS, file, marks, "the plate file")
  local decl = lattice_decls()
  local layer = t.layer == nil and decl.layer[2] or t.layer
  local ok, res = pcall(strict.check, "layer", layer, decl.layer[3], decl.layer[2])
  if not ok then fail(d, t, "layer", "%s", tostring(res)) end
  d.layer = res
  d.name = t.name and tostring(t.name) or file:match("([^/]+)%.ya?ml$") or file
  d.format = t.format or "ascii"
  if d.format ~= "ascii" and d.format ~= "binary" and d.format ~= "binary-long" then
    fail(d, t, "format", "format must be ascii, binary or binary-long, got '%s'", raw(d.format))
  end
  for _, k in ipairs({ "threads", "res" }) do
    if t[k] ~= nil then
      local okk, v = pcall(strict.check, k, t[k], decl[k][3], decl[k][2])
      if not okk then fail(d, t, k, "%s", tostring(v)) end
      d[k] = v
    end
  end
  d.kb = t.kb -- YAML reads `kb: off` as false
  if d.kb == false then d.kb = "off" elseif d.kb == true then d.kb = nil end
  if d.kb ~= nil and type(d.kb) ~= "string" then fail(d, t, "kb", "kb must be a directory, off, or left out (the default cache)") end
  if t.regions ~= nil then -- one set of build styles for the plate: a CLI id means one power and speed
    if type(t.regions) ~= "string" then fail(d, t, "regions", "regions must be default or a process profile file") end
    d.regions = t.regions == "default" and "default" or rel(file, t.regions)
    local okr, rg = pcall(require("gradus.regions").load, d.regions)
    if not okr then fail(d, t, "regions", "%s", tostring(rg)) end
    d.rg = rg
  end
  if t.picture_layer ~= nil then
    if math.type(t.picture_layer) ~= "integer" or t.picture_layer < 1 then
      fail(d, t, "picture_layer", "picture_layer must be a layer number (1, 2, ...), got %s", raw(t.picture_layer))
    end
    d.picture_layer = t.picture_layer
  end
  if t.machine ~= nil then
    d.machine_file = rel(file, tostring(t.machine))
    d.machine = lasers.load(d.machine_file)
    local m = gradus.yaml.load(d.machine_file)
    d.plate = m.plate
  else
    d.machine = lasers.default(1)
  end
  local box = t.plate ~= nil and t.plate or d.plate
  if box == nil then
    fail(d, t, nil, "no plate extent: give plate: {lo: [x, y], hi: [x, y]} (mm) or a machine profile with plate:")
  end
  local bt = t.plate ~= nil and t.plate or box
  if type(bt) ~= "table" then fail(d, t, "plate", "plate must be {lo: [x, y], hi: [x, y]} (mm)") end
  strict.check_keys(bt, set { "lo", "hi" }, file, marks, "plate")
  local function pt(v, k)
    if type(v) ~= "table" or not is_num(v[1]) or not is_num(v[2]) then fail(d, bt, k, "plate.%s must be [x, y] in mm", k) end
    return { v[1], v[2] }
  end
  d.plate = { lo = pt(bt.lo, "lo"), hi = pt(bt.hi, "hi") }
  if not (d.plate.lo[1] < d.plate.hi[1] and d.plate.lo[2] < d.plate.hi[2]) then fail(d, bt, "lo", "plate: lo must be below hi") end
  if type(t.parts) ~= "table" or t.parts[1] == nil then fail(d, t, "parts", "parts must be a non-empty list of parts") end
  d.parts_list = t.parts
  d.parts = {}
  local names = {}
  for i, pt_ in ipairs(t.parts) do
    local part = load_part(d, pt_, i, d.layer, decl)
    if names[part.name] then fail(d, pt_, "name", "two parts are named '%s'", part.name) end
    names[part.name] = true
    d.parts[i] = part
  end
  return d
end

-- ---------------------------------------------------------------------------
-- footprints and checks (mm, plate coordinates)

local function rect_footprint(part)
  local r = math.rad(part.rotation)
  local c, s = math.cos(r), math.sin(r)
  local hx, hy = part.box[1] / 2, part.box[2] / 2
  local out = {}
  for _, q in ipairs({ { -hx, -hy }, { hx, -hy }, { hx, hy }, { -hx, hy } }) do
    out[#out + 1] = { part.at[1] + c * q[1] - s * q[2], part.at[2] + s * q[1] + c * q[2] }
  end
  return out
end

local function inside(poly, lo, hi, tol)
  for _, q in ipairs(poly) do
    if q[1] < lo[1] - tol or q[2] < lo[2] - tol or q[1] > hi[1] + tol or q[2] > hi[2] + tol then return false end
  end
  return true
end

local function bbox(poly)
  local lo, hi = { math.huge, math.huge }, { -math.huge, -math.huge }
  for _, q in ipairs(poly) do
    for a = 1, 2 do lo[a], hi[a] = math.min(lo[a], q[a]), math.max(hi[a], q[a]) end
  end
  return lo, hi
end

local TOL = 1e-6

-- Every footprint on the plate, none overlapping; returns each part's
-- reaching lasers (1-based). Parts with no footprint yet are skipped.
local function check_places(d)
  local P = d.plate
  for _, part in ipairs(d.parts) do
    if part.footprint and not inside(part.footprint, P.lo, P.hi, TOL) then
      local lo, hi = bbox(part.footprint)
      fail(d, part.pos, "at", "part '%s' leaves the plate: its footprint spans [%g, %g] x [%g, %g] mm, the plate is [%g, %g] x [%g, %g] mm",
        part.name, lo[1], hi[1], lo[2], hi[2], P.lo[1], P.hi[1], P.lo[2], P.hi[2])
    end
  end
  for i, a in ipairs(d.parts) do
    for j = i + 1, #d.parts do
      local b = d.parts[j]
      if a.footprint and b.footprint and gradus.cli.overlap(a.footprint, b.footprint, TOL) then
        fail(d, b.pos, "at", "parts '%s' (%s) and '%s' overlap on the plate (their footprints intersect)",
          a.name, where(d, a.pos, "at"), b.name)
      end
    end
  end
  for _, part in ipairs(d.parts) do
    if part.footprint then
      part.reach = {}
      local why = {}
      for li, l in ipairs(d.machine.lasers) do
        local f = l.field
        if not f or inside(part.footprint, f.lo, f.hi, TOL) then part.reach[#part.reach + 1] = li
        else why[#why + 1] = ("%s [%g, %g] x [%g, %g]"):format(l.name, f.lo[1], f.hi[1], f.lo[2], f.hi[2]) end
      end
      if #part.reach == 0 then
        local lo, hi = bbox(part.footprint)
        fail(d, part.pos, "at", "part '%s' is out of every laser's reach: its footprint [%g, %g] x [%g, %g] mm is not inside any laser field (%s)",
          part.name, lo[1], hi[1], lo[2], hi[2], table.concat(why, "; "))
      end
    end
  end
end

-- ---------------------------------------------------------------------------
-- running the parts

-- The machine a part runs with in its own coordinates: the plate machine's
-- lasers `reach` (their styles, no fields: reach was checked on the plate).
local function part_machine(d, reach, path)
  local m = d.machine
  local t = { name = m.name, jump_speed = m.jump_speed, jump_delay = m.jump_delay, polygon_delay = m.polygon_delay,
    recoat_time = m.recoat_time, stitch = m.stitch, lasers = {} }
  for _, li in ipairs(reach) do
    local l = m.lasers[li]
    t.lasers[#t.lasers + 1] = { name = l.name, contour = l.contour, hatch = l.hatch, edge = l.edge }
  end
  local f = assert(io.open(path, "w"))
  f:write(gradus.yaml.encode(t))
  f:close()
  return path
end

local function declared(recipe)
  return require("gradus.sweep").probe(recipe)
end

local function run_part(d, part, tmp)
  local host = require "gradus.host"
  local cli, stats = ("%s/part%d.cli"):format(tmp, part.index), ("%s/part%d.yaml"):format(tmp, part.index)
  local params = {}
  for k, v in pairs(part.params) do params[k] = v end
  local recipe = part.recipe
  local decl = recipe and declared(recipe) or nil
  local function give(k, v) if not decl or decl[k] ~= nil then params[k] = v end end
  local all = {}
  for i = 1, #d.machine.lasers do all[i] = i end
  part.run_lasers = part.reach or all
  give("machine", part_machine(d, part.run_lasers, ("%s/machine%d.yaml"):format(tmp, part.index)))
  give("layer", tostring(d.layer))
  give("format", "binary-long")
  for _, k in ipairs({ "kb", "threads", "res", "regions" }) do
    if d[k] ~= nil and params[k] == nil then give(k, tostring(d[k])) end
  end
  if not recipe then recipe = gradus.root .. "/recipes/lattice.lua" end
  local say = print
  print = function() end -- the part's own summary line would name the temporary files
  local ok, err = host.run(recipe, params, { output = cli, stats = stats, quiet = true })
  print = say
  if not ok then
    local msg = tostring(err):gsub("^gradus: ", ""):gsub("\ntraceback:.*$", "")
    error(("%s: part '%s'%s: %s"):format(where(d, part.pos, part.recipe and "params" or "at"), part.name,
      part.recipe and (" (recipe " .. part.recipe .. ")") or "", msg), 0)
  end
  if gradus.fs.kind(cli) ~= "file" then
    error(("%s: part '%s': the recipe wrote no CLI to -o (%s)"):format(where(d, part.pos, "recipe"), part.name, cli), 0)
  end
  part.cli = cli
  part.stats = gradus.fs.kind(stats) == "file" and gradus.yaml.load(stats) or {}
end

local function cleanup(tmp)
  for _, name in ipairs(gradus.fs.list(tmp) or {}) do os.remove(tmp .. "/" .. name) end
  os.remove(tmp)
end

-- ---------------------------------------------------------------------------
-- stats and pictures

local PART_STATS = { "layers", "solid_volume_mm3", "relative_density", "scan_time_s", "jump_time_s", "recoat_time_s",
  "build_time_s", "balanced_time_s", "voxels" }

local function part_stats(part, info)
  local s = part.stats or {}
  local o = { name = part.name, at = part.at, rotation = part.rotation, recipe = part.recipe,
    lasers = part.map, footprint = part.footprint, length_mm = info.length }
  for _, k in ipairs(PART_STATS) do o[k] = s[k] end
  o.layers = info.layers
  -- the time its lasers scan it (in parallel when it has several), no recoating
  o.laser_time_s = (s.balanced_time_s or ((s.scan_time_s or 0) + (s.jump_time_s or 0))) - (s.recoat_time_s or 0)
  return o
end

local function totals(d, parts, w)
  local st = { plate = d.name, machine = d.machine.name, layers = w.layers, layer_mm = d.layer, form = w.form,
    rounded_out = w.rounded_out,
    dimension = { w.lo, w.hi }, parts = parts, solid_volume_mm3 = 0, scan_time_s = 0, jump_time_s = 0,
    laser_time_s = 0, length_mm = w.length }
  local bulk = 0
  for _, p in ipairs(parts) do
    local v = p.solid_volume_mm3 or 0
    st.solid_volume_mm3 = st.solid_volume_mm3 + v
    if p.relative_density and p.relative_density > 0 then bulk = bulk + v / p.relative_density end
    st.scan_time_s = st.scan_time_s + (p.scan_time_s or 0)
    st.jump_time_s = st.jump_time_s + (p.jump_time_s or 0)
    st.laser_time_s = st.laser_time_s + p.laser_time_s
  end
  st.relative_density = bulk > 0 and st.solid_volume_mm3 / bulk or nil
  -- a laser no part uses: say why (its field holds no whole part)
  local used = {}
  for _, p in ipairs(parts) do for _, l in ipairs(p.lasers or {}) do used[l] = true end end
  for li, l in ipairs(d.machine.lasers) do
    if not used[li] and #d.machine.lasers > 1 then
      local f = l.field
      st.warnings = st.warnings or {}
      st.warnings[#st.warnings + 1] = ("laser %d (%s) gets no work: %s"):format(li, l.name, f and
        ("no part lies wholly inside its field [%g, %g] x [%g, %g] mm (reach)"):format(f.lo[1], f.hi[1], f.lo[2], f.hi[2])
        or "the parts' own runs gave it nothing")
    end
  end
  st.recoat_time_s = w.layers * d.machine.recoat_time
  st.build_time_s = st.laser_time_s + st.recoat_time_s
  return st
end

local function esc(s) return (tostring(s):gsub("&", "&amp;"):gsub("<", "&lt;"):gsub(">", "&gt;")) end

--- M.footprint_svg(path, d): the plate, the laser fields and each part's footprint with its name.
function M.footprint_svg(path, d)
  local P = d.plate
  local W, pad = 800, 0.04 * math.max(P.hi[1] - P.lo[1], P.hi[2] - P.lo[2])
  local x0, y0, x1, y1 = P.lo[1] - pad, P.lo[2] - pad, P.hi[1] + pad, P.hi[2] + pad
  local s = W / (x1 - x0)
  local H, head = math.floor((y1 - y0) * s + 0.5), 40
  local function X(x) return ("%.2f"):format((x - x0) * s) end
  local function Y(y) return ("%.2f"):format(head + (y1 - y) * s) end
  local out = { ('<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" viewBox="0 0 %d %d">'):format(W, H + head, W, H + head),
    '<rect width="100%" height="100%" fill="white"/>',
    ('<text x="10" y="25" font-family="sans-serif" font-size="16">%s: %d parts, plate [%g, %g] x [%g, %g] mm</text>')
      :format(esc(d.name), #d.parts, P.lo[1], P.hi[1], P.lo[2], P.hi[2]),
    ('<rect x="%s" y="%s" width="%.2f" height="%.2f" fill="#f1f3f5" stroke="#495057"/>')
      :format(X(P.lo[1]), Y(P.hi[2]), (P.hi[1] - P.lo[1]) * s, (P.hi[2] - P.lo[2]) * s) }
  local colours = { "#1f3b99", "#d9480f", "#2b8a3e", "#7b2cbf" }
  for li, l in ipairs(d.machine.lasers) do
    if l.field then
      local f, c = l.field, colours[(li - 1) % #colours + 1]
      out[#out + 1] = ('<rect x="%s" y="%s" width="%.2f" height="%.2f" fill="none" stroke="%s" stroke-dasharray="6,4"/>')
        :format(X(f.lo[1]), Y(f.hi[2]), (f.hi[1] - f.lo[1]) * s, (f.hi[2] - f.lo[2]) * s, c)
      out[#out + 1] = ('<text x="%s" y="%s" font-family="sans-serif" font-size="12" fill="%s">%s field</text>')
        :format(X(f.lo[1] + 1), Y(f.hi[2] - 2 - 4 * (li - 1)), c, esc(l.name))
    end
  end
  for _, part in ipairs(d.parts) do
    local pts = {}
    for _, q in ipairs(part.footprint or {}) do pts[#pts + 1] = X(q[1]) .. "," .. Y(q[2]) end
    out[#out + 1] = ('<polygon points="%s" fill="#ffd8a8" stroke="#d9480f"/>'):format(table.concat(pts, " "))
    local lo = bbox(part.footprint or { part.at })
    out[#out + 1] = ('<text x="%s" y="%.2f" font-family="sans-serif" font-size="13" text-anchor="middle">%s</text>')
      :format(X(part.at[1]), tonumber(Y(lo[2])) + 15, esc(part.name)) -- below the footprint
  end
  out[#out + 1] = "</svg>\n"
  gradus.write_file(path, table.concat(out, "\n"))
end

-- ---------------------------------------------------------------------------

local function run(o)
  strict.action()
  if gradus._ctx.sandbox then -- the parts would run as recipes of their own, outside it
    error("a build plate cannot run under --sandbox yet: its parts run as jobs of their own, outside the sandbox", 0)
  end
  local d = type(o.plate) == "table" and o.plate or M.load(o.plate)
  local out = o.output or "out/plate.cli"
  if not out:lower():match("%.cli$") then error(("plate output %s: a .cli file expected"):format(out), 0) end
  -- lattice parts: their footprint (the rotated box) is known before they run
  for _, part in ipairs(d.parts) do
    if part.box then part.footprint = rect_footprint(part) end
  end
  check_places(d)
  local tmp = os.tmpname()
  os.remove(tmp)
  gradus.mkdir(tmp)
  local ok, err = pcall(function()
    for _, part in ipairs(d.parts) do run_part(d, part, tmp) end
    local pl = gradus.cli.plate()
    for _, part in ipairs(d.parts) do
      pl:add(part.cli, { name = part.name, at = part.at, rotation = part.rotation })
    end
    -- recipe parts: the convex hull of their vectors is the footprint
    for i, part in ipairs(d.parts) do
      if not part.box then part.footprint = pl:hull(i) end
    end
    check_places(d)
    -- each part's laser k goes to the k-th laser it ran with; a recipe part
    -- (run with every laser) hands lasers that do not reach it to those that do
    local infos = {}
    for i, part in ipairs(d.parts) do
      local n = pl:part(i).lasers
      local map, usable = {}, {}
      for _, li in ipairs(part.reach) do usable[li] = true end
      for k = 1, math.max(n, 1) do
        local li = part.run_lasers[k] or k
        map[k] = usable[li] and li or part.reach[(k - 1) % #part.reach + 1]
      end
      pl:map(i, map)
      part.map = {}
      for k = 1, n do part.map[k] = map[k] end
      infos[i] = pl:part(i)
    end
    local keep = d.picture_layer
    if keep == nil then
      keep = math.huge
      for _, inf in ipairs(infos) do keep = math.min(keep, inf.layers) end
      keep = math.max(1, math.ceil(keep / 2))
    end
    gradus.mkdir(gradus.dirname(out))
    local w, kept = pl:write(out, { layer = d.layer, format = d.format, lasers = #d.machine.lasers, keep = keep })
    local parts = {}
    for i, part in ipairs(d.parts) do parts[i] = part_stats(part, infos[i]) end
    local st = totals(d, parts, w)
    local base = out:gsub("%.cli$", "")
    local styles = {}
    for l, las in ipairs(d.machine.lasers) do
      for ki, kind in ipairs({ "contour", "hatch", "edge" }) do
        styles[#styles + 1] = { id = (l - 1) * 3 + ki, label = las.name .. "-" .. kind, laser = las.name, kind = kind,
          power = las[kind].power, speed = las[kind].speed, jump_speed = d.machine.jump_speed }
      end
    end
    if d.rg then -- the styles the parts ran with: core and contour from the profile, then each region's
      local rmod = require "gradus.regions"
      local m = rmod.machine(d.rg, d.machine)
      for _, sty in ipairs(styles) do
        local las = m.lasers[(sty.id - 1) // 3 + 1]
        sty.power, sty.speed = las[sty.kind].power, las[sty.kind].speed
      end
      rmod.styles(d.rg, m, styles)
    end
    local mparts = {}
    for i, p in ipairs(parts) do
      mparts[i] = { name = p.name, at = p.at, rotation = p.rotation, recipe = p.recipe, lasers = p.lasers, layers = p.layers }
    end
    gradus.yaml.save(base .. ".manifest.yaml", { cli = out, plate = d.name, format = d.format, form = w.form,
      units_mm = 0.001, layers = w.layers, layer_mm = d.layer, machine = d.machine.name, styles = styles, parts = mparts })
    st.pictures = { base .. "_plate.svg" }
    M.footprint_svg(st.pictures[1], d)
    if kept then
      local title = ("%s: layer %d, z = %.3f mm"):format(d.name, keep, kept:z())
      gradus.svg.layer(base .. "_layer" .. keep .. ".svg", kept, { title = title })
      st.pictures[#st.pictures + 1] = base .. "_layer" .. keep .. ".svg"
      if gradus.png then
        gradus.png.layer(base .. "_layer" .. keep .. ".png", kept, { width = 900, title = title })
        st.pictures[#st.pictures + 1] = base .. "_layer" .. keep .. ".png"
      end
    end
    for _, msg in ipairs(st.warnings or {}) do
      if not gradus.quiet() then io.stderr:write("gradus: warning: " .. msg .. "\n") end
    end
    gradus.write_stats(st)
    return st
  end)
  if not o.keep then cleanup(tmp) end
  if not ok then error(err, 0) end
  return err
end

--- M.run{plate = file | M.load(file), output = "out/plate.cli", keep = false} -> stats
function M.run(o)
  if type(o) ~= "table" or o.plate == nil then error("bad argument #1 to 'plate.run' ({plate = file, output = path} expected)", 2) end
  return gradus.outputs.job(run, o)
end

return M
