local L, T = 2, "0.1*(2*sin(pi*(w+1)/4)+1)"
local A = gradus.distance.offset { surface = "iwp", cell = L, lo = { 2, 2, 0 }, hi = { 4, 4, 2 }, res = 40, thickness = T, kind = "sheet", mode = "exact", voxel = true }
local N = gradus.distance.offset { surface = "iwp", cell = L, lo = { 2, 2, 0 }, hi = { 4, 4, 2 }, res = 40, thickness = 0, kind = "sheet", mode = "exact", voxel = true }
for _, y in ipairs { 4.0, 4.0 - 1e-9, 3.9999, 3.999, 3.997 } do print(y, A:eval(2.519, y, 1.10), "d", N:eval(2.519, y, 1.10)) end
