-- gradus.view: `gradus view FILE.cli [-o FILE.html] | --serve [--port N]`.
-- The page (lua/gradus/view.html, read from the tree at run time) gets the
-- file's layers in the viewer encoding (engine/view.h), base64 in the page,
-- or one layer per request from the server (engine/view_serve.c); the job's
-- manifest and stats are added when they sit beside the CLI.
local gradus = require "gradus"
local M = {}

M.USAGE = "usage: gradus view FILE.cli [-o FILE.html] [--manifest FILE] [--stats FILE]\n" ..
  "       gradus view FILE.cli --serve [--port N]   (127.0.0.1; N = 0: any free port)"
M.QUANTUM = 1e-4 -- mm: coordinates in the page are multiples of 0.1 um
M.DEFAULT_PORT = 8765

local function eprint(...) io.stderr:write(table.concat({ ... }, " "), "\n") end

-- JSON text of a Lua value (tables with 1..n keys are arrays). '<', '>' and
-- '&' are escaped so that the text can sit inside a <script> element.
local function json(v, out)
  local t = type(v)
  if t == "table" then
    local n = #v
    if n > 0 or next(v) == nil then
      out[#out + 1] = "["
      for i = 1, n do
        if i > 1 then out[#out + 1] = "," end
        json(v[i], out)
      end
      out[#out + 1] = "]"
    else
      local keys = {}
      for k in pairs(v) do keys[#keys + 1] = tostring(k) end
      table.sort(keys)
      out[#out + 1] = "{"
      for i, k in ipairs(keys) do
        if i > 1 then out[#out + 1] = "," end
        json(k, out)
        out[#out + 1] = ":"
        local val = v[k]
        if val == nil then val = v[tonumber(k)] end
        json(val, out)
      end
      out[#out + 1] = "}"
    end
  elseif t == "string" then
    out[#out + 1] = '"' .. v:gsub('[%c"\\<>&]', function(c)
      local map = { ['"'] = '\\"', ["\\"] = "\\\\", ["\n"] = "\\n", ["\t"] = "\\t", ["\r"] = "\\r" }
      return map[c] or string.format("\\u%04x", c:byte())
    end) .. '"'
  elseif t == "number" then
    if v ~= v or v == math.huge or v == -math.huge then out[#out + 1] = "null"
    elseif math.type(v) == "integer" then out[#out + 1] = tostring(v)
    else out[#out + 1] = string.format("%.10g", v) end
  elseif t == "boolean" then
    out[#out + 1] = tostring(v)
  else
    out[#out + 1] = "null"
  end
  return out
end
function M.json(v) return table.concat(json(v, {})) end

local function exists(path)
  local f = io.open(path, "rb")
  if f then f:close() return true end
  return false
end

-- The manifest and stats beside FILE.cli: FILE.manifest.yaml and FILE.yaml
-- (what `gradus run -o FILE.cli --stats FILE.yaml` writes). An explicit path
-- must exist and parse; one found beside the CLI is skipped when it does not
-- parse (with a warning).
local function side_file(explicit, guess, what)
  if explicit then return gradus.yaml.load(explicit) end
  if not exists(guess) then return nil end
  local ok, v = pcall(gradus.yaml.load, guess)
  if ok and type(v) == "table" then return v end
  eprint("gradus: view: " .. what .. " " .. guess .. " skipped: " .. tostring(v))
  return nil
end

-- The page template, from the tree (lua/gradus/view.html).
local function template()
  local dir = gradus.root and (gradus.root .. "/lua/gradus/") or "lua/gradus/"
  local f, err = io.open(dir .. "view.html", "rb")
  if not f then error("cannot read the page template: " .. tostring(err), 0) end
  local s = f:read("a")
  f:close()
  return s
end

local MARK = "<!--GRADUS-DATA-->"

--- The page's data table for a CLI index (see doc/formats.md).
function M.data(ix, opts)
  opts = opts or {}
  local info = ix:info()
  local base = info.path:gsub("%.[Cc][Ll][Ii]$", "")
  local d = {
    version = 1, file = info.path:match("[^/]*$"), format = info.format, units = info.units,
    layers = info.layers, z = info.z, dimension = info.dimension, quantum = opts.quantum or M.QUANTUM,
    served = opts.served and true or false, bytes = info.bytes,
  }
  d.manifest = side_file(opts.manifest, base .. ".manifest.yaml", "manifest")
  d.stats = side_file(opts.stats, base .. ".yaml", "stats")
  if not d.served then
    local data, lo, hi = {}, { math.huge, math.huge }, { -math.huge, -math.huge }
    for k = 1, info.layers do
      local s, bb = ix:layer(k, d.quantum)
      data[k] = s
      if bb[3] >= bb[1] then
        lo[1], lo[2] = math.min(lo[1], bb[1]), math.min(lo[2], bb[2])
        hi[1], hi[2] = math.max(hi[1], bb[3]), math.max(hi[2], bb[4])
      end
    end
    d.data = data
    if hi[1] >= lo[1] then d.bbox = { lo[1], lo[2], hi[1], hi[2] } end
  end
  return d
end

--- The HTML page for a data table.
function M.page(d)
  local t = template()
  local at = t:find(MARK, 1, true)
  if not at then error("the page template has no " .. MARK .. " marker", 0) end
  return t:sub(1, at - 1) .. '<script id="gradus-data" type="application/json">' .. M.json(d) .. "</script>" ..
    t:sub(at + #MARK)
end

--- Write the self-contained page for cli to out (atomically); returns the data table.
function M.write(cli, out, opts)
  local ix <close> = gradus.view.open(cli)
  local d = M.data(ix, opts)
  gradus.write_file(out, M.page(d))
  return d
end

--- Serve the page and the layers of cli until Ctrl-C.
function M.serve(cli, port, opts)
  local ix <close> = gradus.view.open(cli)
  local d = M.data(ix, { served = true, manifest = opts and opts.manifest, stats = opts and opts.stats })
  ix:serve { page = M.page(d), port = port, quantum = d.quantum, ready = function(p)
    io.stdout:write(("gradus view: %s (%d layers) at http://127.0.0.1:%d/  (Ctrl-C ends)\n"):format(cli, d.layers, p))
    io.stdout:flush()
  end }
  io.stdout:write("gradus view: stopped\n")
  return d
end

-- Headless Chromium on a page (used by the tests and `make bench`): the
-- page's state (window.gradusView, published as JSON in #gradus-state) as a
-- table, the DOM text and Chromium's log (console messages included).
-- o.dir: a scratch directory (the profile goes there and is removed);
-- o.screenshot: PNG path; o.size: "W,H" (default 1200,800); o.virtual:
-- a virtual-time budget in ms (waits for fetches and timers without real
-- waiting; timings then mean nothing); o.timeout: seconds before Chromium
-- is killed (default 240). Returns state, dom, log or nil, message.
M.CHROMIUM = "chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run " ..
  "--disable-background-networking --disable-component-update --disable-sync --disable-extensions " ..
  "--force-device-scale-factor=1 --hide-scrollbars --enable-logging=stderr --v=0"
local function q(s) return "'" .. tostring(s):gsub("'", "'\\''") .. "'" end
function M.chromium(url, o)
  o = o or {}
  local dir = o.dir or os.getenv("TMPDIR") or "/tmp"
  local prof = ("%s/chromium.%d.%d"):format(dir, os.time(), math.random(1e9))
  local dom, log = prof .. ".dom", prof .. ".log"
  local cmd = ("timeout -k 10 %d %s --user-data-dir=%s --window-size=%s %s %s --dump-dom %s >%s 2>%s")
    :format(o.timeout or 240, M.CHROMIUM, q(prof), o.size or "1200,800",
      o.virtual and ("--virtual-time-budget=" .. o.virtual) or "",
      o.screenshot and ("--screenshot=" .. q(o.screenshot)) or "", q(url), q(dom), q(log))
  local ok = os.execute(cmd)
  local function slurp(p)
    local f = io.open(p, "rb")
    if not f then return "" end
    local t = f:read("a")
    f:close()
    return t
  end
  local dtext, ltext = slurp(dom), slurp(log)
  os.execute("rm -rf " .. q(prof) .. " " .. q(dom) .. " " .. q(log))
  local js = dtext:match('<pre id="gradus%-state"[^>]*>(.-)</pre>')
  if not js or js == "" then
    return nil, ("no page state from chromium (%s); log: %s"):format(ok and "exit 0" or "failed", ltext:sub(-600))
  end
  js = js:gsub("&quot;", '"'):gsub("&lt;", "<"):gsub("&gt;", ">"):gsub("&amp;", "&")
  return gradus.yaml.decode(js, "page state"), dtext, ltext
end

local function parse(args)
  local o, i = {}, 2
  while i <= #args do
    local a = args[i]
    if a == "-o" or a == "--port" or a == "--manifest" or a == "--stats" then
      if not args[i + 1] then return nil, a .. " needs a value" end
      o[a] = args[i + 1]
      i = i + 2
    elseif a == "--serve" then
      o.serve = true
      i = i + 1
    elseif a:sub(1, 1) == "-" then
      return nil, "unknown option " .. a
    elseif o.cli then
      return nil, "one CLI file at a time (got " .. o.cli .. " and " .. a .. ")"
    else
      o.cli = a
      i = i + 1
    end
  end
  if not o.cli then return nil, "no CLI file given" end
  if o["--port"] and not o.serve then return nil, "--port needs --serve" end
  if o["-o"] and o.serve then return nil, "-o and --serve exclude each other" end
  return o
end

-- A file that cannot be read or written: said without our own source's position; exit status 1.
local function failed(e)
  eprint("gradus: view: " .. (tostring(e):gsub("^[^\n]-%.lua:%d+: ", "")))
  return 1
end

--- gradus view ...: returns the exit status.
function M.main(args)
  local o, err = parse(args)
  if not o then eprint("gradus: view: " .. err .. "\n" .. M.USAGE) return 2 end
  local opts = { manifest = o["--manifest"], stats = o["--stats"] }
  if o.serve then
    local port = M.DEFAULT_PORT
    if o["--port"] then
      port = math.tointeger(tonumber(o["--port"]))
      if not port or port < 0 or port > 65535 then
        eprint("gradus: view: --port needs a number 0..65535, got '" .. o["--port"] .. "'")
        return 2
      end
    end
    local ok, e = pcall(M.serve, o.cli, port, opts)
    if not ok then return failed(e) end
    return 0
  end
  local out = o["-o"] or (o.cli:gsub("%.[Cc][Ll][Ii]$", "") .. ".html")
  if out == o.cli then out = o.cli .. ".html" end
  local ok, d = pcall(M.write, o.cli, out, opts)
  if not ok then return failed(d) end
  print(("gradus view: %s (%d layers) -> %s"):format(o.cli, d.layers, out))
  return 0
end

return M
