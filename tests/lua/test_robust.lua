-- Regressions for inputs that crashed (issue 17), through the Lua API.
local t = require "gradus.testing"

t.test("YAML merge key with a scalar is refused with its position", function()
  local err = t.raises(function() gradus.yaml.decode("a: 1\n<<: abcdefgh\n", "m.yaml") end)
  t.ok(err:find("m.yaml:2:5: merge key '<<' needs a mapping or a sequence of mappings, got a string", 1, true), err)
  err = t.raises(function() gradus.yaml.decode("b: &x {c: 1}\na:\n  <<: [*x, 3]\n", "s.yaml") end)
  t.ok(err:find("s.yaml:3:7: merge key '<<' needs a mapping or a sequence of mappings, got a sequence with a scalar", 1, true), err)
  local v = gradus.yaml.decode("b: &x {c: 1}\na:\n  <<: [*x]\n  d: 2\n")
  t.eq(v.a.c, 1, "a sequence of mappings still merges")
end)

t.done()
