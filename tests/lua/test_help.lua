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

t.done()
