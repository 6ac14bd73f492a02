-- Closed loops per laser and stitching between lasers (engine/stitch.c):
-- with two lasers every contour loop is scanned whole by one laser that
-- reaches it; hatch lines cut where two lasers meet overlap by the machine's
-- stitching length; loops no laser reaches whole are split with that overlap
-- and counted.
local t = require "gradus.testing"
local lasers = require "gradus.lasers"
local tmp = t.tmpdir()
local kb = tmp .. "/kb"
local NL = 50

-- a 2 x n x 1 primitive lattice (2 mm cells) run with machine m (nil: one
-- laser); fixed: voxel column i on laser i + 1. Every layer is kept.
local function run(o)
  local j = gradus.place.job { cell = 2, cells = { 2, o.ny, 1 }, layer = 0.04, hatch = 0.05, res = 20, threads = 2,
    lasers = o.lasers or 1 }
  if o.machine then j:machine(o.machine) end
  local s = j:spec { surface = "primitive", thickness = "0.06 + 0.03*z" }
  for jj = 0, o.ny - 1 do
    for i = 0, 1 do j:voxel(i, jj, 0, { spec = s, laser = o.fixed and (i + 1) or nil }) end
  end
  local keep = {}
  for g = 1, NL do keep[g] = g end
  return j:run { kb = kb, keep = keep, output = o.output }
end

local function len(p)
  local s = 0
  for q = 3, #p, 2 do s = s + math.sqrt((p[q] - p[q - 2]) ^ 2 + (p[q + 1] - p[q - 1]) ^ 2) end
  return s
end

local function each_block(kept, fn)
  for g = 1, NL do
    for _, b in ipairs(kept[g]:blocks()) do fn(b, g) end
  end
end

local st1, k1 = run { ny = 2 }
local cli2 = tmp .. "/two.cli"
local st2, k2 = run { ny = 2, lasers = 2, output = cli2 }

t.test("two lasers: no contour cut open, each loop on one laser", function()
  local open, thin, loops, per = 0, 0, 0, { 0, 0 }
  each_block(k2, function(b)
    if b.kind ~= "contour" then return end
    if b.shape == "open" then
      open = open + 1
      if b.thin then thin = thin + 1 end
    else
      loops = loops + 1
      per[b.laser] = per[b.laser] + 1
    end
  end)
  t.eq(open, thin, "every open contour line is a thin-wall line (open by design)")
  local loops1 = 0
  each_block(k1, function(b) if b.kind == "contour" and b.shape == "closed" then loops1 = loops1 + 1 end end)
  t.eq(loops, loops1, "as many closed loops as with one laser")
  t.ok(per[1] > 0 and per[2] > 0, ("both lasers scan loops (%d, %d)"):format(per[1], per[2]))
  t.eq(st2.split_loops, 0, "no loop split: both lasers reach the whole plate")
  -- the CLI as written: a polyline with direction 2 is an open line
  local cli = gradus.cli.read(cli2)
  local dir2 = 0
  for _, l in ipairs(cli.layers) do
    for _, b in ipairs(l:blocks()) do
      if b.kind == "contour" and b.dir == 2 then dir2 = dir2 + 1 end
    end
  end
  t.eq(dir2, thin, "the CLI's direction-2 polylines are the thin-wall lines only")
  -- time and length counted on the laser that scans the loop
  local lenl = { 0, 0 }
  each_block(k2, function(b)
    if b.shape == "segments" then
      for q = 1, #b.points, 4 do lenl[b.laser] = lenl[b.laser] + len({ table.unpack(b.points, q, q + 3) }) end
    else
      lenl[b.laser] = lenl[b.laser] + len(b.points)
    end
  end)
  for l = 1, 2 do t.near(st2.lasers[l].length, lenl[l], 1e-6 * lenl[l], "length of laser " .. l .. " = its blocks") end
end)

