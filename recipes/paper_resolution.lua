-- paper_resolution.lua: vertex/face counts of the paper's Fig. 10 (sphere,
-- R = 3) and Fig. 11 (one P cell, L = 2) at several resolutions.
-- "resolution" = samples per axis over the box (sphere: -R..R padded by one
-- sample spacing; cell: 0..L inclusive). See doc/resolution.md.
local R = gradus.param("radius", 3, { unit = "mm", min = 0.1, max = 100, help = "sphere radius" })
print("sphere R=" .. R)
print("res", "V", "F")
for _, r in ipairs({3, 5, 10, 20}) do
  local h = 2 * R / (r - 1)
  local L = R + h
  local m = gradus.mc(string.format("sqrt(x*x+y*y+z*z)-%.17g", R),
                      {lo={-L,-L,-L}, hi={L,L,L}, res=r + 2, refine=true})
  local nv, nf = m:counts()
  print(r, nv, nf)
end
local f = gradus.field.tpms("primitive", {cell=2})
print("P cell L=2")
print("res", "V", "F", "paper V", "paper F")
local paper = {[10]={260,478}, [20]={1220,2328}, [40]={5052,9856}, [80]={20596,40680}}
for _, r in ipairs({10, 20, 40, 80}) do
  local m = gradus.mc(f, {lo={0,0,0}, hi={2,2,2}, res=r})
  local nv, nf = m:counts()
  print(r, nv, nf, paper[r][1], paper[r][2])
end
