-- gradus.slurm: sweeps and large jobs as Slurm array jobs (doc/cluster.md).
--   gradus sweep RECIPE -D ... --slurm [--partition P] [--time T] [--mem M] [--max-tasks N]
--   gradus run RECIPE ... -o FILE --slurm N [same options]
--   gradus cli cat PART.cli... -o FILE [--stats FILE]
-- Slurm is used as it is: an sbatch script written beside the results,
-- submitted with sbatch, followed with squeue; every task leaves a status
-- file (its exit status) so that a rerun submits only what is not finished.
local gradus = require "gradus"
local sweep = require "gradus.sweep"
local M = {}

local function eprint(...) io.stderr:write(table.concat({ ... }, " "), "\n") end
local q = sweep.shell_quote

local OPTS = { ["--partition"] = "partition", ["--time"] = "time", ["--mem"] = "mem", ["--max-tasks"] = "max_tasks" }

--- M.strip_options(args, with_count) -> args without the Slurm options, and
-- {slurm=true or N, partition=, time=, mem=, max_tasks=}. with_count:
-- --slurm takes the number of tasks (gradus run). Raises on a bad value.
function M.strip_options(args, with_count)
  local rest, o, i = {}, {}, 1
  while i <= #args do
    local a = args[i]
    if a == "--slurm" then
      if with_count then
        local n = math.tointeger(tonumber(args[i + 1] or ""))
        if not n or n < 1 then error("--slurm needs the number of tasks N >= 1, e.g. --slurm 4", 0) end
        o.slurm = n
        i = i + 1
      else
        o.slurm = true
      end
    elseif OPTS[a] then
      local v = args[i + 1]
      if not v then error("option " .. a .. " needs a value", 0) end
      o[OPTS[a]] = v
      i = i + 1
    else
      rest[#rest + 1] = a
    end
    i = i + 1
  end
  if o.max_tasks and not (math.tointeger(tonumber(o.max_tasks)) and tonumber(o.max_tasks) >= 1) then
    error("--max-tasks needs a whole number >= 1, got '" .. o.max_tasks .. "'", 0)
  end
  for flag, key in pairs(OPTS) do
    if o[key] and not o.slurm then error(flag .. " is a Slurm option: it needs --slurm", 0) end
  end
  return rest, o
end

local function sh_ok(cmd) return os.execute(cmd .. " >/dev/null 2>&1") == true end

--- nil when sbatch, squeue and scancel are there; else the message saying so.
function M.missing()
  for _, tool in ipairs({ "sbatch", "squeue", "scancel" }) do
    if not sh_ok("command -v " .. tool) then
      return "gradus: --slurm needs Slurm, and '" .. tool .. "' is not installed here.\n" ..
        "  Run on a cluster's login node, or install Slurm: apt-get install slurm-wlm munge (Debian, as root;\n" ..
        "  then configure it, see doc/cluster.md). Without --slurm the job runs on this machine."
    end
  end
  return nil
end

-- The output of a shell command (stdout and stderr) and whether it succeeded.
function M.capture(cmd)
  local p = io.popen(cmd .. " 2>&1")
  local out = p:read("a")
  local ok = p:close()
  return out, ok == true
end

local capture = M.capture

--- A note when dir lies on a file system only this node sees (tmpfs,
-- ramfs): array tasks on other nodes would not find it. nil otherwise.
function M.local_fs_note(dir, what)
  local t = capture("stat -f -c %T " .. q(dir)):gsub("%s+$", "")
  if t == "tmpfs" or t == "ramfs" then
    return ("slurm: note: the %s %s is on %s, which only this node sees: on a cluster of several nodes "
      .. "put it on a shared file system (doc/cluster.md)"):format(what, dir, t)
  end
  return nil
end

local cwd_cache
local function abs(path)
  if path:sub(1, 1) == "/" then return path end
  cwd_cache = cwd_cache or (capture("pwd -P"):gsub("%s+$", ""))
  if path == "." then return cwd_cache end
  return cwd_cache .. "/" .. (path:gsub("^%./", ""))
end
M.abs = abs

function M.read_all(path)
  local f = io.open(path)
  if not f then return nil end
  local s = f:read("a")
  f:close()
  return s
end

local read_all = M.read_all

--- The exit status a task left in `path` (nil: none).
function M.status_of(path)
  local s = M.read_all(path)
  return s and tonumber(s:match("^%s*(-?%d+)")) or nil
end
local status_of = M.status_of

-- "1-3,5,7-8" from a sorted list of task indices
local function array_spec(list)
  local out, i = {}, 1
  while i <= #list do
    local j = i
    while j < #list and list[j + 1] == list[j] + 1 do j = j + 1 end
    out[#out + 1] = i == j and tostring(list[i]) or (list[i] .. "-" .. list[j])
    i = j + 1
  end
  return table.concat(out, ",")
end
M.array_spec = array_spec

-- #SBATCH lines for the user's options
function M.sbatch_lines(so, name, output)
  local l = { "#SBATCH --job-name=" .. name, "#SBATCH --output=" .. output }
  if so.partition then l[#l + 1] = "#SBATCH --partition=" .. so.partition end
  if so.time then l[#l + 1] = "#SBATCH --time=" .. so.time end
  if so.mem then l[#l + 1] = "#SBATCH --mem=" .. so.mem end
  return table.concat(l, "\n")
end

--- Submit: sbatch --parsable ARGS SCRIPT WORDS -> job id, or nil and sbatch's message.
function M.submit(args, script, words)
  local out, ok = capture("sbatch --parsable " .. args .. " " .. q(script) .. (words and (" " .. words) or ""))
  local id = out:match("^%s*(%d+)")
  if not ok or not id then return nil, "sbatch failed: " .. (out:gsub("%s+$", "")) end
  return id
end

-- Tasks of job `id` still in the queue: count by state, or nil when the job has left it.
local function queued(id)
  local out, ok = capture("squeue -h -r -j " .. id .. " -o %T")
  if not ok then return nil end
  local n, by = 0, {}
  for st in out:gmatch("%S+") do
    n = n + 1
    by[st] = (by[st] or 0) + 1
  end
  if n == 0 then return nil end
  return by
end

--- M.follow(id, tasks, label, quiet): wait for job `id` (tasks: {{status=
-- path}...}, one per array task) to leave the queue, printing done /
-- running / failed counts when they change. Returns the exit status of each
-- task (nil: none written: killed, timed out or never ran).
function M.follow(id, tasks, label, quiet)
  local last, grace = nil, 0
  local status = {}
  while true do
    local by = queued(id)
    local done, failed = 0, 0
    for i, t in ipairs(tasks) do
      status[i] = status[i] or status_of(t.status)
      if status[i] == 0 then done = done + 1 elseif status[i] then failed = failed + 1 end
    end
    local running = by and ((by.RUNNING or 0) + (by.COMPLETING or 0)) or 0
    local pending = by and (by.PENDING or 0) or 0
    local line = ("slurm: job %s (%s): %d done, %d running, %d failed, %d pending, of %d"):format(id, label,
      done, running, failed, pending, #tasks)
    if line ~= last and not quiet then eprint(line) end
    last = line
    if done + failed == #tasks then return status end
    if not by then
      -- the job left the queue: a status file written just before may
      -- take a moment to show on a network file system
      grace = grace + 1
      if grace > 10 then return status end
    elseif pending > 0 and running == 0 and by.PENDING and M.never_runs(id) then
      capture("scancel " .. id)
      return status
    end
    os.execute("sleep 1")
  end
end

--- Jobs submitted by an earlier command for the same results (ids in
-- `file`) that are still in the queue (the user stopped following them,
-- e.g. with Ctrl-C): wait until they have left it, so a rerun never runs a
-- task twice. Then `file` holds `ids` (this submission's, may be empty).
function M.adopt(file)
  local s = M.read_all(file) or ""
  for id in s:gmatch("%d+") do
    local shown = false
    while queued(id) do
      if not shown then eprint(("slurm: job %s from an earlier submission is still in the queue: waiting for it"):format(id)) end
      shown = true
      os.execute("sleep 2")
    end
  end
end

function M.remember(file, ids) gradus.write_file(file, table.concat(ids, " ") .. "\n") end

-- A pending job whose dependency failed never starts.
function M.never_runs(id)
  local out = capture("squeue -h -j " .. id .. " -o %r")
  return out:match("DependencyNeverSatisfied") ~= nil
end

-------------------------------------------------------------------------
-- sweeps

local function sweep_script(recipe, plan, dir, so)
  local L = { "#!/bin/bash",
    "# gradus sweep as a Slurm array job, written by `gradus sweep ... --slurm` (gradus " .. gradus.version .. ").",
    "# Task i runs combination i and leaves " .. dir .. "/runNNN.{cli,yaml,log,status}.",
    "# Submit again by hand, e.g. only combinations 2 and 5: sbatch --array=2,5 " .. dir .. "/sweep.sbatch",
    M.sbatch_lines(so, "gradus-sweep", dir .. "/run%3a.log"),
    "set -u",
    "cd " .. q(abs(".")) .. " || exit 1",
    "i=${SLURM_ARRAY_TASK_ID:?submit with sbatch --array=...}",
    "base=$(printf '%s/run%03d' " .. q(dir) .. " \"$i\")",
    "rm -f \"$base.status\"",
    "case $i in" }
  for n, c in ipairs(plan.combos) do
    local d = {}
    for _, k in ipairs(plan.names) do d[#d + 1] = "-D " .. q(k .. "=" .. c[k]) end
    L[#L + 1] = ("  %d) set -- %s ;;"):format(n, table.concat(d, " "))
  end
  L[#L + 1] = "  *) echo \"no combination $i\" >&2; exit 2 ;;"
  L[#L + 1] = "esac"
  L[#L + 1] = q(gradus.root .. "/build/gradus") .. " run " .. q(abs(recipe)) ..
    " -q -o \"$base.cli\" --stats \"$base.yaml\" \"$@\""
  L[#L + 1] = "rc=$?"
  L[#L + 1] = "echo $rc > \"$base.status.tmp\" && mv \"$base.status.tmp\" \"$base.status\""
  L[#L + 1] = "exit $rc"
  return table.concat(L, "\n") .. "\n"
end

-- The identity of combination n, kept in runNNN.args: a rerun reuses a
-- finished result only for the same recipe and values.
local function combo_id(recipe, plan, n)
  local d = { abs(recipe) }
  for _, k in ipairs(plan.names) do d[#d + 1] = k .. "=" .. plan.combos[n][k] end
  return table.concat(d, "\n") .. "\n"
end

local function sweep_finished(recipe, plan, n, base)
  if status_of(base .. ".status") ~= 0 or read_all(base .. ".args") ~= combo_id(recipe, plan, n) then return false end
  local ok, st = pcall(gradus.yaml.load, base .. ".yaml")
  return ok and type(st) == "table"
end

--- M.sweep(recipe, plan, dir, so, quiet): run the plan's combinations as
-- one Slurm array; combinations finished by an earlier submission are kept.
-- Writes dir/sweep.csv and sweep.yaml like a local sweep. Returns the rows,
-- or nil and a message.
function M.sweep(recipe, plan, dir, so, quiet)
  dir = abs(dir)
  gradus.mkdir(dir)
  local note = M.local_fs_note(dir, "result directory")
  if note then print(note) end
  M.adopt(dir .. "/slurm.jobs")
  local todo = {}
  for n = 1, #plan.combos do
    local base = sweep.base(dir, n)
    if not sweep_finished(recipe, plan, n, base) then
      todo[#todo + 1] = n
      os.remove(base .. ".status")
      os.remove(base .. ".cli")
      gradus.write_file(base .. ".args", combo_id(recipe, plan, n))
    end
  end
  local script = dir .. "/sweep.sbatch"
  gradus.write_file(script, sweep_script(recipe, plan, dir, so))
  print(("slurm: %d of %d combinations finished earlier; submitting %d"):format(#plan.combos - #todo,
    #plan.combos, #todo))
  io.stdout:flush()
  if #todo > 0 then
    local spec = array_spec(todo) .. (so.max_tasks and ("%" .. so.max_tasks) or "")
    local id, err = M.submit("--array=" .. spec, script)
    if not id then return nil, err end
    M.remember(dir .. "/slurm.jobs", { id })
    print(("slurm: submitted job %s: %s --array=%s"):format(id, script, spec))
    io.stdout:flush()
    local tasks = {}
    for i, n in ipairs(todo) do tasks[i] = { status = sweep.base(dir, n) .. ".status" } end
    M.follow(id, tasks, "sweep", quiet)
  end
  local rows = {}
  for n = 1, #plan.combos do
    local base = sweep.base(dir, n)
    rows[n] = sweep.collect(plan, n, base, status_of(base .. ".status"))
  end
  sweep.write_table(dir, plan.names, rows)
  return rows
end

-------------------------------------------------------------------------
-- one job split into layer ranges: see gradus.slurm_run (slurm_run.lua)

function M.run_cmd(args) return require("gradus.slurm_run").main(args) end
function M.task(args) return require("gradus.slurm_run").task(args) end
function M.cat_cmd(args) return require("gradus.slurm_run").cat_cmd(args) end

return M
