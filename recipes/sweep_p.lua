-- A parameter sweep: thickness amplitude x hatch spacing for the graded P
-- cell (recipes/graded_p.lua), 3 x 3 runs on both cores, one shared knowledge
-- base. Writes DIR/sweep.csv, DIR/sweep.yaml and a plot DIR/density.svg of
-- relative density against amplitude, one series per hatch spacing.
--   gradus run recipes/sweep_p.lua -D dir=out/sweep_p
local dir = gradus.param("dir", "out/sweep_p", { help = "output directory" })
local amps = gradus.param("amps", { 0.05, 0.075, 0.1 }, { unit = "mm", help = "thickness amplitudes, comma-separated" })
local hatches = gradus.param("hatches", { 0.04, 0.05, 0.06 }, { unit = "mm", help = "hatch spacings, comma-separated" })
local jobs = gradus.param("jobs", 2, { integer = true, min = 1, max = 64, help = "runs at a time" })
local rows = gradus.sweep {
  recipe = gradus.root .. "/recipes/graded_p.lua",
  params = { amp = amps, hatch = hatches },
  jobs = jobs,
  dir = dir,
  quiet = gradus.quiet(),
}
local series = {}
local failed = 0
for _, r in ipairs(rows) do
  if r.status == "ok" then
    local h = r.params.hatch
    series[h] = series[h] or { name = "hatch " .. h .. " mm", x = {}, y = {} }
    table.insert(series[h].x, tonumber(r.params.amp))
    table.insert(series[h].y, r.stats.relative_density)
  else
    failed = failed + 1
  end
end
local list = {}
for _, s in pairs(series) do list[#list + 1] = s end
table.sort(list, function(a, b) return a.name < b.name end)
gradus.svg.plot(dir .. "/density.svg", { title = "Graded P: relative density vs thickness amplitude",
  xlabel = "amplitude (mm)", ylabel = "relative density", series = list })
if gradus.png and gradus.png.plot then
  gradus.png.plot(dir .. "/density.png", { title = "Graded P: relative density vs thickness amplitude",
    xlabel = "amplitude (mm)", ylabel = "relative density", series = list })
end
print(("sweep: %d runs, %d failed; %s/sweep.csv, %s/density.svg"):format(#rows, failed, dir, dir))
