-- gradus.help: help texts for the REPL, taken from the API reference in
-- doc/api/*.md (one source of truth). A function is documented there by a
-- heading that names it, e.g. "### `gradus.field.tpms(name, opts)`" or
-- "### `mesh:write(path [, format])`"; the text up to the next heading is
-- its help.
local gradus = require "gradus"
local M = {}

local sections -- name -> text

-- Per API file: the module prefix of relative names and the userdata type of
-- its "obj:method" entries.
local FILES = {
  ["field.md"] = { "field.", "field" }, ["mesh.md"] = { "mesh.", "mesh" },
  ["hatch.md"] = { "hatch.", "layer" }, ["distance.md"] = { "distance.", "rings" },
  ["place.md"] = { "place.", "job" }, ["host.md"] = { "", nil }, ["density.md"] = { "", nil },
  ["plate.md"] = { "", "plate" },
}

local function load_sections()
  if sections then return sections end
  sections = {}
  local root = gradus.root
  if not root then return sections end
  for file, spec in pairs(FILES) do
    local f = io.open(root .. "/doc/api/" .. file)
    if f then
      local prefix, mtype = spec[1], spec[2]
      local names, buf = nil, {}
      local function flush()
        if names then
          local text = table.concat(buf, "\n"):gsub("^%s+", ""):gsub("%s+$", "")
          for _, n in ipairs(names) do sections[n] = sections[n] or text end
        end
      end
      for line in f:lines() do
        local is_entry = line:match("^#+ ") or line:match("^%s*[-*] ") or line:match("^|")
        local found = {}
        if is_entry then
          for tok in line:gmatch("([%a_][%w_%.:]*)%s*[%(%{]") do found[#found + 1] = tok end
          for tok in line:gmatch("`([%a_][%w_%.:]*)`") do found[#found + 1] = tok end
        end
        if #found > 0 then
          flush()
          names, buf = {}, { line }
          for _, tok in ipairs(found) do
            local n = tok:gsub("^gradus%.", "")
            local obj, meth = n:match("^([%w_]+):([%w_]+)$")
            if obj then
              names[#names + 1] = (FILES[obj .. ".md"] and obj or (mtype or obj)) .. ":" .. meth
              names[#names + 1] = obj .. ":" .. meth
            elseif tok:match("^gradus%.") or n:find("%.") then
              names[#names + 1] = n
            else
              names[#names + 1] = prefix .. n
              names[#names + 1] = n
            end
          end
        elseif names then
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

-- The help of a recipe parameter of the lattice recipe (its declaration:
-- default, unit, range, one line), or nil.
local function param_text(name)
  local ok, lattice = pcall(require, "gradus.lattice")
  if not ok then return nil end
  local strict = require "gradus.strict"
  for _, d in ipairs(lattice.PARAMS) do
    if d[1] == name then
      local s = d[3]
      local def = s.auto and ("auto: " .. s.auto) or strict.fmt(d[2])
      local r = strict.range_text(s)
      return ("parameter %s of the lattice recipe (-D %s=..., lattice.params().%s): %s\n  default %s%s%s"):format(
        name, name, name, s.help or "", def == "" and '""' or def,
        s.unit and not s.choices and (" " .. s.unit) or "", r ~= "" and ("; accepted: " .. r) or "")
    end
  end
  return nil
end

-- Every section whose name ends in `short` after a '.' or ':' (help("tpms")
-- finds field.tpms), sorted by name.
local function by_short_name(secs, short)
  local names = {}
  for name in pairs(secs) do
    if name ~= short and (name:sub(-#short - 1) == "." .. short or name:sub(-#short - 1) == ":" .. short) then
      names[#names + 1] = name
    end
  end
  table.sort(names)
  return names
end

--- M.text(x): the help text of x (a function, a table of the module, or a
-- name: "field.tpms", "mesh:write", a short name such as "tpms", or a recipe
-- parameter such as "hatch").
function M.text(x)
  local secs = load_sections()
  if type(x) == "string" then
    local name = x:gsub("^gradus%.", "")
    local parts, seen = {}, {}
    local function add(text)
      if text and not seen[text] then seen[text] = true parts[#parts + 1] = text end
    end
    add(secs[name])
    add(param_text(name))
    if not name:find("[.:]") then
      for _, n in ipairs(by_short_name(secs, name)) do add(secs[n]) end
      if type(gradus[name]) == "table" then
        add(("gradus.%s: a table of the module; help(gradus.%s) lists it"):format(name, name))
      end
    end
    if #parts == 0 then return "no help for '" .. x .. "'" end
    return table.concat(parts, "\n\n")
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
