-- gradus.sequence: fabrication sequences, the order in which the voxels
-- (islands) of a layer are scanned. Each returns a function key(i, j, k, nx,
-- ny) -> number; a layer's voxels are scanned in ascending key order. A
-- recipe may pass its own function of the same form.
local M = {}

--- raster: row by row, x fastest.
function M.raster(i, j, _, nx)
  return j * nx + i
end

--- serpentine: row by row, reversing direction on every other row.
function M.serpentine(i, j, _, nx)
  if j % 2 == 1 then i = nx - 1 - i end
  return j * nx + i
end

--- checkerboard: two passes, first the "black" voxels (i+j even), then the
-- "white" ones, each pass in raster order.
function M.checkerboard(i, j, _, nx, ny)
  return ((i + j) % 2) * nx * ny + j * nx + i
end

--- spread: nine passes over a 3 x 3 stride, so that consecutive islands are
-- at least three voxels apart (heat spreads out instead of accumulating).
function M.spread(i, j, _, nx, ny)
  local pass = (j % 3) * 3 + (i % 3)
  return pass * nx * ny + j * nx + i
end

M.names = { "raster", "serpentine", "checkerboard", "spread" }

--- M.get(name or function) -> key function; unknown names list the valid ones.
function M.get(s)
  if type(s) == "function" then return s end
  local f = M[s]
  if type(f) ~= "function" or s == "get" then
    error(("unknown sequence '%s' (valid: %s, or a Lua function)"):format(tostring(s), table.concat(M.names, ", ")), 3)
  end
  return f
end

return M
