-- gradus.density: design by relative density or porosity. The C side
-- (engine/density.c, engine/fieldfile.c) calibrates rho(T) per surface from
-- Gradus's own offset solids and reads field files; this module turns recipe
-- targets (expressions, Lua functions, VTK/.npy field files) into job specs,
-- checks that they are reachable, and measures the achieved density per voxel
-- from the written CLI file.
local gradus = require "gradus"
local M = gradus.density

M.RES = 128 -- calibration samples per cell edge

--- M.cache_dir(kb): where calibrations are kept: <kb>/density for a
-- knowledge-base directory, else the default knowledge base's (GRADUS_CACHE_DIR
-- /kb, XDG_CACHE_HOME/gradus/kb, ~/.cache/gradus/kb); nil when kb is false/"off"
-- and nothing is set.
function M.cache_dir(kb)
  local dir
  if type(kb) == "string" and kb ~= "" and kb ~= "off" then
    dir = kb
  else
    local c, x, h = os.getenv("GRADUS_CACHE_DIR"), os.getenv("XDG_CACHE_HOME"), os.getenv("HOME")
    if c and c ~= "" then dir = c .. "/kb"
    elseif x and x ~= "" then dir = x .. "/gradus/kb"
    elseif h and h ~= "" then dir = h .. "/.cache/gradus/kb" end
  end
  if not dir then return nil end
  dir = dir .. "/density"
  if not pcall(gradus.mkdir, dir) then return nil end
  return dir
end

local tables = {}
--- M.get{surface=, level=0, kind=, side=-1, ratio=1, cell=, track=, res=, kb=, clamp=}:
-- a density table, calibrated once per run and cached on disk.
function M.get(o)
  local key = table.concat({ o.surface, o.level or 0, o.kind or "sheet", o.side or -1, o.ratio or 1,
    o.cell, o.track, o.res or M.RES, tostring(o.clamp) }, "|")
  if not tables[key] then
    tables[key] = M.table { surface = o.surface, level = o.level or 0, kind = o.kind or "sheet",
      side = o.side or -1, ratio = o.ratio or 1, cell = o.cell, track = o.track, res = o.res or M.RES,
      cache = M.cache_dir(o.kb), clamp = o.clamp and true or false }
  end
  return tables[key]
end

local function is_file(v)
  return type(v) == "string" and (v:lower():match("%.vtk$") or v:lower():match("%.npy$"))
end

