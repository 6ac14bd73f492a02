--- gradus.refslice: a reference slicer for measurements (gradus.steptruth,
-- recipes/quality.lua), written apart from the engine's marching squares
-- (engine/march.c) so that the two do not share their errors.
--
-- The boundary of {f < 0} in the plane z over a rectangle, as a soup of
-- segments (no rings: measurements only need distances to it):
--  - a base grid of `cell` (mm), sampled in one call (f:sample2);
--  - cells where neighbouring nodes differ by more than K_JUMP times their
--    spacing (a jump of f, e.g. where a graded thickness T(q) jumps across
--    the medial surface, or a fast turn of the foot point) are split into
--    quarters, down to `cell` / 2^depth, as long as they can hold a part of
--    the boundary: sign change, or (one sign) a node within K_GUARD times
--    the cell's half diagonal of zero. So slivers narrower than the base
--    cell along such jumps are found down to the finest cell;
--  - saddles are split too; every crossing of a leaf cell's edge is a root
--    of f on that edge (regula falsi with the Illinois rule and a bisection
--    every third step, to tol), so every vertex lies on the exact level set
--    (or on the jump);
--  - chords: each segment's midpoint is moved onto the level set along the
--    segment's normal, and the two halves are checked again, until the chord
--    is within `tol` (mm) of the curve.
-- Features narrower than the base cell where f has no jump (two boundaries
-- of a continuous field closer than `cell`) are not searched for.
local M = {}

local K_JUMP, K_GUARD = 1.5, 2.0

local function eval(field, z, xs, ys)
  if #xs == 0 then return {} end
  local zs = {}
  for i = 1, #xs do zs[i] = z end
  return field:eval_many(xs, ys, zs)
end
M.eval = eval

