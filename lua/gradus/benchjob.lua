-- gradus.benchjob: one lattice job run as its own process for the
-- benchmarks (bench/bench_*.lua), timed by CPU (user + system of the child,
-- from the shell's `times`: meaningful on a loaded machine, where wall time
-- is not) and by wall clock.
local gradus = require "gradus"
local M = {}

--- M.run(dir, name, args) -> stats table, CPU seconds, wall seconds.
-- Runs recipes/lattice.lua with `args` (a string of -D options, quoted for
-- the shell) writing dir/name.cli and dir/name.yaml (stats); errors if the
-- job fails.
function M.run(dir, name, args)
  local exe = gradus.root .. "/build/gradus"
  local stats, cpu = dir .. "/" .. name .. ".yaml", dir .. "/" .. name .. ".cpu"
  local cmd = ("'%s' run '%s/recipes/lattice.lua' %s -q -o '%s/%s.cli' --stats '%s'")
    :format(exe, gradus.root, args, dir, name, stats)
  local t0 = gradus.clock()
  local ok = os.execute(("bash -c %q > '%s'"):format(cmd .. " >/dev/null && times", cpu))
  local wall = gradus.clock() - t0
  if not ok then error("benchmark run '" .. name .. "' failed") end
  local f = assert(io.open(cpu))
  local text = f:read("a")
  f:close()
  -- `times` prints the shell's own times, then its children's: "0m1.5s 0m0.1s"
  local m1, s1, m2, s2 = text:match("\n(%d+)m([%d.]+)s%s+(%d+)m([%d.]+)s")
  if not m1 then error("cannot read the CPU time of run '" .. name .. "': " .. text) end
  return gradus.yaml.load(stats), m1 * 60 + s1 + m2 * 60 + s2, wall
end

return M
