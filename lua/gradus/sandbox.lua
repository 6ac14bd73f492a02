-- gradus.sandbox: `gradus run --sandbox`, for recipes from others. Without it
-- a recipe is trusted code: it can run programs, read and write any file the
-- user can, and load C code. With it:
--   * no process execution (os.execute, io.popen) and no os.exit;
--   * file writes only under the output directory (the directory of -o, of
--     --stats, or ./out when -o is not given) and in the knowledge base;
--   * file reads only under the recipe's directory, gradus's own files, the
--     output directory, the knowledge base and the inputs given (-D values
--     that name existing files);
--   * no C modules or binary chunks: `load`/`loadfile`/`dofile` take text
--     only, `require` only gradus's Lua modules, no `package` (loadlib) and
--     no `debug` (sethook); the environment's tables cannot be changed by
--     rawset or setmetatable, the string metatable is locked;
--   * limits: Lua instructions, wall-clock seconds of Lua, Lua memory (MiB)
--     (engine/main.c: a count hook and an allocator with a cap).
-- Each refusal is an error that names what was refused and why.
local gradus = require "gradus"
local fs = gradus.fs
local M = {}

M.defaults = { memory = 1024, instructions = 2e9, seconds = 600 }

local function dirname(p) return p:match("^(.*)/[^/]*$") or "." end

-- The absolute path of p without symbolic links, . or .. (p need not exist:
-- its nearest existing parent is resolved).
local function canonical(p)
  local real = fs.realpath(p)
  if real then return real end
  local parent, base = p:match("^(.*)/([^/]+)$")
  if not parent then parent, base = ".", p end
  if parent == "" then parent = "/" end
  if base == ".." or base == "." then return nil end
  local rp = canonical(parent)
  return rp and ((rp == "/" and "" or rp) .. "/" .. base)
end
M.canonical = canonical

