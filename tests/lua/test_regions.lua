-- Regions with their own build styles (gradus.regions, engine/regions.c): a
-- solid T (a stem under a wider slab, all skin) whose down-skin and up-skin
-- areas are known exactly; ids, powers and speeds against the profile; the
-- hatch length kept whole by the cuts; nothing changes without regions;
-- thin-wall lines; bad profiles refused at file:line.
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local tmp = t.tmpdir()

-- a process profile written to tmp/name (the path)
local function write_profile(name, text)
  local path = tmp .. "/" .. name
  local f = io.open(path, "w")
  f:write(text)
  f:close()
  return path
end

local function mx(...)
  local a = { ... }
  local e = a[1]
  for i = 2, #a do e = ("max(%s,%s)"):format(e, a[i]) end
  return e
end
-- stem [1.5, 2.5] x [0.5, 3.5] x [0, 2], slab [0.5, 3.5]^2 x [2, 2.6] (mm); skin 1 mm
-- makes both solid (half-widths 0.5 and 0.3 mm)
local T = ("min(%s,%s)"):format(mx("1.5-x", "x-2.5", "0.5-y", "y-3.5", "z-2"),
  mx("0.5-x", "x-3.5", "0.5-y", "y-3.5", "2-z", "z-2.6"))
local D = 0.1 -- hatch spacing and layer (mm)

local function params(o)
  local p = lattice.params()
  p.size, p.layer, p.hatch, p.res, p.kb, p.thickness = "4,4,2.6", D, D, 12, tmp .. "/kb", "0.08"
  p.domain, p.skin, p.regions, p.surface = T, 1, "default", "primitive"
  for k, v in pairs(o or {}) do p[k] = v end
  return p
end

