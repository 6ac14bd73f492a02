-- gradus.profiles: process profiles (YAML): the process parameters of a job
-- kept in a file, e.g. recipes/profiles/paper.yaml (the paper's Table 1).
-- Every key must be known; values are checked with the lattice recipe's
-- ranges (gradus.lattice PARAMS); errors name file:line:col.
local gradus = require "gradus"
local strict = require "gradus.strict"
local M = {}

-- key -> the lattice parameter whose declaration checks it
M.KEYS = { name = false, voxel = "cell", layer = "layer", hatch = "hatch", beam_offset = "beam_offset",
  contours = "contours", angle = "angle", rotation = "rotation", pattern = "pattern", regions = false }

--- M.process(path) -> table of the profile's values (name, voxel, layer,
-- hatch, beam_offset, contours, angle, rotation, pattern, regions (checked
-- by gradus.regions.check); each optional).
function M.process(path)
  local p, marks = gradus.yaml.load(path, { marks = true })
  if type(p) ~= "table" then error(("%s: a process profile must be a mapping"):format(path), 0) end
  local known = {}
  for k in pairs(M.KEYS) do known[k] = true end
  strict.check_keys(p, known, path, marks, "the process profile")
  local lattice = require "gradus.lattice"
  local spec = {}
  for _, d in ipairs(lattice.PARAMS) do spec[d[1]] = d end
  local out = {}
  for k, v in pairs(p) do
    local d = M.KEYS[k] and spec[M.KEYS[k]]
    if d then
      local ok, res = pcall(strict.check, k, v, d[3], d[2])
      if not ok then
        local pos = marks and marks[p] and marks[p][k]
        error(("%s%s: %s"):format(path, pos and (":" .. pos) or "", res), 0)
      end
      v = res
    end
    if k == "regions" then v = require("gradus.regions").check(v, path, marks) end
    out[k] = v
  end
  return out
end

return M
