-- gradus.lasers: machine profiles (YAML) and laser assignment rules.
-- A machine profile (see recipes/machine.yaml and doc/formats.md):
--   lasers: [{name, field: {lo: [x,y], hi: [x,y]}, contour|hatch|edge: {power, speed}}]
--   jump_speed (mm/s), jump_delay (s per jump), polygon_delay (s per block),
--   recoat_time (s per layer), stitch (mm: overlap where two lasers meet)
local gradus = require "gradus"
local strict = require "gradus.strict"
local M = {}

-- the keys a machine profile may have, per mapping (anything else is an error)
local function set(...) local t = {} for _, k in ipairs({ ... }) do t[k] = true end return t end
local KEYS = {
  machine = set("name", "plate", "jump_speed", "jump_delay", "polygon_delay", "recoat_time", "stitch", "lasers"),
  laser = set("name", "field", "contour", "hatch", "edge"),
  box = set("lo", "hi"),
  style = set("power", "speed"),
}

local KINDS = { "contour", "hatch", "edge" }
local DEFAULT_STYLE = {
  contour = { power = 100, speed = 600 },
  hatch = { power = 200, speed = 1000 },
  edge = { power = 80, speed = 500 },
}

local function bad(src, what, fmt, ...)
  error(("%s: %s: " .. fmt):format(src, what, ...), 0)
end

local function positive(src, what, v)
  if type(v) ~= "number" or not (v > 0) or v == math.huge then
    bad(src, what, "must be a positive number, got %s", tostring(v))
  end
  return v
end

local function point(src, what, v)
  if type(v) ~= "table" or type(v[1]) ~= "number" or type(v[2]) ~= "number" then
    bad(src, what, "must be [x, y] in mm, got %s", tostring(v))
  end
  return { v[1], v[2] }
end

local function delay(src, what, v)
  if type(v) ~= "number" or not (v >= 0 and v <= 3600) then bad(src, what, "must be in [0, 3600] s, got %s", tostring(v)) end
  return v
end

-- The overlap of two lasers' scans where they meet (mm): a closed contour no
-- single laser reaches, and hatch lines cut at a boundary between lasers,
-- overlap by this much. Default 0.5 mm (doc/formats.md gives the source).
M.STITCH_DEFAULT = 0.5
function M.stitch(src, v)
  if v == nil then return M.STITCH_DEFAULT end
  if type(v) ~= "number" or not (v >= 0 and v <= 10) then bad(src, "stitch", "must be in [0, 10] mm, got %s", tostring(v)) end
  return v
end

-- Recoating time per layer (s) when the profile gives none: 12 s, the
-- per-layer recoat of the additive.tools build-time estimator's L-PBF preset
-- (doc/formats.md); a machine's own value belongs in its profile.
M.RECOAT_DEFAULT = 12

--- M.normalize(profile, source [, marks]) -> machine with every field
-- checked and defaults filled. Errors name the source and the field; an
-- unknown key is an error too, at its line and column when marks (from
-- gradus.yaml.load(path, {marks = true})) are given.
function M.normalize(p, src, marks)
  src = src or "machine profile"
  if type(p) ~= "table" then bad(src, "profile", "must be a mapping") end
  strict.check_keys(p, KEYS.machine, src, marks, "the machine profile")
  if p.plate ~= nil then strict.check_keys(p.plate, KEYS.box, src, marks, "plate") end
  if type(p.lasers) ~= "table" or #p.lasers == 0 then bad(src, "lasers", "must be a non-empty list") end
  local m = {
    name = p.name or src,
    jump_speed = positive(src, "jump_speed", p.jump_speed or 5000),
    jump_delay = delay(src, "jump_delay", p.jump_delay or 0),
    polygon_delay = delay(src, "polygon_delay", p.polygon_delay or 0),
    recoat_time = delay(src, "recoat_time", p.recoat_time or M.RECOAT_DEFAULT),
    stitch = M.stitch(src, p.stitch),
    lasers = {},
  }
  for i, l in ipairs(p.lasers) do
    local w = ("lasers[%d]"):format(i)
    if type(l) ~= "table" then bad(src, w, "must be a mapping") end
    strict.check_keys(l, KEYS.laser, src, marks, w)
    if l.field ~= nil then strict.check_keys(l.field, KEYS.box, src, marks, w .. ".field") end
    for _, k in ipairs(KINDS) do
      if l[k] ~= nil then strict.check_keys(l[k], KEYS.style, src, marks, w .. "." .. k) end
    end
    local out = { name = l.name or ("laser" .. i) }
    if l.field ~= nil then
      out.field = { lo = point(src, w .. ".field.lo", l.field.lo), hi = point(src, w .. ".field.hi", l.field.hi) }
      if out.field.lo[1] >= out.field.hi[1] or out.field.lo[2] >= out.field.hi[2] then
        bad(src, w .. ".field", "lo must be below hi")
      end
    end
    for _, k in ipairs(KINDS) do
      local s = l[k] or DEFAULT_STYLE[k]
      out[k] = {
        power = positive(src, w .. "." .. k .. ".power", s.power or DEFAULT_STYLE[k].power),
        speed = positive(src, w .. "." .. k .. ".speed", s.speed or DEFAULT_STYLE[k].speed),
      }
    end
    m.lasers[i] = out
  end
  return m
