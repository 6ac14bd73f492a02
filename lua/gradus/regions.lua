-- gradus.regions: regions of a part with their own build styles (doc/api/regions.md).
-- A process profile's `regions:` section names a style (power W, speed mm/s)
-- per region: core (the lattice hatches), contour (every contour), skin
-- (the solid band along a domain), thin (thin-wall centre lines), downskin
-- and upskin (hatch within downskin_layers / upskin_layers of an unsupported
-- area below / of open space above). Core and contour override the machine's
-- hatch and contour styles on every laser; the other four get their own CLI
-- ids (region * 48 + laser * 3 + kind + 1) and manifest entries.
local gradus = require "gradus"
local strict = require "gradus.strict"
local M = {}

local function set(...) local t = {} for _, k in ipairs({ ... }) do t[k] = true end return t end
M.NAMES = { "core", "contour", "skin", "thin", "downskin", "upskin" }
M.OWN = { "skin", "thin", "downskin", "upskin" } -- regions with their own ids, in id order
local OWN_INDEX = { skin = 1, thin = 2, downskin = 3, upskin = 4 }
local SECTION = set("core", "contour", "skin", "thin", "downskin", "upskin", "downskin_layers", "upskin_layers")
local STYLE = set("power", "speed", "hatch", "contours")
local HATCHED = set("core", "skin", "downskin", "upskin") -- where a hatch spacing applies
M.DEFAULT = "recipes/profiles/ti64.yaml"

local function where(src, marks, t, k)
  local pos = marks and marks[t] and marks[t][k]
  return src .. (pos and (":" .. pos) or "")
end

--- M.check(section, src, marks) -> the `regions:` section checked: every
-- key known, power and speed finite and > 0 (W, mm/s), hatch > 0 (mm) only
-- where hatches are, contours a whole number >= 0, layer counts 1..64.
-- Errors name src:line:col (marks from gradus.yaml.load(path, {marks = true})).
function M.check(t, src, marks)
  if type(t) ~= "table" then error(("%s: regions: a mapping of region -> {power, speed} expected"):format(src), 0) end
  strict.check_keys(t, SECTION, src, marks, "regions")
  local out = { downskin_layers = 3, upskin_layers = 3 }
  for _, k in ipairs({ "downskin_layers", "upskin_layers" }) do
    local v = t[k]
    if v ~= nil then
      if math.type(v) ~= "integer" or v < 1 or v > 64 then
        error(("%s: regions.%s must be a whole number of layers in 1..64, got %s"):format(where(src, marks, t, k), k, tostring(v)), 0)
      end
      out[k] = v
    end
  end
  for _, name in ipairs(M.NAMES) do
    local s = t[name]
    if s ~= nil then
      local w = "regions." .. name
      if type(s) ~= "table" then error(("%s: %s must be a mapping {power, speed}"):format(where(src, marks, t, name), w), 0) end
      strict.check_keys(s, STYLE, src, marks, w)
      local st = {}
      for _, k in ipairs({ "power", "speed" }) do
        local v = s[k]
        if type(v) ~= "number" or not (v > 0) or v == math.huge then
          error(("%s: %s.%s must be a positive number (%s), got %s"):format(where(src, marks, v ~= nil and s or t, v ~= nil and k or name),
            w, k, k == "power" and "W" or "mm/s", tostring(v)), 0)
        end
        st[k] = v
      end
      if s.hatch ~= nil then
        if not HATCHED[name] then error(("%s: %s.hatch: the %s region has no hatches"):format(where(src, marks, s, "hatch"), w, name), 0) end
        if type(s.hatch) ~= "number" or not (s.hatch > 0) or s.hatch == math.huge then
          error(("%s: %s.hatch must be a positive number (mm), got %s"):format(where(src, marks, s, "hatch"), w, tostring(s.hatch)), 0)
        end
        st.hatch, st.hatch_at = s.hatch, where(src, marks, s, "hatch")
      end
      if s.contours ~= nil then
        if math.type(s.contours) ~= "integer" or s.contours < 0 then
          error(("%s: %s.contours must be a whole number >= 0, got %s"):format(where(src, marks, s, "contours"), w, tostring(s.contours)), 0)
        end
        st.contours, st.contours_at = s.contours, where(src, marks, s, "contours")
      end
      out[name] = st
    end
  end
  out.source = src
  return out
end

--- M.load(spec) -> regions or nil. spec: "" (none), "default" (M.DEFAULT,
-- Ti-6Al-4V) or the path of a process profile with a `regions:` section.
function M.load(spec)
  if spec == nil or spec == "" then return nil end
  local path = spec == "default" and (gradus.root .. "/" .. M.DEFAULT) or spec
  local prof = require("gradus.profiles").process(path)
  if not prof.regions then error(("%s: the process profile has no 'regions' section"):format(path), 0) end
  return prof.regions
