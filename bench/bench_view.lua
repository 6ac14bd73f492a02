-- The viewer's drawing speed (issue 16): a CLI whose layer 2 holds 50,000
-- scan vectors (hatches over a 40 mm disc in two lasers, with contours),
-- `gradus view` to a page, drawn in headless Chromium; the page reports its
-- own timings (#bench=R: the layer drawn R times, each draw waited for by a
-- one-pixel read-back). Also the page's size and the time to write it.
local exe = gradus.root .. "/build/gradus"
local tmp = os.getenv("TMPDIR") or "/tmp"
local dir = tmp .. "/gradus_bench_view." .. tostring(os.time()) .. tostring(math.random(1e6))
gradus.mkdir(dir)
local target = gradus.param("vectors", 50000)
local reps = gradus.param("reps", 15)

-- hatch lines at 45 degrees clipped to a disc of radius R, spacing chosen so
-- that the lines give about `target` vectors once split between two lasers
local R = 20
local function layer(z, n)
  local out = { ("$$LAYER/%.3f"):format(z * 1000) }
  local segs = { {}, {} }
  local d = 4 * R / n -- n/2 lines, each split in two
  local c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
  local count = 0
  for t = -R + d / 2, R, d do
    local h = math.sqrt(math.max(R * R - t * t, 0))
    -- the line from -h to h at offset t, split at its middle between the lasers
    for half = 1, 2 do
      local a, b = (half == 1) and -h or 0, (half == 1) and 0 or h
      local x0, y0 = t * c - a * s, t * s + a * c
      local x1, y1 = t * c - b * s, t * s + b * c
      local list = segs[half]
      list[#list + 1] = ("%.1f,%.1f,%.1f,%.1f"):format(x0 * 1000, y0 * 1000, x1 * 1000, y1 * 1000)
      count = count + 1
    end
  end
  for l = 1, 2 do
    local pts = {}
    for i = 0, 360 do
      local a = math.rad(i)
      pts[#pts + 1] = ("%.1f,%.1f"):format(R * math.cos(a) * 1000, R * math.sin(a) * 1000)
    end
    out[#out + 1] = ("$$POLYLINE/%d,1,361,%s"):format((l - 1) * 3 + 1, table.concat(pts, ","))
    out[#out + 1] = ("$$HATCHES/%d,%d,%s"):format((l - 1) * 3 + 2, #segs[l], table.concat(segs[l], ","))
  end
  return table.concat(out, "\n"), count + 2
end
local l1 = layer(0.04, 1000)
local l2, n2 = layer(0.08, target)
local cli = dir .. "/big.cli"
gradus.write_file(cli, table.concat({ "$$HEADERSTART", "$$ASCII", "$$UNITS/0.001", "$$VERSION/200",
  "$$LAYERS/2", "$$HEADEREND", "$$GEOMETRYSTART", l1, l2, "$$GEOMETRYEND", "" }, "\n"))
local html = dir .. "/big.html"
local t0 = gradus.clock()
assert(os.execute(("'%s' view '%s' -o '%s' >/dev/null"):format(exe, cli, html)))
local twrite = gradus.clock() - t0
local function size(p) local f = io.open(p, "rb"); local n = f:seek("end"); f:close(); return n end

local view = require "gradus.view"
local st, err = view.chromium(("file://%s#layer=2&bench=%d"):format(html, reps), { dir = dir, timeout = 300 })
local mb_html, mb_cli = size(html) / 2 ^ 20, size(cli) / 2 ^ 20
os.execute("rm -rf '" .. dir .. "'")
if not st then error("bench_view: " .. err) end
local b = st.bench
print(("view: layer of %d vectors (%d in the file): draw median %.1f ms (min %.1f, max %.1f, %d draws), decode %.1f ms;" ..
  " page %.1f MB for %.1f MB of ASCII CLI, written in %.2f s")
  :format(b.vectors, n2, b.medianMs, b.minMs, b.maxMs, b.reps, b.decodeMs, mb_html, mb_cli, twrite))
