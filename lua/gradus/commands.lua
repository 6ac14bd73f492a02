-- gradus.commands: the sub-commands `gradus cli ...`, `gradus kb ...` and
-- `gradus sweep ...`. Each takes the whole argument list and returns an exit
-- status.
local gradus = require "gradus"
local M = {}

local function eprint(...) io.stderr:write(table.concat({ ... }, " "), "\n") end

local function fmt_len(mm) return string.format("%.3f m", mm / 1000) end

--- gradus cli info FILE: what a CLI file holds.
function M.cli(args)
  local sub, path = args[2], args[3]
  if sub ~= "info" or not path then
    eprint("usage: gradus cli info FILE")
    return 2
  end
  local ok, info = pcall(gradus.cli.info, path)
  if not ok then eprint("gradus: " .. tostring(info)) return 1 end
  print(gradus.yaml.encode(info))
  return 0
end

local KB_USAGE = "usage: gradus kb list|verify [DIR] | show KEY [DIR] | prune [--older-than DAYS] [DIR]" ..
  " (DIR also as --dir DIR; default: the user's cache)"

-- gradus kb arguments: positional words and --dir/--older-than options;
-- nil, message on anything else
local function kb_args(args)
  local pos, o, i = {}, {}, 3
  while i <= #args do
    local a = args[i]
    if a == "--dir" or a == "--older-than" then
      if not args[i + 1] then return nil, a .. " needs a value" end
      o[a] = args[i + 1]
      i = i + 2
    elseif a:sub(1, 2) == "--" then
      return nil, "unknown option " .. a
    else
      pos[#pos + 1] = a
      i = i + 1
    end
  end
  return pos, o
end

--- gradus kb list [DIR] | show KEY [DIR] | verify [DIR] | prune [--older-than DAYS] [DIR]
function M.kb(args)
  local sub = args[2]
  local pos, o = kb_args(args)
  if not pos then eprint("gradus: kb: " .. o .. "\n" .. KB_USAGE) return 2 end
  local want = sub == "show" and 2 or 1
  if #pos > want or (sub == "show" and #pos < 1) then eprint(KB_USAGE) return 2 end
  local dir = o["--dir"] or pos[want] or gradus.kb.default_dir()
  if pos[want] and o["--dir"] then eprint("gradus: kb: the directory is given twice\n" .. KB_USAGE) return 2 end
  if sub == "list" then
    local entries = gradus.kb.list(dir)
    print(("knowledge base %s: %d templates"):format(dir, #entries))
    for _, e in ipairs(entries) do
      -- stale: built under an older engine geometry (grading rule), never served; prune removes it
      print(("%s  %8d bytes  %s  %s"):format(e.key:sub(1, 16), e.bytes, e.stale and "stale" or
        (e.qualified and "qualified" or "unqualified"), e.signature:sub(1, 100)))
    end
    return 0
  elseif sub == "show" then
    local key = pos[1]
    local t = gradus.kb.show(dir, key)
    if not t then eprint("gradus: no template " .. key .. " in " .. dir) return 1 end
    print(gradus.yaml.encode(t))
    return 0
  elseif sub == "verify" then
    local r = gradus.kb.verify(dir)
    print(gradus.yaml.encode(r))
    return (r.corrupt or 0) == 0 and 0 or 1
  elseif sub == "prune" then
    local opts = {}
    if o["--older-than"] then
      local days = tonumber(o["--older-than"])
      if not days or days < 0 then
        eprint("gradus: kb prune: --older-than needs a number of days >= 0, got '" .. o["--older-than"] .. "'")
        return 2
      end
      -- created at or before (now - DAYS): the C cutoff is strict, in whole seconds
      opts.older_than = os.time() - math.floor(days * 86400) + 1
    end
    local r = gradus.kb.prune(dir, opts)
    print(gradus.yaml.encode(r))
    return 0
  end
  eprint(KB_USAGE)
  return 2
end

-- Sweep values: "a,b,c" or "from:to:step" (inclusive).
local function sweep_values(name, s)
  local a, b, st = s:match("^([^:]+):([^:]+):([^:]+)$")
  if a then
    a, b, st = tonumber(a), tonumber(b), tonumber(st)
    if not (a and b and st) or st == 0 or (b - a) / st < 0 then
      error(("bad sweep range for %s: '%s' (from:to:step)"):format(name, s), 0)
    end
    local out = {}
    local n = math.floor((b - a) / st + 1e-9)
    for i = 0, n do out[#out + 1] = tostring(a + i * st) end
    return out
  end
  local out = {}
  for item in s:gmatch("[^,]+") do out[#out + 1] = item end
  return out
end
M.sweep_values = sweep_values

local function shell_quote(s) return "'" .. tostring(s):gsub("'", "'\\''") .. "'" end

--- Run a sweep: the cross product of the parameter lists, each run a
-- separate `gradus run` process (up to jobs at once) writing its CLI and
-- stats into dir; the table of parameters and stats goes to
-- dir/sweep.csv and dir/sweep.yaml. Returns the rows.
function M.run_sweep(recipe, params, order, opts)
  opts = opts or {}
  local dir = opts.dir or "out/sweep"
  local jobs = opts.jobs or 2
  gradus.mkdir(dir)
  -- which parameters vary (comma lists or ranges); fixed ones pass through
  local names, lists = {}, {}
  for _, k in ipairs(order) do
    names[#names + 1] = k
    lists[#lists + 1] = sweep_values(k, params[k])
  end
  local combos = { {} }
  for i, list in ipairs(lists) do
    local nextc = {}
    for _, c in ipairs(combos) do
      for _, v in ipairs(list) do
        local d = {}
        for kk, vv in pairs(c) do d[kk] = vv end
        d[names[i]] = v
        nextc[#nextc + 1] = d
      end
    end
    combos = nextc
  end
  local exe = gradus.root .. "/build/gradus"
  local running, rows, nextrun = {}, {}, 1
  local function start(n)
    local c = combos[n]
    local base = ("%s/run%03d"):format(dir, n)
    local cmd = { shell_quote(exe), "run", shell_quote(recipe), "-q", "-o", shell_quote(base .. ".cli"),
      "--stats", shell_quote(base .. ".yaml") }
    for _, k in ipairs(names) do cmd[#cmd + 1] = "-D " .. shell_quote(k .. "=" .. c[k]) end
    local line = table.concat(cmd, " ")
    os.remove(base .. ".status")
    os.execute("(" .. line .. " >" .. shell_quote(base .. ".log") .. " 2>&1; echo $? >" ..
      shell_quote(base .. ".status.tmp") .. "; mv " .. shell_quote(base .. ".status.tmp") .. " " ..
      shell_quote(base .. ".status") .. ") &")
    running[n] = base
  end
  local t0 = gradus.clock()
  while nextrun <= #combos or next(running) do
    while nextrun <= #combos and (function() local c = 0 for _ in pairs(running) do c = c + 1 end return c end)() < jobs do
      start(nextrun)
      nextrun = nextrun + 1
    end
    os.execute("sleep 0.05")
    for n, base in pairs(running) do
      local f = io.open(base .. ".status")
      if f then
        local status = tonumber(f:read("l"))
        f:close()
        os.remove(base .. ".status")
        running[n] = nil
        local row = { run = n, status = status == 0 and "ok" or "failed", params = combos[n] }
        if status == 0 then
          local ok, st = pcall(gradus.yaml.load, base .. ".yaml")
          row.stats = ok and st or nil
        else
          local lf = io.open(base .. ".log")
          local log = lf and lf:read("a") or ""
          if lf then lf:close() end
          row.error = (log:gsub("%s+$", "")):match("[^\n]*$")
          os.remove(base .. ".cli")
        end
        rows[n] = row
        if not opts.quiet then
          io.stderr:write(("sweep: run %d/%d %s (%.1f s)\n"):format(n, #combos, row.status, gradus.clock() - t0))
        end
      end
    end
  end
  M.write_table(dir, names, rows)
  return rows
end

-- Flatten the stats of a row into named columns.
local COLUMNS = {
  { "relative_density", function(s) return s.relative_density end },
  { "contour_length_mm", function(s) return s.vectors and s.vectors.contour.length end },
  { "hatch_length_mm", function(s) return s.vectors and s.vectors.hatch.length end },
  { "build_time_s", function(s) return s.build_time_s end },
  { "pore_max", function(s) return s.quality and s.quality.pore_max end },
  { "overmelt_max", function(s) return s.quality and s.quality.overmelt_max end },
  { "templates", function(s) return s.templates and s.templates.unique end },
  { "seconds", function(s) return s.seconds and s.seconds.total end },
}
M.COLUMNS = COLUMNS

function M.write_table(dir, names, rows)
  local header = { "run", "status" }
  for _, k in ipairs(names) do header[#header + 1] = k end
  for _, c in ipairs(COLUMNS) do header[#header + 1] = c[1] end
  header[#header + 1] = "error"
  local lines = { table.concat(header, ",") }
  for _, r in ipairs(rows) do
    local cells = { tostring(r.run), r.status }
    for _, k in ipairs(names) do cells[#cells + 1] = tostring(r.params[k]) end
    for _, c in ipairs(COLUMNS) do
      local v = r.stats and c[2](r.stats)
      cells[#cells + 1] = v ~= nil and tostring(v) or ""
    end
    cells[#cells + 1] = r.error and ('"' .. r.error:gsub('"', "'") .. '"') or ""
    lines[#lines + 1] = table.concat(cells, ",")
  end
  gradus.write_file(dir .. "/sweep.csv", table.concat(lines, "\n") .. "\n")
  gradus.yaml.save(dir .. "/sweep.yaml", { parameters = names, runs = rows })
end

--- gradus sweep RECIPE -D name=v1,v2 -D other=a:b:step [-j N] [-o DIR]
function M.sweep(args)
  local host = require "gradus.host"
  local ok, o = pcall(host.parse_args, args, 2)
  if not ok then eprint("gradus: " .. o) return 2 end
  local recipe = o.rest[1]
  if not recipe then eprint("usage: gradus sweep RECIPE -D name=v1,v2 ... [-j N] [-o DIR]") return 2 end
  local rows = M.run_sweep(recipe, o.params, o.order, { dir = o.output or "out/sweep", jobs = o.jobs or 2, quiet = o.quiet })
  local failed = 0
  for _, r in ipairs(rows) do if r.status ~= "ok" then failed = failed + 1 end end
  print(("sweep: %d runs, %d failed; table in %s/sweep.csv and sweep.yaml"):format(#rows, failed, o.output or "out/sweep"))
  return 0
end

return M
