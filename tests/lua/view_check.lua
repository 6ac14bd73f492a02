-- Checks of `gradus view` pages and served layers, called by tests/sh/test_view.sh
-- (not a test of its own: its name does not start with test_).
--   -D mode=browser -D cli=F.cli -D html=F.html -D dir=SCRATCH [-D url=http://... -D served_cli=G.cli]
--   -D mode=served_layer -D cli=G.cli -D blob=FILE -D layer=K
-- Every geometric expectation comes from the CLI reader (gradus.cli.read),
-- never from the page's own drawing.
local t = require "gradus.testing"
local view = require "gradus.view"
local mode = gradus.param("mode", "browser")
local cli = gradus.param("cli", "")
local dir = gradus.param("dir", os.getenv("TMPDIR") or "/tmp")

local file = gradus.cli.read(cli)
local QUANTUM = view.QUANTUM

-- the reader's vectors of a layer: {laser, pts = {x0, y0, x1, y1, ...}, poly}
local function vectors(layer)
  local out = {}
  for _, b in ipairs(layer:blocks()) do
    local p = b.points
    if b.shape == "segments" then
      for i = 1, #p, 4 do out[#out + 1] = { laser = b.laser, pts = { p[i], p[i + 1], p[i + 2], p[i + 3] } } end
    else
      out[#out + 1] = { laser = b.laser, pts = p }
    end
  end
  return out
end

-- unsigned LEB128 / zigzag reader over a byte string (doc/formats.md)
local function decoder(s)
  local pos = 1
  local function u()
    local v, mul = 0, 1
    repeat
      local b = s:byte(pos)
      if not b then error("layer data ends early at byte " .. pos) end
      pos = pos + 1
      v = v + (b & 127) * mul
      mul = mul * 128
    until b < 128
    return v
  end
  local function sv() local v = u() return (v % 2 == 1) and -(v + 1) // 2 or v // 2 end
  return u, sv, function() return pos > #s end
end

if mode == "served_layer" then
  local k = gradus.param("layer", 1)
  t.test("served layer " .. k .. " holds the reader's vectors of that layer", function()
    local f = assert(io.open(gradus.param("blob", ""), "rb"))
    local blob = f:read("a")
    f:close()
    local u, sv, eof = decoder(blob)
    t.eq(u(), 1, "version")
    local layer = file.layers[k]
    t.near(sv() * QUANTUM, layer:z(), 1e-6, "z")
    local blocks = layer:blocks()
    t.eq(u(), #blocks, "block count")
    local KIND = { contour = 0, hatch = 1, edge = 2 }
    local SHAPE = { closed = 0, open = 1, segments = 2 }
    local head = {}
    for i, b in ipairs(blocks) do
      local id, kind, laser, shape, dir, n = sv(), u(), u(), u(), sv(), u()
      t.eq(kind, KIND[b.kind], "block " .. i .. " kind")
      t.eq(laser, b.laser - 1, "block " .. i .. " laser")
      t.eq(id, (b.laser - 1) * 3 + KIND[b.kind] + 1, "block " .. i .. " build style")
      t.eq(shape, SHAPE[b.shape], "block " .. i .. " shape")
      t.eq(dir, b.dir, "block " .. i .. " dir")
      t.eq(n, #b.points // 2, "block " .. i .. " points")
      head[i] = n
    end
    local x, y, worst = 0, 0, 0
    for i, b in ipairs(blocks) do
      for q = 1, head[i] do
        x, y = x + sv(), y + sv()
        worst = math.max(worst, math.abs(x * QUANTUM - b.points[2 * q - 1]), math.abs(y * QUANTUM - b.points[2 * q]))
      end
    end
    t.ok(worst <= QUANTUM / 2 + 1e-9, "a coordinate is off by " .. worst .. " mm")
    t.ok(eof(), "bytes left after the last point")
  end)
  t.done()
  return
end

-- ---- in Chromium ----
local function page(url, o)
  local st, dom, log = view.chromium(url, { dir = dir, virtual = 60000, size = "1200,800", screenshot = o and o.png })
  if not st then error(dom, 0) end
  return st, log
end

-- no errors caught by the page and no console message at all (the page logs nothing when all is well)
local function clean(st, log, what)
  t.eq(#st.errors, 0, what .. ": page errors " .. table.concat(st.errors, "; "))
  local msg = log:match('CONSOLE[^\n]*')
  t.ok(not msg, what .. ": console says " .. tostring(msg))
  t.ok(st.ready, what .. ": page not ready")
end

local html = gradus.param("html", "")
local K = 2
local png = dir .. "/shot.png"
local st, log
t.test("page at #layer=" .. K .. "&color=laser opens without errors", function()
  st, log = page("file://" .. html .. "#layer=" .. K .. "&color=laser&size=640x480", { png = png })
  clean(st, log, "embedded page")
end)
if not st then t.done() return end

t.test("the layer shown is the one asked for", function()
  t.eq(st.layer, K, "layer")
  t.eq(st.nlayers, #file.layers, "layers")
  t.near(st.z, file.layers[K]:z(), 1e-6, "z")
  t.eq(st.vectors, #vectors(file.layers[K]), "vectors")
  t.eq(st.drawn, st.vectors, "vectors drawn")
  t.eq(st.color, "laser", "colour mode")
end)

-- the screenshot against the reader's layer, mapped with the page's reported view
local w, h, rgba = gradus.view.png_read(png)
local v = st.view
local function px(x, y)
  return v.left + (x - v.cx) * v.scale + v.width / 2, v.top + v.height / 2 - (y - v.cy) * v.scale
end
local vecs = vectors(file.layers[K])
local want = {}    -- pixel -> laser of a vector through it
local samples = {} -- points along every vector, one per pixel step
for _, vec in ipairs(vecs) do
  local p = vec.pts
  for i = 1, #p - 3, 2 do
    local x0, y0 = px(p[i], p[i + 1])
    local x1, y1 = px(p[i + 2], p[i + 3])
    local n = math.max(1, math.ceil(math.max(math.abs(x1 - x0), math.abs(y1 - y0)) * 2))
    for s = 0, n do
      local X, Y = math.floor(x0 + (x1 - x0) * s / n), math.floor(y0 + (y1 - y0) * s / n)
      want[Y * w + X] = vec.laser
      samples[#samples + 1] = Y * w + X
    end
  end
end
local function near(tbl, key, r, val)
  local X, Y = key % w, key // w
  for dy = -r, r do
    for dx = -r, r do
      local got = tbl[(Y + dy) * w + X + dx]
      if got and (val == nil or got == val) then return true end
    end
  end
  return false
end
-- drawn pixels: not white, inside the drawing area
local drawn, ncol = {}, {}
local x0a, x1a = math.floor(v.left), math.floor(v.left + v.width) - 1
local y0a, y1a = math.floor(v.top), math.floor(v.top + v.height) - 1
for Y = y0a, y1a do
  for X = x0a, x1a do
    local o = 4 * (Y * w + X)
    local r, g, b = rgba:byte(o + 1, o + 3)
    if r < 250 or g < 250 or b < 250 then
      local c = string.format("#%02x%02x%02x", r, g, b)
      drawn[Y * w + X] = c
      ncol[c] = (ncol[c] or 0) + 1
    end
  end
end

t.test("drawn pixels fall inside the layer's bounding box", function()
  local lo_x, lo_y, hi_x, hi_y = file.layers[K]:bounds()
  local ax, ay = px(lo_x, hi_y)
  local bx, by = px(hi_x, lo_y)
  local n, out = 0, 0
  for key in pairs(drawn) do
    n = n + 1
    local X, Y = key % w, key // w
    if X < ax - 2 or X > bx + 2 or Y < ay - 2 or Y > by + 2 then out = out + 1 end
  end
  t.ok(n > 500, "only " .. n .. " pixels drawn")
  t.eq(out, 0, "pixels outside the bounding box")
end)

t.test("drawn pixels lie on the layer's vectors and cover them", function()
  local n, on = 0, 0
  for key in pairs(drawn) do
    n = n + 1
    if near(want, key, 2) then on = on + 1 end
  end
  t.ok(on >= 0.99 * n, ("%d of %d drawn pixels are on a vector"):format(on, n))
  local cov = 0
  for _, key in ipairs(samples) do if near(drawn, key, 1) then cov = cov + 1 end end
  t.ok(cov >= 0.98 * #samples, ("%d of %d points along the vectors are drawn"):format(cov, #samples))
end)

t.test("two lasers get two colours, each on its own laser's vectors", function()
  t.eq(#st.legend, 2, "legend entries")
  local a, b = st.legend[1], st.legend[2]
  t.ok(a.color ~= b.color, "both lasers drawn in " .. a.color)
  for _, e in ipairs(st.legend) do
    local laser = tonumber(e.label:match("(%d+)$"))
    local n, own = 0, 0
    for key, c in pairs(drawn) do
      if c == e.color then
        n = n + 1
        if near(want, key, 2, laser) then own = own + 1 end
      end
    end
    t.ok(n > 100, e.label .. ": only " .. n .. " pixels of " .. e.color)
    t.ok(own >= 0.97 * n, ("%s: %d of %d pixels of its colour on its vectors"):format(e.label, own, n))
  end
end)

t.test("the slider moves through every layer", function()
  local sw, slog = page("file://" .. html .. "#layer=1&sweep=1")
  clean(sw, slog, "sweep")
  t.eq(#(sw.sweep or {}), #file.layers, "steps")
  for k, s in ipairs(sw.sweep) do
    t.eq(s.layer, k, "step " .. k .. " layer")
    t.eq(s.slider, k, "step " .. k .. " slider")
    t.near(s.z, file.layers[k]:z(), 1e-6, "step " .. k .. " z")
    t.eq(s.vectors, #vectors(file.layers[k]), "step " .. k .. " vectors")
    t.eq(s.drawn, s.vectors, "step " .. k .. " drawn")
  end
end)

local url = gradus.param("url", "")
if url ~= "" then
  t.test("the served page shows the layer asked for", function()
    local other = gradus.cli.read(gradus.param("served_cli", ""))
    local k = #other.layers
    local ss, slog = page(url .. "#layer=" .. k .. "&color=kind")
    clean(ss, slog, "served page")
    t.ok(ss.served, "not in served mode")
    t.eq(ss.layer, k, "layer")
    t.near(ss.z, other.layers[k]:z(), 1e-6, "z")
    t.eq(ss.vectors, #vectors(other.layers[k]), "vectors")
  end)
end
t.done()
