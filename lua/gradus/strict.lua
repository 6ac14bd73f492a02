-- gradus.strict: parameters that say when the user slips.
--   * declarations: gradus.param(name, default, spec) records the name, its
--     default, unit, one line of help and the accepted range (spec);
--   * checks: numbers finite and inside the declared range, choices, vectors,
--     expressions; every message names the parameter and the accepted range;
--   * did-you-mean suggestions for misspelled names;
--   * the strict parameter table of a recipe (lattice.params()): assigning or
--     reading a field nobody declared raises;
--   * the first action: a recipe declares its parameters before it does any
--     work; the first call into the engine, print or file operation checks
--     every -D name (an unknown one stops the job before anything is
--     written), and under --help stops the recipe and lists the parameters.
local M = {}

local function gradus() return package.loaded.gradus end

local function edit_distance(a, b)
  local prev = {}
  for j = 0, #b do prev[j] = j end
  for i = 1, #a do
    local cur = { [0] = i }
    for j = 1, #b do
      cur[j] = math.min(prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a:sub(i, i) == b:sub(j, j) and 0 or 1))
    end
    prev = cur
  end
  return prev[#b]
end

--- M.suggest(name, names) -> " (did you mean 'x'?)" for the closest of
-- names (at most two edits away, or a prefix), or "".
function M.suggest(name, names)
  local best, bd = nil, 3
  local sorted = {}
  for _, k in ipairs(names) do sorted[#sorted + 1] = k end
  table.sort(sorted)
  for _, k in ipairs(sorted) do
    local d = edit_distance(name, k)
    if d < bd or (not best and #name >= 3 and k:sub(1, #name) == name) then best, bd = k, math.min(d, bd) end
  end
  return best and (" (did you mean '" .. best .. "'?)") or ""
end

local function fmt(v)
  if type(v) == "number" then return v ~= v and "nan" or ("%.6g"):format(v) end
  if v == "" then return '""' end
  if type(v) == "table" then
    local s = {}
    for i, x in ipairs(v) do s[i] = fmt(x) end
    return table.concat(s, ",")
  end
  return tostring(v)
end
M.fmt = fmt

-- The accepted range of a spec, as the messages and --help show it.
local function range_text(s)
  local u = s.unit and s.unit ~= "" and (" " .. s.unit) or ""
  if s.choices then return "one of " .. table.concat(s.choices, ", ") end
  if s.min and s.max then return ("[%s, %s]%s"):format(fmt(s.min), fmt(s.max), u) end
  if s.min then return (">= %s%s"):format(fmt(s.min), u) end
  if s.max then return ("<= %s%s"):format(fmt(s.max), u) end
  return u ~= "" and ("(%s)"):format(u:sub(2)) or ""
end
M.range_text = range_text

local function finite(v) return type(v) == "number" and v == v and v ~= math.huge and v ~= -math.huge end

local function in_range(v, s)
  return finite(v) and not (s.min and v < s.min) and not (s.max and v > s.max)
    and not (s.integer and v ~= math.floor(v))
end

local function refuse(name, what, v)
  error(("parameter '%s' must be %s, got %s"):format(name, what, type(v) == "string" and ("'" .. v .. "'") or fmt(v)), 0)
end

local function number_what(s, n)
  local a = s.integer and (n and (n .. " whole numbers") or "a whole number") or (n and (n .. " numbers") or "a number")
  local r = range_text(s)
  return r ~= "" and (a .. " in " .. r) or a
end

--- M.kind(default, spec) -> the kind of value a declaration accepts:
-- number, boolean, string, choice, vec, expr or auto (a number or "auto").
function M.kind(default, s)
  if s.kind then return s.kind end
  if s.choices then return "choice" end
  if s.n then return "vec" end
  if s.auto then return "auto" end
  local t = type(default)
  if t == "number" or t == "boolean" or t == "string" then return t end
  return "any"
end

--- M.check(name, value, spec [, default]) -> the value converted (vectors to
-- tables of numbers, numeric strings to numbers); raises naming the parameter
-- and the accepted range. spec: {unit=, help=, min=, max=, integer=true,
-- choices={...}, n= (vector length), one=true (with n: one number, or n
-- equal ones, is returned as a number), auto="text" (also accepts "auto"),
-- empty=true (expr: "" allowed), allow={type=true...} (other Lua types
-- passed through, e.g. ["function"]=true)}.
function M.check(name, v, s, default)
  if s.allow and s.allow[type(v)] then return v end
  local kind = M.kind(default, s)
  if kind == "any" then return v end
  if kind == "auto" then
    if v == "auto" or v == nil then return "auto" end
    local x = tonumber(v)
    if not in_range(x, s) then refuse(name, "auto (" .. s.auto .. ") or " .. number_what(s), v) end
    return x
  elseif kind == "number" then
    local x = type(v) == "number" and v or (type(v) == "string" and tonumber(v)) or nil
    if not in_range(x, s) then refuse(name, number_what(s), v) end
    return x
  elseif kind == "boolean" then
    if type(v) ~= "boolean" then refuse(name, "true or false", v) end
    return v
  elseif kind == "choice" then
    for _, c in ipairs(s.choices) do if v == c then return v end end
    local extra = s.allow and s.allow["function"] and " or a Lua function" or ""
    error(("parameter '%s' must be one of %s%s, got '%s'%s"):format(name, table.concat(s.choices, ", "), extra,
      tostring(v), type(v) == "string" and M.suggest(v, s.choices) or ""), 0)
  elseif kind == "vec" then
    if s.empty and v == "" then return "" end
    if s.one and (type(v) == "number" or (type(v) == "string" and not v:find(",")) or (type(v) == "table" and #v == 1)) then
      -- one number stands for all n (a cube cell): checked and returned as a number
      local x = tonumber(type(v) == "table" and v[1] or v)
      if not in_range(x, s) then refuse(name, number_what(s), x or v) end
      return x
    end
    local t = v
    if type(v) == "number" then
      t = {}
      for i = 1, s.n do t[i] = v end
    elseif type(v) == "string" then
      t = {}
      for item in v:gmatch("[^,]+") do t[#t + 1] = tonumber(item) or item end
    end
    local ok = type(t) == "table" and #t == s.n
    for i = 1, ok and s.n or 0 do ok = ok and in_range(t[i], s) end
    if not ok and s.one then
      refuse(name, ("a number or %d numbers in %s 'a,b,c'"):format(s.n, range_text(s)), v)
    end
    if not ok then refuse(name, number_what(s, s.n) .. " 'a,b,c'", v) end
    if s.one then -- n equal numbers are one (a cube cell given as L,L,L)
      local same = true
      for i = 2, s.n do same = same and t[i] == t[1] end
      if same then return t[1] end
    end
    return t
  elseif kind == "expr" then
    local x = type(v) == "number" and v or (type(v) == "string" and tonumber(v)) or nil
    if x then
      if not in_range(x, s) then refuse(name, number_what(s) .. " or an expression", v) end
      return v
    end
    if type(v) ~= "string" or (v:match("^%s*$") and not s.empty) then
      refuse(name, number_what(s) .. " or an expression in x, y, z, u, v, w, L", v)
    end
    return v
  elseif kind == "string" then
    if type(v) ~= "string" then refuse(name, "a string", v) end
    return v
  end
  return v
end

--- M.declare(ctx, name, default, spec): record a declaration in the job's
-- context (the last declaration of a name gives its default; unit and help
-- are kept from an earlier one). Returns the merged spec.
function M.declare(ctx, name, default, spec)
  ctx.decl = ctx.decl or { order = {}, by = {} }
  local d = ctx.decl.by[name]
  if not d then
    d = { name = name, spec = {} }
    ctx.decl.by[name] = d
    ctx.decl.order[#ctx.decl.order + 1] = name
  end
  d.default = default
  for k, v in pairs(spec or {}) do d.spec[k] = v end
  return d.spec
end

--- M.check_keys(t, known, src, marks, where): every key of the mapping t
-- must be in the set known; an unknown one raises "SRC:LINE:COL: unknown key
-- 'k' in WHERE (did you mean ...?)" with the position from marks (the second
-- result of gradus.yaml.load(path, {marks = true})), or "SRC: ..." without.
function M.check_keys(t, known, src, marks, where)
  if type(t) ~= "table" then return end
  local bad = {}
  for k in pairs(t) do
    if not known[k] then bad[#bad + 1] = tostring(k) end
  end
  if #bad == 0 then return end
  table.sort(bad, function(a, b)
    local ma, mb = marks and marks[t] and marks[t][a] or "", marks and marks[t] and marks[t][b] or ""
    if ma ~= mb then return ma < mb end
    return a < b
  end)
  local names = {}
  for k in pairs(known) do names[#names + 1] = k end
  table.sort(names)
  local k = bad[1]
  local pos = marks and marks[t] and marks[t][k]
  error(("%s%s: unknown key '%s' in %s%s; known keys: %s"):format(src, pos and (":" .. pos) or "", k, where,
    M.suggest(k, names), table.concat(names, ", ")), 0)
end

-- ---------------------------------------------------------------------
-- The strict parameter table
local values_of = setmetatable({}, { __mode = "k" })

--- M.table(decls, values, what): a table of parameters that accepts only the
-- declared names (decls: name -> spec, or a list of names); assigning or
-- reading another name raises with a suggestion. What names the table in
-- messages. A value the recipe assigns over one given with -D raises too
-- (the -D would silently do nothing).
function M.table(known, values, what)
  local names = {}
  for k in pairs(known) do names[#names + 1] = k end
  local function unknown(k, verb)
    error(("%s unknown parameter '%s' %s %s%s"):format(verb, tostring(k), verb == "assignment to" and "of" or "in",
      what, M.suggest(tostring(k), names)), 3)
  end
  local proxy = setmetatable({}, {
    __index = function(_, k)
      if not known[k] then unknown(k, "read of") end
      return values[k]
    end,
    __newindex = function(_, k, v)
      if not known[k] then unknown(k, "assignment to") end
      local g = gradus()
      local ctx = g and g._ctx
      -- a value other than the one gradus.param returned: the recipe fixes it
      if ctx and ctx.returned and ctx.returned[k] ~= nil and v ~= ctx.returned[k] then
        if ctx.help and ctx.decl and ctx.decl.by[k] then ctx.decl.by[k].fixed = true end
        if not ctx.help and ctx.params and ctx.params[k] ~= nil then
          error(("-D %s=%s has no effect: the recipe sets %s itself (to %s)"):format(k, tostring(ctx.params[k]), k, fmt(v)), 2)
        end
      end
      values[k] = v
    end,
    __pairs = function() return next, values, nil end,
    __name = "gradus.params",
  })
  values_of[proxy] = values
  return proxy
end

--- M.values(p) -> the plain table behind a strict table, or p itself.
function M.values(p) return values_of[p] or p end

-- ---------------------------------------------------------------------
-- The first action of a recipe
local STOP = setmetatable({}, { __tostring = function() return "gradus: recipe stopped" end })
M.STOP = STOP

local function unused(ctx)
  local out = {}
  for name in pairs(ctx.params or {}) do
    local free = false
    for _, pat in ipairs(ctx.extra or {}) do if name:match(pat) then free = true end end
    if not ctx.read[name] and not free then out[#out + 1] = name end
  end
  table.sort(out)
  return out
end

--- M.check_unused(ctx): every -D name must have been declared (read) by now.
-- An unknown name stops the job (raises STOP with ctx.stop set), unless
-- --allow-unused was given: then a warning, and the stats record it.
function M.check_unused(ctx)
  local bad = unused(ctx)
  if #bad == 0 then return end
  local known = {}
  for k in pairs(ctx.read) do known[#known + 1] = k end
  local lines = {}
  for _, name in ipairs(bad) do
    lines[#lines + 1] = ("-D %s=%s: %s does not declare '%s'%s"):format(name, tostring(ctx.params[name]),
      ctx.recipe or "the recipe", name, M.suggest(name, known))
  end
  if ctx.allow_unused then
    ctx.unused = bad
    for _, l in ipairs(lines) do io.stderr:write("gradus: warning: ", l, " (ignored: --allow-unused)\n") end
    return
  end
  ctx.stop = { msg = "gradus: " .. table.concat(lines, "\ngradus: ") ..
    ("\ngradus: nothing was written; 'gradus run %s --help' lists its parameters (--allow-unused runs anyway)")
      :format(ctx.recipe or "RECIPE") }
  error(STOP, 0)
end

--- M.action(what): called before the recipe does any work (engine call,
-- print, file operation). Under --help it stops the recipe; otherwise the
-- first one checks the -D names.
function M.action()
  local g = gradus()
  local ctx = g and g._ctx
  if not ctx or ctx.acted or not ctx.read then return end
  if ctx.help then
    ctx.stop = { help = true }
    error(STOP, 0)
  end
  M.check_unused(ctx)
  ctx.acted = true
end

-- Members of the gradus module a recipe may use while it declares its
-- parameters; everything else is an action. yaml.save writes: an action.
local DECLARE = { param = true, output = true, quiet = true, root = true, version = true, dirname = true,
  extra_params = true, help = true, _ctx = true }
local function guarded(t, free)
  return setmetatable({}, {
    __index = function(_, k)
      if not free(k) then M.action() end
      return t[k]
    end,
    __newindex = function(_, k, v) t[k] = v end,
  })
end

--- M.guard(env): guard a recipe environment: gradus, print, io and os
-- become views that call M.action() first where they do work.
function M.guard(env)
  local g = env.gradus
  local yaml = guarded(g.yaml, function(k) return k ~= "save" end)
  env.gradus = setmetatable({}, {
    __index = function(_, k)
      if k == "yaml" then return yaml end
      if not DECLARE[k] then M.action() end
      return g[k]
    end,
    __newindex = function(_, k, v) g[k] = v end,
  })
  local print0 = env.print
  env.print = function(...) M.action() return print0(...) end
  local io0 = env.io
  if io0 then
    env.io = guarded(io0, function(k) return k ~= "write" and k ~= "open" and k ~= "output" and k ~= "popen" end)
    local open0 = io0.open
    rawset(env.io, "open", function(path, mode, ...)
      if mode and mode:find("[wa+]") then M.action() end
      return open0(path, mode, ...)
    end)
  end
  local os0 = env.os
  if os0 then
    local acts = { execute = true, remove = true, rename = true, tmpname = true, exit = true }
    env.os = guarded(os0, function(k) return not acts[k] end)
  end
  return env
end

-- ---------------------------------------------------------------------
-- gradus run RECIPE --help
local function recipe_header(path)
  local f = io.open(path, "r")
  if not f then return {} end
  local out = {}
  for line in f:lines() do
    local c = line:match("^%-%-%s?(.*)$")
    if not c then break end
    out[#out + 1] = "  " .. c
  end
  f:close()
  return out
end

local function default_text(d)
  local s, v = d.spec, d.default
  if s.auto and (v == "auto" or v == nil) then return "auto: " .. s.auto end
  if v == "" then return '""' end
  local u = s.unit and s.unit ~= "" and (" " .. s.unit) or ""
  if type(v) == "table" or type(v) == "number" or tostring(v):match("^[%d%.,eE+-]+$") then return fmt(v) .. u end
  return tostring(v)
end

--- M.help_text(ctx): the recipe's description (its leading comment) and its
-- parameters: name, default, unit and accepted range, one line of help.
function M.help_text(ctx)
  local lines = { "recipe " .. tostring(ctx.recipe) }
  for _, l in ipairs(recipe_header(ctx.recipe)) do lines[#lines + 1] = l end
  lines[#lines + 1] = ""
  lines[#lines + 1] = "parameters (-D name=value; default in brackets):"
  local fixed = {}
  for _, name in ipairs(ctx.decl and ctx.decl.order or {}) do
    local d = ctx.decl.by[name]
    if d.fixed then
      fixed[#fixed + 1] = name
    else
      local r = d.spec.choices and ("one of " .. table.concat(d.spec.choices, ", "))
        or ((d.spec.min or d.spec.max) and range_text(d.spec)) or ""
      lines[#lines + 1] = ("  %-14s %-16s %s%s"):format(name, "[" .. default_text(d) .. "]",
        d.spec.help or "", r ~= "" and (" (" .. r .. ")") or "")
    end
  end
  if #fixed > 0 then
    lines[#lines + 1] = "set by the recipe itself (not parameters here): " .. table.concat(fixed, ", ")
  end
  for _, pat in ipairs(ctx.extra or {}) do
    lines[#lines + 1] = ("  (also any name matching the Lua pattern %s)"):format(pat)
  end
  lines[#lines + 1] = ""
  lines[#lines + 1] = "options: -o OUTPUT, --stats FILE, -q, --allow-unused (run despite unknown -D names)"
  return table.concat(lines, "\n")
end

return M
