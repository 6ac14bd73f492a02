-- Trimmed voxels through the shared closest-point table (issue 14): a
-- voxel cut by the domain takes the lattice's values from its group's table
-- and the domain's near its boundary only, like an ordinary voxel. Its
-- contours and hatches must be those of the voxel's own trimmed field
-- sliced on its own (share = false, every node and every refined point
-- evaluated through the full trimmed field): a 2 mm gyroid voxel cut to a
-- cylinder (radius 0.8 mm about its axis) with a 0.3 mm skin, the cylinder
-- written as a distance (its Lipschitz bound estimated from gradients) and
-- squared (made a distance by gradus.field.distance: a meshed zero set).
local t = require "gradus.testing"
local tmp = t.tmpdir()

local function run(name, share, domain)
  local j = gradus.place.job { cell = 2, cells = { 1, 1, 1 }, layer = 0.05, hatch = 0.05, threads = 2, share = share }
  local s = j:spec { surface = "gyroid", thickness = "0.12" }
  j:voxel(0, 0, 0, { spec = s })
  j:domain(domain, { skin = 0.3 })
  local out = tmp .. "/" .. name .. ".cli"
  local st = j:run { output = out, kb = false, direct = true, first = 11, last = 11 }
  return st, gradus.cli.read(out).layers
end

-- contour coordinates and hatch segment count of a layer
local function flat(layer)
  local c, nh = {}, 0
  for _, b in ipairs(layer:blocks()) do
    if b.kind == "contour" then
      for _, v in ipairs(b.points) do c[#c + 1] = v end
    elseif b.kind == "hatch" then
      nh = nh + #b.points // 4
    end
  end
  return c, nh
end

local CASES = {
  { "distance", gradus.field.expr("sqrt((x-1)^2+(y-1)^2)-0.8") },
  { "squared", gradus.field.distance("(x-1)^2+(y-1)^2-0.64", { band = 1.6, cell = 2, box = { 0, 0, 0, 2, 2, 2 } }) },
}
for _, c in ipairs(CASES) do
  t.test("a trimmed voxel through the shared table = on its own: cylinder " .. c[1], function()
    local st, A = run(c[1] .. "_shared", true, c[2])
    local _, B = run(c[1] .. "_alone", false, c[2])
    t.eq(st.trimmed_voxels, 1, "the voxel is trimmed")
    t.eq(#A, #B, "layers")
    local worst, n = 0, 0
    for g = 1, #A do
      local a, ha = flat(A[g])
      local b, hb = flat(B[g])
      t.eq(#a, #b, ("layer %d: contour coordinates"):format(g))
      t.eq(ha, hb, ("layer %d: hatch vectors"):format(g))
      for q = 1, math.min(#a, #b) do worst = math.max(worst, math.abs(a[q] - b[q])) end
      n = n + #a
    end
    t.ok(n > 200, ("contour coordinates compared: %d"):format(n))
    t.ok(worst <= 1e-6, ("shared and alone differ by %.3g mm"):format(worst))
  end)
end

os.execute("rm -rf '" .. tmp .. "'")
t.done()
