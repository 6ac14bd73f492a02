-- kb_store=all|reused|none (issue 14): a 2 x 2 x 1 block whose thickness is
-- constant except in voxel (1,1) has two classes, one of three voxels and
-- one of a single voxel. reused (the default) stores only the first; all
-- stores both; none stores nothing; the stats and the directory agree, and a
-- second run reuses exactly what was stored.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local function run(dir, store)
  local p = lattice.params()
  p.cells, p.kb, p.layers, p.res, p.mode, p.layer = "2,2,1", dir, "1:2", 20, "mesh", 0.2
  p.thickness = "0.08 + 0.02*max(x-2,0)*max(y-2,0)"
  if store then p.kb_store = store end
  return lattice.run(p, nil)
end
local function records(dir) return #gradus.kb.list(dir) end

t.test("kb_store=reused (default) stores only classes that occur more than once", function()
  local dir = tmp .. "/reused"
  local st = run(dir)
  t.eq(st.templates.unique, 2, "two classes")
  t.eq(st.templates.built, 2, "both built")
  t.eq(st.templates.stored, 1, "one stored")
  t.eq(st.templates.not_stored, 1, "the single-voxel class not stored")
  t.eq(records(dir), 1, "one record on disk")
  local warm = run(dir)
  t.eq(warm.templates.reused, 1, "warm: the stored class is reused")
  t.eq(warm.templates.built, 1, "warm: the unstored class is built again")
end)

t.test("kb_store=all stores every class, none stores nothing", function()
  local all = run(tmp .. "/all", "all")
  t.eq(all.templates.stored, 2, "all: both stored")
  t.eq(all.templates.not_stored, 0, "all: none skipped")
  t.eq(records(tmp .. "/all"), 2, "all: two records")
  local none = run(tmp .. "/none", "none")
  t.eq(none.templates.stored, 0, "none: nothing stored")
  t.eq(none.templates.not_stored, 2, "none: both skipped")
  t.eq(records(tmp .. "/none"), 0, "none: no record")
end)

t.test("a bad kb_store is an error naming it", function()
  local j = gradus.place.job { cell = 2, cells = { 1, 1, 1 }, layer = 0.04, hatch = 0.05, res = 20 }
  j:spec { surface = "primitive", thickness = "0.08" }
  t.raises(function() j:run { kb = tmp .. "/bad", kb_store = "some" } end, "kb_store")
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
