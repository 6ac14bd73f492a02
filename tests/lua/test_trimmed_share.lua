-- Trimmed voxels that see the same piece of an STL domain's boundary share
-- a template (issue 14). A box part as an STL in a box of 6 x 2 x 1 cells of
-- 2 mm, every voxel within the skin's reach of a face, so all 12 trimmed.
-- A voxel's template needs the boundary within its window grown by the skin
-- and a quarter cell (under 1.5 mm here): along x, the four middle voxels of
-- a row see the same faces (y = Y0 or y = Y1, z = 0 and 2), the end ones
-- also x = X0 or x = X1; so 3 templates per row, 6 in all, against 12 when
-- computed directly. The section is checked against the box: the outer
-- contour is the box inset by the beam offset b, the skin's inner edge the
-- box inset by the skin less b. Two parts: 0.5 mm inside the box of cells,
-- and the box of cells itself, whose faces are the part's box too: there
-- the contour along the faces must be scanned once (it was also added as
-- short open pieces along the sides, 45 in one layer).
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

-- the box X0..X1 x Y0..Y1 x 0..2 as an STL file (gradus.mesh.box: 12 outward triangles)
local function box_stl(path, X0, X1, Y0, Y1)
  gradus.mesh.box({ X0, Y0, 0 }, { X1, Y1, 2 }):write(path)
end

local b, G = 0.05, 5 -- beam offset (mm); the layer checked (z = 0.9 mm)
local function run(kb, stl)
  local p = lattice.params()
  p.cells, p.kb, p.layers, p.res, p.mode, p.layer = "6,2,1", kb, G .. ":" .. G, 20, "exact", 0.2
  p.thickness, p.kb_store, p.hatch, p.beam_offset = "0.08", "none", 0.1, b
  p.domain, p.skin, p.pictures = stl, 0.3, tostring(G) -- kept in memory (no output path)
  return lattice.run(p, nil)
end

-- contour and hatch lengths of a layer, the number of open contours, the
-- largest ring (area, bounding box) and the largest hole (the skin's inner
-- edge, its bounding box)
local function measure(layer)
  local m = { c = 0, h = 0, open = 0 }
  for _, bk in ipairs(layer:blocks()) do
    local P, len = bk.points, 0
    local step = bk.shape == "segments" and 4 or 2
    for k = 1, #P - 3, step do len = len + math.sqrt((P[k + 2] - P[k]) ^ 2 + (P[k + 3] - P[k + 1]) ^ 2) end
    if bk.kind == "contour" then m.c = m.c + len else m.h = m.h + len end
    if bk.kind == "contour" and bk.shape == "open" then m.open = m.open + 1 end
    if bk.kind == "contour" and bk.shape == "closed" then
      local a, box = 0, { math.huge, math.huge, -math.huge, -math.huge }
      for k = 1, #P - 3, 2 do a = a + P[k] * P[k + 3] - P[k + 2] * P[k + 1] end
      for k = 1, #P - 1, 2 do
        box = { math.min(box[1], P[k]), math.min(box[2], P[k + 1]), math.max(box[3], P[k]), math.max(box[4], P[k + 1]) }
      end
      local r = { area = a / 2, box = box }
      if not m.ring or r.area > m.ring.area then m.ring = r end
      if not m.hole or r.area < m.hole.area then m.hole = r end
    end
  end
  return m
end

local function check(X0, X1, Y0, Y1)
  local stl = ("%s/box_%g.stl"):format(tmp, X0)
  box_stl(stl, X0, X1, Y0, Y1)
  local st, kept = run(tmp .. "/kb", stl)
  local sd, kd = run("off", stl)
  t.eq(st.trimmed_voxels, 12, "every voxel trimmed")
  t.eq(st.trimmed_templates, 6, "the four middle voxels of each row share one template")
  t.eq(sd.trimmed_templates, 12, "computed directly, every trimmed voxel on its own")
  for _, m in ipairs({ measure(kept[G]), measure(kd[G]) }) do
    t.eq(m.open, 0, "every contour closed")
    -- the part's faces: the box inset by b, one ring
    local W, H = X1 - X0 - 2 * b, Y1 - Y0 - 2 * b
    -- (the corners sharp: trimmed templates offset with chords refined; before, where the part's
    -- corner was the box of cells', the ring cut it by one slice cell, 0.005 mm^2 in all)
    t.near(m.ring.area, W * H, 1e-6 * W * H, "outer ring's area")
    local want = { X0 + b, Y0 + b, X1 - b, Y1 - b }
    for k = 1, 4 do t.near(m.ring.box[k], want[k], 1e-6, "outer ring, bound " .. k) end
    -- the skin's inner edge (d = -skin) inset by b: the largest hole spans the box less skin - b
    local s = 0.3 - b
    want = { X0 + s, Y0 + s, X1 - s, Y1 - s }
    for k = 1, 4 do t.near(m.hole.box[k], want[k], 1e-6, "skin's inner edge, bound " .. k) end
  end
  -- the shared templates give the section the direct computation gives
  local m, md = measure(kept[G]), measure(kd[G])
  t.near(m.c, md.c, 1e-4 * md.c, "contour length against the direct computation")
  t.near(m.h, md.h, 1e-4 * md.h, "hatch length against the direct computation")
end

t.test("trimmed voxels along a face share templates; the section is the box's", function()
  check(0.5, 11.5, 0.5, 3.5)
end)

t.test("a part whose faces are the box of cells' is contoured once along them", function()
  check(0, 12, 0, 4)
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
