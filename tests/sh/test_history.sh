#!/usr/bin/env bash
# A template is a pure function of its key: the same recipe gives a
# byte-identical CLI whatever the knowledge base already holds - built in two
# orders (a 2x2x1 job first, then 2x2x2 on the same knowledge base, against a
# fresh 2x2x2) and after a simulated interruption (a job that stopped after
# the first row's templates, then the whole job). Thickness graded in x, y, z
# so that every voxel is its own class and classes share closest points.
cd "$(dirname "$0")/../.." || exit 1
G=${GRADUS:-$PWD/build/gradus}
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_history.sh: $1"; }
fail() { echo "FAIL test_history.sh: $1: $2"; }
C="-D layer=0.1 -D hatch=0.1 -D res=20 -D format=binary -D kb_store=all -D thickness=0.1+0.01*x+0.008*y+0.012*z -q"
run() { "$G" run recipes/lattice.lua $C "$@" >"$d/log" 2>&1 || { cat "$d/log"; return 1; }; }
ok=1
run -D cells=2,2,1 -D kb="$d/k1" -o "$d/a1.cli" && run -D cells=2,2,2 -D kb="$d/k1" -o "$d/a.cli" || ok=0
run -D cells=2,2,2 -D kb="$d/k2" -o "$d/b.cli" || ok=0
run -D cells=2,2,2 -D kb="$d/k3" -D layers=1:20 -o "$d/c1.cli" && run -D cells=2,2,2 -D kb="$d/k3" -o "$d/c.cli" || ok=0
if [ $ok = 0 ]; then fail "jobs" "a job failed"; exit 1; fi
n=$(ls "$d"/k3/t/*.gtp | wc -l)
[ "$n" -ge 8 ] && pass "every voxel its own template ($n)" || fail "classes" "$n templates, expected 8"
cmp -s "$d/a.cli" "$d/b.cli" && pass "2x2x1 then 2x2x2 on one knowledge base = fresh 2x2x2, byte for byte" ||
  fail "order" "$(cmp "$d/a.cli" "$d/b.cli" | head -1)"
cmp -s "$d/c.cli" "$d/b.cli" && pass "after an interruption (first row only) = fresh, byte for byte" ||
  fail "interruption" "$(cmp "$d/c.cli" "$d/b.cli" | head -1)"