end

--- M.fit(rg, p): what a region's style may change in this job. The core is
-- the lattice: it hatches at the job's spacing (p.hatch) with the job's
-- contour count (p.contours), so a core hatch or contour count other than
-- those is refused (set them with -D hatch / -D contours instead). Skin,
-- down-skin and up-skin may have their own hatch spacing (any whole multiple
-- of the job's hatch / n, n <= 16: checked by job:regions). The skin may
-- have more contours than the job (along the part's outer surface); a
-- down-skin or up-skin area shares its outline with the core: a contour
-- count there is refused, not ignored.
function M.fit(rg, p)
  for _, name in ipairs(M.NAMES) do
    local s = rg[name]
    if s and name == "core" and s.hatch and math.abs(s.hatch - p.hatch) > 1e-9 * p.hatch then
      error(("%s: regions.core.hatch = %g mm differs from the job's hatch spacing %g mm: the core hatches at the job's spacing (set -D hatch=%g, or remove regions.core.hatch)")
        :format(s.hatch_at, s.hatch, p.hatch, s.hatch), 0)
    end
    if s and s.contours and (name == "downskin" or name == "upskin") then
      error(("%s: regions.%s.contours: contours follow the section's outline, which the %s shares with the core; their count is the job's (-D contours, or regions.core.contours)")
        :format(s.contours_at, name, name), 0)
    end
    if s and s.contours and name == "skin" and (s.contours < p.contours or s.contours > 20) then
      error(("%s: regions.skin.contours = %d: the skin's contours must be the job's %d .. 20 (the lattice keeps the job's)")
        :format(s.contours_at, s.contours, p.contours), 0)
    end
    if s and s.contours and name ~= "skin" and s.contours ~= p.contours then
      error(("%s: regions.%s.contours = %d differs from the job's contours %d: the lattice's contour count is the job's (set -D contours=%d, or remove it)")
        :format(s.contours_at, name, s.contours, p.contours, s.contours), 0)
    end
  end
end

--- M.machine(rg, machine) -> machine with core (hatch) and contour styles
-- of every laser replaced by the profile's (a copy; machine is unchanged).
function M.machine(rg, machine)
  local m = {}
  for k, v in pairs(machine) do m[k] = v end
  m.lasers = {}
  for i, l in ipairs(machine.lasers) do
    local c = {}
    for k, v in pairs(l) do c[k] = v end
    if rg.core then c.hatch = { power = rg.core.power, speed = rg.core.speed } end
    if rg.contour then c.contour = { power = rg.contour.power, speed = rg.contour.speed } end
    m.lasers[i] = c
  end
  return m
end

--- M.job(rg, job): give the job its regions (after job:machine).
function M.job(rg, job)
  local o = { down = rg.downskin_layers, up = rg.upskin_layers }
  for _, name in ipairs(M.OWN) do
    if rg[name] then
      o[name] = rg[name].speed
      if rg[name].hatch and HATCHED[name] then o[name .. "_hatch"] = rg[name].hatch end
      if name == "skin" and rg.skin.contours then o.skin_contours = rg.skin.contours end
    end
  end
  local ok, err = pcall(job.regions, job, o)
  if not ok then -- named where the profile sets a spacing or the skin's contours, else the file
    local at = rg.source or "regions"
    for _, name in ipairs(M.OWN) do
      local r = rg[name]
      if r and (r.hatch_at or r.contours_at) then at = r.hatch_at or r.contours_at break end
    end
    error(("%s: %s"):format(at, tostring(err):gsub("^job:regions: ", "")), 0)
  end
end

--- M.styles(rg, machine, styles, hatch): tag the core styles region = "core"
-- and append every own region's styles (per laser, contour/hatch/edge) to
-- styles, the manifest's list; hatch styles carry their spacing (mm; hatch:
-- the job's spacing).
function M.styles(rg, machine, styles, hatch)
  for _, s in ipairs(styles) do
    s.region = "core"
    if s.kind == "hatch" then s.hatch = hatch end
  end
  for _, name in ipairs(M.OWN) do
    local r = rg[name]
    if r then
      for l, las in ipairs(machine.lasers) do
        for kindi, kind in ipairs({ "contour", "hatch", "edge" }) do
          styles[#styles + 1] = { id = OWN_INDEX[name] * 48 + (l - 1) * 3 + kindi, label = las.name .. "-" .. name .. "-" .. kind,
            laser = las.name, kind = kind, region = name, power = r.power, speed = r.speed, jump_speed = machine.jump_speed,
            hatch = kind == "hatch" and HATCHED[name] and (r.hatch or hatch) or nil }
        end
      end
    end
  end
  return styles
end

return M
