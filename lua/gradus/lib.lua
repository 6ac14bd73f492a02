-- gradus.lib: the Lua side of the gradus module (loaded by luaopen_gradus).
-- Recipe parameters, output paths, stats, YAML encoding, atomic text files,
-- progress reports, and the help registry. Policy lives here; heavy loops
-- live in C.
local gradus = package.loaded.gradus

-- The running job's context: set by the host (gradus.host.run); a stock
-- `lua5.4 -e 'require "gradus"'` has an empty one, so params take defaults.
gradus._ctx = gradus._ctx or { params = {}, read = {}, quiet = true }

local function to_boolean(name, raw)
  local s = tostring(raw):lower()
  if s == "true" or s == "1" or s == "yes" or s == "on" then return true end
  if s == "false" or s == "0" or s == "no" or s == "off" then return false end
  error(("parameter '%s': true or false expected, got '%s'"):format(name, raw), 3)
end

local function auto(raw)
  if raw == "true" then return true elseif raw == "false" then return false end
  return tonumber(raw) or raw
end

--- gradus.param(name, default [, spec]): the value of `-D name=value`,
-- converted to the type of `default` (number, boolean, string, or a table of
-- numbers written "a,b,c"), or `default` when not given. Declares the
-- parameter: spec = {unit=, help=, min=, max=, integer=, choices=, n=, auto=}
-- (gradus.strict.check) gives `gradus run RECIPE --help` its line and checks
-- a given value against the accepted range. Numbers must be finite.
function gradus.param(name, default, spec)
  if type(name) ~= "string" then error("bad argument #1 to 'param' (string expected)", 2) end
  if spec ~= nil and type(spec) ~= "table" then error("bad argument #3 to 'param' (table expected)", 2) end
  local strict = require "gradus.strict"
  local ctx = gradus._ctx
  local s = strict.declare(ctx, name, default, spec)
  ctx.read[name] = true
  ctx.returned = ctx.returned or {}
  local raw = ctx.params[name]
  if raw == nil or ctx.help then
    ctx.returned[name] = default
    return default
  end
  local v
  if type(raw) ~= "string" then
    v = raw -- set from Lua
  else
    local t = type(default)
    if t == "number" and s.one then
      v = raw -- one number or a list (cell=L or Lx,Ly,Lz): strict.check reads it, naming the range
    elseif t == "number" then
      v = tonumber(raw)
      if not v or v ~= v or v == math.huge or v == -math.huge then
        error(("parameter '%s': a finite number is expected, got '%s'"):format(name, raw), 2)
      end
    elseif t == "boolean" then
      v = to_boolean(name, raw)
    elseif t == "table" then
      v = {}
      for item in raw:gmatch("[^,]+") do
        local x = tonumber(item)
        if not x or x ~= x or x == math.huge or x == -math.huge then
          error(("parameter '%s': a list of finite numbers 'a,b,c' is expected, got '%s'"):format(name, raw), 2)
        end
        v[#v + 1] = x
      end
    elseif t == "string" then
      v = raw
    else
      v = auto(raw)
    end
  end
  if spec then
    local ok, res = pcall(strict.check, name, v, s, default)
    if not ok then error(("%s (-D %s=%s)"):format(tostring(res), name, tostring(raw)), 2) end
    v = res
  end
  ctx.returned[name] = v
  return v
end

--- gradus.extra_params(pattern [, help]): declare free-form parameters: every
-- -D name matching the Lua pattern is accepted. Returns name -> raw string
-- of those given.
function gradus.extra_params(pattern, help)
  if type(pattern) ~= "string" then error("bad argument #1 to 'extra_params' (Lua pattern expected)", 2) end
  local ctx = gradus._ctx
  ctx.extra = ctx.extra or {}
  ctx.extra[#ctx.extra + 1] = pattern
  local out = {}
  for k, v in pairs(ctx.params) do
    if k:match(pattern) then out[k] = v end
  end
  return out
end

--- gradus.output(default): the path given with -o, or `default`.
function gradus.output(default)
  return gradus._ctx.output or default
end

--- gradus.quiet(): true when progress output is off (-q, or not a terminal).
function gradus.quiet()
  local ctx = gradus._ctx
  if ctx.quiet then return true end
  local term = gradus.term
  return not (term and term.isatty(2))
end

--- gradus.mkdir(path): create a directory and its parents (no error if it exists).
function gradus.mkdir(path)
  if path == "" or path == "." then return true end
  local ok = os.execute("mkdir -p '" .. path:gsub("'", "'\\''") .. "' 2>/dev/null")
  if not ok then error("cannot create directory " .. path, 2) end
  return true
end

local function dirname(path)
  return path:match("^(.*)/[^/]*$") or "."
end
gradus.dirname = dirname

--- gradus.write_file(path, text): write atomically (temporary file + rename),
-- creating parent directories; an error leaves nothing behind. Only a
-- regular file is replaced; inside a job (gradus.outputs.job) the file is
-- renamed into place with the job's other outputs.
function gradus.write_file(path, text)
  gradus.mkdir(dirname(path))
  local dest = gradus.outputs.stage(path)
  local tmp = dest .. ".tmp" .. gradus.fs.pid()
  local f, err = io.open(tmp, "wb")
  if not f then error("cannot write " .. path .. ": " .. tostring(err), 2) end
  local ok, werr = f:write(text)
  local cok, cerr = f:close()
  if not ok or not cok then
    os.remove(tmp)
    error("cannot write " .. path .. ": " .. tostring(werr or cerr), 2)
  end
  local rok, rerr = os.rename(tmp, dest)
  if not rok then
    os.remove(tmp)
    error("cannot write " .. path .. ": " .. tostring(rerr), 2)
  end
  return path
end

-- YAML emitter (block style, keys sorted, numbers with 10 significant digits).
local function yaml_scalar(v)
  local t = type(v)
  if t == "number" then
    if v ~= v then return ".nan" end
    if v == math.huge then return ".inf" elseif v == -math.huge then return "-.inf" end
    if math.type(v) == "integer" then return tostring(v) end
    if v == math.floor(v) and math.abs(v) < 1e15 then return string.format("%.1f", v) end
    return string.format("%.10g", v)
  elseif t == "boolean" then
    return tostring(v)
  elseif t == "nil" then
    return "null"
  end
  local s = tostring(v)
  if s == "" or s:match("^[%s%-?:,%[%]{}#&*!|>'\"%%@`]") or s:match("[:#]%s") or s:match(":$")
    or s:match("%s$") or s:match("\n") or tonumber(s) or s == "true" or s == "false"
    or s == "null" or s == "~" or s:lower() == "yes" or s:lower() == "no" then
    return '"' .. s:gsub('\\', '\\\\'):gsub('"', '\\"'):gsub("\n", "\\n") .. '"'
  end
  return s
end

local function is_array(t)
  local n = #t
  if n == 0 then return next(t) == nil end
  for k in pairs(t) do
    if math.type(k) ~= "integer" or k < 1 or k > n then return false end
  end
  return true
end

local function sorted_keys(t)
  local keys = {}
  for k in pairs(t) do keys[#keys + 1] = k end
  table.sort(keys, function(a, b)
    if type(a) == type(b) then return a < b end
    return type(a) == "number"
  end)
  return keys
end

local function emit(out, v, indent)
  local pad = string.rep("  ", indent)
  if type(v) ~= "table" then
    out[#out + 1] = yaml_scalar(v)
    return
  end
  if next(v) == nil then
    out[#out + 1] = is_array(v) and "[]" or "{}"
    return
  end
  if is_array(v) then
    local simple = true
    for _, x in ipairs(v) do if type(x) == "table" then simple = false break end end
    if simple and #v <= 16 then
      local parts = {}
      for i, x in ipairs(v) do parts[i] = yaml_scalar(x) end
      out[#out + 1] = "[" .. table.concat(parts, ", ") .. "]"
      return
    end
    for _, x in ipairs(v) do
      out[#out + 1] = "\n" .. pad .. "- "
      if type(x) == "table" and not is_array(x) and next(x) then
        -- first key on the dash line
        local keys = sorted_keys(x)
        for i, k in ipairs(keys) do
          if i > 1 then out[#out + 1] = "\n" .. pad .. "  " end
          out[#out + 1] = yaml_scalar(k) .. ":"
          if type(x[k]) == "table" and next(x[k]) and not (is_array(x[k]) and #x[k] <= 16) then
            emit(out, x[k], indent + 2)
          else
            out[#out + 1] = " "
            emit(out, x[k], indent + 2)
          end
        end
      else
        emit(out, x, indent + 1)
      end
    end
    return
  end
  for _, k in ipairs(sorted_keys(v)) do
    local x = v[k]
    out[#out + 1] = "\n" .. pad .. yaml_scalar(k) .. ":"
    if type(x) == "table" and next(x) ~= nil and not (is_array(x) and #x <= 16 and
        not (function() for _, y in ipairs(x) do if type(y) == "table" then return true end end end)()) then
      emit(out, x, indent + 1)
    else
      out[#out + 1] = " "
      emit(out, x, indent + 1)
    end
  end
end

--- gradus.yaml.encode(value): YAML text for a Lua value (tables, numbers,
-- strings, booleans).
function gradus.yaml.encode(value)
  local out = {}
  emit(out, value, 0)
  local s = table.concat(out):gsub("^\n", "")
  return s .. "\n"
end

--- gradus.yaml.save(path, value): write value as YAML atomically.
function gradus.yaml.save(path, value)
  return gradus.write_file(path, gradus.yaml.encode(value))
end

--- gradus.write_stats(tbl): write the job's stats (doc/contract.md section 8)
-- to the --stats file, if one was given. Returns the path or nil. When the
-- job ran with --allow-unused, the stats say so and list the ignored names.
function gradus.write_stats(tbl)
  local ctx = gradus._ctx
  local path = ctx.stats
  if not path then return nil end
  if ctx.allow_unused then
    tbl.allow_unused = true
    tbl.unused_parameters = ctx.unused or {}
  end
  return gradus.yaml.save(path, tbl)
end

--- gradus.progress(label, done, total): a progress line on stderr when it is a
-- terminal and -q was not given (layers done, rate, time left).
function gradus.progress(label, done, total)
  if gradus.quiet() then return end
  local ctx = gradus._ctx
  local now = gradus.clock()
  ctx.progress = ctx.progress or {}
  local p = ctx.progress[label]
  if not p or done == 0 then p = { t0 = os.time(), c0 = now, last = -1 } ctx.progress[label] = p end
  if done < total and now - p.last < 0.2 then return end
  p.last = now
  local el = now - p.c0
  local rate = el > 0 and done / el or 0
  local left = (rate > 0) and (total - done) / rate or 0
  io.stderr:write(string.format("\r%s: %d/%d (%.0f/s, %.0f s left)   ", label, done, total, rate, left))
  if done >= total then io.stderr:write("\n") end
end

gradus.svg = require "gradus.svg"
gradus.outputs = require "gradus.outputs"

--- gradus.help(x): help text of a function, table or object of the module
-- (from doc/api/*.md).
function gradus.help(x)
  return require("gradus.help").text(x)
end

--- gradus.sweep{recipe=, params={name={v1,v2,...}|"a:b:step"}, jobs=2, dir=}:
-- run a recipe over the cross product of parameter values (see gradus sweep).
function gradus.sweep(t)
  if type(t) ~= "table" or type(t.recipe) ~= "string" then
    error("bad argument #1 to 'sweep' (table with recipe= expected)", 2)
  end
  local params, order = {}, {}
  for k, v in pairs(t.params or {}) do
    order[#order + 1] = k
    if type(v) == "table" then
      local s = {}
      for i, x in ipairs(v) do s[i] = tostring(x) end
      params[k] = table.concat(s, ",")
    else
      params[k] = tostring(v)
    end
  end
  table.sort(order)
  return require("gradus.commands").run_sweep(t.recipe, params, order,
    { dir = t.dir or "out/sweep", jobs = t.jobs or 2, quiet = t.quiet })
end

return gradus
