-- gradus.testing: a small harness for the Lua tests (tests/lua/*.lua).
-- Each t.test prints "PASS name" or "FAIL name: why"; t.done() raises if any
-- test failed, so `gradus run` exits non-zero.
local M = { failed = 0, passed = 0 }
local src = (package.loaded.gradus and package.loaded.gradus._ctx.recipe or "?"):match("[^/]*$")

local function fail(msg, level)
  error({ gradus_test_failure = msg }, level)
end

function M.ok(cond, msg)
  if not cond then fail(msg or "assertion failed", 3) end
end

function M.eq(a, b, msg)
  if a ~= b then fail(string.format("%s: got %s, want %s", msg or "eq", tostring(a), tostring(b)), 3) end
end

function M.near(a, b, tol, msg)
  if type(a) ~= "number" or type(b) ~= "number" or not (math.abs(a - b) <= tol) then
    fail(string.format("%s: got %s, want %s (tolerance %g)", msg or "near", tostring(a), tostring(b), tol), 3)
  end
end

--- t.raises(fn, pattern): fn must raise an error whose message matches pattern.
function M.raises(fn, pattern, msg)
  local ok, err = pcall(fn)
  if ok then fail((msg or "raises") .. ": no error raised", 3) end
  err = tostring(err)
  if pattern and not err:find(pattern) then
    fail(string.format("%s: error '%s' does not match '%s'", msg or "raises", err, pattern), 3)
  end
  return err
end

--- t.tmpdir(): a new empty directory for a test file's outputs; returns its path.
function M.tmpdir()
  local d = os.tmpname()
  os.remove(d)
  package.loaded.gradus.mkdir(d)
  return d
end

--- t.lattice_params(defaults, o): the lattice recipe's parameters with the
-- table `defaults` and then `o` (may be nil) applied over them.
function M.lattice_params(defaults, o)
  local p = require("gradus.lattice").params()
  for k, v in pairs(defaults) do p[k] = v end
  for k, v in pairs(o or {}) do p[k] = v end
  return p
end

function M.test(name, fn)
  local clock = package.loaded.gradus and package.loaded.gradus.clock
  local t0 = clock and clock()
  local ok, err = xpcall(fn, function(e)
    if type(e) == "table" and e.gradus_test_failure then
      local info = debug.getinfo(3, "Sl")
      return (info and (info.short_src .. ":" .. info.currentline .. ": ") or "") .. e.gradus_test_failure
    end
    return debug.traceback(tostring(e), 2)
  end)
  if ok then
    M.passed = M.passed + 1
    print("PASS " .. src .. ": " .. name .. (t0 and string.format(" (%.1f s)", clock() - t0) or ""))
  else
    M.failed = M.failed + 1
    print("FAIL " .. src .. ": " .. name .. ": " .. tostring(err):gsub("\n", "\n    "))
  end
  io.stdout:flush()
end

--- t.contour_check(layer, {field=, z=, box={x0, y0, x1, y1}, offset=, max_wrong=0.5}) -> report
-- Orientation of every closed contour of `layer` (gradus.layer or a CLI layer):
-- the signed area must agree with the declared direction (dir 1 counter-clockwise
-- outer, dir 0 clockwise hole), and the solid must lie on the left of every
-- contour. The solid is {field < 0 at height z} inside the part's box `box`.
-- Along each contour, every ~offset/2 mm, rays go left and right along the
-- normal, stepping offset/5 up to 3 offset (the beam offset, mm): the first
-- point out of the solid on each side is where the boundary is. A contour with
-- the solid on its left meets the boundary first on its right; a sample whose
-- exit on the left is nearer by two steps or more is wrong, one whose exits are
-- within a step (a wall about 2 offsets wide) or out of reach is not decided. (A field's value or gradient at one point is no
-- test: on a ridge of the field, across a cusp of the section, it points
-- along the contour.) report = {loops=, samples=, bad={{block=, why=, length=,
-- wrong=}}}: a loop is bad when its direction disagrees with its area, or when
-- more than max_wrong of its decided length is wrong.
function M.contour_check(layer, o)
  local box, b, maxw = o.box, o.offset, o.max_wrong or 0.5
  local ds, reach, nstep = b / 2, 3 * b, 15
  local rep = { loops = 0, samples = 0, bad = {} }
  local function outside(x, y, g)
    return g >= 0 or (box and (x < box[1] or x > box[3] or y < box[2] or y > box[4]))
  end
  for bi, bk in ipairs(layer:blocks()) do
    if bk.kind == "contour" and bk.shape == "closed" then
      rep.loops = rep.loops + 1
      local P, n = bk.points, #bk.points // 2
      local area, len = 0, 0
      local xs, ys, zs, w = {}, {}, {}, {}
      for k = 1, n - 1 do
        local x0, y0, x1, y1 = P[2 * k - 1], P[2 * k], P[2 * k + 1], P[2 * k + 2]
        area = area + x0 * y1 - x1 * y0
        local dx, dy = x1 - x0, y1 - y0
        local l = math.sqrt(dx * dx + dy * dy)
        len = len + l
        local m = math.ceil(l / ds)
        for q = 1, l > 0 and m or 0 do
          local s = (q - 0.5) / m
          local px, py, nx, ny = x0 + s * dx, y0 + s * dy, -dy / l, dx / l
          w[#w + 1] = l / m
          for side = 1, -1, -2 do
            for st = 1, nstep do
              local t = side * st * reach / nstep
              xs[#xs + 1], ys[#ys + 1], zs[#zs + 1] = px + t * nx, py + t * ny, o.z
            end
          end
        end
      end
      local g = #xs > 0 and o.field:eval_many(xs, ys, zs) or {}
      local wrong, decided, i = 0, 0, 0
      for q = 1, #w do
        local exit = {}
        for side = 1, 2 do
          for st = 1, nstep do
            i = i + 1
            if not exit[side] and outside(xs[i], ys[i], g[i]) then exit[side] = st end
          end
        end
        local l, r = exit[1] or math.huge, exit[2] or math.huge
        if math.abs(l - r) >= 2 then -- nearer by at least two steps: a wall about as wide as 2 offsets is no answer
          decided = decided + w[q]
          if l < r then wrong = wrong + w[q] end
        end
      end
      rep.samples = rep.samples + #w
      local why
      if (area > 0) ~= (bk.dir == 1) then why = ("dir %d but signed area %.3g mm^2"):format(bk.dir, area / 2)
      elseif decided > 0 and wrong > maxw * decided then
        why = ("solid on the right along %.0f %% of its decided length"):format(100 * wrong / decided)
      end
      if why then rep.bad[#rep.bad + 1] = { block = bi, why = why, length = len, wrong = wrong } end
    end
  end
  return rep
end

-- Iterator over the segments of a layer's blocks of one kind: x0, y0, x1, y1.
function M.segments(layer, kind)
  return coroutine.wrap(function()
    for _, b in ipairs(layer:blocks()) do
      if b.kind == kind then
        local p = b.points
        for q = 1, #p - 3, 2 do coroutine.yield(p[q], p[q + 1], p[q + 2], p[q + 3]) end
      end
    end
  end)
end

-- The segments of a layer's blocks of one kind in cells of h mm: key -> list.
function M.seg_cells(layer, kind, h)
  local cells = {}
  for _, b in ipairs(layer:blocks()) do
    if b.kind == kind then
      local p = b.points
      for q = 1, #p - 3, 2 do
        local s = { p[q], p[q + 1], p[q + 2], p[q + 3] }
        for i = math.floor(math.min(s[1], s[3]) / h), math.floor(math.max(s[1], s[3]) / h) do
          for j = math.floor(math.min(s[2], s[4]) / h), math.floor(math.max(s[2], s[4]) / h) do
            local k = i .. ":" .. j
            cells[k] = cells[k] or {}
            table.insert(cells[k], s)
          end
        end
      end
    end
  end
  return cells
end

-- Largest distance from a point of pts to the segments in cells (h when
-- none lies within h).
function M.farthest(pts, cells, h)
  local worst = 0
  for _, pt in ipairs(pts) do
    local best, ci, cj = h, math.floor(pt[1] / h), math.floor(pt[2] / h)
    for i = ci - 1, ci + 1 do
      for j = cj - 1, cj + 1 do
        for _, s in ipairs(cells[i .. ":" .. j] or {}) do
          local ex, ey = s[3] - s[1], s[4] - s[2]
          local L2 = ex * ex + ey * ey
          local u = L2 > 0 and ((pt[1] - s[1]) * ex + (pt[2] - s[2]) * ey) / L2 or 0
          u = math.max(0, math.min(1, u))
          best = math.min(best, math.sqrt((s[1] + u * ex - pt[1]) ^ 2 + (s[2] + u * ey - pt[2]) ^ 2))
        end
      end
    end
    worst = math.max(worst, best)
  end
  return worst
end

function M.done()
  if M.failed > 0 then error(M.failed .. " test(s) failed", 0) end
end

return M
