-- gradus.strict: the checks behind strict parameters (ranges, NaN and
-- infinities, choices, vectors, expressions), suggestions, the strict table,
-- profile keys with their YAML positions.
local t = require "gradus.testing"
local strict = require "gradus.strict"

local NUM = { unit = "mm", min = 0.005, max = 2 }

t.test("numbers: finite and in range, the range in the message", function()
  t.eq(strict.check("hatch", 0.05, NUM, 0.05), 0.05, "in range")
  t.eq(strict.check("hatch", "0.06", NUM, 0.05), 0.06, "numeric string converted")
  t.eq(strict.check("hatch", 2, NUM, 0.05), 2, "upper bound inclusive")
  t.raises(function() strict.check("hatch", 0 / 0, NUM, 0.05) end, "parameter 'hatch' must be a number in %[0.005, 2%] mm, got nan")
  t.raises(function() strict.check("hatch", 1 / 0, NUM, 0.05) end, "got inf")
  t.raises(function() strict.check("hatch", -1 / 0, NUM, 0.05) end, "got %-inf")
  t.raises(function() strict.check("hatch", 1e-9, NUM, 0.05) end, "got 1e%-09")
  t.raises(function() strict.check("hatch", "abc", NUM, 0.05) end, "got 'abc'")
  t.raises(function() strict.check("n", 2.5, { integer = true, min = 1, max = 9 }, 1) end,
    "parameter 'n' must be a whole number in %[1, 9%], got 2.5")
end)

t.test("auto, choices, vectors, expressions", function()
  local AUTO = { auto = "hatch/2", unit = "mm", min = 0, max = 1 }
  t.eq(strict.check("beam_offset", "auto", AUTO, "auto"), "auto", "auto")
  t.eq(strict.check("beam_offset", 0.03, AUTO, "auto"), 0.03, "a number")
  t.raises(function() strict.check("beam_offset", -1, AUTO, "auto") end, "auto %(hatch/2%) or a number in %[0, 1%] mm, got %-1")
  local CH = { choices = { "sheet", "network" } }
  t.eq(strict.check("kind", "network", CH, "sheet"), "network", "a choice")
  t.raises(function() strict.check("kind", "shet", CH, "sheet") end, "one of sheet, network, got 'shet' %(did you mean 'sheet'%?%)")
  local V = { n = 3, integer = true, min = 1, max = 100000 }
  local v = strict.check("cells", "2,3,4", V, "1,1,1")
  t.ok(v[1] == 2 and v[2] == 3 and v[3] == 4 and #v == 3, "vector parsed")
  t.raises(function() strict.check("cells", "2,3", V, "1,1,1") end, "3 whole numbers")
  t.raises(function() strict.check("cells", "1e9,1,1", V, "1,1,1") end, "in %[1, 100000%]")
  t.raises(function() strict.check("cells", { 1, 0 / 0, 1 }, V, "1,1,1") end, "cells")
  local E = { kind = "expr", unit = "mm", min = 0.005, max = 10 }
  t.eq(strict.check("thickness", "0.1*z", E, "0.1"), "0.1*z", "an expression")
  t.raises(function() strict.check("thickness", "0", E, "0.1") end, "in %[0.005, 10%] mm or an expression")
  t.raises(function() strict.check("thickness", "", E, "0.1") end, "or an expression")
  t.eq(strict.check("inside", "", { kind = "expr", empty = true, min = 0.005 }, ""), "", "empty allowed when declared")
end)

t.test("suggestions and the strict table", function()
  t.eq(strict.suggest("hatc", { "hatch", "layer" }), " (did you mean 'hatch'?)", "one edit")
  t.eq(strict.suggest("zzzzzz", { "hatch", "layer" }), "", "nothing close")
  local p = strict.table({ hatch = true, layer = true }, { hatch = 0.05, layer = 0.04 }, "the test table")
  p.hatch = 0.06
  t.eq(p.hatch, 0.06, "a known field")
  t.raises(function() p.hatc = 0.06 end, "assignment to unknown parameter 'hatc' of the test table %(did you mean 'hatch'%?%)")
  t.raises(function() return p.layr end, "read of unknown parameter 'layr' in the test table %(did you mean 'layer'%?%)")
  local n = 0
  for _ in pairs(p) do n = n + 1 end
  t.eq(n, 2, "pairs sees the values")
end)

t.test("profile keys: unknown keys at their YAML line and column", function()
  local v, marks = gradus.yaml.decode("name: m\nlasers:\n  - name: a\n    hach: {power: 1}\n", "m.yaml", { marks = true })
  t.eq(marks[v].lasers, "2:1", "top-level key position")
  t.eq(marks[v.lasers[1]].hach, "4:5", "nested key position")
  t.eq(select("#", gradus.yaml.decode("a: 1")), 1, "no marks unless asked")
  local lasers = require "gradus.lasers"
  t.raises(function() lasers.normalize(v, "m.yaml", marks) end,
    "m.yaml:4:5: unknown key 'hach' in lasers%[1%] %(did you mean 'hatch'%?%)")
  t.raises(function() lasers.normalize({ lasers = { {} }, jump_sped = 1 }, "t") end,
    "t: unknown key 'jump_sped' in the machine profile %(did you mean 'jump_speed'%?%)")
  t.raises(function() lasers.normalize({ lasers = { {} }, recoat_time = 0 / 0 }, "t") end, "recoat_time")
  t.eq(lasers.normalize({ lasers = { {} }, recoat_time = 8 }, "t").recoat_time, 8, "recoat_time is read")
end)

t.done()
