-- gradus.commands: the sub-commands `gradus info`, `gradus convert`,
-- `gradus cli ...`, `gradus kb ...` and
-- `gradus sweep ...`. Each takes the whole argument list and returns an exit
-- status.
local gradus = require "gradus"
local M = {}

local function eprint(...) io.stderr:write(table.concat({ ... }, " "), "\n") end

--- gradus info FILE: what a CLI or OVF file holds (gradus.info, printed as YAML).
function M.info(args)
  local path = args[2]
  if not path or args[3] then
    eprint("usage: gradus info FILE   (a CLI or OVF file)")
    return 2
  end
  local ok, info = pcall(gradus.info, path)
  if not ok then eprint("gradus: " .. tostring(info)) return 1 end
  print(gradus.yaml.encode(info))
  return 0
end

--- gradus cli info FILE: the same as gradus info FILE; gradus cli cat: gradus.slurm.
function M.cli(args)
  if args[2] == "cat" then return require("gradus.slurm").cat_cmd(args) end
  if args[2] ~= "info" or not args[3] or args[4] then
    eprint("usage: gradus cli info FILE | cat PART.cli... -o FILE [--stats FILE]")
    return 2
  end
  return M.info({ "info", args[3] })
end

--- gradus convert IN OUT [--format ascii|binary|ovf]: the format from OUT's
-- extension (.cli binary, .ovf) unless given.
function M.convert(args)
  local pos, format, i = {}, nil, 2
  while i <= #args do
    if args[i] == "--format" then
      format = args[i + 1]
      if not format then eprint("gradus: --format needs a value (ascii, binary or ovf)") return 2 end
      i = i + 2
    else
      pos[#pos + 1] = args[i]
      i = i + 1
    end
  end
  if #pos ~= 2 then
    eprint("usage: gradus convert IN OUT [--format ascii|binary|ovf]")
    return 2
  end
  local ok, err = pcall(gradus.convert, pos[1], pos[2], { format = format })
  if not ok then eprint("gradus: " .. tostring(err)) return 1 end
  return 0
end

--- gradus view FILE.cli [-o FILE.html] | --serve [--port N]: see gradus.view.
function M.view(args) return require("gradus.view").main(args) end

local KB_USAGE = "usage: gradus kb list|verify [DIR] | show KEY [DIR] | prune [--older-than DAYS] [DIR]" ..
  " (DIR also as --dir DIR; default: the user's cache)"

-- gradus kb arguments: positional words and --dir/--older-than options;
-- nil, message on anything else
local function kb_args(args)
  local pos, o, i = {}, {}, 3
  while i <= #args do
    local a = args[i]
    if a == "--dir" or a == "--older-than" then
      if not args[i + 1] then return nil, a .. " needs a value" end
      o[a] = args[i + 1]
      i = i + 2
    elseif a:sub(1, 2) == "--" then
      return nil, "unknown option " .. a
    else
      pos[#pos + 1] = a
      i = i + 1
    end
  end
  return pos, o
end

--- gradus kb list [DIR] | show KEY [DIR] | verify [DIR] | prune [--older-than DAYS] [DIR]
function M.kb(args)
  local sub = args[2]
  local pos, o = kb_args(args)
  if not pos then eprint("gradus: kb: " .. o .. "\n" .. KB_USAGE) return 2 end
  local want = sub == "show" and 2 or 1
  if #pos > want or (sub == "show" and #pos < 1) then eprint(KB_USAGE) return 2 end
  local dir = o["--dir"] or pos[want] or gradus.kb.default_dir()
  if pos[want] and o["--dir"] then eprint("gradus: kb: the directory is given twice\n" .. KB_USAGE) return 2 end
  -- a misspelled directory is no empty knowledge base (the default one may not exist yet)
  local kind = (o["--dir"] or pos[want]) and (gradus.fs.kind(dir) or "absent")
  if kind and kind ~= "directory" then
    eprint(("gradus: kb: no knowledge base at %s (%s)"):format(dir, kind == "absent" and "no such directory" or "not a directory"))
    return 1
  end
  if sub == "list" then
    local entries = gradus.kb.list(dir)
    print(("knowledge base %s: %d templates"):format(dir, #entries))
    for _, e in ipairs(entries) do
      -- stale: built under an older engine geometry (grading rule), never served; prune removes it
      print(("%s  %8d bytes  %s  %s"):format(e.key:sub(1, 16), e.bytes, e.stale and "stale" or
        (e.qualified and "qualified" or "unqualified"), e.signature:sub(1, 100)))
    end
    return 0
  elseif sub == "show" then
    local key = pos[1]
    local t = gradus.kb.show(dir, key)
    if not t then eprint("gradus: no template " .. key .. " in " .. dir) return 1 end
    print(gradus.yaml.encode(t))
    return 0
  elseif sub == "verify" then
    local r = gradus.kb.verify(dir)
    print(gradus.yaml.encode(r))
    return (r.corrupt or 0) == 0 and 0 or 1
  elseif sub == "prune" then
    local opts = {}
    if o["--older-than"] then
      local days = tonumber(o["--older-than"])
      if not days or days < 0 then
        eprint("gradus: kb prune: --older-than needs a number of days >= 0, got '" .. o["--older-than"] .. "'")
        return 2
      end
      -- created at or before (now - DAYS): the C cutoff is strict, in whole seconds
      opts.older_than = os.time() - math.floor(days * 86400) + 1
    end
    local r = gradus.kb.prune(dir, opts)
    print(gradus.yaml.encode(r))
    return 0
  end
  eprint(KB_USAGE)
  return 2
end

-- gradus sweep: lua/gradus/sweep.lua (and gradus.slurm for --slurm)
function M.sweep(args) return require("gradus.sweep").main(args) end
function M.run_sweep(...) return require("gradus.sweep").run_sweep(...) end
function M.sweep_values(...) return require("gradus.sweep").sweep_values(...) end

-- internal: one stage of a `--slurm` job, run by its sbatch script (gradus.slurm)
M["slurm-task"] = function(args) return require("gradus.slurm").task(args) end

return M
