-- Continuous grading at part scale (issue 14): an n x n x n P sheet of 2 mm
-- cells whose half-thickness varies smoothly over the whole part,
--   T = 0.1 + 0.04*sin(x/3)*cos(y/2.5) + 0.004*z   (every voxel unique)
-- against the same part at constant thickness 0.1 (one voxel class), each
-- size measured in the same run, each job a separate process with a fresh
-- knowledge base. Reports the CPU time of the process (user + system, from
-- the shell's `times`: meaningful on a loaded machine where wall time is
-- not), CPU per unique voxel-layer, peak RSS, the most templates held at
-- once (streamed row by row of voxels), the continuous/constant CPU ratio
-- and the marginal CPU per unique voxel-layer (the two jobs' difference in
-- CPU per unique voxel-layer beyond the constant job's one: fixed costs
-- apart), at three sizes (2, 3 and 4 cells a side). `-D sizes=2,3,4,6`
-- adds the issue's 6 x 6 x 6 (about a minute of CPU);
-- `-D extra='-D kb_store=all'` passes options to every job. Last, the same
-- grading about a thin and a thick mean on 3 x 3 x 1 cells (thick sheets cost
-- several times more per voxel-layer).
local sizes_s = gradus.param("sizes", "2,3,4", { help = "cube sizes n (cells per side), comma-separated" })
local extra = gradus.param("extra", "", { help = "more -D options for every job" })
local benchjob = require "gradus.benchjob"
local tmp = os.getenv("TMPDIR") or "/tmp"
local dir = tmp .. "/gradus_bench_continuous." .. tostring(os.time()) .. tostring(math.random(1e6))
gradus.mkdir(dir)
local CONT = "0.1+0.04*sin(x/3)*cos(y/2.5)+0.004*z"

-- one job: its stats, CPU seconds (user + system of the child) and wall seconds
local function run(name, n, thickness)
  return benchjob.run(dir, name, ("-D cells=%d,%d,%d -D format=binary -D 'thickness=%s' -D kb='%s/kb_%s' %s")
    :format(n, n, n, thickness, dir, name, extra))
end

print(("continuous grading, P sheet, cell 2 mm, layer 0.04, exact mode, res 40, T = %s %s"):format(CONT, extra))
print("  size     job         classes  built  stored  held   CPU s   wall s  ms CPU/unique voxel-layer  peak RSS MB  CPU ratio  marginal ms")
for s in sizes_s:gmatch("%d+") do
  local n = tonumber(s)
  local const, ccpu, cwall = run("const" .. n, n, "0.1")
  local cont, tcpu, twall = run("cont" .. n, n, CONT)
  for _, r in ipairs({ { "constant", const, ccpu, cwall }, { "continuous", cont, tcpu, twall } }) do
    local st = r[2]
    local per_voxel = st.layers / n -- local layers of one voxel
    local vl = st.templates.unique * per_voxel
    local stored = st.templates.stored and tostring(st.templates.stored) or "-"
    -- marginal: the continuous job's CPU less the constant job's, per unique voxel-layer beyond
    -- the constant job's one class (what each more unique voxel-layer costs, fixed costs apart)
    local cont_row = r[1] == "continuous"
    local marginal = cont_row and 1000 * (tcpu - ccpu) / ((st.templates.unique - 1) * per_voxel) or nil
    print(("  %dx%dx%d  %-10s  %7d  %5d  %6s  %4s  %6.2f  %7.2f  %24.2f  %11.0f  %9s  %11s"):format(n, n, n, r[1],
      st.templates.unique, st.templates.built, stored, tostring(st.templates.held_max or "-"), r[3], r[4],
      1000 * r[3] / vl, st.peak_rss_mb, cont_row and ("%.1fx"):format(tcpu / ccpu) or "",
      marginal and ("%.2f"):format(marginal) or ""))
  end
end
-- The thickness matters as much as the count: a 3 x 3 x 1 block (9 unique
-- voxels) with the same grading about a thin and a thick mean. Thick sheets
-- lie beyond the surface's reach, where every refined point searches the
-- mesh for a nearer patch (doc/performance.md, "The 20 x 20 x 20 continuous
-- cube, run").
print("thickness effect: 3x3x1 cells, kb off (9 unique voxels, 50 layers; fixed costs included)")
for _, th in ipairs({ "0.1+0.04*sin(x/3)*cos(y/2.5)", "0.26+0.04*sin(x/3)*cos(y/2.5)" }) do
  local st, cpu = benchjob.run(dir, "thick", ("-D cells=3,3,1 -D format=binary -D kb=off -D 'thickness=%s' %s")
    :format(th, extra))
  print(("  T = %-30s  CPU %6.2f s  %6.2f ms per unique voxel-layer"):format(th, cpu,
    1000 * cpu / (st.templates.unique * st.layers)))
end
os.execute("rm -rf '" .. dir .. "'")
