--- gradus.steptruth: the true section of voxels graded differently, for
-- measurements (tests, recipes/quality.lua), independent of the engine's
-- templates and of its face-step code (engine/facestep.c).
--
-- Under voxel-owned grading a voxel's solid is its own field's, cut at its
-- faces: where neighbours differ, the section steps exactly on the face.
-- Two views of that section:
--  - M.field(voxels): one field for slicing and point tests, the union of
--    each voxel's field cut to its voxel by half-spaces (a point on a face
--    belongs to the voxel above it). Sliced on a grid its step corners are
--    cut by up to a grid cell where they fall between nodes: fine for areas
--    (verify's pore and overmelt), not for micrometre distances.
--  - M.edges(voxels, z, window, cell): the boundary as segments, exact at the
--    step: each voxel's own field sliced over its own square (crossings on the
--    faces refined on that field), the edges along the faces replaced by the
--    parts of the face where exactly one side is solid.
-- voxels: list of {lo = {x, y}, hi = {x, y}, field = f} (squares tiling the
-- region, fields of gradus.distance.offset or any gradus field).
local gradus = require "gradus"
local refslice = require "gradus.refslice"
local M = {}

function M.field(voxels)
  local F
  for _, v in ipairs(voxels) do
    -- inside the square: x in [lo, hi), y in [lo, hi)
    local box = gradus.field.expr(("max(max(%.17g - x - 1e-9, x - %.17g), max(%.17g - y - 1e-9, y - %.17g))")
      :format(v.lo[1], v.hi[1], v.lo[2], v.hi[2]))
    local g = gradus.field.max(v.field, box)
    F = F and gradus.field.min(F, g) or g
  end
  return F
end

local function inside(list, s)
  for _, iv in ipairs(list) do if s > iv[1] and s < iv[2] then return true end end
  return false
end

