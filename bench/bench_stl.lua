-- An STL part at 1,000 cells (issue 14): the L-bracket of
-- recipes/plate_bracket.lua (20 x 20 x 20 mm, foot and upright 6 mm thick,
-- 20 triangles) as the domain of a 10 x 10 x 10 gyroid sheet of 2 mm cells
-- (half-thickness 0.15 mm, solid skin 0.4 mm, exact mode, binary CLI, 500
-- layers, a fresh knowledge base), against the same box of cells uncut,
-- both in the same run. Reports CPU (user + system), wall time, trimmed
-- voxels and the templates they needed (voxels along a face that see the
-- same piece of the boundary share one), peak RSS and the cut/uncut ratio.
-- The issue's target: the STL part in <= 30 s.
local benchjob = require "gradus.benchjob"
local threads = gradus.param("threads", 2, { integer = true, min = 1, max = 64, help = "worker threads of each job" })
local tmp = os.getenv("TMPDIR") or "/tmp"
local dir = tmp .. "/gradus_bench_stl." .. tostring(os.time()) .. tostring(math.random(1e6))
gradus.mkdir(dir)
local stl = dir .. "/bracket.stl"
local ok = os.execute(("'%s/build/gradus' run '%s/recipes/plate_bracket.lua' -D length=20 -D depth=20 -D height=20 " ..
  "-D foot=6 -D wall=6 -q -o '%s' >/dev/null"):format(gradus.root, gradus.root, stl))
if not ok then error("cannot write the bracket's STL") end

local common = ("-D surface=gyroid -D cells=10,10,10 -D thickness=0.15 -D format=binary -D threads=%d"):format(threads)
print(("STL domain: L-bracket 20 x 20 x 20 mm (20 triangles), gyroid sheet T = 0.15 mm, 2 mm cells 10 x 10 x 10, skin 0.4 mm, exact, res 40, 500 layers, %d threads"):format(threads))
print("  job        voxels  trimmed  trimmed templates  templates   CPU s   wall s  peak RSS MB  CPU ratio")
local rows = {}
for _, r in ipairs({ { "uncut", "" }, { "bracket", ("-D domain='%s' -D skin=0.4"):format(stl) } }) do
  local st, cpu, wall = benchjob.run(dir, r[1], ("%s -D kb='%s/kb_%s' %s"):format(common, dir, r[1], r[2]))
  rows[#rows + 1] = cpu
  print(("  %-9s  %6d  %7d  %17d  %9d  %6.2f  %7.2f  %11.0f  %s"):format(r[1], st.voxels, st.trimmed_voxels or 0,
    st.trimmed_templates or 0, st.templates.unique, cpu, wall, st.peak_rss_mb,
    #rows == 2 and ("%.1fx"):format(rows[2] / rows[1]) or ""))
end
os.execute("rm -rf '" .. dir .. "'")