--- M.roots(field, z, S, tol) -> xs, ys: for each bracket S[i] = {ax, ay, fa,
-- bx, by, fb} (fa, fb of opposite signs: f < 0 inside), a point of the segment
-- a..b where the sign of f changes, within tol (mm), all brackets at once.
function M.roots(field, z, S, tol)
  local n = #S
  local t0, t1, f0, f1, side, len = {}, {}, {}, {}, {}, {}
  local rx, ry, active = {}, {}, {}
  for i = 1, n do
    local s = S[i]
    t0[i], t1[i], f0[i], f1[i], side[i] = 0, 1, s[3], s[6], 0
    len[i] = math.sqrt((s[4] - s[1]) ^ 2 + (s[5] - s[2]) ^ 2)
    active[i] = i
  end
  local it = 0
  while #active > 0 do
    it = it + 1
    local xs, ys, ts = {}, {}, {}
    for k, i in ipairs(active) do
      local t = 0.5 * (t0[i] + t1[i])
      if it % 3 ~= 0 and it < 60 then
        local tf = (t0[i] * f1[i] - t1[i] * f0[i]) / (f1[i] - f0[i])
        if tf > t0[i] and tf < t1[i] then t = tf end
      end
      local s = S[i]
      ts[k], xs[k], ys[k] = t, s[1] + t * (s[4] - s[1]), s[2] + t * (s[5] - s[2])
    end
    local v = eval(field, z, xs, ys)
    local keep = {}
    for k, i in ipairs(active) do
      local t, fv = ts[k], v[k]
      if (fv < 0) == (f0[i] < 0) then
        t0[i], f0[i] = t, fv
        if side[i] == -1 then f1[i] = 0.5 * f1[i] end
        side[i] = -1
      else
        t1[i], f1[i] = t, fv
        if side[i] == 1 then f0[i] = 0.5 * f0[i] end
        side[i] = 1
      end
      if math.abs(fv) <= 1e-3 * tol or (t1[i] - t0[i]) * len[i] <= tol or it >= 200 then
        local tr = math.abs(fv) <= 1e-3 * tol and t or 0.5 * (t0[i] + t1[i])
        local s = S[i]
        rx[i], ry[i] = s[1] + tr * (s[4] - s[1]), s[2] + tr * (s[5] - s[2])
      else
        keep[#keep + 1] = i
      end
    end
    active = keep
  end
  return rx, ry
end

-- the four corners of a cell, counter-clockwise from (x0, y0); edge k runs
-- from corner k to corner k + 1
local CX, CY = { 0, 1, 1, 0 }, { 0, 0, 1, 1 }

-- does a cell (corner values v[1..4], size h) need splitting? "leaf" (a
-- crossing cell), "split" or nil (no boundary). A jump between two corners
-- (more than K_JUMP h apart) means f is two functions here, each of slope
-- about 1: a side that comes within K_GUARD h sqrt(2) of zero at a corner may
-- hide a sliver, so the cell is split (where the sides stay far from zero the
-- boundary in the cell is the jump itself, which the chords follow). Below
-- the base grid (deep) a cell whose corners come within K_GUARD h / sqrt(2)
-- of zero is split too (a zero inside a cell of a slope-1 function is that
-- close to a corner).
local function classify(v, h, deep, can_split)
  local neg, lo, jump = 0, math.huge, false
  for k = 1, 4 do
    if v[k] < 0 then neg = neg + 1 end
    lo = math.min(lo, math.abs(v[k]))
    if math.abs(v[k] - v[k % 4 + 1]) > K_JUMP * h then jump = true end
  end
  local mixed = neg > 0 and neg < 4
  local saddle = neg == 2 and (v[1] < 0) == (v[3] < 0)
  if can_split then
    if saddle then return "split" end
    if jump and lo <= K_GUARD * h * math.sqrt(2) then return "split" end
    if deep and not mixed and lo <= K_GUARD * h * math.sqrt(0.5) then return "split" end
  end
  return mixed and "leaf" or nil
end

-- leaf cells {x0, y0, hx, v, hy} -> brackets of their crossing edges, and the
-- pairs of crossings that make segments
local function leaf_brackets(leaves)
  local S, pairs_ = {}, {}
  for _, c in ipairs(leaves) do
    local x0, y0, hx, v, hy = c[1], c[2], c[3], c[4], c[5]
    local e = {}
    for k = 1, 4 do
      local k2 = k % 4 + 1
      if (v[k] < 0) ~= (v[k2] < 0) then
        S[#S + 1] = { x0 + CX[k] * hx, y0 + CY[k] * hy, v[k], x0 + CX[k2] * hx, y0 + CY[k2] * hy, v[k2] }
        e[k] = #S
      end
    end
    if e[1] and e[2] and e[3] and e[4] then
      -- a saddle at the finest cell: cut off corners 2 and 4 (either way is
      -- within the cell)
      pairs_[#pairs_ + 1] = { e[1], e[2] }
      pairs_[#pairs_ + 1] = { e[3], e[4] }
    else
      local a, b
      for k = 1, 4 do if e[k] then if a then b = e[k] else a = e[k] end end end
      pairs_[#pairs_ + 1] = { a, b }
    end
  end
  return S, pairs_
end

-- split the cells C {x0, y0, hx, v, hy} into quarters; returns the children
local function split(field, z, C)
  local xs, ys = {}, {}
  for _, c in ipairs(C) do
    local x0, y0, ax, ay = c[1], c[2], 0.5 * c[3], 0.5 * c[5]
    for _, p in ipairs { { 1, 0 }, { 2, 1 }, { 1, 2 }, { 0, 1 }, { 1, 1 } } do
      xs[#xs + 1], ys[#ys + 1] = x0 + p[1] * ax, y0 + p[2] * ay
    end
  end
  local m = eval(field, z, xs, ys)
  local out = {}
  for i, c in ipairs(C) do
    local x0, y0, ax, v, ay = c[1], c[2], 0.5 * c[3], c[4], 0.5 * c[5]
    local b, r, tp, l, ce = m[5 * i - 4], m[5 * i - 3], m[5 * i - 2], m[5 * i - 1], m[5 * i]
    out[#out + 1] = { x0, y0, ax, { v[1], b, ce, l }, ay }
    out[#out + 1] = { x0 + ax, y0, ax, { b, v[2], r, ce }, ay }
    out[#out + 1] = { x0 + ax, y0 + ay, ax, { ce, r, v[3], tp }, ay }
    out[#out + 1] = { x0, y0 + ay, ax, { l, ce, tp, v[4] }, ay }
  end
  return out
end

-- midpoints of the segments moved onto the level set along their normals;
-- returns the refined segments (appended to E)
local function chords(field, z, segs, tol, E, stats)
  local pending, budget = segs, #segs + 20000
  for _ = 1, 64 do
    if #pending == 0 then break end
    local xs, ys = {}, {}
    for i, s in ipairs(pending) do xs[i], ys[i] = 0.5 * (s[1] + s[3]), 0.5 * (s[2] + s[4]) end
    local fm = eval(field, z, xs, ys)
    local todo = {}
    for i, s in ipairs(pending) do
      if math.abs(fm[i]) <= 0.5 * tol then
        E[#E + 1] = s
      elseif (s[3] - s[1]) ^ 2 + (s[4] - s[2]) ^ 2 <= (2 * tol) ^ 2 or budget <= 0 then
        -- a chord of 2 tol is within tol of any curve through its ends;
        -- where the field is noisy at that scale (a closest point switching
        -- patches back and forth, so that the chords never settle) the
        -- budget of new chords runs out: stop, and count
        E[#E + 1] = s
        stats.short = stats.short + 1
      else
        todo[#todo + 1] = i
      end
    end
    -- brackets along the normal, from a quarter to four chord lengths (the
    -- nearest sign change: a chord across a corner sharper than the grid)
    local br, found = {}, {}
    for _, frac in ipairs { 0.25, 0.5, 1, 2, 4 } do
      local qx, qy, who = {}, {}, {}
      for _, i in ipairs(todo) do
        if not found[i] then
          local s = pending[i]
          local dx, dy = s[3] - s[1], s[4] - s[2]
          for sg = -1, 1, 2 do
            qx[#qx + 1], qy[#qy + 1] = xs[i] - sg * frac * dy, ys[i] + sg * frac * dx
            who[#who + 1] = i
          end
        end
      end
      local fq = eval(field, z, qx, qy)
      for k, i in ipairs(who) do
        if not found[i] and (fq[k] < 0) ~= (fm[i] < 0) then
          found[i] = true
          br[#br + 1] = { xs[i], ys[i], fm[i], qx[k], qy[k], fq[k], i }
        end
      end
    end
    local rx, ry = M.roots(field, z, br, 1e-3 * tol)
    local nxt = {}
    for k, q in ipairs(br) do
      local s = pending[q[7]]
      local mx, my = rx[k], ry[k]
      if math.abs(mx - q[1]) + math.abs(my - q[2]) <= tol then
        E[#E + 1] = { s[1], s[2], mx, my }
        E[#E + 1] = { mx, my, s[3], s[4] }
      else
        nxt[#nxt + 1] = { s[1], s[2], mx, my }
        nxt[#nxt + 1] = { mx, my, s[3], s[4] }
        budget = budget - 1
      end
    end
    for _, i in ipairs(todo) do
      if not found[i] then E[#E + 1] = pending[i]; stats.unresolved = stats.unresolved + 1 end
    end
    pending = nxt
  end
  for _, s in ipairs(pending) do E[#E + 1] = s; stats.unresolved = stats.unresolved + 1 end
end

--- M.boundary(field, z, lo, hi, opts) -> E, stats: the boundary of {f < 0}
-- inside the rectangle lo..hi (mm) at height z, segments {x0, y0, x1, y1};
-- none along the rectangle's border (see M.line for those). opts: cell (base
-- grid, mm), depth (splits below it, default 9), tol (chord and vertex
-- tolerance, mm, default 1e-5). stats: cells, leaves, split, unresolved,
-- and the base grid's node values (stats.grid: nx, ny, hx, hy, values).
function M.boundary(field, z, lo, hi, opts)
  local cell, depth, tol = opts.cell, opts.depth or 9, opts.tol or 1e-5
  local nx = math.max(1, math.ceil((hi[1] - lo[1]) / cell - 1e-9))
  local ny = math.max(1, math.ceil((hi[2] - lo[2]) / cell - 1e-9))
  local hx, hy = (hi[1] - lo[1]) / nx, (hi[2] - lo[2]) / ny
  local g = field:sample2 { z = z, lo = lo, hi = hi, n = { nx + 1, ny + 1 } }
  local stats = { cells = nx * ny, leaves = 0, split = 0, unresolved = 0, short = 0,
    grid = { nx = nx, ny = ny, hx = hx, hy = hy, v = g } }
  local leaves, todo = {}, {}
  local h = math.max(hx, hy)
  local far = K_GUARD * h * math.sqrt(2) -- one sign, all corners farther: nothing here
  for j = 0, ny - 1 do
    for i = 0, nx - 1 do
      local b0 = 1 + i + (nx + 1) * j
      local a, b, c, d = g[b0], g[b0 + 1], g[b0 + nx + 2], g[b0 + nx + 1]
      local same = (a < 0) == (b < 0) and (a < 0) == (c < 0) and (a < 0) == (d < 0)
      if not (same and math.abs(a) > far and math.abs(b) > far and math.abs(c) > far and math.abs(d) > far) then
        local v = { a, b, c, d }
        local k = classify(v, h, false, depth > 0)
        if k then
          local cell_ = { lo[1] + i * hx, lo[2] + j * hy, hx, v, hy }
          if k == "leaf" then leaves[#leaves + 1] = cell_ else todo[#todo + 1] = cell_ end
        end
      end
    end
  end
  local lvl = 0
  while #todo > 0 do
    lvl = lvl + 1
    stats.split = stats.split + #todo
    local kids = split(field, z, todo)
    todo = {}
    for _, c in ipairs(kids) do
      local k = classify(c[4], math.max(c[3], c[5]), true, lvl < depth)
      if k == "leaf" then leaves[#leaves + 1] = c elseif k == "split" then todo[#todo + 1] = c end
    end
  end
  stats.leaves = #leaves
  local S, P = leaf_brackets(leaves)
  local rx, ry = M.roots(field, z, S, 1e-3 * tol)
  local segs = {}
  for _, p in ipairs(P) do
    segs[#segs + 1] = { rx[p[1]], ry[p[1]], rx[p[2]], ry[p[2]] }
  end
  local E = {}
  chords(field, z, segs, tol, E, stats)
  return E, stats
end

--- M.runs(field, z, ax, c, s0, s1, opts) -> {{a, b}, ...}: the parts of the
-- line {x = c} (ax = 1) or {y = c} (ax = 2), s0 <= s <= s1, where f < 0, in
-- order; the same base cell, splits and tolerance as M.boundary.
function M.runs(field, z, ax, c, s0, s1, opts)
  local cell, depth, tol = opts.cell, opts.depth or 9, opts.tol or 1e-5
  local n = math.max(1, math.ceil((s1 - s0) / cell - 1e-9))
  local function pt(s) if ax == 1 then return c, s end return s, c end
  local xs, ys = {}, {}
  for i = 0, n do xs[i + 1], ys[i + 1] = pt(s0 + (s1 - s0) * i / n) end
  local v = eval(field, z, xs, ys)
  local cur = {}
  for i = 1, n do cur[i] = { s0 + (s1 - s0) * (i - 1) / n, v[i], s0 + (s1 - s0) * i / n, v[i + 1] } end
  local S = {}
  for lvl = 0, depth do
    local nxt = {}
    for _, q in ipairs(cur) do
      local h = q[3] - q[1]
      local jump, mixed = math.abs(q[2] - q[4]) > K_JUMP * h, (q[2] < 0) ~= (q[4] < 0)
      local lo = math.min(math.abs(q[2]), math.abs(q[4]))
      local can = lvl < depth
      if mixed and not (can and jump) then
        local ax0, ay0 = pt(q[1])
        local bx0, by0 = pt(q[3])
        S[#S + 1] = { ax0, ay0, q[2], bx0, by0, q[4] }
      elseif can and (mixed or (jump and lo <= K_GUARD * h) or (lvl > 0 and lo <= 0.5 * K_GUARD * h)) then
        nxt[#nxt + 1] = q
      end
    end
    if #nxt == 0 then break end
    local mx, my = {}, {}
    for i, q in ipairs(nxt) do mx[i], my[i] = pt(0.5 * (q[1] + q[3])) end
    local fm = eval(field, z, mx, my)
    cur = {}
    for i, q in ipairs(nxt) do
      local m = 0.5 * (q[1] + q[3])
      cur[#cur + 1] = { q[1], q[2], m, fm[i] }
      cur[#cur + 1] = { m, fm[i], q[3], q[4] }
    end
  end
  local rx, ry = M.roots(field, z, S, 1e-3 * tol)
  local r = {}
  for i = 1, #S do r[i] = ax == 1 and ry[i] or rx[i] end
  table.sort(r)
  local out, inside, start = {}, v[1] < 0, s0
  for _, x in ipairs(r) do
    if inside then out[#out + 1] = { start, x } else start = x end
    inside = not inside
  end
  if inside then out[#out + 1] = { start, s1 } end
  return out
end

return M
