-- OVF as Gradus writes it, checked outside our own reader: the file's framing
-- (magic, int64 positions, varint lengths) is followed here in Lua, and the
-- messages are decoded by Debian's `protoc --decode_raw`, which knows no
-- schema: it shows the published field numbers. A two-laser job: every
-- block's marking parameters are the manifest's power and speed of its laser
-- and kind; the geometry equals the binary CLI of the same job; `gradus info`
-- and `gradus convert` on both formats; malformed files refused.
local t = require "gradus.testing"
local root = gradus.root
local exe = root .. "/build/gradus"
local tmp = (os.getenv("TMPDIR") or "/tmp") .. "/gradus_test_ovf_" .. tostring(os.time()) .. "_" .. tostring(math.random(1e6))
gradus.mkdir(tmp)

local function sh(cmd) -- -> ok, output (stdout and stderr)
  local p = io.popen(cmd .. " 2>&1")
  local out = p:read("a")
  local ok = p:close()
  return ok, out
end
local function slurp(path) local f = assert(io.open(path, "rb")); local s = f:read("a"); f:close(); return s end
local function spit(path, s) local f = assert(io.open(path, "wb")); f:write(s); f:close() end
local function exists(path) local f = io.open(path, "rb"); if f then f:close() end; return f ~= nil end

-- the job: two lasers with their own powers and speeds, 2 x 1 cells, 3 layers
spit(tmp .. "/m2.yaml", [[
name: test-2-laser
jump_speed: 6000
lasers:
  - name: left
    field: {lo: [-1, -1], hi: [2.5, 5]}
    contour: {power: 110, speed: 610}
    hatch: {power: 210, speed: 1010}
  - name: right
    field: {lo: [1.5, -1], hi: [5, 5]}
    contour: {power: 120, speed: 620}
    hatch: {power: 220, speed: 1020}
]])
local job = ("'%s' run '%s/recipes/lattice.lua' -q -D cells=2,1,1 -D machine='%s/m2.yaml' -D layers=1:3 -D kb=off")
  :format(exe, root, tmp)
local ovf, cli = tmp .. "/j.ovf", tmp .. "/j.cli"
local ok1, o1 = sh(job .. " -o '" .. ovf .. "'")
local ok2, o2 = sh(job .. " -D format=binary-long -o '" .. cli .. "'")
assert(ok1 and ok2, "the job failed: " .. o1 .. o2)
local manifest = gradus.yaml.load(tmp .. "/j.manifest.yaml")

-- ---- the file's own framing, read here ----
local bytes = slurp(ovf)
local function varint_at(s, p) -- p 0-based -> value, next p
  local v, sh_ = 0, 0
  repeat
    local c = s:byte(p + 1)
    p = p + 1
    v = v | ((c & 127) << sh_)
    sh_ = sh_ + 7
  until c < 128
  return v, p
