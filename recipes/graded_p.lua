-- One graded Schwarz P job for parameter studies: the half-thickness of
-- eq. (8) scaled by `amp` (0.1 in the paper), a few cells, a chosen hatch
-- spacing. Used by recipes/sweep_p.lua; runs on its own too:
--   gradus run recipes/graded_p.lua -D amp=0.08 -D hatch=0.05 --stats s.yaml
local lattice = require "gradus.lattice"
-- pore, overmelt, contour deviation of the layers in `verify`
local p = lattice.params { format = "binary", verify = "10,25,40" }
local amp = gradus.param("amp", 0.1, { unit = "mm", min = 0.005, max = 1,
  help = "amplitude of eq. (8): T = amp*(2*sin(pi*(w+1)/4)+1)" })
p.thickness = ("%.17g*(2*sin(pi*(w+1)/4)+1)"):format(amp)
local st = lattice.run(p, gradus.output("out/graded_p.cli"))
print(("amp %.3f mm, hatch %.3f mm: relative density %.3f, scan %.2f m, build %.1f s, pore %.3f%%, overmelt %.3f%%"):format(amp, p.hatch,
  st.relative_density, (st.vectors.contour.length + st.vectors.hatch.length) / 1000, st.build_time_s,
  100 * st.quality.pore_max, 100 * st.quality.overmelt_max))
