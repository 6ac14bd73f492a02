-- Steps at x and y faces (engine/facestep.c): two voxels side by side with
-- different thickness. Under voxel-owned grading the solid is each voxel's
-- own section cut at the shared face, so it steps exactly on the face plane.
-- Checked against an independent truth: each voxel's offset field over the
-- whole part (gradus.distance.offset, constant thickness), cut to its voxel
-- by a half-space and united (field min/max), sliced on a grid whose lines
-- hold the face (a point on the face belongs to the voxel above it, as the
-- rule says), so the step's corners are vertices of the truth.
--  - every contour is closed and oriented (t.contour_check on the truth);
--  - where a contour runs along the face (segments parallel to it within
--    2 b of it), it lies on the plane face -+ b within 1 um, and there is such
--    a run;
--  - verify() on the truth: pores <= 0.5 %, overmelt <= 1 %; the contour's
--    distance to the truth's boundary is b within 1 um at p99 (every point).
-- Templates through the knowledge-base path and kb=off (direct), exact mode.
local t = require "gradus.testing"
local L, d, lt, b = 2, 0.05, 0.04, 0.025
local RES = 30

-- the part: voxels (0,0) and (1,0) (axis "x") or (0,0) and (0,1) (axis "y")
local function run(c, direct, keep)
  local nx, ny = c.axis == "x" and 2 or 1, c.axis == "y" and 2 or 1
  local j = gradus.place.job { cell = L, cells = { nx, ny, 1 }, layer = lt, hatch = d, res = RES, threads = 2 }
  local sa = j:spec { surface = c.surface, kind = c.kind, thickness = c.T[1] }
  local sb = j:spec { surface = c.surface, kind = c.kind, thickness = c.T[2] }
  j:voxel(0, 0, 0, { spec = sa })
  j:voxel(nx - 1, ny - 1, 0, { spec = sb })
  local _, kept = j:run { kb = false, direct = direct, keep = keep }
  return kept, { nx * L, ny * L }
end

-- the truth: the first voxel's field where coordinate < L, the second's from L on
local function truth(c, hi)
  local function f(T)
    return gradus.distance.offset { surface = c.surface, cell = L, lo = { 0, 0, 0 }, hi = { hi[1], hi[2], L }, res = RES,
      thickness = T, kind = c.kind, mode = "exact" }
  end
  local a = c.axis
  local A = gradus.field.max(f(c.T[1]), gradus.field.expr(("%s - %g"):format(a, L)))
  local B = gradus.field.max(f(c.T[2]), gradus.field.expr(("%g - %s - 1e-9"):format(L, a)))
  return gradus.field.min(A, B)
end

