-- gradus.slurm_run: `gradus run RECIPE ... -o FILE --slurm N`: one job
-- split into N layer ranges (the recipe's `layers=a:b` parameter) run as a
-- Slurm array, after a first stage that builds every template once into the
-- knowledge base; then `gradus cli cat` merges the parts, their manifests
-- and their stats. Files go to FILE's name with .parts (work directory).
local gradus = require "gradus"
local slurm = require "gradus.slurm"
local sweep = require "gradus.sweep"
local M = {}

local function eprint(...) io.stderr:write(table.concat({ ... }, " "), "\n") end
local q = sweep.shell_quote
local abs = slurm.abs

local read_all, status_of = slurm.read_all, slurm.status_of

--- The layer range of task i of n over `total` layers: a, b (a > b: none).
function M.range(i, n, total)
  return (i - 1) * total // n + 1, i * total // n
end

local function part_base(work, i) return ("%s/part%02d"):format(work, i) end

-------------------------------------------------------------------------
-- merging parts (also `gradus cli cat` by hand)

-- statistics that add up over layer ranges (paths in the stats table)
local SUM = { "layers", "build_time_s", "balanced_time_s", "thin_walls", "solid_volume_mm3",
  "dropped_short_vectors", "contours.dropped_short", "contours.dropped_short_length", "jumps.count",
  "jumps.length", "templates.built", "templates.reused",
  "templates.verified", "templates.corrupt_rebuilt", "seconds.classify", "seconds.templates",
  "seconds.layers", "seconds.write", "seconds.total" }
for _, k in ipairs({ "contour", "hatch", "edge" }) do
  SUM[#SUM + 1] = "vectors." .. k .. ".count"
  SUM[#SUM + 1] = "vectors." .. k .. ".length"
end

local function get(t, path)
  for key in path:gmatch("[^.]+") do
    if type(t) ~= "table" then return nil end
    t = t[key]
  end
  return t
end

local function set(t, path, v)
  local keys = {}
  for key in path:gmatch("[^.]+") do keys[#keys + 1] = key end
  for i = 1, #keys - 1 do
    if type(t[keys[i]]) ~= "table" then return end
    t = t[keys[i]]
  end
  t[keys[#keys]] = v
end

local function deep_copy(v)
  if type(v) ~= "table" then return v end
  local c = {}
  for k, x in pairs(v) do c[k] = deep_copy(x) end
  return c
end

--- M.merge_stats(list) -> the stats of the whole job from the parts' stats
-- (in layer order): counts, lengths, times and seconds summed; the relative
-- density weighted by layers; laser shares and balance recomputed; the
-- rest (parameters, voxels, units...) from the first part.
function M.merge_stats(list)
  local m = deep_copy(list[1])
  for _, path in ipairs(SUM) do
    local s, any = 0, false
    for _, st in ipairs(list) do
      local v = get(st, path)
      if type(v) == "number" then s, any = s + v, true end
    end
    if any then set(m, path, s) end
  end
  local dens, nl = 0, 0
  for _, st in ipairs(list) do
    if st.relative_density and st.layers then dens, nl = dens + st.relative_density * st.layers, nl + st.layers end
  end
  if nl > 0 then m.relative_density = dens / nl end
  if type(m.lasers) == "table" then
    local total = 0
    for la, l in ipairs(m.lasers) do
      l.length, l.scan_time_s = 0, 0
      for _, st in ipairs(list) do
        local p = st.lasers and st.lasers[la]
        if p then l.length, l.scan_time_s = l.length + (p.length or 0), l.scan_time_s + (p.scan_time_s or 0) end
      end
      total = total + l.scan_time_s
    end
    for _, l in ipairs(m.lasers) do l.share = total > 0 and l.scan_time_s / total or 0 end
  end
  if m.build_time_s and m.balanced_time_s then
    m.balance_efficiency = m.build_time_s > 0 and m.balanced_time_s / m.build_time_s or 1
  end
  local peak = 0
  for _, st in ipairs(list) do peak = math.max(peak, st.peak_rss_mb or 0) end
  if m.peak_rss_mb then m.peak_rss_mb = peak end
  if type(m.parameters) == "table" then m.parameters.layers = "" end
  m.parts = #list
  return m
end

local function strip_cli(path) return (path:gsub("%.cli$", "")) end

-- a parameter's value as text: vectors (tables) as "a,b,c"
local function show(v)
  if type(v) ~= "table" then return tostring(v) end
  local t = {}
  for i, x in ipairs(v) do t[i] = show(x) end
  return table.concat(t, ",")
end

--- M.same_job(parts): raise when the parts' stats (PART.yaml, where there)
-- record different parameters (other than layers): the CLI header alone
-- does not tell a hatch spacing or a thickness apart.
function M.same_job(parts)
  local first, fpath
  for _, p in ipairs(parts) do
    local f = strip_cli(p) .. ".yaml"
    local ok, st = pcall(gradus.yaml.load, f)
    local par = ok and type(st) == "table" and type(st.parameters) == "table" and st.parameters or nil
    if par and not first then
      first, fpath = par, p
    elseif par then
      local set, keys = {}, {}
      for k in pairs(first) do set[k] = true end
      for k in pairs(par) do set[k] = true end
      for k in pairs(set) do keys[#keys + 1] = k end
      table.sort(keys) -- the first differing parameter in name order: the same message every time
      for _, k in ipairs(keys) do
        if k ~= "layers" and show(first[k]) ~= show(par[k]) then
          error(("%s and %s are not parts of one job: parameter %s is %s in one and %s in the other (their stats)")
            :format(fpath, p, k, show(first[k]), show(par[k])), 0)
        end
      end
    end
  end
end

--- M.cat(parts, out, stats_out): merge CLI parts into out (byte for byte,
-- gradus.cli.cat), their manifests (PART.manifest.yaml, when every part has
-- one) into OUT.manifest.yaml, and, with stats_out, their stats (PART.yaml)
-- into stats_out. Returns the cat info {layers=, first=, last=, layer_mm=}.
function M.cat(parts, out, stats_out, extra)
  M.same_job(parts)
  local ok, info = pcall(gradus.cli.cat, parts, out)
  if not ok then error((tostring(info):gsub("^[^\n]-%.lua:%d+: ", "")), 0) end
  local manifests = {}
  for i, p in ipairs(parts) do
    local f = strip_cli(p) .. ".manifest.yaml"
    local ok, man = pcall(gradus.yaml.load, f)
    manifests[i] = ok and type(man) == "table" and man or nil
  end
  if #manifests == #parts then
    local man = manifests[1]
    man.cli, man.layers = out, info.layers
    gradus.yaml.save(strip_cli(out) .. ".manifest.yaml", man)
  end
  if stats_out then
    -- parts in layer order, as the merge put them
    local list = {}
    for _, p in ipairs(parts) do
      local f = strip_cli(p) .. ".yaml"
      local ok, st = pcall(gradus.yaml.load, f)
      if not ok or type(st) ~= "table" then error("cli cat: no stats for " .. p .. " (" .. f .. ")", 0) end
      list[#list + 1] = st
    end
    table.sort(list, function(a, b)
      local pa, pb = a.parameters and a.parameters.layers, b.parameters and b.parameters.layers
      return (tonumber(tostring(pa):match("^(%d+)")) or 0) < (tonumber(tostring(pb):match("^(%d+)")) or 0)
    end)
    local m = M.merge_stats(list)
    if extra then for k, v in pairs(extra) do m[k] = v end end
    gradus.yaml.save(stats_out, m)
  end
  return info
end

--- gradus cli cat PART.cli... -o FILE [--stats FILE]
function M.cat_cmd(args)
  local usage = "usage: gradus cli cat PART.cli... -o FILE [--stats FILE]"
  local parts, out, stats, i = {}, nil, nil, 3
  while i <= #args do
    local a = args[i]
    if a == "-o" or a == "--stats" then
      if not args[i + 1] then eprint("gradus: " .. a .. " needs a value\n" .. usage) return 2 end
      if a == "-o" then out = args[i + 1] else stats = args[i + 1] end
      i = i + 1
    elseif a:sub(1, 1) == "-" then
      eprint("gradus: cli cat: unknown option " .. a .. "\n" .. usage) return 2
    else
      parts[#parts + 1] = a
    end
    i = i + 1
  end
  if #parts == 0 or not out then eprint(usage) return 2 end
  local ok, info = pcall(M.cat, parts, out, stats)
  if not ok then eprint("gradus: " .. tostring(info)) return 1 end
  print(("%s: %d layers (%d-%d, %.4g mm) from %d part%s"):format(out, info.layers, info.first, info.last,
    info.layer_mm, #parts, #parts == 1 and "" or "s"))
  return 0
end

-------------------------------------------------------------------------
-- the stages, run by the sbatch script: gradus slurm-task templates WORK RECIPE -D ...

-- Stage 1: how many layers, and every template into the knowledge base:
-- one layer of every row of voxels (every s-th layer, s = the fewest layers
-- of a row), so the layer tasks only read templates.
local function stage_templates(work, recipe, params)
  local host = require "gradus.host"
  local probe = work .. "/templates"
  local function one(g)
    local p = {}
    for k, v in pairs(params) do p[k] = v end
    p.layers = g .. ":" .. g
    -- every template built here is read by the layer tasks: store them all
    -- (a recipe without kb_store ignores it: allow_unused, this output is discarded)
    if p.kb_store == nil then p.kb_store = "all" end
    local ok, err = host.run(recipe, p, { output = probe .. ".cli", stats = probe .. ".yaml", quiet = true,
      allow_unused = true })
    if not ok then error(err, 0) end
    return gradus.yaml.load(probe .. ".yaml")
  end
  local st = one(1)
  local total = st.layers_total
  if type(total) ~= "number" then error(recipe .. ": its stats have no layers_total (not a gradus job?)", 0) end
  local par = st.parameters or {}
  local L, t = tonumber(type(par.cell) == "table" and par.cell[3] or par.cell), tonumber(par.layer) -- Lz: a row's height
  local built = st.templates and st.templates.built or 0
  if params.kb == "off" then
    print("templates: kb=off: every layer task builds its own voxels")
  elseif L and t and t > 0 then
    local s = math.max(1, math.floor(L / t + 1e-9))
    for g = 1 + s, total, s do
      local r = one(g)
      built = built + (r.templates and r.templates.built or 0)
    end
    print(("templates: %d built into the knowledge base (one layer every %d of %d)"):format(built, s, total))
  else
    print("templates: the recipe records no cell and layer parameters: the layer tasks build what they need")
  end
  for _, ext in ipairs({ ".cli", ".yaml", ".manifest.yaml" }) do os.remove(probe .. ext) end
  gradus.write_file(work .. "/layers_total", tostring(total) .. "\n")
end

--- gradus slurm-task templates WORK RECIPE [-D name=value]...: stage 1 of
-- a split job (the sbatch script runs it); writes WORK/layers_total and
-- WORK/templates.status.
function M.task(args)
  local host = require "gradus.host"
  local what, work = args[2], args[3]
  local ok, o = pcall(host.parse_args, args, 4)
  if what ~= "templates" or not work or not ok or not o.rest[1] then
    eprint("usage: gradus slurm-task templates WORK RECIPE [-D name=value]... (run by gradus run --slurm)")
    return 2
  end
  local sok, err = pcall(stage_templates, work, o.rest[1], o.params)
  if not sok then eprint(tostring(err)) end
  gradus.write_file(work .. "/templates.status", (sok and "0" or "1") .. "\n")
  return sok and 0 or 1
end

-------------------------------------------------------------------------
-- submitting a split job

local function run_script(recipe, work, n, params, order, so)
  local d = {}
  for _, k in ipairs(order) do d[#d + 1] = "-D " .. q(k .. "=" .. params[k]) end
  local G = q(gradus.root .. "/build/gradus")
  local L = {
    "#!/bin/bash",
    "# gradus run --slurm " .. n .. ", written by gradus " .. gradus.version .. ". Two stages:",
    "#   sbatch --output=" .. work .. "/templates.log " .. work .. "/job.sbatch templates",
    "#     (1 task: counts the layers, builds every template once into the knowledge base)",
    "#   sbatch --array=1-" .. n .. " --dependency=afterok:JOBID " .. work .. "/job.sbatch layers",
    "#     (task i of " .. n .. ": layer range i, written to part<i>.cli)",
    "# then: gradus cli cat " .. work .. "/part*.cli -o OUT.cli --stats OUT.yaml",
    slurm.sbatch_lines(so, "gradus-run", work .. "/part%2a.log"),
    "set -u",
    "cd " .. q(abs(".")) .. " || exit 1",
    "G=" .. G .. "; R=" .. q(abs(recipe)) .. "; W=" .. q(work) .. "; N=" .. n,
    "D=(" .. table.concat(d, " ") .. ")",
    "case ${1:-layers} in",
    "  templates) exec \"$G\" slurm-task templates \"$W\" \"$R\" \"${D[@]}\" ;;",
    "  layers) ;;",
    "  *) echo \"unknown stage $1 (templates or layers)\" >&2; exit 2 ;;",
    "esac",
    "i=${SLURM_ARRAY_TASK_ID:?submit with sbatch --array=1-$N}",
    "part=$(printf '%s/part%02d' \"$W\" \"$i\")",
    "rm -f \"$part.status\"",
    "total=$(cat \"$W/layers_total\") || exit 1",
    "a=$(( (i - 1) * total / N + 1 )); b=$(( i * total / N ))",
    "rc=0",
    "if [ \"$a\" -le \"$b\" ]; then",
    "  \"$G\" run \"$R\" -q -o \"$part.cli\" --stats \"$part.yaml\" \"${D[@]}\" -D \"layers=$a:$b\"",
    "  rc=$?",
    "fi",
    "echo $rc > \"$part.status.tmp\" && mv \"$part.status.tmp\" \"$part.status\"",
    "exit $rc",
  }
  return table.concat(L, "\n") .. "\n"
end

-- Is part i finished (status 0, its CLI and stats there, or an empty range)?
local function part_done(work, i, n, total)
  local base = part_base(work, i)
  if status_of(base .. ".status") ~= 0 then return false end
  local a, b = M.range(i, n, total)
  if a > b then return true end
  local f = io.open(base .. ".cli")
  if not f then return false end
  f:close()
  local ok, st = pcall(gradus.yaml.load, base .. ".yaml")
  return ok and type(st) == "table" and st.layers == b - a + 1
end

-- The work directory of this command: kept when the recipe, values and N
-- are those of the last submission, else emptied.
local function prepare_work(work, id)
  gradus.mkdir(work)
  if read_all(work .. "/job.id") == id then return false end
  local p = io.popen("ls " .. q(work))
  for name in p:lines() do
    if name:match("^part%d+%.") or name:match("^templates%.") or name == "layers_total" then os.remove(work .. "/" .. name) end
  end
  p:close()
  gradus.write_file(work .. "/job.id", id)
  return true
end

local function failed_parts(work, list, total, n)
  local lines = {}
  for _, i in ipairs(list) do
    local base = part_base(work, i)
    local a, b = M.range(i, n, total)
    local st = status_of(base .. ".status")
    lines[#lines + 1] = ("slurm: part %d (layers %d-%d) failed (%s); log %s.log"):format(i, a, b,
      st and ("exit status " .. st) or "no exit status: killed or timed out", base)
  end
  return table.concat(lines, "\n")
end

-- Submit what is left of the split job and wait for it. Returns the number
-- of layers or nil, message. times: wall seconds of the stages (filled in).
local function submit_and_follow(recipe, work, n, params, order, so, quiet, times)
  local t0 = gradus.clock()
  local script = work .. "/job.sbatch"
  gradus.write_file(script, run_script(recipe, work, n, params, order, so))
  local tid
  local total = tonumber(read_all(work .. "/layers_total") or "")
  if not total then
    os.remove(work .. "/templates.status")
    local err
    tid, err = slurm.submit("--output=" .. q(work .. "/templates.log"), script, "templates")
    if not tid then return nil, err end
    print(("slurm: submitted job %s: templates (%s templates)"):format(tid, script))
  end
  local todo = {}
  for i = 1, n do
    if not (total and part_done(work, i, n, total)) then todo[#todo + 1] = i end
  end
  if tid then slurm.remember(work .. "/slurm.jobs", { tid }) end
  if #todo < n then print(("slurm: %d of %d parts finished earlier"):format(n - #todo, n)) end
  local lid
  if #todo > 0 then
    for _, i in ipairs(todo) do os.remove(part_base(work, i) .. ".status") end
    local spec = slurm.array_spec(todo) .. (so.max_tasks and ("%" .. so.max_tasks) or "")
    local err
    lid, err = slurm.submit("--array=" .. spec .. (tid and (" --dependency=afterok:" .. tid) or ""), script, "layers")
    if not lid then
      if tid then os.execute("scancel " .. tid) end
      return nil, err
    end
    slurm.remember(work .. "/slurm.jobs", { tid or lid, lid })
    print(("slurm: submitted job %s: layers --array=%s of %d"):format(lid, spec, n))
  end
  io.stdout:flush()
  if tid then
    local st = slurm.follow(tid, { { status = work .. "/templates.status" } }, "templates", quiet)
    if st[1] ~= 0 then
      if lid then os.execute("scancel " .. lid .. " >/dev/null 2>&1") end
      return nil, ("the templates stage failed; log %s/templates.log"):format(work)
    end
    total = tonumber(read_all(work .. "/layers_total") or "")
  end
  times.templates_s = gradus.clock() - t0
  if lid then
    local tasks = {}
    for k, i in ipairs(todo) do tasks[k] = { status = part_base(work, i) .. ".status" } end
    slurm.follow(lid, tasks, "layers", quiet)
  end
  times.layers_s = gradus.clock() - t0 - times.templates_s
  local bad = {}
  for i = 1, n do if not part_done(work, i, n, total) then bad[#bad + 1] = i end end
  if #bad > 0 then
    return nil, failed_parts(work, bad, total, n) .. "\nslurm: the same command again submits only these parts"
  end
  return total
end

--- gradus run RECIPE [-D ...] -o FILE [--stats FILE] --slurm N [--partition P]
-- [--time T] [--mem M] [--max-tasks K]
function M.main(args)
  local host = require "gradus.host"
  local ok, rest, so = pcall(slurm.strip_options, args, true)
  if not ok then eprint("gradus: " .. rest) return 2 end
  local pok, o = pcall(host.parse_args, rest, 2)
  if not pok then eprint("gradus: " .. o) return 2 end
  local recipe = o.rest[1]
  if not recipe or #o.rest > 1 then eprint("usage: gradus run RECIPE [-D name=value]... -o FILE.cli --slurm N") return 2 end
  if not o.output then eprint("gradus: --slurm needs -o FILE.cli (where the parts are merged)") return 2 end
  local f = io.open(recipe, "r")
  if not f then eprint("gradus: cannot open recipe " .. recipe) return 1 end
  f:close()
  if o.params.layers then eprint("gradus: --slurm splits the layers itself: drop -D layers=" .. o.params.layers) return 2 end
  local why = slurm.missing()
  if why then eprint(why) return 1 end
  local n = so.slurm
  local out = abs(o.output)
  local work = strip_cli(out) .. ".parts"
  local params, order = {}, {}
  for _, k in ipairs(o.order) do params[k], order[#order + 1] = o.params[k], k end
  -- one knowledge base for every task, on a file system they all see
  if params.kb == nil or params.kb == "" then
    params.kb, order[#order + 1] = gradus.kb.default_dir(), "kb"
  elseif params.kb ~= "off" then
    params.kb = abs(params.kb)
  end
  local id = { abs(recipe), "N=" .. n }
  for _, k in ipairs(order) do id[#id + 1] = k .. "=" .. params[k] end
  gradus.mkdir(work)
  slurm.adopt(work .. "/slurm.jobs")
  if prepare_work(work, table.concat(id, "\n") .. "\n") then
    print(("slurm: %s: %d layer tasks, knowledge base %s"):format(work, n, params.kb))
  end
  if params.kb ~= "off" then gradus.mkdir(params.kb) end
  for _, d in ipairs({ { work, "work directory" }, { params.kb ~= "off" and params.kb or nil, "knowledge base" } }) do
    local note = d[1] and slurm.local_fs_note(d[1], d[2])
    if note then print(note) end
  end
  local times = { tasks = n }
  local total, err = submit_and_follow(recipe, work, n, params, order, so, o.quiet, times)
  if not total then eprint("gradus: " .. err) return 1 end
  local parts = {}
  for i = 1, n do
    local a, b = M.range(i, n, total)
    if a <= b then parts[#parts + 1] = part_base(work, i) .. ".cli" end
  end
  local t1 = gradus.clock()
  local cok, info = pcall(M.cat, parts, o.output, o.stats, { slurm = times })
  if not cok then eprint("gradus: " .. tostring(info)) return 1 end
  times.merge_s = gradus.clock() - t1
  if o.stats then -- the merge's own time, now known
    local st = gradus.yaml.load(o.stats)
    st.slurm.merge_s = times.merge_s
    gradus.yaml.save(o.stats, st)
  end
  print(("%s: %d layers merged from %d parts (%s)"):format(o.output, info.layers, #parts, work))
  print(("slurm: wall time: templates stage %.1f s (from submission), layer tasks %.1f s, merge %.1f s")
    :format(times.templates_s, times.layers_s, times.merge_s))
  return 0
end

return M
