-- gradus.host: the `gradus` command line: run, REPL, help, version, and the
-- sub-commands (cli, kb, sweep) found in gradus.commands.
local gradus = require "gradus"
local M = {}

local USAGE = [[
usage: gradus run RECIPE [-D name=value]... [-o OUTPUT] [--stats FILE] [-q]
       gradus sweep RECIPE -D name=v1,v2,... -D other=a:b:step [-j N] [-o DIR]
       gradus info FILE            layers, z range, blocks, vectors and lengths of a CLI or OVF file
       gradus convert IN OUT [--format ascii|binary|ovf]   CLI <-> OVF (format from OUT's extension)
       gradus cli info FILE        the same as gradus info FILE
       gradus kb list|show KEY|verify|prune [--dir DIR]
       gradus                      interactive Lua prompt with gradus loaded
       gradus --version | help

Recipes are Lua files (see recipes/ and doc/guide.md). They read -D values
with gradus.param(name, default); -o with gradus.output(default).]]

local function eprint(...)
  io.stderr:write(table.concat({ ... }, " "), "\n")
end

-- Is this source one of gradus's own Lua files?
local libdir = gradus.root and (gradus.root .. "/lua/") or nil
local function is_library(src)
  return src == "=[C]" or src:sub(1, 1) ~= "@" or (libdir and src:sub(2, #libdir + 1) == libdir)
    or src:match("^@.-/lua/gradus/[^/]+%.lua$") ~= nil
end

-- The first frame above `level` that is the user's Lua code.
local function user_frame(level)
  while true do
    local info = debug.getinfo(level, "Sl")
    if not info then return nil end
    if info.currentline and info.currentline > 0 and not is_library(info.source) then
      return info
    end
    level = level + 1
  end
end

-- Error handler for recipes: the message points at the recipe's line (not
-- the C frame or the library), followed by a short traceback of user frames.
local function handler(err)
  local msg = type(err) == "string" and err or tostring(err)
  local info = user_frame(3)
  local pos = msg:match("^([^\n:]+:%d+): ")
  if info then
    local here = info.short_src .. ":" .. info.currentline
    if not pos then
      msg = here .. ": " .. msg
    elseif pos ~= here and is_library("@" .. pos:match("^(.-):%d+$")) then
      msg = here .. ": " .. msg:sub(#pos + 3)
    end
  end
  local lines = {}
  local level = 3
  while #lines < 6 do
    local fi = debug.getinfo(level, "Sln")
    if not fi then break end
    if fi.currentline and fi.currentline > 0 and not is_library(fi.source) then
      lines[#lines + 1] = string.format("  %s:%d: in %s", fi.short_src, fi.currentline,
        fi.name and ("function '" .. fi.name .. "'") or (fi.what == "main" and "main chunk" or "function"))
    end
    level = level + 1
  end
  if #lines > 1 then msg = msg .. "\ntraceback:\n" .. table.concat(lines, "\n") end
  return msg
end
M.handler = handler

-- The environment of a recipe: chosen globals plus gradus; reading or
-- assigning an undeclared global raises.
local SAFE = { "assert", "error", "ipairs", "next", "pairs", "pcall", "print", "rawequal",
  "rawget", "rawlen", "rawset", "select", "setmetatable", "getmetatable", "tonumber",
  "tostring", "type", "xpcall", "require", "math", "string", "table", "utf8", "os", "io",
  "coroutine", "debug", "load", "dofile", "collectgarbage", "_VERSION" }
function M.recipe_env()
  local base = { gradus = gradus }
  for _, k in ipairs(SAFE) do base[k] = _G[k] end
  base._G = base
  return setmetatable({}, {
    __index = function(_, k)
      local v = base[k]
      if v == nil then error("read of undeclared global '" .. tostring(k) .. "'", 2) end
      return v
    end,
    __newindex = function(_, k)
      error("assignment to undeclared global '" .. tostring(k) .. "' (declare it with 'local')", 2)
    end,
  })
end

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

--- Run a recipe file with parameters. opts: output, stats, quiet.
-- Returns true, or false and the error message.
function M.run(path, params, opts)
  opts = opts or {}
  local ctx = { params = params or {}, read = {}, output = opts.output, stats = opts.stats,
    quiet = opts.quiet, recipe = path }
  local saved = gradus._ctx
  gradus._ctx = ctx
  local chunk, err = loadfile(path, "t", M.recipe_env())
  local ok = chunk ~= nil
  if chunk then ok, err = xpcall(chunk, handler) end
  gradus._ctx = saved
  if not ok then return false, err end
  -- -D names never read: probable typos
  local known = {}
  for k in pairs(ctx.read) do known[#known + 1] = k end
  table.sort(known)
  for name in pairs(ctx.params) do
    if not ctx.read[name] then
      local best, bd = nil, 3
      for _, k in ipairs(known) do
        local d = edit_distance(name, k)
        if d < bd then best, bd = k, d end
      end
      eprint(string.format("gradus: warning: -D %s was never read by %s (a typo?%s)", name, path,
        best and (" did you mean '" .. best .. "'?") or ""))
    end
  end
  return true
end

-- Parse "-D name=value", "-Dname=value", "-o X", "--stats X", "-q", "-j N".
function M.parse_args(args, first)
  local o = { params = {}, order = {}, rest = {} }
  local i = first
  while i <= #args do
    local a = args[i]
    local function value()
      i = i + 1
      if args[i] == nil then error("option " .. a .. " needs a value", 0) end
      return args[i]
    end
    if a == "-D" or a:match("^%-D.") then
      local kv = a == "-D" and value() or a:sub(3)
      local k, v = kv:match("^([%w_%.]+)=(.*)$")
      if not k then error("bad -D '" .. kv .. "': expected name=value", 0) end
      if o.params[k] == nil then o.order[#o.order + 1] = k end
      o.params[k] = v
    elseif a == "-o" or a == "--output" then
      o.output = value()
    elseif a == "--stats" then
      o.stats = value()
    elseif a == "-q" or a == "--quiet" then
      o.quiet = true
    elseif a == "-j" then
      o.jobs = tonumber(value())
      if not o.jobs or o.jobs < 1 then error("-j needs a positive number", 0) end
    elseif a:sub(1, 1) == "-" and #a > 1 then
      error("unknown option " .. a, 0)
    else
      o.rest[#o.rest + 1] = a
    end
    i = i + 1
  end
  return o
end

local function cmd_run(args)
  local ok, o = pcall(M.parse_args, args, 2)
  if not ok then eprint("gradus: " .. o) eprint(USAGE) return 2 end
  local recipe = o.rest[1]
  if not recipe then eprint("gradus: run needs a recipe file") eprint(USAGE) return 2 end
  if #o.rest > 1 then eprint("gradus: unexpected argument " .. o.rest[2]) return 2 end
  local f = io.open(recipe, "r")
  if not f then eprint("gradus: cannot open recipe " .. recipe) return 1 end
  f:close()
  local rok, err = M.run(recipe, o.params, o)
  if not rok then eprint(err) return 1 end
  return 0
end

-- REPL ------------------------------------------------------------------
local function show(v, depth, seen)
  depth = depth or 0
  seen = seen or {}
  local t = type(v)
  if t == "string" then return string.format("%q", v) end
  if t ~= "table" then return tostring(v) end
  local mt = getmetatable(v)
  if mt and mt.__tostring then return tostring(v) end
  if seen[v] or depth > 2 then return tostring(v) end
  seen[v] = true
  local parts, n = {}, 0
  for i, x in ipairs(v) do
    n = n + 1
    if n > 20 then parts[#parts + 1] = "..." break end
    parts[#parts + 1] = show(x, depth + 1, seen)
  end
  for k, x in pairs(v) do
    if not (math.type(k) == "integer" and k >= 1 and k <= #v) then
      n = n + 1
      if n > 40 then parts[#parts + 1] = "..." break end
      local key = (type(k) == "string" and k:match("^[%a_][%w_]*$")) and k or ("[" .. show(k, depth + 1, seen) .. "]")
      parts[#parts + 1] = key .. " = " .. show(x, depth + 1, seen)
    end
  end
  return "{" .. table.concat(parts, ", ") .. "}"
end
M.show = show

function M.repl()
  local term = gradus.term
  local tty = term.isatty(0)
  local hist = os.getenv("HOME") and (os.getenv("HOME") .. "/.gradus_history")
  if tty then
    print("Gradus " .. gradus.version .. " (Lua 5.4). help(gradus) lists the module; Ctrl-D quits.")
    if hist then term.read_history(hist) end
  end
  local env = setmetatable({ gradus = gradus,
    help = function(x) print(gradus.help(x == nil and gradus or x)) end }, { __index = _G })
  while true do
    local line = term.readline(tty and "> " or "")
    if not line then break end
    local src = line
    local chunk, err
    while true do
      chunk, err = load("return " .. src, "=stdin", "t", env)
      if not chunk then chunk, err = load(src, "=stdin", "t", env) end
      if chunk or not err:match("<eof>$") then break end
      local more = term.readline(tty and ">> " or "")
      if not more then break end
      src = src .. "\n" .. more
    end
    term.add_history(src)
    if not chunk then
      print(err)
    else
      local res = table.pack(xpcall(chunk, function(e) return tostring(e) end))
      if not res[1] then
        print(res[2])
      elseif res.n > 1 then
        local out = {}
        for i = 2, res.n do out[#out + 1] = show(res[i]) end
        print(table.concat(out, "\t"))
      end
    end
  end
  if tty and hist then term.write_history(hist) end
  return 0
end

function M.main(args)
  local cmd = args[1]
  if cmd == nil then return M.repl() end
  if cmd == "--version" or cmd == "version" then
    print("gradus " .. gradus.version .. " (" .. _VERSION .. ")")
    return 0
  elseif cmd == "help" or cmd == "--help" or cmd == "-h" then
    print(USAGE)
    return 0
  elseif cmd == "run" then
    return cmd_run(args)
  end
  local ok, commands = pcall(require, "gradus.commands")
  if ok and commands[cmd] then
    local cok, rc = xpcall(commands[cmd], handler, args)
    if not cok then eprint("gradus: " .. tostring(rc)) return 1 end
    return rc or 0
  end
  eprint("gradus: unknown command '" .. tostring(cmd) .. "'")
  eprint(USAGE)
  return 2
end

return M
