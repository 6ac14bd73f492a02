-- OVF against binary CLI on the part-scale benchmark of bench_cube.lua (a
-- 40 mm cube of 2 mm graded P cells, 8000 voxels, 1000 layers), both with a
-- warm knowledge base so that the layers and the writer dominate. Reports
-- the wall time and the time spent writing of each format (best of `runs`,
-- the formats alternating so that a load change hits both), the bytes, and
-- the time to read one work plane through the LUTs against one pass over
-- the whole file. Targets (issue 22): OVF <= 1.2x the time of the job and <=
-- 1.1x the bytes of the binary CLI; one work plane in milliseconds. The time
-- spent writing alone is shown too (it moves with the disk: 1.13-1.48x in
-- one session, doc/performance.md).
local exe = gradus.root .. "/build/gradus"
local tmp = os.getenv("TMPDIR") or "/tmp"
local dir = tmp .. "/gradus_bench_ovf"
os.execute("rm -rf '" .. dir .. "'")
gradus.mkdir(dir)
local runs = gradus.param("runs", 2)
local common = "-D cells=20,20,20 -D cell=2 -D layer=0.04 -D hatch=0.05 " ..
  "-D 'thickness=0.06 + 0.002*z' -D res=40 -q -D kb=" .. dir .. "/kb"

local function run(name, extra, out)
  local stats = dir .. "/" .. name .. ".yaml"
  os.execute("sync")
  local t0 = gradus.clock()
  local ok = os.execute(("'%s' run '%s/recipes/lattice.lua' %s %s -o '%s' --stats '%s'")
    :format(exe, gradus.root, common, extra, out, stats))
  local wall = gradus.clock() - t0
  if not ok then error("benchmark run '" .. name .. "' failed") end
  local st = gradus.yaml.load(stats)
  os.remove(stats)
  return wall, st.seconds.write
end
local function size(path)
  local f = assert(io.open(path, "rb"))
  local n = f:seek("end")
  f:close()
  return n
end

local cli, ovf = dir .. "/cube.cli", dir .. "/cube.ovf"
local tcold = run("cold", "-D format=binary-long", cli) -- fills the knowledge base
local best = { cli = { math.huge, math.huge }, ovf = { math.huge, math.huge } }
for _ = 1, runs do
  for _, f in ipairs({ { "cli", "-D format=binary-long", cli }, { "ovf", "-D format=ovf", ovf } }) do
    local wall, write = run(f[1], f[2], f[3])
    best[f[1]][1] = math.min(best[f[1]][1], wall)
    best[f[1]][2] = math.min(best[f[1]][2], write)
  end
end
local bc, bo = size(cli), size(ovf)
-- one work plane through the LUTs (in this process) against a pass over the file
local reps, t0 = 20, gradus.clock()
local plane
for i = 1, reps do plane = gradus.ovf.plane(ovf, 500 + i) end
local tplane = (gradus.clock() - t0) / reps
t0 = gradus.clock()
local info = gradus.info(ovf)
local tpass = gradus.clock() - t0
print(("OVF vs binary CLI, cube 40 mm, 8000 voxels, %d layers (warm knowledge base; cold run %.1f s; best of %d)")
  :format(info.layers, tcold, runs))
print(("  binary CLI: %6.2f s wall, writing %.2f s, %.1f MB"):format(best.cli[1], best.cli[2], bc / 2 ^ 20))
print(("  OVF:        %6.2f s wall, writing %.2f s, %.1f MB"):format(best.ovf[1], best.ovf[2], bo / 2 ^ 20))
print(("  ratio OVF/CLI: wall %.2fx (target <= 1.2x), writing alone %.2fx, bytes %.3fx (target <= 1.1x)")
  :format(best.ovf[1] / best.cli[1], best.ovf[2] / best.cli[2], bo / bc))
print(("  one work plane through the LUTs: %.2f ms (%d blocks); a pass over the whole file: %.2f s")
  :format(tplane * 1000, #plane:blocks(), tpass))
os.execute("rm -rf '" .. dir .. "'")