local function under(path, dir)
  return path == dir or path:sub(1, #dir + 1) == (dir == "/" and "/" or dir .. "/")
end

--- M.policy{recipe=, output=, stats=, params=, kb=} -> the policy the
-- guards ask (policy:allow(path, mode)).
function M.policy(o)
  local pol = { read = {}, write = {}, files = {} }
  local function add(list, d)
    local c = d and canonical(d)
    if c then list[#list + 1] = c end
  end
  add(pol.read, dirname(o.recipe))
  add(pol.read, gradus.root)
  local outdirs = {}
  if o.output then outdirs[#outdirs + 1] = dirname(o.output) else outdirs[#outdirs + 1] = "out" end
  if o.stats then outdirs[#outdirs + 1] = dirname(o.stats) end
  for _, d in ipairs(outdirs) do
    gradus.mkdir(d)
    add(pol.write, d)
  end
  add(pol.write, o.kb or gradus.kb.default_dir())
  for _, d in ipairs(pol.write) do pol.read[#pol.read + 1] = d end
  for _, v in pairs(o.params or {}) do
    if type(v) == "string" and fs.kind(v) == "file" then pol.files[canonical(v)] = true end
  end
  pol.outdirs = pol.write
  return setmetatable(pol, { __index = M })
end

function M.allow(pol, path, mode)
  local c = canonical(tostring(path))
  if mode == "w" then
    for _, d in ipairs(pol.write) do if c and under(c, d) then return true end end
    error(("sandbox: writing '%s' refused (writes only under %s)"):format(path, table.concat(pol.write, ", ")), 0)
  end
  if c and pol.files[c] then return true end
  for _, d in ipairs(pol.read) do if c and under(c, d) then return true end end
  error(("sandbox: reading '%s' refused (reads only under the recipe's directory, the output directory and the inputs given)")
    :format(path), 0)
end

local function refused(name, why)
  return function() error(("sandbox: %s refused (%s)"):format(name, why), 2) end
end

-- A read-only view of t: the recipe sees t's values; assignments raise.
local function frozen(t, name, wrap)
  local view = {}
  for k, v in pairs(t) do view[k] = (wrap and wrap[k]) or v end
  return setmetatable({}, {
    __index = view,
    __newindex = function(_, k) error(("sandbox: changing %s.%s refused"):format(name, tostring(k)), 2) end,
    __metatable = "sandboxed",
    __pairs = function() return next, view, nil end,
  })
end

-- gradus as the recipe sees it: no term (the limits), no fs clear_interrupt;
-- sub-libraries read-only.
local function gradus_view(pol)
  local view = {}
  for k, v in pairs(gradus) do
    if k ~= "term" and k ~= "_ctx" then
      view[k] = (type(v) == "table" and k ~= "fs") and frozen(v, "gradus." .. k) or v
    end
  end
  view.fs = frozen({ kind = fs.kind, refusal = fs.refusal }, "gradus.fs")
  view.mkdir = function(p) pol:allow(p, "w") return gradus.mkdir(p) end
  return frozen(view, "gradus")
end

--- M.env(pol) -> the recipe's environment (undeclared globals raise, as
-- without the sandbox).
function M.env(pol)
  local function check(path, mode) return pol:allow(path, mode) end
  local io_open = io.open
  local sio = {
    open = function(path, mode)
      mode = mode or "r"
      check(path, mode:match("[wa+]") and "w" or "r")
      if mode:match("[wa+]") then gradus.outputs.check(path) end
      return io_open(path, mode)
    end,
    lines = function(path, ...)
      if path ~= nil then check(path, "r") end
      return io.lines(path, ...)
    end,
    read = io.read, write = io.write, type = io.type, stdout = io.stdout, stderr = io.stderr,
    popen = refused("io.popen", "no process execution"),
    input = function(f) if f ~= nil then error("sandbox: io.input with a file refused (use io.open)", 2) end return io.input() end,
    output = function(f) if f ~= nil then error("sandbox: io.output with a file refused (use io.open)", 2) end return io.output() end,
  }
  local sos = {
    time = os.time, clock = os.clock, date = os.date, difftime = os.difftime, getenv = os.getenv,
    remove = function(p) check(p, "w") return os.remove(p) end,
    rename = function(a, b) check(a, "w") check(b, "w") return os.rename(a, b) end,
    execute = refused("os.execute", "no process execution"),
    exit = refused("os.exit", "the host ends the job"),
    tmpname = refused("os.tmpname", "writes only under the output directory"),
  }
  local env
  local function sload(chunk, name, mode, e)
    if mode ~= nil and mode ~= "t" then error("sandbox: load in mode '" .. tostring(mode) .. "' refused (text chunks only, no binary chunks)", 2) end
    return load(chunk, name, "t", e or env)
  end
  local function sloadfile(path, mode, e)
    check(path, "r")
    if mode ~= nil and mode ~= "t" then error("sandbox: loadfile in mode '" .. tostring(mode) .. "' refused (text only)", 2) end
    return loadfile(path, "t", e or env)
  end
  local function srequire(name)
    name = tostring(name)
    if name == "gradus" then return env.gradus end
    if not name:match("^gradus%.[%w_]+$") or not package.searchpath(name, package.path) then
      error(("sandbox: require '%s' refused (only gradus's Lua modules; no C modules)"):format(name), 2)
    end
    local mod = require(name)
    return type(mod) == "table" and frozen(mod, name) or mod
  end
  -- a limit reached or Ctrl-C is not the recipe's to catch
  local function stopping() return (gradus.term and gradus.term.limit_reached()) or fs.interrupted() ~= 0 end
  local function pass(ok, ...)
    if not ok and stopping() then error((...), 0) end
    return ok, ...
  end
  local base = {
    pcall = function(...) return pass(pcall(...)) end,
    xpcall = function(...) return pass(xpcall(...)) end,
    assert = assert, error = error, ipairs = ipairs, next = next, pairs = pairs, print = print,
    rawequal = rawequal, rawlen = rawlen, select = select, tonumber = tonumber, tostring = tostring,
    type = type, _VERSION = _VERSION, getmetatable = getmetatable,
    collectgarbage = function(opt) if opt == nil or opt == "collect" or opt == "count" then return collectgarbage(opt) end
      error("sandbox: collectgarbage('" .. tostring(opt) .. "') refused", 2) end,
    rawget = rawget,
    rawset = function(t, k, v)
      if t == env or getmetatable(t) == "sandboxed" then
        error(("sandbox: rawset of '%s' on a sandbox table refused (declare it with 'local')"):format(tostring(k)), 2)
      end
      return rawset(t, k, v)
    end,
    setmetatable = function(t, mt)
      if t == env then error("sandbox: setmetatable of the environment refused", 2) end
      return setmetatable(t, mt)
    end,
    load = sload, loadfile = sloadfile,
    dofile = function(path) local f, err = sloadfile(path) if not f then error(err, 2) end return f() end,
    require = srequire,
    math = frozen(math, "math"), string = frozen(string, "string"), table = frozen(table, "table"),
    utf8 = frozen(utf8, "utf8"),
    coroutine = frozen(coroutine, "coroutine", { resume = function(...) return pass(coroutine.resume(...)) end }),
    io = frozen(sio, "io"), os = frozen(sos, "os"),
    debug = frozen({ traceback = debug.traceback }, "debug"),
    gradus = gradus_view(pol),
  }
  env = setmetatable({}, {
    __index = function(_, k)
      local v = base[k]
      if v == nil then
        if k == "package" then error("sandbox: 'package' refused (no C modules: package.loadlib, package.cpath)", 2) end
        error("read of undeclared global '" .. tostring(k) .. "'", 2)
      end
      return v
    end,
    __newindex = function(_, k)
      error("assignment to undeclared global '" .. tostring(k) .. "' (declare it with 'local')", 2)
    end,
    __metatable = "sandboxed",
  })
  base._G = env
  return env
end

--- M.start(ctx, opts): the policy on ctx (the guards ask it), the string
-- metatable locked, the limits set. opts: memory (MiB), instructions, seconds.
function M.start(ctx, opts)
  ctx.sandbox = M.policy { recipe = ctx.recipe, output = ctx.output, stats = ctx.stats, params = ctx.params }
  debug.getmetatable("").__metatable = "sandboxed"
  local lim = {}
  for k, v in pairs(M.defaults) do lim[k] = (opts and opts[k]) or v end
  lim.library = gradus.root and (gradus.root .. "/lua/") or ""
  if gradus.term then gradus.term.limits(lim) end
  return ctx.sandbox
end

function M.stop()
  if gradus.term then gradus.term.limits {} end
end

return M