--- M.edges(voxels, z, window, cell [, opts]) -> segments {{x0, y0, x1, y1}, ...},
-- stats: the true boundary inside window = {lo = {x, y}, hi = {x, y}}
-- (closed along the window's border) at height z. Each voxel's own field
-- over its own square (gradus.refslice: base grid `cell` mm, split at jumps
-- of the field, vertices and chords on the level set within opts.tol, default
-- 1e-5 mm; opts.depth splits, default 9), and on each face the parts where
-- exactly one side is solid (the runs of each side's field along the face).
-- stats: base cells, split cells, leaves, unresolved chords (summed).
function M.edges(voxels, z, window, cell, opts)
  opts = opts or {}
  local o = { cell = cell, depth = opts.depth, tol = opts.tol }
  local E, face = {}, {} -- face["1:2"] = {ax, c, lo = {runs of the voxels below}, hi = {...}}
  local stats = { cells = 0, split = 0, leaves = 0, unresolved = 0, short = 0 }
  local function on_face(ax, c, side, runs)
    local key = ("%d:%.17g"):format(ax, c)
    face[key] = face[key] or { ax = ax, c = c, lo = {}, hi = {} }
    local l = face[key][side]
    for _, r in ipairs(runs) do l[#l + 1] = r end
  end
  for _, v in ipairs(voxels) do
    local lo = { math.max(v.lo[1], window.lo[1]), math.max(v.lo[2], window.lo[2]) }
    local hi = { math.min(v.hi[1], window.hi[1]), math.min(v.hi[2], window.hi[2]) }
    if hi[1] > lo[1] and hi[2] > lo[2] then
      local Ev, st = refslice.boundary(v.field, z, lo, hi, o)
      for _, e in ipairs(Ev) do E[#E + 1] = e end
      for k in pairs(stats) do stats[k] = stats[k] + st[k] end
      for ax = 1, 2 do
        local s0, s1 = lo[3 - ax], hi[3 - ax]
        on_face(ax, lo[ax], "hi", refslice.runs(v.field, z, ax, lo[ax], s0, s1, o))
        on_face(ax, hi[ax], "lo", refslice.runs(v.field, z, ax, hi[ax], s0, s1, o))
      end
    end
  end
  for _, f in pairs(face) do
    local bp = {}
    for _, side in ipairs { "lo", "hi" } do
      for _, iv in ipairs(f[side]) do bp[#bp + 1] = iv[1]; bp[#bp + 1] = iv[2] end
    end
    table.sort(bp)
    for k = 1, #bp - 1 do
      local m = 0.5 * (bp[k] + bp[k + 1])
      if bp[k + 1] > bp[k] and inside(f.lo, m) ~= inside(f.hi, m) then
        E[#E + 1] = f.ax == 1 and { f.c, bp[k], f.c, bp[k + 1] } or { bp[k], f.c, bp[k + 1], f.c }
      end
    end
  end
  return E, stats
end

-- the vertices x1, y1, x2, y2, ... of a polyline with n points evenly spaced
-- inside each of its segments added after the segment's first vertex
local function contour_points(P, n)
  if n <= 0 then return P end
  local out = {}
  for q = 1, #P, 2 do
    out[#out + 1] = P[q]
    out[#out + 1] = P[q + 1]
    if q + 3 <= #P then
      for s = 1, n do
        local f = s / (n + 1)
        out[#out + 1] = P[q] + f * (P[q + 2] - P[q])
        out[#out + 1] = P[q + 1] + f * (P[q + 3] - P[q + 1])
      end
    end
  end
  return out
end

--- M.points(layer, E, b, box, chords) -> list of {x, y, dev}: for every point of the
-- layer's contours (thin-wall lines excluded), optionally only those inside
-- box = {x0, y0, x1, y1}, its distance to the segments E minus b (mm, signed:
-- negative where the boundary is nearer than b). chords = n (default 0) also
-- measures n points evenly spaced inside every segment of a contour: the
-- laser follows the straight chord between two vertices, and where the
-- offset curves (an arc of radius b around a corner of the section) the
-- chord's middle lies off it although both ends lie on it.
function M.points(layer, E, b, box, chords)
  local h = 0.05
  local grid = {}
  local function key(i, j) return i * 1000003 + j end
  for _, e in ipairs(E) do
    local i0, i1 = math.floor(math.min(e[1], e[3]) / h), math.floor(math.max(e[1], e[3]) / h)
    local j0, j1 = math.floor(math.min(e[2], e[4]) / h), math.floor(math.max(e[2], e[4]) / h)
    for i = i0, i1 do
      for j = j0, j1 do
        local k = key(i, j)
        grid[k] = grid[k] or {}
        grid[k][#grid[k] + 1] = e
      end
    end
  end
  local reach = math.ceil(3 * b / h) + 1
  local pts = {}
  for _, bk in ipairs(layer:blocks()) do
    if bk.kind == "contour" and not bk.thin then
      local P = contour_points(bk.points, chords or 0)
      for q = 1, #P, 2 do
        local px, py = P[q], P[q + 1]
        if not box or (px >= box[1] and px <= box[3] and py >= box[2] and py <= box[4]) then
          local best, pi, pj = math.huge, math.floor(px / h), math.floor(py / h)
          for i = pi - reach, pi + reach do
            for j = pj - reach, pj + reach do
              for _, e in ipairs(grid[key(i, j)] or {}) do
                local ex, ey = e[3] - e[1], e[4] - e[2]
                local l2 = ex * ex + ey * ey
                local s = l2 > 0 and ((px - e[1]) * ex + (py - e[2]) * ey) / l2 or 0
                s = s < 0 and 0 or s > 1 and 1 or s
                local dx, dy = e[1] + s * ex - px, e[2] + s * ey - py
                local dd = dx * dx + dy * dy
                if dd < best then best = dd end
              end
            end
          end
          pts[#pts + 1] = { px, py, math.sqrt(best) - b }
        end
      end
    end
  end
  return pts
end

--- M.deviations(layer, E, b, box, chords) -> sorted list of | distance - b | (mm) of
-- the points of M.points.
function M.deviations(layer, E, b, box, chords)
  local devs = {}
  for _, q in ipairs(M.points(layer, E, b, box, chords)) do devs[#devs + 1] = math.abs(q[3]) end
  table.sort(devs)
  return devs
end

-- the voxel whose square holds (x, y) (x in [lo, hi), y in [lo, hi))
local function owner(voxels, x, y)
  for _, v in ipairs(voxels) do
    if x >= v.lo[1] and x < v.hi[1] and y >= v.lo[2] and y < v.hi[2] then return v end
  end
end

--- M.local_deviation(voxels, z, x, y, b [, opts]) -> distance - b (mm), found:
-- the distance from (x, y) to the nearest void (field > 0 of the voxel whose
-- square holds the point) found on a grid of step opts.h (default 1e-4 mm)
-- over the disc of radius b + opts.reach (default 0.002 mm), bisected on the
-- segment to it (to 1e-6 mm). Independent of any slicer: where the field is
-- nearly flat at zero (a crease of the sheet's distance along the medial
-- surface just touching zero), a slicer's boundary is ill-conditioned, this
-- is not. found = false when no void lies within the disc (then the result is
-- opts.reach, a lower bound). Cost: about (2 (b + reach) / h)^2 evaluations.
function M.local_deviation(voxels, z, x, y, b, opts)
  opts = opts or {}
  local h, reach = opts.h or 1e-4, opts.reach or 0.002
  if not (h > 0 and h < math.huge) then error(("steptruth.local_deviation: bad option 'h' (grid step > 0 mm expected, got %s)"):format(h), 2) end
  if not (reach >= 0 and reach < math.huge) then error(("steptruth.local_deviation: bad option 'reach' (>= 0 mm expected, got %s)"):format(reach), 2) end
  local R = b + reach
  local n = math.floor(R / h)
  local byv = {}
  for j = -n, n do
    for i = -n, n do
      if i * i + j * j <= n * n then
        local px, py = x + i * h, y + j * h
        local v = owner(voxels, px, py)
        if v then
          local t = byv[v]
          if not t then t = { xs = {}, ys = {}, zs = {} }; byv[v] = t end
          local k = #t.xs + 1
          t.xs[k], t.ys[k], t.zs[k] = px, py, z
        end
      end
    end
  end
  local best, bx, by = math.huge, nil, nil
  for v, t in pairs(byv) do
    local f = v.field:eval_many(t.xs, t.ys, t.zs)
    for k = 1, #f do
      if f[k] > 0 then
        local dd = (t.xs[k] - x) ^ 2 + (t.ys[k] - y) ^ 2
        if dd < best then best, bx, by = dd, t.xs[k], t.ys[k] end
      end
    end
  end
  if not bx then return reach, false end
  local function void(s)
    local px, py = x + s * (bx - x), y + s * (by - y)
    local v = owner(voxels, px, py)
    return v and v.field:eval(px, py, z) > 0
  end
  local a, c, L = 0, 1, math.sqrt(best)
  while (c - a) * L > 1e-6 do
    local m = 0.5 * (a + c)
    if void(m) then c = m else a = m end
  end
  return c * L - b, true
end

--- M.quantile(sorted, p) -> the p-quantile of a sorted list (0 when empty).
function M.quantile(s, p)
  if #s == 0 then return 0 end
  return s[math.max(1, math.ceil(p * #s))]
end

return M
