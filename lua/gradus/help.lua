-- gradus.help: help texts for the REPL, taken from the API reference in
-- doc/api/*.md (one source of truth). A function is documented there by a
-- heading that names it, e.g. "### `gradus.field.tpms(name, opts)`" or
-- "### `mesh:write(path [, format])`"; the text up to the next heading is
-- its help.
local gradus = require "gradus"
local M = {}

local sections -- name -> text

local function load_sections()
  if sections then return sections end
  sections = {}
  local root = gradus.root
  if not root then return sections end
  local p = io.popen("ls '" .. root .. "/doc/api/' 2>/dev/null")
  local files = {}
  if p then
    for f in p:lines() do if f:match("%.md$") then files[#files + 1] = root .. "/doc/api/" .. f end end
    p:close()
  end
  for _, path in ipairs(files) do
    local f = io.open(path)
    if f then
      local names, buf = nil, {}
      local function flush()
        if names then
          local text = table.concat(buf, "\n"):gsub("^%s+", ""):gsub("%s+$", "")
          for _, n in ipairs(names) do sections[n] = sections[n] or (names.heading .. "\n" .. text) end
        end
      end
      for line in f:lines() do
        if line:match("^#+ ") then
          flush()
          names, buf = { heading = line:gsub("^#+%s*", "") }, {}
          for sig in line:gmatch("`([^`]+)`") do
            local n = sig:match("^([%w_%.:]+)%s*%(") or sig:match("^([%w_%.:]+)$")
            if n then names[#names + 1] = n:gsub("^gradus%.", "") end
          end
        else
          buf[#buf + 1] = line
        end
      end
      flush()
      f:close()
    end
  end
  return sections
end

-- Every documented-or-not public function: name -> function. Methods of the
-- userdata types appear as "type:method".
function M.functions()
  local out, seen = {}, {}
  local function walk(t, prefix, depth)
    if seen[t] or depth > 3 then return end
    seen[t] = true
    for k, v in pairs(t) do
      if type(k) == "string" and not k:match("^_") then
        local name = prefix .. k
        if type(v) == "function" then out[name] = v
        elseif type(v) == "table" and k ~= "doc" and k ~= "loaded" then walk(v, name .. ".", depth + 1) end
      end
    end
  end
  walk(gradus, "", 0)
  local reg = debug.getregistry()
  for _, ty in ipairs({ "field", "mesh", "rings", "layer", "job", "bvh", "cli_writer" }) do
    local mt = reg["gradus." .. ty]
    if type(mt) == "table" and type(mt.__index) == "table" then
      for k, v in pairs(mt.__index) do
        if type(v) == "function" and not k:match("^_") then out[ty .. ":" .. k] = v end
      end
    end
  end
  return out
end

--- M.text(x): the help text of x (a function, a table of the module, or a
-- name such as "field.tpms" or "mesh:write").
function M.text(x)
  local secs = load_sections()
  if type(x) == "string" then
    return secs[x:gsub("^gradus%.", "")] or ("no help for '" .. x .. "'")
  end
  if type(x) == "function" then
    for name, f in pairs(M.functions()) do
      if f == x then
        return secs[name] or ("gradus." .. name .. ": (not documented)")
      end
    end
    return "not a gradus function"
  end
  if type(x) == "table" then
    local names = {}
    for k, v in pairs(x) do
      if type(k) == "string" and not k:match("^_") then
        names[#names + 1] = k .. (type(v) == "function" and "()" or (type(v) == "table" and ".*" or ""))
      end
    end
    table.sort(names)
    return "contents: " .. table.concat(names, ", ") .. "\n(help(f) for a function's text)"
  end
  if type(x) == "userdata" then
    local mt = getmetatable(x)
    local ty = mt and mt.__name and mt.__name:gsub("^gradus%.", "")
    local names = {}
    if mt and type(mt.__index) == "table" then
      for k in pairs(mt.__index) do names[#names + 1] = ty .. ":" .. k .. "()" end
    end
    table.sort(names)
    return tostring(x) .. "\nmethods: " .. table.concat(names, ", ")
  end
  return "no help for a " .. type(x)
end

return M