end

--- M.load(path) -> machine
function M.load(path)
  local p, marks = gradus.yaml.load(path, { marks = true })
  return M.normalize(p, path, marks)
end

--- M.default(n) -> a machine of n identical lasers reaching the whole plate.
function M.default(n)
  local p = { name = n .. "-laser default", lasers = {} }
  for i = 1, n do p.lasers[i] = { name = "laser" .. i } end
  return M.normalize(p, "default machine")
end

local function reaches(l, x0, y0, x1, y1)
  local f = l.field
  if not f then return true end
  return x0 >= f.lo[1] - 1e-9 and y0 >= f.lo[2] - 1e-9 and x1 <= f.hi[1] + 1e-9 and y1 <= f.hi[2] + 1e-9
end
M.reaches = reaches

--- M.reach(machine, x0, y0, x1, y1) -> list of 0-based laser indices that can
-- scan the whole box; an error when none can (the fields do not cover the part).
function M.reach(m, x0, y0, x1, y1)
  local out = {}
  for i, l in ipairs(m.lasers) do
    if reaches(l, x0, y0, x1, y1) then out[#out + 1] = i - 1 end
  end
  if #out == 0 then
    error(("laser fields of '%s' do not cover the part: no laser reaches the voxel [%.3f, %.3f] x [%.3f, %.3f] mm")
      :format(m.name, x0, x1, y0, y1), 0)
  end
  return out
end

--- M.zones(machine, xmin, xmax) -> rule(x0,y0,x1,y1) -> laser: the part's
-- x-range cut into equal zones, one per laser; a voxel goes to its zone's
-- laser if it reaches it, else to the nearest zone's laser that does.
function M.zones(m, xmin, xmax)
  local n = #m.lasers
  return function(x0, y0, x1, y1)
    local cx = 0.5 * (x0 + x1)
    local z = math.floor((cx - xmin) / (xmax - xmin) * n)
    z = math.max(0, math.min(n - 1, z))
    local best, bd
    for _, l in ipairs(M.reach(m, x0, y0, x1, y1)) do
      local d = math.abs(l - z)
      if not bd or d < bd then best, bd = l, d end
    end
    return best
  end
end

--- M.warnings(machine, stats, part) -> list of messages: each laser with no
-- work or under 10 % of the scan time, with the reason. part = {origin =
-- {x, y, z}, cells = {nx, ny, nz}, cell = L or {Lx, Ly, Lz} (mm), assign = "balance" |
-- "zones" | function}: the voxel columns the lasers could reach.
function M.warnings(m, st, part)
  local out = {}
  if #m.lasers < 2 then return out end
  local C, o, c = require("gradus.part").lengths(part.cell), part.origin, part.cells
  local ncol = c[1] * c[2]
  for i, las in ipairs(m.lasers) do
    local share = st.lasers[i] and st.lasers[i].share or 0
    if share < 0.1 then
      local reach = 0
      for jj = 0, c[2] - 1 do
        for ii = 0, c[1] - 1 do
          local x0, y0 = o[1] + ii * C[1], o[2] + jj * C[2]
          if reaches(las, x0, y0, x0 + C[1], y0 + C[2]) then reach = reach + 1 end
        end
      end
      local why
      local f = las.field
      if reach == 0 then
        why = ("its field [%g, %g] x [%g, %g] mm does not reach the part [%g, %g] x [%g, %g] mm (reach)"):format(
          f.lo[1], f.hi[1], f.lo[2], f.hi[2], o[1], o[1] + c[1] * C[1], o[2], o[2] + c[2] * C[2])
      elseif reach < ncol then
        why = ("its field reaches only %d of the part's %d voxel columns (reach)"):format(reach, ncol)
      elseif part.assign == "zones" then
        why = "assign=zones: its zone of the part's x-range holds little of the lattice (zones)"
      else
        why = "the voxel rule fixed the lasers of most voxels (rule)"
      end
      out[#out + 1] = ("laser %d (%s) %s (%.1f %% of the scan time): %s"):format(i, las.name,
        share == 0 and "gets no work" or "gets under 10 % of the work", 100 * share, why)
    end
  end
  return out
end

return M
