-- A part of any size (lattice parameter `size`, gradus.part): cells enough
-- to cover it, the lattice cut and contoured at the faces inside a cell, the
-- layer count round(Z / layer), the CLI header's extent the part's (also for
-- a range of layers); a size of whole cells is the same job as `cells`.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local function params(o) return t.lattice_params({ thickness = "0.08", kb = tmp .. "/kb", res = 20, threads = 2 }, o) end

-- Largest x and y of the closed contours, and of the open (thin-wall) lines.
local function extent(cli)
  local c, o = { -math.huge, -math.huge }, { -math.huge, -math.huge }
  for _, l in ipairs(cli.layers) do
    for _, b in ipairs(l:blocks()) do
      local m = b.shape == "closed" and c or o
      for q = 1, #b.points, 2 do m[1], m[2] = math.max(m[1], b.points[q]), math.max(m[2], b.points[q + 1]) end
    end
  end
  return c, o
end

t.test("size 5 x 4 x 2.4 mm with 2 mm cells: cut and contoured at x = 5, 60 layers", function()
  local out = tmp .. "/s.cli"
  local st = lattice.run(params { size = "5,4,2.4" }, out)
  t.eq(st.layers, 60, "layers = 2.4 / 0.04")
  -- the cut at x = 5 is a box solid (gradus.part), its other faces 10 cells away: the column of
  -- voxels it trims (2 per row of voxels) all see the same face and share one template
  t.eq(st.trimmed_voxels, 4, "the voxels the cut at x = 5 trims")
  t.eq(st.trimmed_templates, 1, "one template for the voxels along the cut")
  local cli = gradus.cli.read(out)
  t.eq(#cli.layers, 60, "layers in the file")
  t.near(cli.layers[60]:z(), 2.4, 1e-6, "top layer at the part's height")
  local d = cli.header.dimension
  for a, v in ipairs({ 0, 0, 0, 5, 4, 2.4 }) do t.near(d[a], v, 1e-6, "header dimension " .. a) end
  local c, o = extent(cli)
  local b = st.effective.beam_offset
  t.near(c[1], 5 - b, 1e-3, "closed contours along the cut face x = 5 at the beam offset")
  -- (contours are kept to 5e-6 mm past a cut side, GR_FACE_EPS in engine/template.h)
  t.ok(c[2] <= 4 - b + 6e-6, "no closed contour beyond y = 4 - b")
  t.ok(o[1] <= 5 and o[2] <= 4, ("open (thin-wall, hatch) lines inside the part (%g, %g)"):format(o[1], o[2]))
end)

t.test("a range of layers: the header gives the heights written", function()
  local out = tmp .. "/r.cli"
  lattice.run(params { cells = "2,2,3", layers = "1:125" }, out)
  local d = gradus.cli.read(out).header.dimension
  t.near(d[3], 0, 1e-9, "from z = 0")
  t.near(d[6], 5, 1e-6, "to 125 x 0.04 = 5 mm, not the 6 mm of the cells")
  lattice.run(params { cells = "2,2,3", layers = "26:50" }, out)
  d = gradus.cli.read(out).header.dimension
  t.near(d[3], 1, 1e-6, "layers 26:50 start at z = 1")
  t.near(d[6], 2, 1e-6, "and end at z = 2")
end)

t.test("a size of whole cells is the job of cells; bad sizes", function()
  local a, b = tmp .. "/a.cli", tmp .. "/b.cli"
  lattice.run(params { size = "4,4,2" }, a)
  lattice.run(params { cells = "2,2,1" }, b)
  local fa, fb = io.open(a):read("a"), io.open(b):read("a")
  t.ok(fa == fb, "size=4,4,2 writes the same file as cells=2,2,1")
  t.raises(function() lattice.run(params { size = "5,0,2" }, nil) end, "parameter 'size' must be 3 numbers in")
  t.raises(function() lattice.run(params { size = "5,4" }, nil) end, "parameter 'size' must be 3 numbers")
  t.raises(function() lattice.run(params { size = "5,4,2", faces = false }, nil) end, "faces=false")
  t.ok(not io.open(tmp .. "/none.cli"), "no output")
end)

t.done()