t.test("hatch lines overlap by the stitching length where two lasers meet", function()
  t.near(lasers.default(2).stitch, 0.5, 0, "default stitching length 0.5 mm")
  local pairs_, full, bad, sum = 0, 0, 0, 0
  for g = 1, NL do
    local a = math.rad((45 + (g - 1) * 67) % 360) -- the hatch angle of layer g
    local ca, sa = math.cos(a), math.sin(a)
    local lines = {}
    for _, b in ipairs(k2[g]:blocks()) do
      if b.kind == "hatch" then
        local p = b.points
        for q = 1, #p, 4 do
          local s0, s1 = p[q] * ca + p[q + 1] * sa, p[q + 2] * ca + p[q + 3] * sa
          local key = math.floor((-p[q] * sa + p[q + 1] * ca) / 0.05 + 0.5)
          lines[key] = lines[key] or {}
          table.insert(lines[key], { math.min(s0, s1), math.max(s0, s1), b.laser })
        end
      end
    end
    for _, segs in pairs(lines) do
      for x = 1, #segs do
        for y = x + 1, #segs do
          local u, v = segs[x], segs[y]
          local ov = math.min(u[2], v[2]) - math.max(u[1], v[1])
          if u[3] ~= v[3] and ov > -1e-6 then
            pairs_ = pairs_ + 1
            sum = sum + ov
            -- 0.5 mm, or less where a piece is shorter than half the
            -- stitch: then it lies wholly in the other's run-on (equal ends)
            local short = math.abs(u[1] - v[1]) < 1e-6 or math.abs(u[2] - v[2]) < 1e-6
            if math.abs(ov - 0.5) < 1e-6 then full = full + 1 elseif not short or ov > 0.5 then bad = bad + 1 end
            if ov < 1e-6 then bad = bad + 1 end
          end
        end
      end
    end
  end
  t.ok(pairs_ > 100, ("hatch lines meet across the laser boundary (%d pairs)"):format(pairs_))
  t.eq(bad, 0, "every meeting overlaps by the stitching length, or by all of a piece shorter than half of it")
  t.ok(full > 0, ("%d of %d overlaps are the full 0.5 mm"):format(full, pairs_))
  -- the extra hatch length is exactly the overlaps measured
  t.near(st2.vectors.hatch.length - st1.vectors.hatch.length, sum, 1e-6 * sum, "extra hatch length = sum of overlaps")
  t.near(st2.vectors.contour.length, st1.vectors.contour.length, 1e-9 * st1.vectors.contour.length,
    "contours: the same length as with one laser")
end)

t.test("a loop no laser reaches whole is split with the overlap and counted", function()
  local m = lasers.normalize({ name = "near", lasers = {
    { name = "a", field = { lo = { -10, -10 }, hi = { 2.5, 10 } } },
    { name = "b", field = { lo = { 1.5, -10 }, hi = { 10, 10 } } } } }, "test")
  t.eq(m.stitch, 0.5, "default stitch in a profile")
  local _, k1b = run { ny = 1 }
  local st, k = run { ny = 1, machine = m, fixed = true }
  -- the loops of the one-laser run that leave both fields ([1.5, 2.5] in x)
  local want, wantlen = 0, 0
  each_block(k1b, function(b)
    if b.kind == "contour" and b.shape == "closed" then
      local x0, x1 = math.huge, -math.huge
      for q = 1, #b.points, 2 do x0, x1 = math.min(x0, b.points[q]), math.max(x1, b.points[q]) end
      if x0 < 1.5 and x1 > 2.5 then want, wantlen = want + 1, wantlen + len(b.points) end
    end
  end)
  t.ok(want > 0, "the lattice has loops across the two fields")
  t.eq(st.split_loops, want, "split loops counted")
  local pieces, plen, outside = 0, 0, 0
  each_block(k, function(b)
    if b.kind == "contour" and b.shape == "open" then
      pieces, plen = pieces + 1, plen + len(b.points)
      local f = m.lasers[b.laser].field
      for q = 1, #b.points, 2 do
        if b.points[q] < f.lo[1] - 1e-9 or b.points[q] > f.hi[1] + 1e-9 then outside = outside + 1 end
      end
    end
  end)
  t.ok(pieces >= 2 * want, "each split loop in at least two pieces")
  t.eq(outside, 0, "every piece inside its laser's field")
  -- each piece runs on by half the stitch at both ends: pieces overlap by 0.5 mm (to 1e-3 mm in
  -- all: where a loop meets the box's side its joint carries a few nm, the contour being kept to
  -- 5e-6 mm past the side, GR_FACE_EPS, and the pieces cut there differ from the loop by that)
  t.near(plen - wantlen, 0.5 * pieces, 1e-3, "pieces = loops + 0.5 mm per joint")
  t.raises(function() lasers.normalize({ lasers = { {} }, stitch = -1 }, "p.yaml") end, "p.yaml: stitch: must be in %[0, 10%] mm")
end)

t.done()
