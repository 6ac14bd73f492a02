-- YAML through libyaml: values, types, anchors, errors with line and column.
local t = require "gradus.testing"
local yaml = gradus.yaml

t.test("scalars and collections", function()
  local v = yaml.decode([[
a: 1
b: 2.5
c: text
d: "42"
e: [true, no, ~, .inf]
f: {g: -3e-2}
list:
  - x: 1
  - x: 2
]])
  t.eq(v.a, 1, "integer") ; t.eq(math.type(v.a), "integer", "integer type")
  t.eq(v.b, 2.5, "float") ; t.eq(v.c, "text", "string") ; t.eq(v.d, "42", "quoted stays string")
  t.eq(v.e[1], true, "true") ; t.eq(v.e[2], false, "no") ; t.eq(v.e[3], nil, "null") ; t.eq(v.e[4], math.huge, "inf")
  t.near(v.f.g, -0.03, 1e-15, "exponent") ; t.eq(#v.list, 2, "list") ; t.eq(v.list[2].x, 2, "nested")
end)

t.test("anchors, aliases and merge keys", function()
  local v = yaml.decode("base: &b {speed: 1000, power: 200}\nhatch: *b\ncontour:\n  <<: *b\n  speed: 600\n")
  t.eq(v.hatch.speed, 1000, "alias") ; t.eq(v.contour.speed, 600, "override") ; t.eq(v.contour.power, 200, "merged")
end)

t.test("syntax error names line and column", function()
  local err = t.raises(function() yaml.decode("a: 1\nb: [1, 2\nc: 3\n", "bad.yaml") end)
  t.ok(err:find("bad.yaml:%d+:%d+: "), "position in '" .. err .. "'")
end)

t.test("duplicate key is an error with its line", function()
  t.raises(function() yaml.decode("a: 1\nb: 2\na: 3\n", "dup.yaml") end, "dup.yaml:3:1: duplicate key 'a'")
end)

t.test("unknown alias", function()
  t.raises(function() yaml.decode("a: *nope\n", "al.yaml") end, "unknown alias")
end)

t.test("load a file: the paper's process profile", function()
  local p = yaml.load(gradus.root .. "/recipes/profiles/paper.yaml")
  t.eq(p.voxel, 2.0, "voxel") ; t.eq(p.layer, 0.04, "layer") ; t.eq(p.hatch, 0.05, "hatch")
  t.raises(function() yaml.load("/nonexistent/x.yaml") end, "cannot read YAML file /nonexistent/x.yaml")
end)

t.test("encode then decode round-trips", function()
  local v = { layers = 50, name = "a: b", list = { 1, 2.5, 3 }, nested = { { id = 1, kind = "hatch" }, { id = 2, kind = "yes" } },
    flag = false, empty = {} }
  local back = yaml.decode(yaml.encode(v))
  t.eq(back.layers, 50, "int") ; t.eq(back.name, "a: b", "quoted string") ; t.eq(back.list[2], 2.5, "list")
  t.eq(back.nested[2].kind, "yes", "'yes' stays a string") ; t.eq(back.nested[1].id, 1, "nested map in list")
  t.eq(back.flag, false, "bool")
end)

t.done()
