-- Trimmed voxels (issue 14): a voxel wholly inside an expression domain,
-- beyond the skin's reach, is an ordinary voxel. A 4 x 4 x 1 block of 2 mm
-- cells cut to a cylinder of radius 4.3 mm about the block's centre axis:
-- the four centre voxels (their corners at most 2.83 mm from the axis, so
-- at least 1.47 mm inside, more than skin + sample spacing) are not trimmed
-- and share one template; the twelve others reach beyond the cylinder
-- (their outer corners are 4.47 mm or more from the axis) and are trimmed.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local function run(domain)
  local p = lattice.params()
  p.cells, p.kb, p.layers, p.res, p.mode, p.layer = "4,4,1", tmp .. "/kb", "1:1", 20, "mesh", 0.2
  p.thickness, p.kb_store = "0.08", "none"
  p.domain, p.skin = domain, 0.1
  return lattice.run(p, nil)
end

t.test("voxels wholly inside an expression domain beyond the skin are ordinary, the others trimmed", function()
  local st = run("sqrt((x-4)^2+(y-4)^2)-4.3")
  t.eq(st.voxels, 16, "every voxel has lattice")
  t.eq(st.trimmed_voxels, 12, "the twelve outer voxels are trimmed")
  t.eq(st.templates.unique, 13, "the four inside voxels share one template")
end)

t.test("a voxel within the skin's reach stays trimmed", function()
  -- radius 4.0: the centre voxels, grown by the contour margin and the skin (0.175 mm), are
  -- inside (0.92 mm at their farthest sample) but within skin + sample spacing (0.69 mm) times
  -- the gradient's safety factor 1.5 of the boundary: still trimmed
  local st = run("sqrt((x-4)^2+(y-4)^2)-4.0")
  t.eq(st.trimmed_voxels, 16, "every voxel trimmed")
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
