-- Every public function of the module has help (from doc/api/*.md).
local t = require "gradus.testing"
local help = require "gradus.help"

t.test("help exists for every public function", function()
  local missing = {}
  for name, f in pairs(help.functions()) do
    local text = help.text(f)
    if text:find("not documented") or text:find("no help") then missing[#missing + 1] = name end
  end
  table.sort(missing)
  t.ok(#missing == 0, "undocumented: " .. table.concat(missing, ", "))
end)

t.test("help text of a function names it", function()
  t.ok(help.text(gradus.place.job):find("gradus.place.job"), "place.job")
  t.ok(help.text("field.tpms"):find("tpms"), "by name")
end)

t.test("help(short name) finds every public function", function()
  local missing = {}
  for name, f in pairs(help.functions()) do
    local short = name:match("[.:]([%w_]+)$") or name
    local full = help.text(f)
    local text = help.text(short)
    if text:find("no help for") or not text:find(full, 1, true) then missing[#missing + 1] = name .. " as " .. short end
  end
  table.sort(missing)
  t.ok(#missing == 0, "not found by short name: " .. table.concat(missing, ", "))
end)

t.test("help(name) finds every parameter of the lattice recipe", function()
  local lattice = require "gradus.lattice"
  local missing = {}
  for _, d in ipairs(lattice.PARAMS) do
    local text = help.text(d[1])
    if not text:find("parameter " .. d[1], 1, true) or not text:find(d[3].help, 1, true) then missing[#missing + 1] = d[1] end
  end
  t.ok(#missing == 0, "parameters without help: " .. table.concat(missing, ", "))
  local h = help.text("hatch")
  t.ok(h:find("hatch spacing d", 1, true) and h:find("[0.005, 2] mm", 1, true), "help('hatch'): " .. h)
  t.ok(h:find("gradus.hatch", 1, true), "help('hatch') also points at the module")
  t.ok(help.text("no_such_name_xyz"):find("no help for"), "unknown names say so")
end)

t.done()
