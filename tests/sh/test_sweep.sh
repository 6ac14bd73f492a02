#!/usr/bin/env bash
# gradus sweep: 4 runs give a table of 4 rows with their parameters; a
# failing combination is recorded as failed while the others succeed.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_sweep: $1"; }
fail() { echo "FAIL test_sweep: $1: $2"; }
cat > "$d/r.lua" <<'L'
local a = gradus.param("a", 1.0)
local b = gradus.param("b", 1.0)
if a < 0 then error(("a must be >= 0, got %g"):format(a)) end
gradus.write_stats({ relative_density = a * b, build_time_s = a + b, seconds = { total = 0 } })
L
out=$($G sweep "$d/r.lua" -D a=1,2 -D b=0.5:1.0:0.5 -j 2 -o "$d/s1" -q 2>&1); rc=$?
[ $rc = 0 ] && pass "sweep exits 0" || fail "sweep exits 0" "rc=$rc: $out"
rows=$(($(wc -l < "$d/s1/sweep.csv") - 1))
[ "$rows" = 4 ] && pass "4 rows" || fail "4 rows" "got $rows"
# every (a, b) pair is there once, with density a*b
for ab in "1 0.5" "1 1" "2 0.5" "2 1"; do
  set -- $ab
  line=$(awk -F, -v a="$1" -v b="$2" 'NR>1 && $3+0==a+0 && $4+0==b+0' "$d/s1/sweep.csv")
  dens=$(echo "$line" | cut -d, -f5)
  want=$(awk -v a="$1" -v b="$2" 'BEGIN{print a*b}')
  if [ -n "$line" ] && awk -v x="$dens" -v y="$want" 'BEGIN{exit !(x+0==y+0)}'; then pass "row a=$1 b=$2"; else fail "row a=$1 b=$2" "line '$line'"; fi
done
out=$($G sweep "$d/r.lua" -D a=-1,3 -D b=2 -o "$d/s2" -q 2>&1)
ok=$(grep -c ',ok,' "$d/s2/sweep.csv"); bad=$(grep -c ',failed,' "$d/s2/sweep.csv")
[ "$ok" = 1 ] && [ "$bad" = 1 ] && pass "failed run recorded, other succeeds" || fail "failed run recorded" "ok=$ok failed=$bad"
grep -q 'a must be >= 0, got -1' "$d/s2/sweep.csv" && pass "error recorded" || fail "error recorded" "$(cat "$d/s2/sweep.csv")"
grep -q 'runs:' "$d/s2/sweep.yaml" && pass "YAML table" || fail "YAML table" "no runs"
