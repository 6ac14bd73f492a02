-- The figures and tables of doc/density.md: rho(T) of every catalogue
-- surface (sheet and network), the reachable ranges at the default process
-- values, and the comparison with ASLI's published level-set fits.
--   gradus run recipes/density_curves.lua [-D images=doc/images] [-o out/density_curves.md]
local density = require "gradus.density"
local images = gradus.param("images", "doc/images")
local L = gradus.param("cell", 2.0)
local track = gradus.param("track", 0.05)
local out = gradus.output("out/density_curves.md")
local md = {}
local function add(s) md[#md + 1] = s end

-- 1. curves and ranges
add(("| surface | sheet: reachable rho | sheet: wall 2T, mm | network: reachable rho | network: T, mm | sd range / L |"))
add("|---|---|---|---|---|---|")
for _, s in ipairs(gradus.field.surfaces()) do
  local series = {}
  local row = { s }
  local ext
  for _, kind in ipairs({ "sheet", "network" }) do
    local t = density.get { surface = s, kind = kind, cell = L, track = track }
    local xs, ys = {}, {}
    for i = 0, 50 do
      xs[#xs + 1] = i / 100
      ys[#ys + 1] = t:rho(i / 100 * L)
    end
    series[#series + 1] = { name = kind, x = xs, y = ys }
    local lo, hi, tlo, thi = t:range()
    row[#row + 1] = ("%.3f..%.3f"):format(lo, hi)
    row[#row + 1] = kind == "sheet" and ("%.3f..%.3f"):format(2 * tlo, 2 * thi) or ("%.3f..%.3f"):format(tlo, thi)
    local a, b = t:extent()
    ext = ("%.3f..%.3f"):format(-a, b)
  end
  row[#row + 1] = ext
  add("| " .. table.concat(row, " | ") .. " |")
  local svg = ("%s/density_%s.svg"):format(images, s)
  gradus.svg.plot(svg, { title = s .. ": relative density of the offset solids", xlabel = "half-thickness T / L",
    ylabel = "relative density", width = 560, height = 360, series = series })
  density.svg_to_png(svg, (svg:gsub("%.svg$", ".png")), 560, 360)
end

-- 2. ASLI's sheet fits (src/Infill.cpp of github.com/tpms-lattice/ASLI):
-- level t(vf) of the sheet |phi| <= t and wall size / L of level t, as
-- polynomial coefficients a + b x + c x^2 + ...; their phi has period 2 pi.
local asli = {
  gyroid = { vf = { -0.00224e-3, 1.59, -0.117 }, wall = { -0.00584, 0.387, -1.24, 2.73, -2.43, 0.767 } },
  diamond = { vf = { -0.0108, 1.82, -5.48, 17.74, -23.55, 10.88 }, wall = { -0.00219, 0.226, -0.155, 0.160 } },
  primitive = { vf = { -0.0250, 2.83, -8.89, 26.90, -34.93, 17.03 }, wall = { -0.00488, 0.236, -0.140, 0.150, -0.0652, 0.0106 } },
}
local function poly(c, x)
  local s, p = 0, 1
  for _, a in ipairs(c) do s, p = s + a * p, p * x end
  return s
end
-- the level-set sheet |phi| <= t measured on a 64^3 periodic grid (L = 1):
-- its volume fraction, and its local wall 2t/|grad phi| over points near H
local N = 64
local function levelset_sheet(s, t)
  local f = gradus.field.tpms(s, { cell = 1 })
  local g = f:sample { lo = { 0.5 / N, 0.5 / N, 0.5 / N }, hi = { 1 - 0.5 / N, 1 - 0.5 / N, 1 - 0.5 / N }, n = { N, N, N } }
  local function at(i, j, k) return g[(i % N) + N * ((j % N) + N * (k % N)) + 1] end
  local inside, wmin, wmax = 0, math.huge, 0
  for k = 0, N - 1 do
    for j = 0, N - 1 do
      for i = 0, N - 1 do
        local v = at(i, j, k)
        if math.abs(v) <= t then inside = inside + 1 end
        if math.abs(v) < 0.05 then
          local gx = (at(i + 1, j, k) - at(i - 1, j, k)) * N / 2
          local gy = (at(i, j + 1, k) - at(i, j - 1, k)) * N / 2
          local gz = (at(i, j, k + 1) - at(i, j, k - 1)) * N / 2
          local w = 2 * t / math.sqrt(gx * gx + gy * gy + gz * gz)
          wmin, wmax = math.min(wmin, w), math.max(wmax, w)
        end
      end
    end
  end
  return inside / N ^ 3, wmin, wmax
end
add("")
add("| surface (sheet) | target rho | ASLI level t | ASLI sheet's rho (measured) | ASLI wall-size fit / L | ASLI sheet's local wall / L (min..max) | Gradus wall 2T / L |")
add("|---|---|---|---|---|---|---|")
for _, s in ipairs({ "gyroid", "diamond", "primitive" }) do
  local t = density.get { surface = s, kind = "sheet", cell = L, track = track }
  for _, rho in ipairs({ 0.1, 0.2, 0.3, 0.4, 0.5 }) do
    local lv = poly(asli[s].vf, rho)
    local got, wmin, wmax = levelset_sheet(s, lv)
    add(("| %s | %.2f | %.4f | %.4f | %.4f | %.4f..%.4f | %.4f |"):format(s, rho, lv, got, poly(asli[s].wall, lv),
      wmin, wmax, 2 * t:thickness(rho) / L))
  end
end
gradus.write_file(out, table.concat(md, "\n") .. "\n")
print(out)
