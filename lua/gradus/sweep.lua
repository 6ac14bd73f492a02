-- gradus.sweep: `gradus sweep RECIPE -D name=v1,v2 ...`: which parameters
-- are axes, the runs (local processes, or a Slurm array with --slurm, see
-- gradus.slurm), and the table of their parameters and stats.
local gradus = require "gradus"
local M = {}

local function eprint(...) io.stderr:write(table.concat({ ... }, " "), "\n") end

-- Sweep values: "a,b,c" or "from:to:step" (inclusive).
function M.sweep_values(name, s)
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
  return M.split_list(s)
end

--- Split s at the commas outside parentheses and brackets:
-- "max(w,0.1),0.2" -> {"max(w,0.1)", "0.2"}.
function M.split_list(s)
  local out, depth, cur = {}, 0, {}
  for ch in s:gmatch(".") do
    if ch == "(" or ch == "[" then depth = depth + 1 elseif ch == ")" or ch == "]" then depth = depth - 1 end
    if ch == "," and depth == 0 then
      out[#out + 1] = table.concat(cur)
      cur = {}
    else
      cur[#cur + 1] = ch
    end
  end
  out[#out + 1] = table.concat(cur)
  return out
end

-- Parameters that are vectors when the recipe cannot be asked (see probe).
local VECTORS = { cells = true, origin = true }

local STOP = setmetatable({}, { __tostring = function() return "gradus sweep: probe stop" end })

--- M.probe(recipe) -> {name = default}: the parameters the recipe reads
-- before it starts producing (gradus.output, gradus.write_stats, a job),
-- with their defaults. The recipe runs with no -D values and those calls
-- stopped, so nothing is computed or written.
function M.probe(recipe)
  local host = require "gradus.host"
  local found = {}
  local saved = { param = gradus.param, output = gradus.output, write_stats = gradus.write_stats,
    write_file = gradus.write_file, job = gradus.place.job, ctx = gradus._ctx }
  local function stop() error(STOP, 0) end
  gradus.param = function(name, default)
    if type(name) == "string" and found[name] == nil then found[name] = default == nil and false or default end
    return saved.param(name, default)
  end
  gradus.output, gradus.write_stats, gradus.write_file, gradus.place.job = stop, stop, stop, stop
  gradus._ctx = { params = {}, read = {}, quiet = true }
  local chunk = loadfile(recipe, "t", host.recipe_env())
  if chunk then pcall(chunk) end
  gradus.param, gradus.output, gradus.write_stats = saved.param, saved.output, saved.write_stats
  gradus.write_file, gradus.place.job, gradus._ctx = saved.write_file, saved.job, saved.ctx
  return found
end

local function is_vector_default(d)
  if type(d) == "table" then return true end
  return type(d) == "string" and d:match("^%s*[-+%d.eE]+%s*,[-+%d.eE,%s]*$") ~= nil
end

--- M.plan(recipe, params, order) -> {axes = {{name=, values={...}}...},
-- fixed = {{name=, value=}...}, combos = {{name = value}...}}.
-- An axis is what the user writes as one: a list "a,b" or a range
-- "from:to:step" of a scalar parameter, or an explicit list of vectors
-- "[1,1,2],[2,2,1]"; a vector parameter ("cells=3,3,1", known from the
-- recipe's default) stays fixed.
function M.plan(recipe, params, order)
  local defaults = M.probe(recipe)
  local plan = { axes = {}, fixed = {} }
  for _, k in ipairs(order) do
    local v = params[k]
    local values
    if v:match("^%s*%[") then
      values = {}
      for _, item in ipairs(M.split_list(v)) do
        local inner = item:match("^%s*%[(.*)%]%s*$")
        if not inner then
          error(("bad list of vectors for %s: '%s' (write [a,b,c],[d,e,f])"):format(k, v), 0)
        end
        values[#values + 1] = inner
      end
    elseif not (is_vector_default(defaults[k]) or (defaults[k] == nil and VECTORS[k])) then
      values = M.sweep_values(k, v)
    end
    if values and #values > 1 then
      plan.axes[#plan.axes + 1] = { name = k, values = values, vectors = v:match("^%s*%[") ~= nil }
    else
      plan.fixed[#plan.fixed + 1] = { name = k, value = values and values[1] or v }
    end
  end
  local combos = { {} }
  for _, axis in ipairs(plan.axes) do
    local nextc = {}
    for _, c in ipairs(combos) do
      for _, val in ipairs(axis.values) do
        local d = {}
        for kk, vv in pairs(c) do d[kk] = vv end
        d[axis.name] = val
        nextc[#nextc + 1] = d
      end
    end
    combos = nextc
  end
  for _, c in ipairs(combos) do
    for _, f in ipairs(plan.fixed) do c[f.name] = f.value end
  end
  plan.combos = combos
  plan.names = order
  return plan
end

--- The lines saying what a plan will run.
function M.describe(plan, dir)
  local out = {}
  for _, a in ipairs(plan.axes) do
    local shown = {}
    for i, v in ipairs(a.values) do shown[i] = a.vectors and ("[" .. v .. "]") or v end
    out[#out + 1] = ("sweep: axis %s: %s (%d)"):format(a.name, table.concat(shown, ", "), #a.values)
  end
  for _, f in ipairs(plan.fixed) do out[#out + 1] = ("sweep: fixed %s=%s"):format(f.name, f.value) end
  out[#out + 1] = ("sweep: %d run%s into %s"):format(#plan.combos, #plan.combos == 1 and "" or "s", dir)
  return table.concat(out, "\n")
end

function M.shell_quote(s) return "'" .. tostring(s):gsub("'", "'\\''") .. "'" end
local shell_quote = M.shell_quote

--- The files of run n: dir/runNNN.{cli,yaml,log,status}.
function M.base(dir, n) return ("%s/run%03d"):format(dir, n) end

--- The shell words of run n's command (gradus run RECIPE -q -o ... -D ...).
function M.command(recipe, plan, n, base)
  local c = plan.combos[n]
  local cmd = { shell_quote(gradus.root .. "/build/gradus"), "run", shell_quote(recipe), "-q",
    "-o", shell_quote(base .. ".cli"), "--stats", shell_quote(base .. ".yaml") }
  for _, k in ipairs(plan.names) do cmd[#cmd + 1] = "-D " .. shell_quote(k .. "=" .. c[k]) end
  return table.concat(cmd, " ")
end

-- The log's last line that says what went wrong: not the closing remark
-- that nothing was written (the cause, a misspelled -D with its suggestion,
-- is the line before it).
local function last_cause(log)
  local lines = {}
  for l in log:gmatch("[^\n]+") do if l:match("%S") then lines[#lines + 1] = l end end
  for i = #lines, 1, -1 do
    if not lines[i]:match("^gradus: nothing was written") then return lines[i] end
  end
  return lines[#lines] or ""
end

--- The row of run n from its files: status "ok" (exit status 0 and stats
-- read), else "failed" with the log's last line of cause as the error.
function M.collect(plan, n, base, status)
  local row = { run = n, status = "failed", params = plan.combos[n], log = base .. ".log" }
  if status == 0 then
    local ok, st = pcall(gradus.yaml.load, base .. ".yaml")
    if ok and type(st) == "table" then
      row.status, row.stats = "ok", st
      return row
    end
    row.error = "no stats in " .. base .. ".yaml"
    return row
  end
  local lf = io.open(base .. ".log")
  local log = lf and lf:read("a") or ""
  if lf then lf:close() end
  -- Slurm's own word on a task it ended (cancelled, time limit, node
  -- failure, out of memory) beats whatever the shell printed last
  row.error = log:match("[^\n]*%*%*%* JOB [^\n]*%*%*%*") or log:match("[^\n]*oom%-kill[^\n]*") or last_cause(log)
  if row.error == "" then
    row.error = status and ("exit status " .. status) or "no exit status (the task was killed, timed out or never ran)"
  end
  return row
end

--- Run a sweep locally: each run a separate `gradus run` process (up to
-- jobs at once) writing its CLI, stats and log into dir; the table of
-- parameters and stats goes to dir/sweep.csv and dir/sweep.yaml. params,
-- order: the -D values as given; or plan = M.plan(...) in opts. Returns the
-- rows.
function M.run_sweep(recipe, params, order, opts)
  opts = opts or {}
  local dir = opts.dir or "out/sweep"
  local jobs = opts.jobs or 2
  local plan = opts.plan or M.plan(recipe, params, order)
  gradus.mkdir(dir)
  local combos = plan.combos
  local running, nrunning, rows, nextrun = {}, 0, {}, 1
  local function start(n)
    local base = M.base(dir, n)
    local line = M.command(recipe, plan, n, base)
    os.remove(base .. ".status")
    os.execute("(" .. line .. " >" .. shell_quote(base .. ".log") .. " 2>&1; echo $? >" ..
      shell_quote(base .. ".status.tmp") .. "; mv " .. shell_quote(base .. ".status.tmp") .. " " ..
      shell_quote(base .. ".status") .. ") &")
    running[n] = base
    nrunning = nrunning + 1
  end
  local t0 = gradus.clock()
  while nextrun <= #combos or nrunning > 0 do
    while nextrun <= #combos and nrunning < jobs do
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
        nrunning = nrunning - 1
        local row = M.collect(plan, n, base, status)
        if row.status ~= "ok" then os.remove(base .. ".cli") end
        rows[n] = row
        if not opts.quiet then
          io.stderr:write(("sweep: run %d/%d %s (%.1f s)\n"):format(n, #combos, row.status, gradus.clock() - t0))
        end
      end
    end
  end
  M.write_table(dir, plan.names, rows)
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

-- A CSV cell: quoted when it holds a comma, a quote or a line break.
local function csv(v)
  v = tostring(v)
  if v:find('[,"\n]') then return '"' .. v:gsub('"', '""'):gsub("\n", " ") .. '"' end
  return v
end

--- Write dir/sweep.csv (run, status, the parameters, the stats columns,
-- error) and dir/sweep.yaml ({parameters=, runs=}).
function M.write_table(dir, names, rows)
  local header = { "run", "status" }
  for _, k in ipairs(names) do header[#header + 1] = k end
  for _, c in ipairs(COLUMNS) do header[#header + 1] = c[1] end
  header[#header + 1] = "error"
  local lines = { table.concat(header, ",") }
  for _, r in ipairs(rows) do
    local cells = { tostring(r.run), r.status }
    for _, k in ipairs(names) do cells[#cells + 1] = csv(r.params[k]) end
    for _, c in ipairs(COLUMNS) do
      local v = r.stats and c[2](r.stats)
      cells[#cells + 1] = v ~= nil and csv(v) or ""
    end
    cells[#cells + 1] = r.error and csv(r.error) or ""
    lines[#lines + 1] = table.concat(cells, ",")
  end
  gradus.write_file(dir .. "/sweep.csv", table.concat(lines, "\n") .. "\n")
  gradus.yaml.save(dir .. "/sweep.yaml", { parameters = names, runs = rows })
end

--- The summary of finished rows; returns the exit status (1 if any failed).
function M.report(rows, plan, dir)
  local failed = {}
  for _, r in ipairs(rows) do if r.status ~= "ok" then failed[#failed + 1] = r end end
  print(("sweep: %d runs, %d failed; table in %s/sweep.csv and sweep.yaml"):format(#rows, #failed, dir))
  for _, r in ipairs(failed) do
    local kv = {}
    for _, a in ipairs(plan.axes) do kv[#kv + 1] = a.name .. "=" .. r.params[a.name] end
    print(("sweep: failed run %d (%s): %s; log %s"):format(r.run, table.concat(kv, " "), r.error or "?", r.log))
  end
  return #failed > 0 and 1 or 0
end

local USAGE = "usage: gradus sweep RECIPE -D name=v1,v2 -D other=from:to:step -D vec=[a,b,c],[d,e,f] ... [-j N] [-o DIR]\n" ..
  "         [--slurm [--partition P] [--time T] [--mem M] [--max-tasks N]]"

--- gradus sweep RECIPE -D name=v1,v2 -D other=a:b:step [-j N] [-o DIR] [--slurm ...]
function M.main(args)
  local host = require "gradus.host"
  local slurm = require "gradus.slurm"
  local sok, rest, so = pcall(slurm.strip_options, args, false)
  if not sok then eprint("gradus: " .. rest) eprint(USAGE) return 2 end
  local ok, o = pcall(host.parse_args, rest, 2)
  if not ok then eprint("gradus: " .. o) eprint(USAGE) return 2 end
  local recipe = o.rest[1]
  if not recipe or #o.rest > 1 then eprint(USAGE) return 2 end
  local f = io.open(recipe, "r")
  if not f then eprint("gradus: cannot open recipe " .. recipe) return 1 end
  f:close()
  local dir = o.output or "out/sweep"
  local pok, plan = pcall(M.plan, recipe, o.params, o.order)
  if not pok then eprint("gradus: " .. tostring(plan)) return 2 end
  if so.slurm then
    local why = slurm.missing()
    if why then eprint(why) return 1 end
  end
  print(M.describe(plan, dir))
  io.stdout:flush()
  local rows
  if so.slurm then
    local err
    rows, err = slurm.sweep(recipe, plan, dir, so, o.quiet)
    if not rows then eprint("gradus: " .. err) return 1 end
  else
    rows = M.run_sweep(recipe, nil, nil, { plan = plan, dir = dir, jobs = o.jobs or 2, quiet = o.quiet })
  end
  return M.report(rows, plan, dir)
end

return M