-- per layer: hatch length x spacing (an area, mm^2) per region, and the
-- down-skin hatch midpoints
local function areas(path)
  local cli = gradus.cli.read(path)
  local out, mids = {}, {}
  for g, l in ipairs(cli.layers) do
    out[g] = {}
    for _, b in ipairs(l:blocks()) do
      if b.kind == "hatch" then
        local p = b.points
        for q = 1, #p, 4 do
          out[g][b.region] = (out[g][b.region] or 0) + math.sqrt((p[q + 2] - p[q]) ^ 2 + (p[q + 3] - p[q + 1]) ^ 2) * D
          if b.region == "downskin" then mids[#mids + 1] = { (p[q] + p[q + 2]) / 2, (p[q + 1] + p[q + 3]) / 2 } end
        end
      end
    end
  end
  return out, cli, mids
end

local out = tmp .. "/t.cli"
local st = lattice.run(params(), out)
local h = st.effective.beam_offset -- hatch region: the section inset by b (one contour, no gap)

t.test("T: down-skin exactly on the 3 slab layers over void, with the overhang's area", function()
  local a, _, mids = areas(out)
  local want = (3 - 2 * h) * 2 -- slab hatch region minus the stem's
  for g = 1, #a do
    local ds = a[g].downskin or 0
    if g >= 21 and g <= 23 then
      t.near(ds, want, D * 1.0, ("layer %d: down-skin area %.3f mm^2 = (3 - 2h) x 2 = %.3f within d x 1 mm"):format(g, ds, want))
    else
      t.eq(ds, 0, ("layer %d: no down-skin (stem on the plate, or slab over 3 slab layers)"):format(g))
    end
  end
  local inside = 0
  for _, m in ipairs(mids) do
    if m[1] > 1.5 + h + 1e-6 and m[1] < 2.5 - h - 1e-6 then inside = inside + 1 end
  end
  t.eq(inside, 0, "no down-skin hatch over the stem's footprint")
end)

t.test("T: up-skin on the top 3 layers (whole slab), skin elsewhere, no core", function()
  local a = areas(out)
  for g = 1, #a do
    local us, sk = a[g].upskin or 0, a[g].skin or 0
    if g >= 24 and g <= 26 then
      t.near(us, (3 - 2 * h) ^ 2, D * 1.0, ("layer %d: up-skin area %.3f = (3 - 2h)^2"):format(g, us))
    else
      t.eq(us, 0, ("layer %d: no up-skin"):format(g))
    end
    if g <= 23 then t.near(sk, (1 - 2 * h) * (3 - 2 * h), D * 1.0, ("layer %d: skin area %.3f = the stem's"):format(g, sk)) end
    t.eq(a[g].core or 0, 0, ("layer %d: no core hatch (all within the 1 mm skin)"):format(g))
  end
end)

t.test("T: contour pieces over the overhang are down-skin, under open space up-skin, on the stem core", function()
  local cli = gradus.cli.read(out)
  local side = 3 - 2 * h -- the slab's contour: a square of this side
  for g, l in ipairs(cli.layers) do
    local len = {}
    for _, b in ipairs(l:blocks()) do
      if b.kind == "contour" then
        local p = b.points
        for q = 1, #p - 2, 2 do
          len[b.region] = (len[b.region] or 0) + math.sqrt((p[q + 2] - p[q]) ^ 2 + (p[q + 3] - p[q + 1]) ^ 2)
        end
      end
    end
    local ds, us, co = len.downskin or 0, len.upskin or 0, len.core or 0
    if g >= 21 and g <= 23 then -- all but the two stretches over the stem (1 mm each)
      t.near(ds, 4 * side - 2, 1e-6, ("layer %d: down-facing contour %.6f mm = 4 x %.2f - 2"):format(g, ds, side))
      t.near(co, 2, 1e-6, ("layer %d: the contour over the stem stays core (%.6f mm)"):format(g, co))
    elseif g >= 24 then
      t.near(us, 4 * side, 1e-6, ("layer %d: the whole top contour is up-facing (%.6f mm)"):format(g, us))
    else
      t.ok(ds == 0 and us == 0, ("layer %d: the stem's contour is neither (down %.3g, up %.3g)"):format(g, ds, us))
    end
  end
end)

t.test("skin contours: 3 along the T's outer surface (rectangles b, b + d, b + 2d in), hatch from the last", function()
  local path = write_profile("skin3.yaml", "regions:\n  skin: {power: 200, speed: 1250, contours: 3}\n")
  local o2 = tmp .. "/skin3.cli"
  lattice.run(params { regions = path }, o2)
  local cli = gradus.cli.read(o2)
  for g, l in ipairs(cli.layers) do
    local cl, hl = 0, 0
    for _, b in ipairs(l:blocks()) do
      local p = b.points
      if b.kind == "hatch" then
        for q = 1, #p, 4 do hl = hl + math.sqrt((p[q + 2] - p[q]) ^ 2 + (p[q + 3] - p[q + 1]) ^ 2) end
      else
        for q = 1, #p - 2, 2 do cl = cl + math.sqrt((p[q + 2] - p[q]) ^ 2 + (p[q + 3] - p[q + 1]) ^ 2) end
      end
    end
    local w, l2 = g <= 20 and 1 or 3, 3 -- the stem's section 1 x 3, the slab's 3 x 3 (mm)
    local want = 0
    for i = 0, 2 do want = want + 2 * (w - 2 * (h + i * D)) + 2 * (l2 - 2 * (h + i * D)) end
    -- every contour vertex on its rectangle (vertices are solved to 1e-6 mm)
    local cx, cy, worst = 2, 2, 0
    for _, b in ipairs(l:blocks()) do
      if b.kind ~= "hatch" then
        local p = b.points
        for q = 1, #p - 1, 2 do
          local best = math.huge
          for i = 0, 2 do
            local hx, hy = w / 2 - (h + i * D), l2 / 2 - (h + i * D) -- the rectangle's half sides
            local dx, dy = math.abs(p[q] - cx) - hx, math.abs(p[q + 1] - cy) - hy
            local d = (dx > 0 or dy > 0) and math.sqrt(math.max(dx, 0) ^ 2 + math.max(dy, 0) ^ 2) or -math.max(dx, dy)
            best = math.min(best, d)
          end
          worst = math.max(worst, best)
        end
      end
    end
    t.ok(worst < 1e-6, ("layer %d: a contour vertex %.3g um off its rectangle"):format(g, worst * 1e3))
    -- the perimeters: every corner in place (a chord that cut one off-centre passed the chord
    -- test with the corner 0.8 um away, before offsets put corners in; they fall between the
    -- offset grid's nodes)
    t.near(cl, want, 1e-6, ("layer %d: three contour rectangles %.6f mm, want %.6f"):format(g, cl, want))
    local hw = h + 2 * D -- the hatch region: inset by the last skin contour
    t.near(hl * D, (w - 2 * hw) * (l2 - 2 * hw), 0.02, ("layer %d: hatch area %.4f mm2 inside the third contour"):format(g, hl * D))
  end
end)

t.test("six skin contours reach past the template window's usual margin: every rectangle whole", function()
  -- a solid bar [0.5, 2.47] x [0.5, 3.5]: its right side lies 0.47 mm beyond the voxels' face
  -- x = 2, past a margin of b + 2d + 2 cells (0.35 mm); the deepest contours (b + 4d, b + 5d
  -- in) of the voxels left of the face come from that side, so their windows reach it
  local bar = mx("0.5-x", "x-2.47", "0.5-y", "y-3.5", "-z", "z-0.3")
  local path = write_profile("skin6.yaml", "regions:\n  skin: {power: 200, speed: 1250, contours: 6}\n")
  local o6 = tmp .. "/skin6.cli"
  lattice.run(params { regions = path, domain = bar, size = "4,4,0.3" }, o6)
  local cli = gradus.cli.read(o6)
  t.eq(#cli.layers, 3, "three layers")
  for g, l in ipairs(cli.layers) do
    local cl = 0
    for _, b in ipairs(l:blocks()) do
      if b.kind ~= "hatch" then
        local p = b.points
        for q = 1, #p - 2, 2 do cl = cl + math.sqrt((p[q + 2] - p[q]) ^ 2 + (p[q + 3] - p[q + 1]) ^ 2) end
      end
    end
    local want = 0
    for i = 0, 5 do want = want + 2 * (1.97 - 2 * (h + i * D)) + 2 * (3 - 2 * (h + i * D)) end
    t.near(cl, want, 1e-6, ("layer %d: six contour rectangles %.6f mm, want %.6f"):format(g, cl, want))
  end
end)

t.test("skin contours on a gyroid cut to a cylinder: extra rings along the surface only, pores' contours unchanged", function()
  local function run(prof, path)
    local q = lattice.params()
    q.cells, q.surface, q.domain, q.skin, q.kb = "2,2,1", "gyroid", "sqrt((x-2)^2+(y-2)^2)-1.8", 0.3, tmp .. "/kbc"
    q.regions, q.layers, q.layer = prof, "4:6", 0.1
    local st = lattice.run(q, path)
    return gradus.cli.read(path), st.effective.beam_offset, q.hatch
  end
  local p1 = write_profile("s1.yaml", "regions:\n  skin: {power: 200, speed: 1250}\n")
  local p3 = write_profile("s3.yaml", "regions:\n  skin: {power: 200, speed: 1250, contours: 3}\n")
  local c1, b, d = run(p1, tmp .. "/c1.cli")
  local c3 = run(p3, tmp .. "/c3.cli")
  local R = 1.8
  for g = 1, 3 do
    local function scan(cli)
      local n, dev, pore, hmax = { 0, 0, 0 }, { 0, 0, 0 }, {}, 0
      for _, bk in ipairs(cli.layers[g]:blocks()) do
        local p = bk.points
        for q = 1, #p, 2 do
          local r = math.sqrt((p[q] - 2) ^ 2 + (p[q + 1] - 2) ^ 2)
          if bk.kind == "hatch" then hmax = math.max(hmax, r)
          else
            local i = math.floor((R - b - r) / d + 0.5) -- 0, 1, 2: which ring
            if i >= 0 and i <= 2 and r > R - b - 2.4 * d then
              n[i + 1] = n[i + 1] + 1
              dev[i + 1] = math.max(dev[i + 1], math.abs(r - (R - b - i * d)))
            else pore[#pore + 1] = { p[q], p[q + 1] } end
          end
        end
      end
      return n, dev, pore, hmax
    end
    local n1, _, pore1, h1 = scan(c1)
    local n3, dev3, pore3, h3 = scan(c3)
    t.ok(n1[2] == 0 and n1[3] == 0 and n3[2] > 100 and n3[3] > 100, ("layer %d: one ring along the surface without, three with (%d, %d, %d points)"):format(g, n3[1], n3[2], n3[3]))
    t.ok(dev3[1] < 1e-3 and dev3[2] < 1e-3 and dev3[3] < 1e-3,
      ("layer %d: rings at R - b - i d within 1 um (%.2g, %.2g, %.2g mm)"):format(g, dev3[1], dev3[2], dev3[3]))
    -- the skin's contours scanned deeper widen the templates' window: the pores' contours keep
    -- their place, not every vertex: each within the offsets' chord tolerance (0.5 um) of the
    -- offset of a section whose own chords are within 0.2 um: 1.2 um apart at most
    local a = t.farthest(pore3, t.seg_cells(c1.layers[g], "contour", 0.1), 0.1)
    local z = t.farthest(pore1, t.seg_cells(c3.layers[g], "contour", 0.1), 0.1)
    t.ok(#pore1 > 100 and #pore3 > 100 and a < 1.2e-3 and z < 1.2e-3,
      ("layer %d: the pores' contours unchanged (%d and %d points, within %.3g and %.3g um)"):format(g, #pore1, #pore3, a * 1e3, z * 1e3))
    t.ok(h3 <= R - b - 2 * d + 1e-6 and h1 <= R - b + 1e-6 and h1 > R - b - 1e-3,
      ("layer %d: hatches end on the last contour (%.6f, without: %.6f)"):format(g, h3, h1))
  end
end)

t.test("T: a layer range reads the layers around it (21:26 as in the whole job)", function()
  local o2 = tmp .. "/r.cli"
  lattice.run(params { layers = "21:26" }, o2)
  local a = areas(o2)
  t.eq(#a, 6, "6 layers")
  t.near(a[1].downskin or 0, (3 - 2 * h) * 2, D, "layer 21 down-skin as in the whole job")
  t.near(a[4].upskin or 0, (3 - 2 * h) ^ 2, D, "layer 24 up-skin as in the whole job")
end)

t.test("ids, labels and manifest: each region's style as the profile gives it", function()
  local man = gradus.yaml.load(tmp .. "/t.manifest.yaml")
  local prof = require("gradus.regions").load("default")
  local by = {}
  for _, s in ipairs(man.styles) do by[s.id] = s end
  local want = { [2] = { "core", prof.core }, [1] = { "core", prof.contour }, [50] = { "skin", prof.skin },
    [97] = { "thin", prof.thin }, [146] = { "downskin", prof.downskin }, [194] = { "upskin", prof.upskin } }
  for id, w in pairs(want) do
    t.ok(by[id] ~= nil, ("manifest lists id %d"):format(id))
    if by[id] then
      t.eq(by[id].region, w[1], ("id %d region"):format(id))
      t.eq(by[id].power, w[2].power, ("id %d power (W)"):format(id))
      t.eq(by[id].speed, w[2].speed, ("id %d speed (mm/s)"):format(id))
    end
  end
  local _, cli = areas(out)
  local labels = {}
  for id, text in io.open(out):read("a"):gmatch("%$%$LABEL/(%d+),([^\n]*)") do labels[tonumber(id)] = text end
  local seen, bad = {}, 0
  for _, l in ipairs(cli.layers) do
    for _, b in ipairs(l:blocks()) do
      seen[b.id] = true
      local r = ({ "core", "skin", "thin", "downskin", "upskin" })[(b.id - 1) // 48 + 1]
      if not by[b.id] or by[b.id].region ~= b.region or r ~= b.region then bad = bad + 1 end
    end
  end
  t.eq(bad, 0, "every block's id is in the manifest with the block's region")
  t.ok(seen[146] and seen[194] and seen[50], "the file uses the down-skin, up-skin and skin hatch ids")
  for _, id in ipairs({ 50, 146, 194 }) do
    t.eq(labels[id], "laser1-" .. by[id].region .. "-hatch", ("header label of %d names its region"):format(id))
  end
end)

t.test("stats: region lengths add up, scan time = length / the region's speed", function()
  local r = st.regions
  local prof = require("gradus.regions").load("default")
  t.near(r.downskin.scan_time_s, r.downskin.length / prof.downskin.speed, 1e-9, "down-skin time")
  t.near(r.upskin.scan_time_s, r.upskin.length / prof.upskin.speed, 1e-9, "up-skin time")
  local sum = 0
  for _, k in ipairs({ "core", "skin", "thin", "downskin", "upskin" }) do sum = sum + r[k].length end
  local all = st.vectors.contour.length + st.vectors.hatch.length + st.vectors.edge.length
  t.near(sum, all, 1e-6 * all, "regions' lengths = all vectors' length")
end)

-- per layer and region: the hatch length (mm) and the distinct offsets of
-- the hatch lines across their direction (mm, rounded to 0.1 um)
local function lines(path)
  local cli = gradus.cli.read(path)
  local len, off = {}, {}
  for g, l in ipairs(cli.layers) do
    len[g], off[g] = {}, {}
    for _, b in ipairs(l:blocks()) do
      if b.kind == "hatch" then
        local p, r = b.points, b.region
        off[g][r] = off[g][r] or {}
        for q = 1, #p, 4 do
          local dx, dy = p[q + 2] - p[q], p[q + 3] - p[q + 1]
          local n = math.sqrt(dx * dx + dy * dy)
          len[g][r] = (len[g][r] or 0) + n
          off[g][r][math.floor(math.abs(-p[q] * dy + p[q + 1] * dx) / n * 1e4 + 0.5)] = true
        end
      end
    end
  end
  return len, off, cli
end

t.test("own hatch spacings: down-skin at 0.05 mm, up-skin at 0.2 mm, skin at the job's 0.1 mm", function()
  local path = write_profile("spacing.yaml", "regions:\n  skin: {power: 200, speed: 1250}\n" ..
    "  downskin: {power: 100, speed: 1500, hatch: 0.05}\n  upskin: {power: 150, speed: 1000, hatch: 0.2}\n")
  local o2 = tmp .. "/spacing.cli"
  local s2 = lattice.run(params { regions = path }, o2)
  local len, off, cli = lines(o2)
  local want = { skin = 0.1, downskin = 0.05, upskin = 0.2 }
  local seen = {}
  for g = 1, #len do
    for r, set in pairs(off[g]) do
      local v = {}
      for k in pairs(set) do v[#v + 1] = k end
      table.sort(v)
      local lo, off = math.huge, 0 -- the smallest gap; the largest distance of a gap from a whole multiple
      for i = 2, #v do
        local d = (v[i] - v[i - 1]) * 1e-4
        lo = math.min(lo, d)
        off = math.max(off, math.abs(d - want[r] * math.floor(d / want[r] + 0.5)))
      end
      if #v > 1 then
        seen[r] = true
        t.ok(math.abs(lo - want[r]) < 2e-4 and off < 2e-4,
          ("layer %d %s: lines %.4f mm apart (gaps off a multiple by %.1g), want %.2f"):format(g, r, lo, off, want[r]))
      end
    end
    -- the areas of test 1 and 2, each region's length times its own spacing
    if g >= 21 and g <= 23 then
      t.near((len[g].downskin or 0) * 0.05, (3 - 2 * h) * 2, 0.05, ("layer %d: down-skin area at 0.05 mm"):format(g))
    end
    if g >= 24 then
      t.near((len[g].upskin or 0) * 0.2, (3 - 2 * h) ^ 2, 0.2 * 3, ("layer %d: up-skin area at 0.2 mm"):format(g))
    end
  end
  t.ok(seen.skin and seen.downskin and seen.upskin, "every region's spacing measured")
  t.eq(s2.regions.downskin.hatch, 0.05, "stats: down-skin spacing")
  t.eq(s2.regions.upskin.hatch, 0.2, "stats: up-skin spacing")
  local _, _, base = lines(out)
  local same = true
  for g = 1, 20 do
    local a, b = base.layers[g]:blocks(), cli.layers[g]:blocks()
    if #a ~= #b then same = false end
    for i = 1, math.min(#a, #b) do
      if a[i].id ~= b[i].id or #a[i].points ~= #b[i].points then same = false break end
      for q = 1, #a[i].points do if a[i].points[q] ~= b[i].points[q] then same = false break end end
    end
  end
  t.ok(same, "layers 1-20 (no down- or up-skin) scan exactly as with the job's one spacing")
  local man = gradus.yaml.load(tmp .. "/spacing.manifest.yaml")
  local hs = {}
  for _, sty in ipairs(man.styles) do if sty.kind == "hatch" then hs[sty.region] = sty.hatch end end
  t.ok(hs.core == 0.1 and hs.skin == 0.1 and hs.downskin == 0.05 and hs.upskin == 0.2,
    "the manifest gives each hatch style its spacing")
end)

local function body(path)
  local s = io.open(path, "rb"):read("a")
  return (s:gsub("%$%$DATE/%d+", ""))
end

-- a small lattice with thin walls (thickness 0.02 mm), first layers
local SMALL = { domain = "", skin = 0, size = "", cells = "1,1,1", pictures = "12,15", kb_store = "all", thickness = "0.02", layers = "12:17", layer = 0.04, hatch = 0.05 }
local KEPT_PLAIN, KEPT_REGIONS -- layers 12 and 15 as the engine gave them
local function small(regions, path)
  local q = {}
  for k, v in pairs(SMALL) do q[k] = v end
  q.regions = regions
  return lattice.run(params(q), path)
end

t.test("no regions asked: the same CLI bytes, also from a profile with an empty regions: section", function()
  local f = io.open(tmp .. "/empty.yaml", "w")
  f:write("name: none\nregions: {}\n")
  f:close()
  small(tmp .. "/empty.yaml", tmp .. "/e.cli")
  local plain
  plain, KEPT_PLAIN = small("", tmp .. "/p.cli")
  t.ok(body(tmp .. "/e.cli") == body(tmp .. "/p.cli"), "same CLI bytes (date aside)")
  t.ok(not body(tmp .. "/p.cli"):find("LABEL/49,"), "no region labels")
  t.eq(plain.regions, nil, "no regions in the stats without regions")
  local s
  s, KEPT_REGIONS = small("default", tmp .. "/thin.cli")
  t.near(s.vectors.hatch.length, plain.vectors.hatch.length, 1e-6 * plain.vectors.hatch.length,
    "the cuts keep the hatch length of the job without regions")
  t.ok(s.regions.downskin.length > 0, "the lattice has down-skin hatch")
end)

t.test("thin-wall centre lines get the thin style", function()
  local function count(kept)
    local n, mismatch = 0, 0
    for _, g in ipairs({ 12, 15 }) do
      for _, b in ipairs(kept[g]:blocks()) do
        if b.thin then n = n + 1 end
        if KEPT_REGIONS == kept and b.thin ~= (b.region == "thin" and b.id == 97) then mismatch = mismatch + 1 end
      end
    end
    return n, mismatch
  end
  local n0 = count(KEPT_PLAIN)
  local n1, bad = count(KEPT_REGIONS)
  t.ok(n0 > 0, ("the lattice has thin-wall lines (%d on layers 12 and 15)"):format(n0))
  t.eq(n1, n0, "as many thin-wall lines with regions as without")
  t.eq(bad, 0, "a block has the thin style (id 97) exactly when it is a thin-wall line")
end)

t.test("OVF: down-skin and up-skin blocks carry lpbf_metadata.skin_type DOWN_SKIN / UP_SKIN", function()
  -- the paper's graded sheet (hatched walls) on the top layers of one cell, as CLI and OVF
  local q = { domain = "", skin = 0, size = "", cells = "1,1,1", layers = "44:50", layer = 0.04, hatch = 0.05,
    kb_store = "all", thickness = lattice.EQ8 }
  lattice.run(params(q), tmp .. "/o.cli")
  lattice.run(params(q), tmp .. "/o.ovf")
  local n, back = {}, {} -- blocks per region: the CLI, and the OVF read back
  for _, l in ipairs(gradus.cli.read(tmp .. "/o.cli").layers) do
    for _, b in ipairs(l:blocks()) do n[b.region] = (n[b.region] or 0) + 1 end
  end
  for _, l in ipairs(gradus.cli.read(tmp .. "/o.ovf").layers) do
    for _, b in ipairs(l:blocks()) do back[b.region] = (back[b.region] or 0) + 1 end
  end
  local bytes = io.open(tmp .. "/o.ovf", "rb"):read("a")
  -- a hatch block's lpbf_metadata (101, length 2): skin_type (2) = 1 or 2, part_area VOLUME (0)
  -- omitted; a contour piece's (length 4): part_area CONTOUR (1 = 1), then skin_type
  local function count(pat) local k = 0 for _ in bytes:gmatch(pat) do k = k + 1 end return k end
  t.ok((n.downskin or 0) > 0 and (n.upskin or 0) > 0, "the lattice has down-skin and up-skin blocks")
  t.eq(count("\xaa\x06\x02\x10\x01") + count("\xaa\x06\x04\x08\x01\x10\x01"), n.downskin,
    "one DOWN_SKIN mark per down-skin block (hatch or contour)")
  t.eq(count("\xaa\x06\x02\x10\x02") + count("\xaa\x06\x04\x08\x01\x10\x02"), n.upskin,
    "one UP_SKIN mark per up-skin block (hatch or contour)")
  t.eq(back.downskin, n.downskin, "the OVF reader maps DOWN_SKIN back to the down-skin region")
  t.eq(back.upskin, n.upskin, "and UP_SKIN to up-skin")
end)

local function profile(text) return write_profile("bad.yaml", text) end

t.test("bad profiles: file:line, nothing written", function()
  local bad = tmp .. "/bad.cli"
  t.raises(function() lattice.run(params { regions = profile("regions:\n  skin: {power: 200, speed: 900}\n  dowskin: {power: 1, speed: 1}\n") }, bad) end,
    "bad.yaml:3:%d+: unknown key 'dowskin'.*downskin", "unknown region named with line and suggestion")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  skin: {power: -5, speed: 900}\n") }, bad) end,
    "bad.yaml:2:%d+: regions.skin.power must be a positive number", "negative power")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  skin: {power: 5, speed: 900, focus: 1}\n") }, bad) end,
    "bad.yaml:2:%d+: unknown key 'focus'", "unknown key in a style")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  skin: {power: 5, speed: 900, hatch: 0.0123}\n") }, bad) end,
    "bad.yaml:2:%d+: regions: the hatch spacings 0.1 %(the job's%), 0.0123 %(skin%) mm have no common line spacing", "incommensurate spacings")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  core: {power: 5, speed: 900, hatch: 0.08}\n") }, bad) end,
    "bad.yaml:2:%d+: regions.core.hatch = 0.08 mm differs from the job's hatch spacing 0.1 mm", "core spacing is the job's")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  downskin: {power: 5, speed: 900, contours: 2}\n") }, bad) end,
    "bad.yaml:2:%d+: regions.downskin.contours: contours follow the section's outline", "contours on a shared outline")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  thin: {power: 5, speed: 900, hatch: 0.1}\n") }, bad) end,
    "bad.yaml:2:%d+: regions.thin.hatch: the thin region has no hatches", "hatch where there is none")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  skin: {power: 5, speed: 900, contours: 0}\n"), contours = 1 }, bad) end,
    "bad.yaml:2:%d+: regions.skin.contours = 0: the skin's contours must be the job's 1 .. 20", "fewer skin contours than the lattice's")
  t.raises(function() lattice.run(params { regions = profile("regions:\n  downskin_layers: 0\n") }, bad) end,
    "bad.yaml:2:%d+: regions.downskin_layers must be a whole number", "layer count")
  t.raises(function() lattice.run(params { kb = "off" }, bad) end, "not with kb=off", "direct mode refused")
  t.ok(io.open(bad, "r") == nil, "no CLI left behind")
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
