-- gradus.testing: a small harness for the Lua tests (tests/lua/*.lua).
-- Each t.test prints "PASS name" or "FAIL name: why"; t.done() raises if any
-- test failed, so `gradus run` exits non-zero.
local M = { failed = 0, passed = 0 }
local src = (package.loaded.gradus and package.loaded.gradus._ctx.recipe or "?"):match("[^/]*$")

local function fail(msg, level)
  error({ gradus_test_failure = msg }, level)
end

function M.ok(cond, msg)
  if not cond then fail(msg or "assertion failed", 3) end
end

function M.eq(a, b, msg)
  if a ~= b then fail(string.format("%s: got %s, want %s", msg or "eq", tostring(a), tostring(b)), 3) end
end

function M.near(a, b, tol, msg)
  if type(a) ~= "number" or type(b) ~= "number" or not (math.abs(a - b) <= tol) then
    fail(string.format("%s: got %s, want %s (tolerance %g)", msg or "near", tostring(a), tostring(b), tol), 3)
  end
end

--- t.raises(fn, pattern): fn must raise an error whose message matches pattern.
function M.raises(fn, pattern, msg)
  local ok, err = pcall(fn)
  if ok then fail((msg or "raises") .. ": no error raised", 3) end
  err = tostring(err)
  if pattern and not err:find(pattern) then
    fail(string.format("%s: error '%s' does not match '%s'", msg or "raises", err, pattern), 3)
  end
  return err
end

function M.test(name, fn)
  local ok, err = xpcall(fn, function(e)
    if type(e) == "table" and e.gradus_test_failure then
      local info = debug.getinfo(3, "Sl")
      return (info and (info.short_src .. ":" .. info.currentline .. ": ") or "") .. e.gradus_test_failure
    end
    return debug.traceback(tostring(e), 2)
  end)
  if ok then
    M.passed = M.passed + 1
    print("PASS " .. src .. ": " .. name)
  else
    M.failed = M.failed + 1
    print("FAIL " .. src .. ": " .. name .. ": " .. tostring(err):gsub("\n", "\n    "))
  end
  io.stdout:flush()
end

function M.done()
  if M.failed > 0 then error(M.failed .. " test(s) failed", 0) end
end

return M