end
local function msg_at(p) local n, q = varint_at(bytes, p); return bytes:sub(q + 1, q + n) end
local function i64_at(p) return (string.unpack("<i8", bytes, p + 1)) end
-- the two LUT messages hold only varints and packed varints: enough to follow them
local function lut(m)
  local pos, list, p = nil, {}, 0
  while p < #m do
    local key
    key, p = varint_at(m, p)
    if key == 8 then pos, p = varint_at(m, p)
    elseif key == 18 then
      local n
      n, p = varint_at(m, p)
      local stop = p + n
      while p < stop do list[#list + 1], p = varint_at(m, p) end
    else error("unexpected LUT field key " .. key) end
  end
  return pos, list
end
local function decode_raw(m)
  local f = tmp .. "/m.bin"
  spit(f, m)
  local ok, out = sh("protoc --decode_raw < '" .. f .. "'")
  assert(ok, "protoc --decode_raw failed: " .. out)
  return out
end
local function varint_bytes(v)
  local s = ""
  repeat
    local c = v & 127
    v = v >> 7
    s = s .. string.char(c | (v > 0 and 128 or 0))
  until v == 0
  return s
end

local shell_pos, planes = lut(msg_at(i64_at(4)))

t.test("file structure: magic, job LUT, one LUT per work plane", function()
  t.eq(bytes:sub(1, 4), "LVF!", "magic")
  t.eq(#planes, 3, "work planes in the job LUT")
  t.eq(planes[1], 12, "the first work plane starts after magic and job LUT position")
  for i = 2, #planes do t.ok(planes[i] > planes[i - 1], "work planes in file order") end
  t.ok(shell_pos > planes[#planes] and shell_pos < #bytes, "job shell after the work planes")
end)

t.test("protoc --decode_raw: job shell and work-plane shell carry the published field numbers", function()
  local job_txt = "\n" .. decode_raw(msg_at(shell_pos))
  t.ok(job_txt:find('\n2 {\n  1: %d+\n  2: 1\n  3: "j.ovf"'), "job_meta_data (2): creation time (1), version (2), job_name (3):\n" .. job_txt)
  t.ok(job_txt:find("\n3 {\n  1: 5\n  2 {\n    1: 0x435c0000\n    2: 0x447f0000\n"), "marking_params_map (3) key 5: power 220 W (1), speed 1020 mm/s (2)")
  t.ok(job_txt:find('26: "right%-hatch"'), "marking params name (26)")
  t.ok(job_txt:find("\n4 {\n  1: 1\n  2 {\n    1: \"j.ovf\""), "parts_map (4) key 1 with its name (1)")
  t.ok(job_txt:find("\n6: 3\n"), "num_work_planes (6) = 3")
  local wp_lut = msg_at(i64_at(planes[2]))
  local wshell = lut(wp_lut)
  local wp_txt = decode_raw(msg_at(wshell))
  t.ok(wp_txt:find("^4: 0x3da3d70a\n"), "z_pos_in_mm (4) = 0.08 as float:\n" .. wp_txt)
  t.ok(wp_txt:find("\n8: %d+\n") and wp_txt:find("\n10: 1\n") and wp_txt:find("\n13 {\n  1: 0x"), "num_blocks (8), work_plane_number (10), meta_data (13)")

  -- the shell's total scan (13.1) and jump (13.2) distances against the layer's own stats
  local st = gradus.cli.read(cli).layers[2]:stats()
  local function f64(hex) return (string.unpack("<d", string.pack("<I8", tonumber(hex)))) end
  local scan, jump = wp_txt:match("\n13 {\n  1: (0x%x+)\n  2: (0x%x+)\n")
  t.ok(scan, "scan and jump distances present")
  t.near(f64(scan), st.contour.length + st.hatch.length + st.edge.length, 1e-3, "total_scan_distance_in_mm")
  t.near(f64(jump), st.jump_length, 1e-3, "total_jump_distance_in_mm")
end)

-- float from a decode_raw fixed32 "0x..." text
local function f32(hex) return (string.unpack("<f", string.pack("<I4", tonumber(hex)))) end

t.test("two lasers: each block's marking parameters are its laser's power and speed", function()
  local job_txt = "\n" .. decode_raw(msg_at(shell_pos))
  local params = {}
  for key, body in job_txt:gmatch("\n3 {\n  1: (%d+)\n  2 {\n(.-)\n  }\n}") do
    params[tonumber(key)] = { power = f32(body:match("\n?    1: (0x%x+)")), speed = f32(body:match("\n    2: (0x%x+)")) }
  end
  local seen = {}
  for i, start in ipairs(planes) do
    local _, blocks = lut(msg_at(i64_at(start)))
    -- the blocks wrapped as repeated field 1 make the whole WorkPlane for protoc
    local wp = {}
    for _, p in ipairs(blocks) do wp[#wp + 1] = "\10" .. varint_bytes(#msg_at(p)) .. msg_at(p) end
    local txt = decode_raw(table.concat(wp))
    local n = 0
    for body in (txt .. "1 {"):gmatch("1 {\n(.-)\n}\n()") do
      n = n + 1
      local key = tonumber(body:match("\n  50: (%d+)"))
      local laser = tonumber(body:match("\n  53: (%d+)") or "0") + 1
      local area = tonumber(body:match("\n  101 {\n    1: (%d+)") or "0")
      local kind = area == 1 and "contour" or "hatch"
      t.ok(body:find("\n  100 {\n    3: 1\n"), "part_key 1 in meta_data (100)")
      t.ok(body:match("^  ([12]) {") == (kind == "hatch" and "2" or "1"), "contours as line sequences (1), hatches as hatches (2)")
      local las = manifest.styles[(laser - 1) * 3 + (kind == "contour" and 1 or 2)]
      t.ok(params[key], "key " .. tostring(key) .. " in the marking_params_map")
      t.eq(params[key].power, las.power, ("layer %d block %d (laser %d %s): power"):format(i, n, laser, kind))
      t.eq(params[key].speed, las.speed, ("layer %d block %d (laser %d %s): speed"):format(i, n, laser, kind))
      seen[laser .. kind] = true
    end
    t.eq(n, #blocks, "blocks decoded in layer " .. i)
  end
  t.ok(seen["1contour"] and seen["2contour"] and seen["1hatch"] and seen["2hatch"], "both lasers, both kinds")
end)

local function same_layers(a, b, tol, what)
  t.eq(#a, #b, what .. ": layers")
  for i = 1, math.min(#a, #b) do
    t.near(a[i]:z(), b[i]:z(), 1e-6, what .. ": z of layer " .. i)
    local A, B = a[i]:blocks(), b[i]:blocks()
    t.eq(#A, #B, what .. ": blocks of layer " .. i)
    for k = 1, math.min(#A, #B) do
      t.ok(A[k].kind == B[k].kind and A[k].laser == B[k].laser and A[k].shape == B[k].shape and #A[k].points == #B[k].points,
        ("%s: layer %d block %d: %s/%s laser %d/%d %s/%s %d/%d points"):format(what, i, k, A[k].kind, B[k].kind, A[k].laser,
          B[k].laser, A[k].shape, B[k].shape, #A[k].points, #B[k].points))
      for q = 1, #A[k].points do
        if math.abs(A[k].points[q] - B[k].points[q]) > tol then
          t.ok(false, ("%s: layer %d block %d coordinate %d: %g vs %g"):format(what, i, k, q, A[k].points[q], B[k].points[q]))
        end
      end
    end
  end
end

t.test("the OVF holds the geometry, lasers and kinds of the CLI of the same job", function()
  local a, b = gradus.cli.read(cli), gradus.cli.read(ovf)
  t.eq(b.header.format, "ovf", "format seen")
  same_layers(a.layers, b.layers, 1e-5, "cli vs ovf")
  local plane = gradus.ovf.plane(ovf, 2)
  same_layers({ a.layers[2] }, { plane }, 1e-5, "one work plane through the LUTs")
end)

t.test("gradus info, gradus cli info, gradus convert CLI -> OVF -> CLI", function()
  local ok, txt = sh(("'%s' info '%s'"):format(exe, ovf))
  t.ok(ok and txt:find("\nlayers: 3\n") and txt:find("format: ovf") and txt:find("power: 220"), "info on OVF:\n" .. txt)
  local ok2, txt2 = sh(("'%s' cli info '%s'"):format(exe, ovf))
  t.ok(ok2 and txt2 == txt, "cli info is an alias")
  local o2, c2 = tmp .. "/r.ovf", tmp .. "/r.cli"
  t.ok(sh(("'%s' convert '%s' '%s'"):format(exe, cli, o2)), "convert to OVF")
  t.ok(sh(("'%s' convert '%s' '%s' --format ascii"):format(exe, o2, c2)), "convert back to ASCII CLI")
  local A, B = gradus.info(cli), gradus.info(c2)
  t.eq(B.format, "ascii", "format chosen by --format")
  t.eq(A.layers, B.layers, "layers")
  t.eq(#A.styles, #B.styles, "build styles")
  for i = 1, math.min(#A.styles, #B.styles) do
    t.eq(A.styles[i].id, B.styles[i].id, "id")
    t.eq(A.styles[i].vectors, B.styles[i].vectors, "vectors of id " .. A.styles[i].id)
    t.near(A.styles[i].length_mm, B.styles[i].length_mm, 1e-3, "length of id " .. A.styles[i].id)
  end
  same_layers(gradus.cli.read(cli).layers, gradus.cli.read(c2).layers, 2e-6, "cli -> ovf -> cli")
end)

t.test("format=binary: the short form where the part fits, said by the manifest, within half a unit", function()
  local short = tmp .. "/s.cli"
  local ok, out = sh(job .. " -D format=binary -o '" .. short .. "'")
  t.ok(ok, out)
  t.eq(gradus.yaml.load(tmp .. "/s.manifest.yaml").form, "short", "manifest form")
  t.eq(gradus.yaml.load(tmp .. "/j.manifest.yaml").form, "long", "binary-long: long form")
  t.eq(gradus.info(short).format, "binary-short", "info sees the short commands")
  same_layers(gradus.cli.read(cli).layers, gradus.cli.read(short).layers, 0.0005 + 1e-6, "long vs short (1 um units)")
end)

t.test("format=binary: no zero-length mark from rounding to the unit, and the stats say how many were left out", function()
  -- a graded 2 x 2 x 1 job, 25 layers: about 170 polyline points fall onto the one before them at 1 um
  local base = ("'%s' run '%s/recipes/lattice.lua' -q -D cells=2,2,1 -D kb=off -D layers=1:25 "
    .. "-D 'thickness=0.1+0.04*sin(x/3)*cos(y/2.5)'"):format(exe, gradus.root)
  local short, long = tmp .. "/r.cli", tmp .. "/rl.cli"
  local ok, out = sh(base .. " -D format=binary -o '" .. short .. "' --stats '" .. tmp .. "/r.yaml'")
  t.ok(ok, out)
  ok, out = sh(base .. " -D format=binary-long -o '" .. long .. "'")
  t.ok(ok, out)
  local st = gradus.yaml.load(tmp .. "/r.yaml")
  t.ok(st.rounded_out and st.rounded_out.points > 0, "the job has points that round onto the one before")
  local function count(path)
    local pts, vec, marks = 0, 0, 0
    for _, l in ipairs(gradus.cli.read(path).layers) do
      for _, b in ipairs(l:blocks()) do
        local P = b.points
        if b.shape == "segments" then
          for q = 1, #P - 3, 4 do
            vec = vec + 1
            if P[q] == P[q + 2] and P[q + 1] == P[q + 3] then marks = marks + 1 end
          end
        else
          pts = pts + #P / 2
          local dot = #P == 4
          for q = 1, #P - 3, 2 do
            if not dot and P[q] == P[q + 2] and P[q + 1] == P[q + 3] then marks = marks + 1 end
          end
        end
      end
    end
    return pts, vec, marks
  end
  local sp, sv, sm = count(short)
  local lp, lv = count(long)
  t.eq(sm, 0, "zero-length marks in the short form")
  t.eq(sp + st.rounded_out.points, lp, "polyline points: the short form's and those left out = the long form's")
  t.eq(sv + st.rounded_out.vectors, lv, "hatch vectors: the short form's and those left out = the long form's")
end)

t.test("malformed files: error with file and byte offset, non-zero exit, nothing written", function()
  local cases = {
    { "truncated", bytes:sub(1, #bytes - 5), "past the end" },
    { "wrong magic", "LVX!" .. bytes:sub(5), "LVF!" },
    { "job LUT outside", bytes:sub(1, 4) .. string.pack("<i8", #bytes + 7) .. bytes:sub(13), "job LUT position outside the file" },
  }
  for _, c in ipairs(cases) do
    local bad, out = tmp .. "/bad.ovf", tmp .. "/out.cli"
    spit(bad, c[2])
    local ok, txt = sh(("'%s' info '%s'"):format(exe, bad))
    t.ok(not ok and txt:find("bad.ovf", 1, true) and txt:find("byte %d+") and txt:find(c[3], 1, true), c[1] .. ": " .. txt)
    ok, txt = sh(("'%s' convert '%s' '%s'"):format(exe, bad, out))
    t.ok(not ok and not exists(out), c[1] .. ": convert fails and writes nothing: " .. txt)
  end
end)

os.execute("rm -rf '" .. tmp .. "'")
t.done()
