-- gradus.host: the `gradus` command line: run, REPL, help, version, and the
-- sub-commands (cli, kb, sweep) found in gradus.commands.
local gradus = require "gradus"
local M = {}

local USAGE = [[
usage: gradus run RECIPE [-D name=value]... [-o OUTPUT] [--stats FILE] [-q] [--allow-unused]
                   [--sandbox] [--limits memory=MiB,instructions=N,seconds=S]
       gradus run RECIPE --help    the recipe's parameters: defaults, units, ranges
       gradus sweep RECIPE -D name=v1,v2,... -D other=a:b:step [-j N] [-o DIR]
       gradus run RECIPE ... -o FILE --slurm N   N layer ranges as a Slurm array (doc/cluster.md)
       gradus sweep ... --slurm [--partition P] [--time T] [--mem M] [--max-tasks N]
       gradus info FILE            layers, z range, blocks, vectors and lengths of a CLI or OVF file
       gradus convert IN OUT [--format ascii|binary|ovf]   CLI <-> OVF (format from OUT's extension)
       gradus cli info FILE        the same as gradus info FILE
       gradus cli cat PART.cli... -o FILE [--stats FILE]   merge layer-range parts
       gradus view FILE [-o HTML]  the layers in a browser page (--serve [--port N]: over HTTP)
       gradus kb list|show KEY|verify|prune [--dir DIR]
       gradus                      interactive Lua prompt with gradus loaded
       gradus --version | help

Recipes are Lua files (see recipes/ and doc/guide.md). They read -D values
with gradus.param(name, default [, spec]); -o with gradus.output(default).
A -D name the recipe does not declare is an error (nothing is written).
Recipes are trusted code (they can run programs and write any file);
run recipes from others with --sandbox (doc/safety.md).]]

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
  require("gradus.strict").guard(base)
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

--- Run a recipe file with parameters. opts: output, stats, quiet, help
-- (list the recipe's parameters instead of running it), allow_unused, sandbox
-- (true or {memory = MiB, instructions = n, seconds = s}: gradus.sandbox).
-- Returns true, or false, the error message and the job's context.
function M.run(path, params, opts)
  opts = opts or {}
  local strict = require "gradus.strict"
  local ctx = { params = params or {}, read = {}, output = opts.output, stats = opts.stats,
    quiet = opts.quiet, recipe = path, help = opts.help, allow_unused = opts.allow_unused }
  local saved = gradus._ctx
  gradus._ctx = ctx
  local env, sandbox = M.recipe_env(), nil
  if opts.sandbox then
    sandbox = require "gradus.sandbox"
    local sok, serr = pcall(sandbox.start, ctx, type(opts.sandbox) == "table" and opts.sandbox or nil)
    if not sok then gradus._ctx = saved return false, "gradus: --sandbox: " .. tostring(serr), ctx end
    env = sandbox.env(ctx.sandbox)
  end
  local chunk, err = loadfile(path, "t", env)
  local ok = chunk ~= nil
  if chunk then ok, err = xpcall(chunk, handler) end
  if sandbox then
    local limit = gradus.term and gradus.term.limit_reached()
    sandbox.stop()
    if not ok and limit and not tostring(err):find("sandbox: ", 1, true) then
      err = ("sandbox: %s (%s)"):format(limit, tostring(err))
    end
  end
  -- unknown -D names stop the job at its first action (gradus.strict); a
  -- recipe that did nothing is checked here
  if ok and not ctx.help and not ctx.acted then ok, err = pcall(strict.check_unused, ctx) end
  gradus._ctx = saved
  if ctx.stop and ctx.stop.help or (ok and ctx.help) then print(strict.help_text(ctx)) return true end
  if ctx.stop then return false, ctx.stop.msg, ctx end
  if not ok then return false, err, ctx end
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
    elseif a == "--help" or a == "-h" then
      o.help = true
    elseif a == "--allow-unused" then
      o.allow_unused = true
    elseif a == "-q" or a == "--quiet" then
      o.quiet = true
    elseif a == "--sandbox" then
      o.sandbox = o.sandbox or true
    elseif a == "--limits" then -- memory=MiB,instructions=N,seconds=S (implies --sandbox)
      local lim = {}
      for k, v in value():gmatch("(%a+)=([^,]+)") do lim[k] = tonumber(v) end
      o.sandbox = lim
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
  for _, a in ipairs(args) do
    if a == "--slurm" then return require("gradus.slurm").run_cmd(args) end -- doc/cluster.md
  end
  local ok, o = pcall(M.parse_args, args, 2)
  if not ok then eprint("gradus: " .. o) eprint(USAGE) return 2 end
  local recipe = o.rest[1]
  if not recipe then eprint("gradus: run needs a recipe file") eprint(USAGE) return 2 end
  if #o.rest > 1 then eprint("gradus: unexpected argument " .. o.rest[2]) return 2 end
  local f = io.open(recipe, "r")
  if not f then eprint("gradus: cannot open recipe " .. recipe) return 1 end
  f:close()
  local rok, err, ctx = M.run(recipe, o.params, o)
  if not rok then
    eprint(err)
    if gradus.fs.interrupted() ~= 0 then
      local gone = ctx and ctx.removed_temporaries or {}
      eprint(("gradus: stopped by Ctrl-C; no output was replaced%s"):format(#gone > 0 and
        ("; temporaries removed: " .. table.concat(gone, ", ")) or ""))
      return 130
    end
    return 1
  end
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
      gradus.fs.clear_interrupt() -- a Ctrl-C at the prompt does not stop the next command
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
