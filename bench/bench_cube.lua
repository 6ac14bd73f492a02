-- The part-scale benchmark of issue 5: a 40 mm cube of 2 mm graded P cells
-- (20 x 20 x 20 = 8000 voxels, half-thickness graded along the height,
-- 1000 layers of 0.04 mm) to a binary CLI. Runs, each a separate process so
-- that peak memory is its own:
--   cold   knowledge base empty
--   warm   the same job again (every template from the knowledge base)
--   direct kb=off (every voxel computed directly) on the first layers
--   floor  writing as many bytes from memory (the time to write the output alone)
local direct_layers = gradus.param("direct_layers", 5, { integer = true, min = 1, max = 1000,
  help = "layers of the kb=off run" }) -- declared before the first action
local exe = gradus.root .. "/build/gradus"
local tmp = os.getenv("TMPDIR") or "/tmp"
local dir = tmp .. "/gradus_bench_cube"
os.execute("rm -rf '" .. dir .. "'")
gradus.mkdir(dir)
local common = "-D cells=20,20,20 -D cell=2 -D layer=0.04 -D hatch=0.05 -D format=binary " ..
  "-D 'thickness=0.06 + 0.002*z' -D res=40 -q"

local function run(name, extra)
  local stats = dir .. "/" .. name .. ".yaml"
  -- flush earlier runs' output to disk first, so each run pays for its own writes only
  os.execute("sync")
  local t0 = gradus.clock()
  local ok = os.execute(("'%s' run '%s/recipes/lattice.lua' %s %s -o '%s/%s.cli' --stats '%s'")
    :format(exe, gradus.root, common, extra, dir, name, stats))
  local wall = gradus.clock() - t0
  if not ok then error("benchmark run '" .. name .. "' failed") end
  return gradus.yaml.load(stats), wall
end

local kb = dir .. "/kb"
local cold, tcold = run("cold", "-D kb=" .. kb)
local warm, twarm = run("warm", "-D kb=" .. kb)
local direct, tdirect = run("direct", "-D kb=off -D layers=1:" .. direct_layers)
local f = io.open(dir .. "/cold.cli", "rb")
local bytes = f:seek("end")
f:close()
-- the floor: writing as many bytes from memory the way the CLI writer does
-- (4 MiB blocks, O_DIRECT), and through the page cache for comparison
local function timed(cmd)
  os.execute("sync")
  local t0 = gradus.clock()
  os.execute(cmd)
  return gradus.clock() - t0
end
local blocks = math.ceil(bytes / 2 ^ 22)
local tfloor = timed(("dd if=/dev/zero of='%s/floor.bin' bs=4M count=%d oflag=direct status=none"):format(dir, blocks))
local tcache = timed(("dd if=/dev/zero of='%s/floor2.bin' bs=4M count=%d status=none"):format(dir, blocks))

local per_layer_kb = twarm / cold.layers
local per_layer_direct = tdirect / direct.layers
print(("cube 40 mm, 8000 voxels, %d layers, %d classes (reuse %.0fx), CLI %.1f MB"):format(cold.layers,
  cold.templates.unique, cold.templates.voxels_per_template, bytes / 2 ^ 20))
print(("  cold knowledge base: %6.2f s wall (templates %.2f s, layers %.2f s of which writing %.2f s), peak RSS %.0f MB"):format(tcold,
  cold.seconds.templates, cold.seconds.layers, cold.seconds.write, cold.peak_rss_mb))
print(("  warm knowledge base: %6.2f s wall (layers %.2f s of which writing %.2f s), peak RSS %.0f MB, %d templates built"):format(twarm,
  warm.seconds.layers, warm.seconds.write, warm.peak_rss_mb, warm.templates.built))
print(("  direct (kb=off):     %6.2f s for %d layers = %.3f s/layer (warm kb: %.4f s/layer) -> speed-up %.0fx"):format(
  tdirect, direct.layers, per_layer_direct, per_layer_kb, per_layer_direct / per_layer_kb))
print(("  write floor: %.1f MB from memory took %.2f s direct (%.0f MB/s; through the page cache %.2f s); the warm job is %.1fx the floor"):format(
  bytes / 2 ^ 20, tfloor, bytes / 2 ^ 20 / tfloor, tcache, twarm / tfloor))
os.execute("rm -rf '" .. dir .. "'")
