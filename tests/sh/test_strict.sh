#!/usr/bin/env bash
# Strict parameters: unknown -D names, unknown fields of a recipe's parameter
# table and unknown profile keys are errors with a suggestion, exit non-zero,
# nothing written; --allow-unused runs and the stats say so; numbers outside
# their physical range (and NaN, infinities) are refused with the range in the
# message; `gradus run RECIPE --help` lists every recipe's parameters and runs
# nothing; the stats give effective values and consistent ratios.
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
G=${GRADUS:-$ROOT/build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_strict: $1"; }
fail() { echo "FAIL test_strict: $1: $2"; }
expect() { # name, pattern, text
  if printf '%s' "$3" | grep -qE -- "$2"; then pass "$1"; else fail "$1" "wanted /$2/ in: $3"; fi
}
# refused: name, output file, command... (exit non-zero, no output file, no stats)
refused() {
  local name=$1 out=$2; shift 2
  if [ "$rc" != 0 ] && [ ! -e "$out" ] && [ ! -e "$d/s.yaml" ]; then pass "$name: exit $rc, nothing written"
  else fail "$name" "rc=$rc, left: $(ls "$d")"; fi
}
FAST="-D cells=1,1,1 -D kb=off -D layers=1:2"

# 1. an unknown -D name
out=$($G run "$ROOT/recipes/lattice.lua" -D hatc=0.06 $FAST -o "$d/a.cli" --stats "$d/s.yaml" 2>&1); rc=$?
expect "unknown -D is an error with a suggestion" "-D hatc=0.06: .*lattice.lua does not declare 'hatc' \(did you mean 'hatch'\?\)" "$out"
refused "unknown -D" "$d/a.cli"

# 2. --allow-unused runs, and the stats record it
out=$($G run "$ROOT/recipes/lattice.lua" -D hatc=0.06 $FAST -o "$d/b.cli" --stats "$d/b.yaml" --allow-unused -q 2>&1); rc=$?
expect "--allow-unused warns" "warning: -D hatc=0.06.*ignored: --allow-unused" "$out"
[ $rc = 0 ] && [ -s "$d/b.cli" ] && pass "--allow-unused runs" || fail "--allow-unused runs" "rc=$rc $out"
expect "--allow-unused recorded in the stats" "^allow_unused: true" "$(cat "$d/b.yaml" 2>/dev/null)"
expect "unused names listed in the stats" "^unused_parameters: \[hatc\]" "$(cat "$d/b.yaml" 2>/dev/null)"
rm -f "$d"/b.*

# 3. a misspelled field of the parameter table, in a recipe
cat > "$d/r.lua" <<'L'
local lattice = require "gradus.lattice"
local p = lattice.params { cells = "1,1,1", kb = "off", layers = "1:2" }
p.hatc = 0.06
lattice.run(p, gradus.output("x.cli"))
L
out=$($G run "$d/r.lua" -o "$d/c.cli" 2>&1); rc=$?
expect "p.hatc is an error at its line" "r.lua:3: assignment to unknown parameter 'hatc' .*\(did you mean 'hatch'\?\)" "$out"
refused "p.hatc" "$d/c.cli"

printf 'local lattice = require "gradus.lattice"\nlocal p = lattice.params { hatc = 0.06 }\n' > "$d/r2.lua"
out=$($G run "$d/r2.lua" 2>&1); rc=$?
expect "a misspelled recipe default is an error" "r2.lua:2: lattice.params: unknown parameter 'hatc' in the defaults \(did you mean 'hatch'\?\)" "$out"
[ $rc != 0 ] && pass "misspelled default: exit non-zero" || fail "misspelled default: exit non-zero" "rc=$rc"

# 4. a -D the recipe overrides silently
out=$($G run "$ROOT/recipes/paper_assembly.lua" -D cells=3,3,1 -D kb=off -o "$d/e.cli" 2>&1); rc=$?
expect "-D of a parameter the recipe sets itself" "-D cells=3,3,1 has no effect: the recipe sets cells itself" "$out"
refused "overridden -D" "$d/e.cli"

# 5. free-form extras, declared
printf 'local x = gradus.extra_params("^note_")\nlocal n = gradus.param("n", 1)\nprint(x.note_a, n)\n' > "$d/x.lua"
out=$($G run "$d/x.lua" -D note_a=hi -D n=2 2>&1); rc=$?
[ $rc = 0 ] && expect "declared extras are accepted" "^hi	2$" "$out" || fail "declared extras" "rc=$rc $out"

# 6. unknown keys in machine and process profiles: file:line:col and a suggestion
cat > "$d/m.yaml" <<'Y'
name: typo
jump_sped: 7000
lasers:
  - name: a
Y
out=$($G run "$ROOT/recipes/lattice.lua" $FAST -D machine="$d/m.yaml" -o "$d/f.cli" 2>&1); rc=$?
expect "machine profile: unknown key at line:col" "m.yaml:2:1: unknown key 'jump_sped' in the machine profile \(did you mean 'jump_speed'\?\)" "$out"
refused "machine profile typo" "$d/f.cli"
cat > "$d/m2.yaml" <<'Y'
name: typo2
lasers:
  - name: a
    hach: {power: 200, speed: 1000}
Y
out=$($G run "$ROOT/recipes/lattice.lua" $FAST -D machine="$d/m2.yaml" -o "$d/f.cli" 2>&1); rc=$?
expect "machine profile: unknown laser key" "m2.yaml:4:5: unknown key 'hach' in lasers\[1\] \(did you mean 'hatch'\?\)" "$out"
refused "laser key typo" "$d/f.cli"
printf 'name: p\nvoxel: 2\nhach: 0.05\n' > "$d/p.yaml"
out=$($G run /dev/stdin <<<"require('gradus.profiles').process('$d/p.yaml')" 2>&1); rc=$?
expect "process profile: unknown key at line:col" "p.yaml:3:1: unknown key 'hach' in the process profile \(did you mean 'hatch'\?\)" "$out"
printf 'name: p\nvoxel: .nan\n' > "$d/q.yaml"
out=$($G run /dev/stdin <<<"require('gradus.profiles').process('$d/q.yaml')" 2>&1)
expect "process profile: NaN refused at its line" "q.yaml:2:1: parameter 'voxel' must be a number in \[0.1, 100\] mm, got nan" "$out"

# 7. numbers that must be refused, with the accepted range in the message
check_range() { # name, -D, pattern
  out=$($G run "$ROOT/recipes/lattice.lua" -D kb=off -D layers=1:2 -D $2 -o "$d/g.cli" 2>&1); rc=$?
  expect "$1 refused with its range" "$3" "$out"
  refused "$1" "$d/g.cli"
}
check_range "beam_offset=10" beam_offset=10 "parameter 'beam_offset' must be auto \(hatch/2\) or a number in \[0, 1\] mm, got '10'"
check_range "cell=1e9" cell=1e9 "parameter 'cell' must be a number in \[0.1, 100\] mm, got 1e\+09"
check_range "thickness=0" thickness=0 "parameter 'thickness' must be a number in \[0.005, 10\] mm or an expression, got '0'"
check_range "cells=1e9,1,1" cells=1e9,1,1 "parameter 'cells' must be 3 whole numbers in \[1, 100000\] 'a,b,c', got '1e9,1,1'"
check_range "hatch=1e9" hatch=1e9 "parameter 'hatch' must be a number in \[0.005, 2\] mm, got 1e\+09"
check_range "hatch=0.000000001" hatch=0.000000001 "parameter 'hatch' must be a number in \[0.005, 2\] mm, got 1e-09"
check_range "origin=1e999,0,0" origin=1e999,0,0 "parameter 'origin' must be 3 numbers in \[-1000, 1000\] mm 'a,b,c', got '1e999,0,0'"
check_range "threads=1000000" threads=1000000 "parameter 'threads' must be a whole number in \[1, 64\], got 1e\+06"
check_range "slice_cell=nan" slice_cell=nan "parameter 'slice_cell' must be auto \(hatch/2\) or a number in \[0.0005, 1\] mm"
check_range "layer=inf" layer=inf "parameter 'layer': a finite number is expected, got 'inf'"
for c in 2,0,2 2,2 a,b,c 2,nan,2; do # stretched cells (cell=Lx,Ly,Lz)
  check_range "cell=$c" cell=$c "parameter 'cell' must be a number or 3 numbers in \[0.1, 100\] mm 'a,b,c', got '$c'"
done
check_range "cell=nan" cell=nan "parameter 'cell' must be a number in \[0.1, 100\] mm, got 'nan'"
check_range "hatch for a 100 mm cell" "cell=100 -D hatch=0.04" "parameter 'hatch' must be at least cell/2000 = 0.05 mm"
check_range "size and cells both given" "size=5,5,1 -D cells=3,3,1" "parameters 'size' and 'cells' both given \(size=5,5,1, cells=3,3,1\)"
check_range "lasers beside a machine profile of another count" "lasers=3 -D machine=$ROOT/recipes/machine.yaml" "parameters 'lasers' and 'machine' both given \(lasers=3, machine=.*machine.yaml with 2\)"
check_range "cells=1000,1000,1000 (10,10,10 meant)" cells=1000,1000,1000 "cells 1000 x 1000 x 1000 are 1e\+09 voxels, more than a job holds \(1e\+08\): a part of 2000 x 2000 x 2000 mm"
check_range "a skin with no domain" skin=0.3 "parameter 'skin' \(0.3 mm\) is a solid band along the domain's boundary, and there is no domain"
check_range "an inside thickness for a network" "kind=network -D inside=0.05" "bad option 'inside' \(the inside half-thickness of an asymmetric sheet: a network has one side"
check_range "a picture of a layer the job does not have" pictures=999 "bad pictures '999': layer 999 is not one of the job's 50 layers"
check_range "a check of a layer the job does not have" verify=51 "bad verify '51': layer 51 is not one of the job's 50 layers"
check_range "pictures that are no layer numbers" "pictures=2;3" "bad pictures '2;3': layer numbers a,b,c expected"
check_range "layer 0" layers=0:2 "bad layers '0:2': layers are numbered from 1"
check_range "hatch=1.5 (0.15 meant) for a 2 mm cell" hatch=1.5 "parameter 'hatch' \(1.5 mm\) makes the automatic beam offset hatch/2 = 0.75 mm larger than cell/4 = 0.5 mm"
# the output's extension and format= must agree (an OVF file named .cli would go to a machine as CLI)
out=$($G run "$ROOT/recipes/lattice.lua" $FAST -D format=ovf -o "$d/o.cli" 2>&1); rc=$?
expect "format=ovf into a .cli file refused" "parameter 'format' \(ovf\) and the output .*o.cli disagree" "$out"
refused "format=ovf into a .cli file" "$d/o.cli"
out=$($G run "$ROOT/recipes/lattice.lua" $FAST -D format=binary -o "$d/o.ovf" 2>&1); rc=$?
expect "format=binary into a .ovf file refused" "parameter 'format' \(binary\) and the output .*o.ovf disagree" "$out"
refused "format=binary into a .ovf file" "$d/o.ovf"
# NaN set by a recipe (the old sentinels meant "default")
for k in slice_cell beam_offset skin min_length; do
  printf 'local lattice = require "gradus.lattice"\nlocal p = lattice.params { cells = "1,1,1", kb = "off", layers = "1:2" }\np.%s = 0/0\nlattice.run(p, gradus.output("x.cli"))\n' "$k" > "$d/n.lua"
  out=$($G run "$d/n.lua" -o "$d/h.cli" 2>&1); rc=$?
  expect "NaN $k from a recipe refused" "n.lua:4: parameter '$k' must be .*\[.*\] mm, got nan" "$out"
  refused "NaN $k" "$d/h.cli"
done

# 8. --help for every recipe: parameters listed, nothing run or written
mkdir -p "$d/help" && cd "$d/help" || exit 1
for r in "$ROOT"/recipes/*.lua; do
  n=$(basename "$r")
  out=$($G run "$r" --help 2>&1); rc=$?
  if [ $rc = 0 ] && printf '%s' "$out" | grep -q "^parameters (-D name=value" && printf '%s' "$out" | grep -qE '^  [a-z_]+ +\['; then
    pass "--help $n"
  else fail "--help $n" "rc=$rc: $out"; fi
done
left=$(ls -A "$d/help"); [ -z "$left" ] && pass "--help writes nothing" || fail "--help writes nothing" "$left"
cd - >/dev/null || exit 1
out=$($G run "$ROOT/recipes/lattice.lua" --help)
expect "--help: default, unit, help, range" "^  hatch +\[0.05 mm\] +hatch spacing d \(\[0.005, 2\] mm\)" "$out"
expect "--help: the recipe's description" "The general recipe" "$out"
out=$($G run "$ROOT/recipes/demo.lua" --help)
expect "--help: a recipe's own defaults" "^  cells +\[4,4,2\]" "$out"

# 9. stats: effective values, ratios that agree with the counts
$G run "$ROOT/recipes/lattice.lua" -D cells=2,1,1 -D kb="$d/kb" -D layers=1:2 -o "$d/s1.cli" --stats "$d/s1.yaml" -q >/dev/null 2>&1
$G run "$ROOT/recipes/lattice.lua" -D cells=2,1,1 -D kb="$d/kb" -D layers=1:2 -o "$d/s2.cli" --stats "$d/s2.yaml" -q >/dev/null 2>&1
s1=$(cat "$d/s1.yaml" 2>/dev/null); s2=$(cat "$d/s2.yaml" 2>/dev/null)
expect "effective beam_offset (hatch/2), not a sentinel" "^  beam_offset: 0.025$" "$s1"
expect "effective slice_cell, not a sentinel" "^  slice_cell: 0.025$" "$s1"
printf '%s' "$s1" | grep -qE -- "-1.0|auto" && fail "no sentinels in the stats" "$(printf '%s' "$s1" | grep -E -- '-1.0|auto')" || pass "no sentinels in the stats"
expect "default machine named in the stats" "^  machine: 1-laser default$" "$s1"
expect "layer range used in the stats" "^  layers: 1:2$" "$s1"
expect "nothing reused: reuse_ratio 0" "reuse_ratio: 0.0" "$s1"
expect "all reused: reuse_ratio 1" "reuse_ratio: 1.0" "$s2"
expect "reused counts agree" "reused: 1" "$s2"
expect "voxels per template" "voxels_per_template: 2.0" "$s1"

# 10. progress totals are the real totals (template layers: one template, 50 layers)
printf 'local j = gradus.place.job { cells = { 1, 1, 1 } }\nj:spec { thickness = 0.1 }\nj:voxel(0, 0, 0, {})\nj:run { kb = false, quiet = false }\n' > "$d/pr.lua"
out=$($G run "$d/pr.lua" 2>&1 >/dev/null | tr '\r' '\n')
expect "template progress counts template layers to the real total" "^template layers: 50/50 " "$out"
expect "layer progress total" "^layers: 50/50 " "$out"