-- The truth's boundary as segments, exactly at the step: each voxel's field
-- sliced over its own voxel (grid lines on the face: crossings refined on
-- that voxel's field), the edges along the face replaced by the parts of the
-- face where exactly one side is solid.
local function truth_edges(c, z, hi)
  local ax = c.axis == "x" and 1 or 2
  local E, face = {}, { {}, {} }
  for v = 1, 2 do
    local lo, top = { 0, 0 }, { hi[1], hi[2] }
    if v == 1 then top[ax] = L else lo[ax] = L end
    local f = gradus.distance.offset { surface = c.surface, cell = L, lo = { 0, 0, 0 }, hi = { hi[1], hi[2], L },
      res = RES, thickness = c.T[v], kind = c.kind, mode = "exact" }
    local sec = gradus.slice.field(f, z, { lo = lo, hi = top, cell = d / 8 })
    for i = 1, sec:count() do
      local r = sec:ring(i)
      local n = #r // 2
      for k = 1, n do
        local k2 = k % n + 1
        local e = { r[2 * k - 1], r[2 * k], r[2 * k2 - 1], r[2 * k2] }
        if math.abs(e[ax] - L) < 1e-9 and math.abs(e[ax + 2] - L) < 1e-9 then
          local s0, s1 = e[3 - ax], e[5 - ax]
          face[v][#face[v] + 1] = { math.min(s0, s1), math.max(s0, s1) }
        else
          E[#E + 1] = e
        end
      end
    end
  end
  local bp = {}
  for v = 1, 2 do for _, iv in ipairs(face[v]) do bp[#bp + 1] = iv[1]; bp[#bp + 1] = iv[2] end end
  table.sort(bp)
  local function on(v, s)
    for _, iv in ipairs(face[v]) do if s > iv[1] and s < iv[2] then return true end end
    return false
  end
  for k = 1, #bp - 1 do
    local m = 0.5 * (bp[k] + bp[k + 1])
    if bp[k + 1] > bp[k] and on(1, m) ~= on(2, m) then
      E[#E + 1] = ax == 1 and { L, bp[k], L, bp[k + 1] } or { bp[k], L, bp[k + 1], L }
    end
  end
  return E
end

-- p99 of | distance of the contour points to the truth's boundary - b |
local function dev_p99(layer, E)
  local devs = {}
  for _, bk in ipairs(layer:blocks()) do
    if bk.kind == "contour" and not bk.thin then
      local P = bk.points
      for q = 1, #P, 2 do
        local px, py, best = P[q], P[q + 1], math.huge
        for _, e in ipairs(E) do
          if math.abs(e[1] - px) < 0.1 and math.abs(e[2] - py) < 0.1 then
            local ex, ey = e[3] - e[1], e[4] - e[2]
            local l2 = ex * ex + ey * ey
            local s = l2 > 0 and ((px - e[1]) * ex + (py - e[2]) * ey) / l2 or 0
            s = s < 0 and 0 or s > 1 and 1 or s
            local dx, dy = e[1] + s * ex - px, e[2] + s * ey - py
            local dd = dx * dx + dy * dy
            if dd < best then best = dd end
          end
        end
        devs[#devs + 1] = math.abs(math.sqrt(best) - b)
        if os.getenv("FSDEV") and devs[#devs] > 1e-3 then print(("    dev %.2f um at %.4f %.4f"):format(devs[#devs] * 1e3, px, py)) end
      end
    end
  end
  table.sort(devs)
  return devs[math.max(1, math.ceil(0.99 * #devs))] or 0, #devs, devs[#devs] or 0
end

-- contour segments parallel to the face within 2 b of it: their distance to
-- the face's offset planes (worst) and their total length
local function step_runs(layer, c)
  local ax = c.axis == "x" and 1 or 2
  local worst, len = 0, 0
  for _, bk in ipairs(layer:blocks()) do
    if bk.kind == "contour" then
      local P = bk.points
      for q = 1, #P - 3, 2 do
        local a0, a1 = P[q + ax - 1], P[q + 2 + ax - 1]
        local s0, s1 = P[q + 2 - ax], P[q + 4 - ax]
        local l = math.abs(s1 - s0)
        if l > 2e-3 and math.abs(a1 - a0) < 1e-6 * l and math.abs(a0 - L) < 2 * b then
          worst = math.max(worst, math.abs(math.abs(a0 - L) - b))
          len = len + l
        end
      end
    end
  end
  return worst, len
end

local cases = {
  { name = "P sheet 0.06 | 0.12 across an x face", surface = "primitive", kind = "sheet", T = { 0.06, 0.12 }, axis = "x",
    layers = { 13, 25 } },
  { name = "gyroid network 0.05 | 0.15 across a y face", surface = "gyroid", kind = "network", T = { 0.05, 0.15 },
    axis = "y", layers = { 7, 30 } },
}

for _, c in ipairs(cases) do
  for _, direct in ipairs { false, true } do
    t.test(("%s (%s)"):format(c.name, direct and "kb=off, direct" or "templates"), function()
      local kept, hi = run(c, direct, c.layers)
      local F = truth(c, hi)
      local total_run = 0
      for _, g in ipairs(c.layers) do
        local layer, z = kept[g], g * lt - lt / 2
        local open = 0
        for _, bk in ipairs(layer:blocks()) do
          if bk.kind == "contour" and bk.shape ~= "closed" and not bk.thin then open = open + 1 end
        end
        t.eq(open, 0, ("layer %d: every contour closed"):format(g))
        local rep = t.contour_check(layer, { field = F, z = z, box = { 0, 0, hi[1], hi[2] }, offset = b })
        t.ok(rep.loops > 0 and #rep.bad == 0, ("layer %d: %d loops, %d badly oriented"):format(g, rep.loops, #rep.bad))
        local worst, len = step_runs(layer, c)
        total_run = total_run + len
        t.ok(worst <= 1e-3, ("layer %d: contour along the step %.3g um off the plane face -+ b"):format(g, worst * 1e3))
        local sec = gradus.slice.field(F, z, { lo = { 0, 0 }, hi = hi, cell = d / 8 })
        local r = gradus.hatch.verify(sec, layer, { track = d, pixel = d / 20, offset = b, spacing = d, contours = 1 })
        t.ok(r.pore <= 0.005, ("layer %d: pore %.3f %%"):format(g, 100 * r.pore))
        t.ok(r.overmelt <= 0.01, ("layer %d: overmelt %.3f %%"):format(g, 100 * r.overmelt))
        local p99, n, dmax = dev_p99(layer, truth_edges(c, z, hi))
        print(("  info: layer %d: %d loops, step run %.3f mm (%.3g um off), pore %.3f %%, overmelt %.3f %%, dev p99 %.3g um max %.3g um")
          :format(g, rep.loops, len, worst * 1e3, 100 * r.pore, 100 * r.overmelt, p99 * 1e3, dmax * 1e3))
        t.ok(n > 100 and p99 <= 1e-3, ("layer %d: contour deviation p99 %.3g um (max %.3g, %d points)")
          :format(g, p99 * 1e3, dmax * 1e3, n))
      end
      t.ok(total_run > 0.02, ("the contours run along the step (%.3f mm over the layers)"):format(total_run))
    end)
  end
end
t.done()
