-- gradus.part: the part's box. `cells` gives a box of whole cells; `size`
-- (mm) gives any box: cells enough to cover it, the lattice cut at the faces
-- that fall inside a cell (x, y: a box domain, so the cut faces are
-- contoured like any domain boundary; z: the layers stop at the part's
-- height), the layer count round(Z / layer) and the CLI header's extent.
local gradus = require "gradus"
local M = {}

local function fmt(v) return ("%.17g"):format(v) end

--- M.lengths(cell) -> {Lx, Ly, Lz}: the cell lengths (mm) of a checked
-- `cell` parameter, a number (a cube) or a table of three (a stretched cell).
function M.lengths(cell)
  if type(cell) == "table" then return { cell[1], cell[2], cell[3] } end
  return { cell, cell, cell }
end

--- M.box(p) -> {cells = {nx, ny, nz}, hi = {x, y, z} (the part's max corner,
-- mm) or nil, layers = N or nil, domain = function(d) -> d cut by the box}
-- for checked lattice parameters p (cell, cells, size, origin, layer).
function M.box(p)
  if p.size == nil or p.size == "" then
    return { cells = p.cells, domain = function(d) return d end }
  end
  local C, o, cells, hi, terms = M.lengths(p.cell), p.origin, {}, {}, {}
  for a = 1, 3 do
    local n = p.size[a] / C[a]
    local whole = math.floor(n + 0.5)
    if math.abs(n - whole) <= 1e-9 * math.max(1, n) then
      cells[a] = math.max(1, whole)
    else
      cells[a] = math.ceil(n)
      if a < 3 then terms[#terms + 1] = ("(%s-%s)"):format(({ "x", "y" })[a], fmt(o[a] + p.size[a])) end
    end
    hi[a] = o[a] + p.size[a]
  end
  local layers = math.floor(p.size[3] / p.layer + 0.5)
  if layers < 1 then
    error(("parameter 'size': the height %g mm is less than half a layer (%g mm)"):format(p.size[3], p.layer), 0)
  end
  if #terms > 0 and not p.faces then
    error(("parameter 'size': %g x %g mm is not whole cells of %s mm, and faces=false (leaving the cut open) is not supported with size yet")
      :format(p.size[1], p.size[2], C[1] == C[2] and ("%g"):format(C[1]) or ("%g x %g"):format(C[1], C[2])), 0)
  end
  local cut -- nil: no face inside a cell
  if #terms == 1 then cut = terms[1] elseif #terms == 2 then cut = ("max(%s,%s)"):format(terms[1], terms[2]) end
  -- with no domain of the user's, the cut as a box solid (an STL-like domain: trimmed voxels
  -- along a cut face see the same boundary and share templates), its other faces 10 cells away
  local function cut_solid()
    local lo, top = {}, {}
    for a = 1, 3 do
      lo[a] = o[a] - 10 * C[a]
      top[a] = (a < 3 and hi[a] < o[a] + cells[a] * C[a] - 1e-9) and hi[a] or o[a] + (cells[a] + 10) * C[a]
    end
    return gradus.mesh.box(lo, top):solid()
  end
  local function domain(d)
    if not cut then return d end
    if d == nil then return cut_solid() end
    if type(d) == "string" then return ("max((%s),%s)"):format(d, cut) end
    return gradus.field.max(d, gradus.field.expr(cut))
  end
  return { cells = cells, hi = hi, layers = layers, domain = domain }
end

return M