local function numbers(name, s, n)
  if type(s) == "table" then return s end
  local t = {}
  for item in tostring(s):gmatch("[^,]+") do t[#t + 1] = tonumber(item) end
  if #t == 1 then for a = 2, n do t[a] = t[1] end end
  if #t ~= n then error(("bad %s '%s': %d numbers 'a,b,c' expected"):format(name, tostring(s), n), 3) end
  return t
end

--- M.file(path, {origin=, spacing=, pad=}): a field file (VTK legacy
-- STRUCTURED_POINTS, or .npy with origin and spacing), trilinear.
function M.file(path, o)
  o = o or {}
  return gradus.field.file(path, { origin = o.origin and numbers("density_origin", o.origin, 3) or nil,
    spacing = o.spacing and o.spacing ~= "" and numbers("density_spacing", o.spacing, 3) or nil, pad = o.pad or 0 })
end

--- M.source(o): the target of o.density or o.porosity (exactly one): a
-- number, an expression in x,y,z,u,v,w,L, a Lua function f(x,y,z), a field,
-- or a .vtk/.npy file (o.origin, o.spacing, o.pad for .npy). Returns
-- {what = "density"|"porosity", expr = density expression | nil,
--  field = density field | nil, fn = density function | nil, text = as given}.
function M.source(o)
  local v, what = o.density, "density"
  if o.porosity ~= nil and o.porosity ~= "" then
    if v ~= nil and v ~= "" then error("give density or porosity, not both", 3) end
    v, what = o.porosity, "porosity"
  end
  if v == nil or v == "" then return nil end
  local s = { what = what, text = tostring(v) }
  if type(v) == "number" then v = ("%.17g"):format(v) end
  if is_file(v) then
    local ok, f = pcall(M.file, v, o)
    if not ok then error(("bad %s '%s': %s"):format(what, v, tostring(f)), 3) end
    s.field = what == "porosity" and gradus.field.blend(1, 0, f) or f -- 1 - porosity
  elseif type(v) == "string" then
    s.expr = what == "porosity" and ("1-(" .. v .. ")") or v
  elseif type(v) == "function" then
    s.fn = what == "porosity" and function(x, y, z) return 1 - v(x, y, z) end or v
  elseif type(v) == "userdata" then
    s.field = what == "porosity" and gradus.field.blend(1, 0, v) or v
  else
    error(("bad %s: a number, expression, function, field or .vtk/.npy file expected, got %s"):format(what, type(v)), 3)
  end
  return s
end

-- The expression with u, v, w, L replaced for the voxel centred at c (its
-- interior: u = 2 (x - cx) / L).
local function local_expr(e, c, L)
  local rep = {
    u = ("(2*(x-(%.17g))/%.17g)"):format(c[1], L), v = ("(2*(y-(%.17g))/%.17g)"):format(c[2], L),
    w = ("(2*(z-(%.17g))/%.17g)"):format(c[3], L), L = ("%.17g"):format(L) }
  return (e:gsub("%f[%w_]([%a_][%w_]*)%f[^%w_]", function(id) return rep[id] end))
end

--- M.targets(src, lo, L, n): the target density at the 4^3 midpoints of
-- the voxel with corner lo: xs, ys, zs, values.
function M.targets(src, lo, L, n)
  n = n or 4
  local xs, ys, zs = {}, {}, {}
  for a = 0, n - 1 do
    for b = 0, n - 1 do
      for c = 0, n - 1 do
        xs[#xs + 1] = lo[1] + (a + 0.5) / n * L
        ys[#ys + 1] = lo[2] + (b + 0.5) / n * L
        zs[#zs + 1] = lo[3] + (c + 0.5) / n * L
      end
    end
  end
  local vals
  if src.expr then
    local f = gradus.field.expr(local_expr(src.expr, { lo[1] + L / 2, lo[2] + L / 2, lo[3] + L / 2 }, L))
    vals = f:eval_many(xs, ys, zs)
  elseif src.field then
    vals = src.field:eval_many(xs, ys, zs)
  else
    vals = {}
    for i = 1, #xs do vals[i] = src.fn(xs[i], ys[i], zs[i]) end
  end
  return xs, ys, zs, vals
end

-- A Lua function sampled onto a .npy grid (spacing L/8 over the box grown by a
-- cell), so that worker threads can read it: the job's path for functions.
local function function_field(fn, lo, hi, L, path)
  local h = L / 8
  local n = {}
  for a = 1, 3 do n[a] = math.floor((hi[a] - lo[a] + 2 * L) / h + 0.5) + 1 end
  local org = { lo[1] - L, lo[2] - L, lo[3] - L }
  local parts = {}
  for i = 0, n[1] - 1 do
    for j = 0, n[2] - 1 do
      for k = 0, n[3] - 1 do
        parts[#parts + 1] = string.pack("<d", fn(org[1] + i * h, org[2] + j * h, org[3] + k * h))
      end
    end
  end
  local header = ("{'descr': '<f8', 'fortran_order': False, 'shape': (%d, %d, %d), }"):format(n[1], n[2], n[3])
  header = header .. string.rep(" ", 63 - (10 + #header) % 64) .. "\n"
  gradus.write_file(path, "\147NUMPY\1\0" .. string.pack("<I2", #header) .. header .. table.concat(parts))
  return gradus.field.file(path, { origin = org, spacing = { h, h, h } })
end

-- A thickness given by a field file: specs only (no table, nothing to check).
local function thickness_file(p)
  local pad = type(p.cell) == "table" and math.max(p.cell[1], p.cell[2], p.cell[3]) or p.cell -- stretched: the longest
  local ok, f = pcall(M.file, p.thickness, { origin = p.density_origin, spacing = p.density_spacing, pad = pad })
  if not ok then error(("bad thickness '%s': %s"):format(p.thickness, tostring(f)), 4) end
  return {
    spec = function(_, surface)
      return { surface = surface, level = p.level, kind = p.kind, thickness = "0", target = f }
    end,
    check = function() end,
  }
end

--- M.prepare(p, origin, cells, out): the density design of a lattice run
-- (p: lattice parameters with density or porosity, or a thickness given as a
-- .vtk/.npy file), or nil when p has none. Returns an object d with
-- d:spec(surface) -> job:spec options, d:check(surface_of) (targets reachable
-- in every voxel; counts clamps; sets d.target), d:measure(cli, domain, b, t).
function M.prepare(p, origin, cells, out)
  local src = M.source { density = p.density, porosity = p.porosity, origin = p.density_origin,
    spacing = p.density_spacing, pad = p.cell }
  if not src then return is_file(p.thickness) and thickness_file(p) or nil end
  if gradus._ctx.params.thickness ~= nil then
    error(("give thickness or %s, not both"):format(src.what), 3)
  end
  local L = p.cell
  local track = (type(p.track) == "number" and p.track > 0) and p.track or p.hatch
  local hi = { origin[1] + cells[1] * L, origin[2] + cells[2] * L, origin[3] + cells[3] * L }
  if src.fn then
    src.field = function_field(src.fn, origin, hi, L, (out or "out/density.cli"):gsub("%.cli$", "") .. ".target.npy")
  end
  local d = { src = src, L = L, track = track, origin = origin, cells = cells, p = p, clamped = 0 }
  local ratio = 1
  if p.inside ~= nil and p.inside ~= "" then
    ratio = tonumber(p.inside)
    if not ratio or ratio <= 0 then
      error(("bad inside '%s': with a density target, inside is the inside/outside thickness ratio (a number > 0)"):format(tostring(p.inside)), 3)
    end
    if src.field then error("an asymmetric sheet (inside=) needs a density expression, not a field", 3) end
  end
  d.ratio = ratio
  function d:table(surface)
    return M.get { surface = surface, level = p.level, kind = p.kind, ratio = ratio, cell = L, track = track,
      kb = p.kb, clamp = p.clamp }
  end
  function d:spec(surface)
    local t = self:table(surface)
    return { surface = surface, level = p.level, kind = p.kind, thickness = src.expr or "0",
      inside = ratio ~= 1 and src.expr or nil, density_table = t, target = src.field }
  end
  -- every voxel's targets: reachable (or clamped, counted), and their mean
  function d:check(surface_of)
    self.target = {}
    for k = 0, cells[3] - 1 do
      for j = 0, cells[2] - 1 do
        for i = 0, cells[1] - 1 do
          local surface = surface_of(i, j, k)
          if surface then
            local lo = { origin[1] + i * L, origin[2] + j * L, origin[3] + k * L }
            local xs, ys, zs, v = M.targets(src, lo, L)
            local t, sum, clamped = self:table(surface), 0, false
            local rlo, rhi = t:range()
            for q = 1, #v do
              if not p.clamp or v[q] ~= v[q] then t:check(v[q], xs[q], ys[q], zs[q], src.what) end
              if v[q] < rlo or v[q] > rhi then clamped = true end
              sum = sum + math.min(math.max(v[q], rlo), rhi)
            end
            if clamped then self.clamped = self.clamped + 1 end
            self.target[i + cells[1] * (j + cells[2] * k) + 1] = sum / #v
          end
        end
      end
    end
  end
  function d:measure(cli, domain, beam_offset, layer)
    return M.measure(cli, self, domain, beam_offset, layer)
  end
  return d
end

-- Is the voxel wholly inside the domain (5^3 samples, corners included)?
local function full_voxel(domain, lo, L)
  if not domain then return true end
  local xs, ys, zs = {}, {}, {}
  for a = 0, 4 do
    for b = 0, 4 do
      for c = 0, 4 do
        xs[#xs + 1], ys[#ys + 1], zs[#zs + 1] = lo[1] + a * L / 4, lo[2] + b * L / 4, lo[3] + c * L / 4
      end
    end
  end
  local f = type(domain) == "userdata" and domain or gradus.field.expr(domain)
  for _, v in ipairs(f:eval_many(xs, ys, zs)) do
    if v >= 0 then return false end
  end
  return true
end

--- M.measure(cli, d, domain, beam_offset, layer): achieved density per voxel
-- from the CLI's contours (gradus.density.achieved) against the targets of
-- d:check. Voxels cut by the domain are counted but not compared. Returns the
-- stats table {what, target_source, track_mm, clamped_voxels, compared,
-- partial, error = {min, mean, max, max_abs}, voxels = {{i,j,k,target,achieved,diff}...}}.
function M.measure(cli, d, domain, beam_offset, layer)
  local L, cells, origin = d.L, d.cells, d.origin
  local vol = M.achieved(cli, { origin = origin, cell = L, cells = cells, layer = layer, beam_offset = beam_offset })
  local st = { what = d.src.what, target = d.src.text, track_mm = d.track, clamped_voxels = d.clamped,
    compared = 0, partial = 0, voxels = {} }
  local emin, emax, esum, eabs = math.huge, -math.huge, 0, 0
  for k = 0, cells[3] - 1 do
    for j = 0, cells[2] - 1 do
      for i = 0, cells[1] - 1 do
        local idx = i + cells[1] * (j + cells[2] * k) + 1
        local tgt = d.target and d.target[idx]
        if tgt then
          local lo = { origin[1] + i * L, origin[2] + j * L, origin[3] + k * L }
          if full_voxel(domain, lo, L) then
            local a = vol[idx] / (L * L * L)
            local por = d.src.what == "porosity"
            local tv, av = por and 1 - tgt or tgt, por and 1 - a or a
            local diff = av - tv
            st.voxels[#st.voxels + 1] = { i = i, j = j, k = k, target = tv, achieved = av, diff = diff }
            st.compared = st.compared + 1
            emin, emax, esum = math.min(emin, diff), math.max(emax, diff), esum + diff
            eabs = math.max(eabs, math.abs(diff))
          else
            st.partial = st.partial + 1
          end
        end
      end
    end
  end
  if st.compared > 0 then
    st.error = { min = emin, mean = esum / st.compared, max = emax, max_abs = eabs }
  end
  return st
end

--- M.plot(path, st, title): target vs achieved per voxel (SVG, and PNG
-- beside it through headless chromium when present). Returns the paths.
function M.plot(path, st, title)
  local xs, ys, ideal = {}, {}, {}
  local lo, hi = math.huge, -math.huge
  for _, v in ipairs(st.voxels) do
    xs[#xs + 1], ys[#ys + 1] = v.target, v.achieved
    lo, hi = math.min(lo, v.target), math.max(hi, v.target)
  end
  if #xs == 0 then return {} end
  local svg = path:gsub("%.png$", "") .. ".svg"
  gradus.svg.plot(svg, { title = title or ("target vs achieved " .. st.what .. " per voxel"),
    xlabel = "target " .. st.what, ylabel = "achieved " .. st.what, width = 720, height = 480,
    series = { { name = "voxels", x = xs, y = ys }, { name = "achieved = target", x = { lo, hi }, y = { lo, hi } } } })
  local out = { svg }
  local png = svg:gsub("%.svg$", ".png")
  if M.svg_to_png(svg, png, 720, 480) then out[#out + 1] = png end
  return out
end

--- M.svg_to_png(svg, png, w, h): rasterise through headless chromium (the
-- Debian package); false when chromium is missing or fails.
function M.svg_to_png(svg, png, w, h)
  local abs = svg:sub(1, 1) == "/" and svg or (os.getenv("PWD") or ".") .. "/" .. svg
  local cmd = ("chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=%d,%d --screenshot=%q %q >/dev/null 2>&1")
    :format(w, h, png, "file://" .. abs)
  return os.execute(cmd) == true
end

return M
