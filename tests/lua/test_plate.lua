-- A build plate (gradus.plate, gradus.cli.plate): parts placed (rotated
-- about z, translated) and merged by z into one CLI; per-part stats beside
-- the plate's; bad plates refused by name with no output left.
local t = require "gradus.testing"
local plate = require "gradus.plate"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

local function write(name, text)
  local f = assert(io.open(tmp .. "/" .. name, "w"))
  f:write(text)
  f:close()
  return tmp .. "/" .. name
end
local function exists(p) return gradus.fs.kind(p) ~= nil end

-- small, quick parts: 2 mm cells, 0.2 mm layers, coarse surfaces
local PART = "    surface: primitive\n    cell: 2\n    hatch: 0.1\n    thickness: 0.2\n"
local HEAD = ("layer: 0.2\nformat: ascii\nres: 8\nkb: %s/kb\nplate: {lo: [0, 0], hi: [100, 100]}\n"):format(tmp)

-- plate layer g's blocks, and all points of a layer as a list of {x, y}
local function points(layer)
  local out = {}
  for _, b in ipairs(layer:blocks()) do
    for q = 1, #b.points, 2 do out[#out + 1] = { b.points[q], b.points[q + 1] } end
  end
  return out
end

t.test("engine: a part rotated by 90 degrees and moved lands at at + R(q - c), point by point", function()
  local own = tmp .. "/own.cli"
  local p = lattice.params()
  p.surface, p.cell, p.size, p.hatch, p.thickness, p.res, p.layer, p.kb = "primitive", 2, "4,2,0.4", 0.1, "0.2", 8, 0.2, tmp .. "/kb"
  lattice.run(p, own)
  local pl = gradus.cli.plate()
  t.eq(pl:add(own, { name = "box", at = { 50, 60 }, rotation = 90 }), 1, "part number")
  local info = pl:part(1)
  t.eq(info.layers, 2, "layers of the part")
  t.near(info.centre[1], 2, 1e-9, "centre x of the 4 x 2 box")
  t.near(info.centre[2], 1, 1e-9, "centre y")
  local w, kept = pl:write(tmp .. "/rot.cli", { layer = 0.2, format = "ascii", keep = 1 })
  t.eq(w.layers, 2, "plate layers")
  local before = points(gradus.cli.read(own).layers[1])
  local after = points(kept)
  t.eq(#after, #before, "every point kept")
  t.ok(#after > 10, "the layer has vectors")
  for k, q in ipairs(before) do -- R(90) (x, y) = (-y, x)
    t.near(after[k][1], 50 - (q[2] - 1), 1e-4, "x of point " .. k)
    t.near(after[k][2], 60 + (q[1] - 2), 1e-4, "y of point " .. k)
  end
  -- the placed 4 x 2 box spans [49, 51] x [58, 62]; its footprint hull lies inside
  for _, q in ipairs(pl:hull(1)) do
    t.ok(q[1] >= 49 - 1e-6 and q[1] <= 51 + 1e-6 and q[2] >= 58 - 1e-6 and q[2] <= 62 + 1e-6, "hull inside the turned box")
  end
  local back = gradus.cli.read(tmp .. "/rot.cli")
  local d = back.header.dimension
  t.ok(d[1] >= 49 - 1e-6 and d[4] <= 51 + 1e-6 and d[2] >= 58 - 1e-6 and d[5] <= 62 + 1e-6, "header x-y inside the box")
  t.near(d[3], 0, 1e-9, "header z from the floor")
  t.near(d[6], 0.4, 1e-9, "header z to the top")
end)

t.test("engine: footprints overlap exactly (rotated squares whose axis boxes overlap are apart)", function()
  local function diamond(cx, cy, h) return { { cx + h, cy }, { cx, cy + h }, { cx - h, cy }, { cx, cy - h } } end
  local h = 2 * math.sqrt(2) -- a 4 x 4 square turned by 45 degrees
  t.ok(not gradus.cli.overlap(diamond(0, 0, h), diamond(3, 3, h)), "|dx| + |dy| = 6 > 2h: apart")
  t.ok(gradus.cli.overlap(diamond(0, 0, h), diamond(2.5, 2.5, h)), "|dx| + |dy| = 5 < 2h: overlap")
  local sq = { { 0, 0 }, { 4, 0 }, { 4, 4 }, { 0, 4 } }
  t.ok(not gradus.cli.overlap(sq, { { 4, 0 }, { 8, 0 }, { 8, 4 }, { 4, 4 } }), "sharing an edge is not overlapping")
end)

t.test("two parts of different heights, one turned: layers merged by z, header, per-part stats sum", function()
  local file = write("two.yaml", HEAD .. "parts:\n" ..
    "  - name: low\n    at: [20, 30]\n    size: [2, 2, 0.4]\n" .. PART ..
    "  - name: tall\n    at: [60, 30]\n    rotation: 90\n    size: [4, 2, 0.8]\n" .. PART)
  local out = tmp .. "/two.cli"
  local st = plate.run { plate = file, output = out }
  t.eq(st.layers, 4, "plate layers: the tall part's 0.8 / 0.2")
  t.eq(st.parts[1].layers, 2, "low part layers")
  t.eq(st.parts[2].layers, 4, "tall part layers")
  local cli = gradus.cli.read(out)
  t.eq(#cli.layers, 4, "layers in the file")
  for g = 1, 4 do t.near(cli.layers[g]:z(), 0.2 * g, 1e-9, "z of layer " .. g) end
  local function xs(layer) -- parts present in a layer, told apart by x
    local low, tall = 0, 0
    for _, q in ipairs(points(layer)) do
      if q[1] < 40 then low = low + 1 else tall = tall + 1 end
      if q[1] < 40 then t.ok(q[1] >= 19 - 1e-6 and q[1] <= 21 + 1e-6 and q[2] >= 29 - 1e-6 and q[2] <= 31 + 1e-6, "low inside its box")
      else t.ok(q[1] >= 59 - 1e-6 and q[1] <= 61 + 1e-6 and q[2] >= 28 - 1e-6 and q[2] <= 32 + 1e-6, "tall inside its turned box") end
    end
    return low, tall
  end
  local l1, t1 = xs(cli.layers[1])
  local l4, t4 = xs(cli.layers[4])
  t.ok(l1 > 0 and t1 > 0, "layer 1 holds both parts")
  t.ok(l4 == 0 and t4 > 0, "layer 4 holds only the tall part")
  local d = cli.header.dimension
  t.near(d[3], 0, 1e-9, "$$DIMENSION z min")
  t.near(d[6], 0.8, 1e-9, "$$DIMENSION z max: the tall part")
  t.ok(d[1] >= 19 - 1e-6 and d[1] < 20 and d[4] > 60 and d[4] <= 61 + 1e-6, "$$DIMENSION x spans both parts")
  local sum = { solid_volume_mm3 = 0, scan_time_s = 0, jump_time_s = 0, laser_time_s = 0, length_mm = 0 }
  for _, p in ipairs(st.parts) do
    for k in pairs(sum) do sum[k] = sum[k] + p[k] end
  end
  for k, v in pairs(sum) do t.near(st[k], v, 1e-9 * math.max(1, v), "plate " .. k .. " = sum of parts") end
  t.ok(st.solid_volume_mm3 > 0 and st.scan_time_s > 0, "non-zero totals")
  t.near(st.build_time_s, st.laser_time_s + st.recoat_time_s, 1e-9, "build = lasers + recoating")
  t.near(st.recoat_time_s, 4 * 12, 1e-9, "recoating: 4 layers of 12 s (default machine)")
  local bulk = 0
  for _, p in ipairs(st.parts) do bulk = bulk + p.solid_volume_mm3 / p.relative_density end
  t.near(st.relative_density, st.solid_volume_mm3 / bulk, 1e-9, "plate density: solid over the parts' volumes")
  t.ok(exists(tmp .. "/two.manifest.yaml") and exists(tmp .. "/two_plate.svg"), "manifest and footprint picture")
end)

t.test("plate file: kb: off (a YAML boolean) means no knowledge base, not a directory named false", function()
  local d = plate.load(write("kboff.yaml", "kb: off\nplate: {lo: [0, 0], hi: [10, 10]}\nparts:\n  - {name: a, at: [5, 5]}\n"))
  t.eq(d.kb, "off", "kb")
  t.eq(d.layer, 0.04, "the default layer thickness")
  t.eq(d.parts[1].box[1], 4, "default cells 2 x 2 mm: a 4 mm box")
end)

-- every bad plate: refused with the message, and nothing written
local function refused(name, yaml, pattern)
  t.test("refused: " .. name, function()
    local file = write(name:gsub("%W", "_") .. ".yaml", yaml)
    local base = tmp .. "/" .. name:gsub("%W", "_")
    local out = base .. ".cli"
    t.raises(function() plate.run { plate = file, output = out } end, pattern, name)
    for _, f in ipairs({ out, base .. ".manifest.yaml", base .. "_plate.svg" }) do
      t.ok(not exists(f), "no output " .. f)
    end
  end)
end

local one = "  - name: cube\n    at: [50, 50]\n    size: [2, 2, 0.4]\n" .. PART
refused("a part outside the plate", HEAD .. "parts:\n  - name: far\n    at: [99.5, 50]\n    size: [2, 2, 0.4]\n" .. PART,
  "a_part_outside_the_plate%.yaml:8:5: part 'far' leaves the plate")
refused("two parts overlapping", HEAD .. "parts:\n" .. one ..
  "  - name: turned\n    at: [52.2, 50.5]\n    rotation: 45\n    size: [2, 2, 0.4]\n" .. PART,
  "parts 'cube' %(.-:%d+:%d+%) and 'turned' overlap")
refused("size not positive", HEAD .. "parts:\n  - name: flat\n    at: [50, 50]\n    size: [2, -2, 0.4]\n" .. PART,
  ":9:5: part 'flat': .*size")
refused("cell not positive", HEAD .. "parts:\n  - name: c0\n    at: [50, 50]\n    size: [2, 2, 0.4]\n    cell: 0\n",
  ":10:5: part 'c0': .*cell")
refused("an unknown key in a part", HEAD .. "parts:\n" .. one .. "    rotaton: 5\n", ":14:5: unknown key 'rotaton' in part 'cube'.*rotation")
refused("an unknown key in the plate", HEAD .. "machin: x.yaml\nparts:\n" .. one, ":6:1: unknown key 'machin' in the plate file")
refused("a rotation that is not a number", HEAD .. "parts:\n  - name: r\n    at: [50, 50]\n    rotation: ninety\n    size: [2, 2, 0.4]\n" .. PART,
  ":9:5: part 'r': rotation must be a number %(degrees%), got 'ninety'")
refused("a missing recipe file", HEAD .. "parts:\n  - name: m\n    at: [50, 50]\n    recipe: nowhere.lua\n",
  ":9:5: part 'm': recipe file .*nowhere%.lua not found")
refused("a part with another layer thickness", HEAD .. "parts:\n" .. one .. "    layer: 0.1\n",
  ":14:5: part 'cube': layer 0%.1 differs from the plate's layer thickness 0%.2 mm")
local machine = write("m2.yaml", "name: m2\nplate: {lo: [0, 0], hi: [100, 100]}\nlasers:\n" ..
  "  - {name: left, field: {lo: [0, 0], hi: [40, 100]}}\n  - {name: right, field: {lo: [60, 0], hi: [100, 100]}}\n")
refused("a part out of every laser's reach",
  ("layer: 0.2\nres: 8\nkb: %s/kb\nmachine: %s\nparts:\n"):format(tmp, machine) .. one,
  "part 'cube' is out of every laser's reach.*left %[0, 40%]")

refused("regions set in a part (a plate has one set of build styles)", HEAD .. "parts:\n" .. one .. "    regions: default\n",
  ":14:5: unknown key 'regions' in part 'cube' %('regions' is set for the whole plate%)")

t.test("regions for the whole plate: region ids in the CLI, labelled, with the profile's styles in the manifest", function()
  local file = write("regions.yaml", HEAD .. "regions: default\nparts:\n  - name: cube\n    at: [50, 50]\n    size: [2, 2, 1.2]\n" .. PART)
  local out = tmp .. "/regions.cli"
  plate.run { plate = file, output = out }
  local rg = require("gradus.regions").load("default")
  local up_id = 4 * 48 + 0 * 3 + 1 + 1 -- region upskin (4), laser 1, hatch
  local cli = gradus.cli.read(out)
  local upskin = 0 -- a lattice's sloping walls face up on every layer, the top layers all over
  for _, l in ipairs(cli.layers) do
    for _, b in ipairs(l:blocks()) do
      if b.region == "upskin" then upskin = upskin + 1; t.eq(b.id % 48, (b.id - 1) % 3 + 1, "laser 1 id") end
    end
  end
  t.ok(upskin > 0, "up-skin blocks in the plate's CLI")
  local f = assert(io.open(out))
  local head = f:read(4096)
  f:close()
  t.ok(head:find("$$LABEL/" .. up_id .. ",laser1-upskin-hatch", 1, true), "the header labels the up-skin hatch style")
  local man = gradus.yaml.load(tmp .. "/regions.manifest.yaml")
  local seen = {}
  for _, sty in ipairs(man.styles) do seen[sty.id] = sty end
  t.ok(seen[up_id] and seen[up_id].region == "upskin", "manifest style " .. up_id .. " is the up-skin hatch")
  t.eq(seen[up_id].power, rg.upskin.power, "up-skin power from the profile")
  t.eq(seen[up_id].speed, rg.upskin.speed, "up-skin speed from the profile")
  t.eq(seen[2].power, rg.core.power, "core hatch power from the profile, as the part ran")
end)

t.test("a recipe part: its footprint is the hull of its vectors; lasers reassigned to the one that reaches it", function()
  local recipe = write("cube_recipe.lua", [[
local lattice = require "gradus.lattice"
lattice.run(lattice.params { surface = "primitive", cell = 2, size = "2,2,0.4", hatch = 0.1, thickness = "0.2", res = 8 },
  gradus.output("x.cli"))
]])
  local file = write("rec.yaml", ("layer: 0.2\nres: 8\nkb: %s/kb\nmachine: %s\nparts:\n"):format(tmp, machine) ..
    "  - name: r\n    at: [80, 50]\n    recipe: " .. recipe .. "\n")
  local st = plate.run { plate = file, output = tmp .. "/rec.cli" }
  t.eq(#st.parts[1].lasers, 1, "one laser used (balance over one voxel)")
  t.eq(st.parts[1].lasers[1], 2, "laser 1's vectors go to 'right', the only laser reaching the part")
  local info = gradus.cli.info(tmp .. "/rec.cli")
  t.ok(not info.lasers[1] or (info.lasers[1].vectors or 0) == 0, "laser 1 scans nothing")
  t.ok(info.lasers[2] and info.lasers[2].vectors > 0, "laser 2 scans the part")
  t.ok(st.warnings and st.warnings[1]:find("laser 1 %(left%) gets no work: no part lies wholly inside its field %[0, 40%]"),
    "a warning says laser 1 is idle and why")
  -- the same recipe part overlapping a lattice part: found after it ran, from its hull
  local bad = write("rec_bad.yaml", HEAD .. "parts:\n" .. one .. "  - name: r\n    at: [51.5, 50]\n    recipe: " .. recipe .. "\n")
  t.raises(function() plate.run { plate = bad, output = tmp .. "/rb.cli" } end, "parts 'cube' .- and 'r' overlap")
  t.ok(not exists(tmp .. "/rb.cli"), "no output")
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
