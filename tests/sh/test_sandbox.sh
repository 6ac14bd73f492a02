#!/usr/bin/env bash
# gradus run --sandbox: each way out of a recipe is refused by name (process
# execution, writes outside the output directory, reads outside the recipe's
# directory and the inputs, C modules, binary chunks, rawset of _G, changing
# gradus's modules), the limits stop endless loops (even under pcall) and
# memory hogs, and a lattice job still runs, writing into its output directory.
# Inputs are the -D values that name existing files.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
export GRADUS_CACHE_DIR=$d/cache
pass() { echo "PASS test_sandbox: $1"; }
fail() { echo "FAIL test_sandbox: $1: $2"; }
mkdir -p "$d/r" "$d/out"
echo secret > "$d/secret.txt"; echo "a: 1" > "$d/input.yaml"
cat > "$d/r/evil.lua" <<'L'
local what = gradus.param("what", "")
local input = gradus.param("input", "")
if what == "exec" then os.execute("true") end
if what == "popen" then io.popen("id") end
if what == "write" then io.open(gradus.param("path", ""), "w") end
if what == "read" then io.open("/etc/passwd") end
if what == "yaml" then gradus.yaml.load("/etc/hostname") end
if what == "dotdot" then io.open(gradus.param("dir", "") .. "/../secret.txt") end
if what == "input" then print("input a=" .. gradus.yaml.load(input).a) end
if what == "rawset" then rawset(_G, "x", 1) end
if what == "binary" then load(string.dump(function() end), "x", "b") end
if what == "cmodule" then require "lfs" end
if what == "loadlib" then package.loadlib("/lib/x.so", "f") end
if what == "modify" then local o = require "gradus.outputs" o.guard = function() end end
if what == "loop" then while true do end end
if what == "pcall" then while true do pcall(function() while true do end end) end end
if what == "memory" then local t = {} for i = 1, 1e9 do t[i] = ("x"):rep(64) .. i end end
if what == "kb" then gradus.kb.prune(gradus.param("path", "")) end
if what == "job" then
  local lattice = require "gradus.lattice"
  local st = lattice.run(lattice.params(), gradus.output("out/x.cli"))
  print("layers " .. st.layers)
end
L
check() { # name, pattern, args...
  local name=$1 pat=$2; shift 2
  local out; out=$($G run "$d/r/evil.lua" --limits memory=64,instructions=2e7,seconds=60 "$@" 2>&1); local rc=$?
  if [ $rc != 0 ] && printf '%s' "$out" | grep -qE -- "$pat"; then pass "$name"; else fail "$name" "rc=$rc, wanted /$pat/ in: $out"; fi
}
check "os.execute refused" "evil.lua:3: sandbox: os.execute refused \(no process execution\)" -D what=exec
check "io.popen refused" "sandbox: io.popen refused" -D what=popen
check "write outside the output directory refused" "sandbox: writing '$d/elsewhere.txt' refused" -D what=write -D path="$d/elsewhere.txt" -o "$d/out/x.cli"
check "read outside refused" "sandbox: reading '/etc/passwd' refused" -D what=read
check "read through gradus.yaml refused" "sandbox: reading '/etc/hostname' refused" -D what=yaml
check "read by .. out of the recipe's directory refused" "sandbox: reading '$d/r/../secret.txt' refused" -D what=dotdot -D dir="$d/r"
check "rawset of _G refused" "sandbox: rawset of 'x' on a sandbox table refused" -D what=rawset
check "binary chunk refused" "sandbox: load in mode 'b' refused" -D what=binary
check "C module refused" "sandbox: require 'lfs' refused \(only gradus's Lua modules; no C modules\)" -D what=cmodule
check "package.loadlib refused" "sandbox: 'package' refused" -D what=loadlib
check "gradus's modules read-only" "sandbox: changing gradus.outputs.guard refused" -D what=modify
check "instruction limit" "evil.lua:15: sandbox: instruction limit of 20000000 reached" -D what=loop
check "instruction limit under pcall" "sandbox: instruction limit of 20000000 reached" -D what=pcall
check "memory limit" "sandbox: memory limit of 64 MiB reached" -D what=memory
check "knowledge base elsewhere refused" "sandbox: writing '$d/otherkb' refused" -D what=kb -D path="$d/otherkb"
out=$($G run "$d/r/evil.lua" --sandbox -D what=input -D input="$d/input.yaml" 2>&1)
[ "$out" = "input a=1" ] && pass "a given input is readable" || fail "input" "$out"
out=$($G run "$d/r/evil.lua" --sandbox -D what=job -D cells=1,1,1 -D cell=2 -D hatch=0.3 -D layers=1:2 -q -o "$d/out/x.cli" 2>&1); rc=$?
[ $rc = 0 ] && [ -f "$d/out/x.cli" ] && [ -f "$d/out/x.manifest.yaml" ] && pass "a lattice job runs in the sandbox" || fail "job" "rc=$rc $out"
out=$($G run "$d/r/evil.lua" -D what=exec 2>&1); rc=$?
[ $rc = 0 ] && pass "without --sandbox the recipe is trusted (os.execute runs)" || fail "trusted" "rc=$rc $out"
