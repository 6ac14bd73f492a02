-- gradus.svg: pictures people look at. gradus.svg.layer draws a layer's scan
-- vectors (coloured by laser and kind, jumps dashed, a scale bar, y up);
-- gradus.svg.plot draws x-y series with axes. Both write atomically.
local gradus = require "gradus"
local M = {}

-- per laser: {contour, hatch, edge}
local PALETTE = {
  { "#1f3b99", "#d9480f", "#2b8a3e" }, { "#7b2cbf", "#e8a317", "#0b7285" },
  { "#c2255c", "#5c940d", "#495057" }, { "#364fc7", "#f76707", "#087f5b" },
}
M.PALETTE = PALETTE

local function esc(s) return (tostring(s):gsub("&", "&amp;"):gsub("<", "&lt;"):gsub(">", "&gt;")) end

--- gradus.svg.layer(path, layer, {width=800, jumps=false, title=, section=rings})
function M.layer(path, layer, o)
  o = o or {}
  local blocks = layer:blocks()
  local x0, y0, x1, y1 = math.huge, math.huge, -math.huge, -math.huge
  for _, b in ipairs(blocks) do
    for q = 1, #b.points, 2 do
      local x, y = b.points[q], b.points[q + 1]
      if x < x0 then x0 = x end
      if x > x1 then x1 = x end
      if y < y0 then y0 = y end
      if y > y1 then y1 = y end
    end
  end
  if x0 > x1 then x0, y0, x1, y1 = 0, 0, 1, 1 end
  local W = o.width or 800
  local pad = 0.05 * math.max(x1 - x0, y1 - y0, 1e-3)
  x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
  local s = W / (x1 - x0)
  local H = math.floor((y1 - y0) * s + 0.5)
  local head = 40
  local out = { ('<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" viewBox="0 0 %d %d">')
    :format(W, H + head, W, H + head), '<rect width="100%" height="100%" fill="white"/>' }
  local function X(x) return (x - x0) * s end
  local function Y(y) return head + (y1 - y) * s end
  local lw = math.max(0.6, (o.track or 0.05) * s * 0.6)
  if o.section then
    local parts = {}
    for i = 1, o.section:count() do
      local r = o.section:ring(i)
      local d = {}
      for q = 1, #r, 2 do d[#d + 1] = (q == 1 and "M" or "L") .. ("%.2f %.2f"):format(X(r[q]), Y(r[q + 1])) end
      parts[#parts + 1] = table.concat(d, " ") .. " Z"
    end
    out[#out + 1] = ('<path d="%s" fill="#e9ecef" fill-rule="evenodd" stroke="none"/>'):format(table.concat(parts, " "))
  end
  local kinds = { contour = 1, hatch = 2, edge = 3 }
  local lastx, lasty
  local jumps = {}
  for _, b in ipairs(blocks) do
    local pal = PALETTE[((b.laser or 1) - 1) % #PALETTE + 1]
    local col = pal[kinds[b.kind] or 3]
    local d = {}
    if b.shape == "segments" then
      for q = 1, #b.points, 4 do
        d[#d + 1] = ("M%.2f %.2fL%.2f %.2f"):format(X(b.points[q]), Y(b.points[q + 1]), X(b.points[q + 2]), Y(b.points[q + 3]))
        if lastx then jumps[#jumps + 1] = ("M%.2f %.2fL%.2f %.2f"):format(X(lastx), Y(lasty), X(b.points[q]), Y(b.points[q + 1])) end
        lastx, lasty = b.points[q + 2], b.points[q + 3]
      end
    else
      for q = 1, #b.points, 2 do d[#d + 1] = (q == 1 and "M" or "L") .. ("%.2f %.2f"):format(X(b.points[q]), Y(b.points[q + 1])) end
      if lastx then jumps[#jumps + 1] = ("M%.2f %.2fL%.2f %.2f"):format(X(lastx), Y(lasty), X(b.points[1]), Y(b.points[2])) end
      lastx, lasty = b.points[#b.points - 1], b.points[#b.points]
    end
    out[#out + 1] = ('<path class="%s" d="%s" fill="none" stroke="%s" stroke-width="%.2f" stroke-linecap="round"/>')
      :format(b.kind, table.concat(d), col, b.kind == "hatch" and lw * 0.6 or lw)
  end
  if o.jumps and #jumps > 0 then
    out[#out + 1] = ('<path class="jumps" d="%s" fill="none" stroke="#adb5bd" stroke-width="0.5" stroke-dasharray="3,3"/>')
      :format(table.concat(jumps))
  end
  -- scale bar: a round length near a fifth of the width
  local target = (x1 - x0) / 5
  local bar = 10 ^ math.floor(math.log(target, 10))
  if bar * 5 <= target then bar = bar * 5 elseif bar * 2 <= target then bar = bar * 2 end
  out[#out + 1] = ('<path d="M%.1f %.1fh%.1f" stroke="black" stroke-width="3"/><text x="%.1f" y="%.1f" font-family="sans-serif" font-size="13">%g mm</text>')
    :format(10, head + H - 10, bar * s, 15 + bar * s, head + H - 6, bar)
  local st = layer:stats()
  out[#out + 1] = ('<text x="10" y="17" font-family="sans-serif" font-size="15">%s</text>'):format(esc(o.title or ("z = " .. layer:z() .. " mm")))
  out[#out + 1] = ('<text x="10" y="34" font-family="sans-serif" font-size="12" fill="#495057">contours %.1f mm, hatches %.1f mm (colour: laser and kind; grey dashes: jumps)</text>')
    :format(st.contour.length, st.hatch.length)
  out[#out + 1] = "</svg>\n"
  return gradus.write_file(path, table.concat(out, "\n"))
end

--- gradus.svg.plot(path, {title=, xlabel=, ylabel=, series={{name=, x={}, y={}}}, width=640, height=420})
function M.plot(path, o)
  local W, H = o.width or 640, o.height or 420
  local L, R, T, B = 70, 160, 40, 50
  local xmin, xmax, ymin, ymax = math.huge, -math.huge, math.huge, -math.huge
  for _, s in ipairs(o.series or {}) do
    for i = 1, #s.x do
      xmin, xmax = math.min(xmin, s.x[i]), math.max(xmax, s.x[i])
      ymin, ymax = math.min(ymin, s.y[i]), math.max(ymax, s.y[i])
    end
  end
  if xmin > xmax then xmin, xmax, ymin, ymax = 0, 1, 0, 1 end
  if xmax == xmin then xmax = xmin + 1 end
  if ymax == ymin then ymax = ymin + 1 end
  local py = 0.08 * (ymax - ymin)
  ymin, ymax = ymin - py, ymax + py
  local function X(x) return L + (x - xmin) / (xmax - xmin) * (W - L - R) end
  local function Y(y) return H - B - (y - ymin) / (ymax - ymin) * (H - T - B) end
  local out = { ('<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d">'):format(W, H),
    '<rect width="100%" height="100%" fill="white"/>',
    ('<path d="M%d %dV%dH%d" fill="none" stroke="black"/>'):format(L, T, H - B, W - R) }
  for i = 0, 4 do
    local xv, yv = xmin + i * (xmax - xmin) / 4, ymin + i * (ymax - ymin) / 4
    out[#out + 1] = ('<text x="%.1f" y="%d" font-size="11" text-anchor="middle" font-family="sans-serif">%.4g</text>'):format(X(xv), H - B + 16, xv)
    out[#out + 1] = ('<text x="%d" y="%.1f" font-size="11" text-anchor="end" font-family="sans-serif">%.4g</text>'):format(L - 6, Y(yv) + 4, yv)
    out[#out + 1] = ('<path d="M%d %.1fH%d" stroke="#dee2e6"/>'):format(L, Y(yv), W - R)
  end
  local colours = { "#1f3b99", "#d9480f", "#2b8a3e", "#7b2cbf", "#e8a317", "#0b7285" }
  for k, s in ipairs(o.series or {}) do
    local c = colours[(k - 1) % #colours + 1]
    local idx = {}
    for i = 1, #s.x do idx[i] = i end
    table.sort(idx, function(a, b) return s.x[a] < s.x[b] end)
    local d = {}
    for n, i in ipairs(idx) do
      d[#d + 1] = (n == 1 and "M" or "L") .. ("%.1f %.1f"):format(X(s.x[i]), Y(s.y[i]))
      out[#out + 1] = ('<circle cx="%.1f" cy="%.1f" r="3.5" fill="%s"/>'):format(X(s.x[i]), Y(s.y[i]), c)
    end
    out[#out + 1] = ('<path d="%s" fill="none" stroke="%s" stroke-width="2"/>'):format(table.concat(d), c)
    out[#out + 1] = ('<text x="%d" y="%d" font-size="12" font-family="sans-serif" fill="%s">%s</text>'):format(W - R + 10, T + 18 * k, c, esc(s.name or ("series " .. k)))
  end
  out[#out + 1] = ('<text x="%d" y="22" font-size="15" font-family="sans-serif">%s</text>'):format(L, esc(o.title or ""))
  out[#out + 1] = ('<text x="%.1f" y="%d" font-size="12" text-anchor="middle" font-family="sans-serif">%s</text>'):format((L + W - R) / 2, H - 12, esc(o.xlabel or "x"))
  out[#out + 1] = ('<text x="16" y="%.1f" font-size="12" text-anchor="middle" font-family="sans-serif" transform="rotate(-90 16 %.1f)">%s</text>'):format((T + H - B) / 2, (T + H - B) / 2, esc(o.ylabel or "y"))
  out[#out + 1] = "</svg>\n"
  return gradus.write_file(path, table.concat(out, "\n"))
end

return M
