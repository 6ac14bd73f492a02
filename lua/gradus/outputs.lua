-- gradus.outputs: the outputs of a job (CLI files, manifest, stats, pictures)
-- as one transaction, and the guards every output goes through.
--
--   outputs.job(fn, ...)  run fn(...) as a job: every output written while it
--       runs goes to a temporary "<path>.tmp<PID>" beside its path; when fn
--       returns, each temporary is checked and renamed into place; when fn
--       raises (or Ctrl-C stops it), every temporary is removed and no output
--       is replaced. Jobs nest: an inner job's outputs join the outer one.
--   outputs.stage(path) -> the path a writer must write now (the temporary
--       inside a job, path itself outside one). Refuses a path that exists
--       and is not a regular file (a device, FIFO, socket, directory or
--       symbolic link), and sweeps the directory once (outputs.sweep).
--   outputs.check(path)  the refusal alone (and the sandbox's, when on).
--   outputs.guard(path, mode)  the sandbox's refusal alone ("r" or "w").
--   outputs.sweep(dir) -> names removed: temporaries "<file>.<ext>.tmp<PID>"
--       (ext one of the output extensions) whose process no longer runs,
--       said on stderr. Done once per directory and process.
local gradus = require "gradus"
local fs = gradus.fs
local M = {}

local EXT = { cli = true, yaml = true, svg = true, png = true, csv = true, stl = true, ply = true, obj = true }

local function dirname(p) return p:match("^(.*)/[^/]*$") or "." end

-- the open transactions of the running job, innermost last
local function open_jobs()
  local ctx = gradus._ctx
  ctx.outputs = ctx.outputs or {}
  return ctx.outputs
end

--- outputs.guard(path, mode): ask the sandbox (when on) whether path may be
-- read ("r") or written ("w"); raises its refusal. The C readers call it.
function M.guard(path, mode)
  local sb = gradus._ctx.sandbox
  if sb then sb:allow(path, mode) end
end

function M.check(path)
  M.guard(path, "w")
  local why = fs.refusal(path)
  if why then error(("cannot write %s: it is %s (only regular files are replaced)"):format(path, why), 0) end
end

-- The process id in a temporary's name when it is one of ours, else nil.
local function temp_owner(name)
  local base, pid = name:match("^(.-)%.tmp(%d+)$")
  if not base then return nil end
  while base:match("%.tmp%d+$") do base = base:gsub("%.tmp%d+$", "") end
  local ext = base:match("%.(%w+)$")
  return ext and EXT[ext:lower()] and tonumber(pid) or nil
end

local swept = {}
function M.sweep(dir)
  if swept[dir] then return {} end
  swept[dir] = true
  local removed = {}
  local me = fs.pid()
  for _, name in ipairs(fs.list(dir) or {}) do
    local pid = temp_owner(name)
    local path = dir .. "/" .. name
    if pid and pid ~= me and not fs.alive(pid) and fs.kind(path) == "file" and os.remove(path) then
      removed[#removed + 1] = name
    end
  end
  if #removed > 0 then
    table.sort(removed)
    io.stderr:write(("gradus: removed %d temporary file(s) that stopped jobs left in %s: %s\n")
      :format(#removed, dir, table.concat(removed, ", ")))
  end
  return removed
end

function M.stage(path)
  M.check(path)
  M.sweep(dirname(path))
  local jobs = open_jobs()
  local tx = jobs[#jobs]
  if not tx then return path end
  if not tx.staged[path] then
    tx.staged[path] = path .. ".tmp" .. fs.pid()
    tx.order[#tx.order + 1] = path
  end
  return tx.staged[path]
end

-- Remove every temporary of tx (and a writer's own temporary inside it).
-- Returns the names removed.
local function abort(tx)
  local removed = {}
  for _, path in ipairs(tx.order) do
    local tmp = tx.staged[path]
    for _, f in ipairs({ tmp, tmp .. ".tmp" .. fs.pid() }) do
      if fs.kind(f) == "file" and os.remove(f) then removed[#removed + 1] = f end
    end
  end
  return removed
end

-- Every temporary complete, every target still replaceable: rename them all.
local function commit(tx)
  for _, path in ipairs(tx.order) do
    if fs.kind(tx.staged[path]) ~= "file" then
      abort(tx)
      error(("output %s was not written (its temporary %s is missing)"):format(path, tx.staged[path]), 0)
    end
    local ok, err = pcall(M.check, path)
    if not ok then abort(tx) error(err, 0) end
  end
  for i, path in ipairs(tx.order) do
    local ok, err = os.rename(tx.staged[path], path)
    if not ok then
      local rest = { staged = tx.staged, order = { table.unpack(tx.order, i) } }
      abort(rest)
      error(("cannot write %s: %s (%d of %d outputs were already in place)"):format(path, tostring(err), i - 1, #tx.order), 0)
    end
  end
end

function M.job(fn, ...)
  local jobs = open_jobs()
  local tx = { staged = {}, order = {} }
  jobs[#jobs + 1] = tx
  local res = table.pack(pcall(fn, ...))
  for i = #jobs, 1, -1 do if jobs[i] == tx then table.remove(jobs, i) end end
  if not res[1] then
    gradus._ctx.removed_temporaries = abort(tx)
    error(res[2], 0)
  end
  local outer = jobs[#jobs]
  if outer then -- the outer job renames them with its own outputs
    for _, path in ipairs(tx.order) do
      if not outer.staged[path] then outer.order[#outer.order + 1] = path end
      outer.staged[path] = tx.staged[path]
    end
  else
    commit(tx)
  end
  return table.unpack(res, 2, res.n)
end

return M
