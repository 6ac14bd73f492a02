-- Build time as a machine sees it: recoating per layer from the machine
-- profile (default 12 s) apart from scanning and jumps; a warning when a
-- laser gets no work or under 10 % of it, with the reason (reach, zones).
local t = require "gradus.testing"
local lattice = require "gradus.lattice"
local lasers = require "gradus.lasers"
local tmp = t.tmpdir()

local function params(o)
  return t.lattice_params({ thickness = "0.08", kb = tmp .. "/kb", res = 20, threads = 2, layers = "1:20" }, o)
end

local function machine(path, text)
  local f = assert(io.open(path, "w"))
  f:write(text)
  f:close()
  return path
end

t.test("recoating counted per layer, apart from scan and jump time", function()
  t.eq(lasers.default(1).recoat_time, 12, "default recoat time 12 s")
  local st = lattice.run(params {}, nil)
  t.near(st.recoat_time_s, 20 * 12, 1e-9, "20 layers x 12 s")
  local sum = 0
  for _, l in ipairs(st.lasers) do sum = sum + l.scan_time_s end
  t.near(st.scan_time_s + st.jump_time_s, sum, 1e-9 * sum, "scan + jump time = the lasers' time")
  t.near(st.build_time_s, sum + st.recoat_time_s, 1e-9 * sum, "one laser: build time = its time + recoating")
  t.ok(st.scan_time_s > 0 and st.jump_time_s > 0, "both parts present")
  local m = machine(tmp .. "/r.yaml", "lasers: [{name: a}]\nrecoat_time: 7.5\n")
  local st2 = lattice.run(params { machine = m }, nil)
  t.near(st2.recoat_time_s, 20 * 7.5, 1e-9, "the profile's recoat time")
  t.eq(st.warnings, nil, "one laser: no warning")
end)

t.test("a laser with no work or under 10 % of it is named, with the reason", function()
  -- the example machine at the default origin: laser 2's field starts at x = 100 mm
  local m = machine(tmp .. "/two.yaml", [[
lasers:
  - {name: near, field: {lo: [0, 0], hi: [150, 250]}}
  - {name: far, field: {lo: [100, 0], hi: [250, 250]}}
]])
  local st = lattice.run(params { machine = m }, nil)
  t.ok(st.warnings and #st.warnings == 1, "one warning")
  t.ok(st.warnings[1]:find("laser 2 (far) gets no work", 1, true) and st.warnings[1]:find("(reach)", 1, true),
    st.warnings[1])
  -- zones: laser 2's zone (x in [2, 4] mm) holds no lattice
  local p = params { lasers = 2, assign = "zones" }
  p.rule = function(i) return { skip = i >= 1 } end
  local st2 = lattice.run(p, nil)
  t.eq(st2.voxels, 2, "the rule's skip leaves the voxels empty")
  t.ok(st2.warnings and st2.warnings[1]:find("laser 2 (laser2) gets no work", 1, true)
    and st2.warnings[1]:find("(zones)", 1, true), st2.warnings and st2.warnings[1] or "no warning")
  -- balanced lasers: none
  local st3 = lattice.run(params { lasers = 2 }, nil)
  t.eq(st3.warnings, nil, "balanced: no warning")
  t.ok(st3.balance_efficiency > 0.8 and st3.balance_efficiency <= 1, "balance without recoating")
end)

t.done()
