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
# an axis is what the user writes as one: a vector parameter stays fixed
cat > "$d/v.lua" <<'L'
local cells = gradus.param("cells", "2,2,1")
local a = gradus.param("a", 1.0)
local n = 0
for x in tostring(cells):gmatch("[^,]+") do n = n + 1 end
if n ~= 3 then error("bad cells: 3 numbers expected, got " .. tostring(cells)) end
gradus.write_stats({ relative_density = a, build_time_s = n, seconds = { total = 0 } })
L
out=$($G sweep "$d/v.lua" -D cells=3,3,1 -D a=0.1,0.2 -o "$d/s3" -q 2>&1); rc=$?
[ $rc = 0 ] && echo "$out" | grep -q "^sweep: 2 runs into" && pass "a vector value stays fixed (2 runs, not 6)" ||
  fail "a vector value stays fixed" "rc=$rc: $out"
echo "$out" | grep -q "^sweep: axis a: 0.1, 0.2 (2)" && echo "$out" | grep -q "^sweep: fixed cells=3,3,1" &&
  pass "axes and fixed values printed first" || fail "axes printed" "$out"
grep -q '^1,ok,"3,3,1",0.1,' "$d/s3/sweep.csv" && pass "fixed vector in the CSV, quoted" || fail "fixed vector in the CSV" "$(cat "$d/s3/sweep.csv")"
out=$($G sweep "$d/v.lua" -D 'cells=[1,1,1],[2,2,1]' -D a=0.5 -o "$d/s4" -q 2>&1); rc=$?
[ $rc = 0 ] && echo "$out" | grep -q "axis cells: \[1,1,1\], \[2,2,1\] (2)" && grep -q '^2,ok,"2,2,1",0.5,' "$d/s4/sweep.csv" &&
  pass "an explicit list of vectors is an axis" || fail "a list of vectors is an axis" "rc=$rc: $out $(cat "$d/s4/sweep.csv" 2>&1)"
out=$($G sweep "$d/r.lua" -D a=-1,3 -D b=2 -o "$d/s5" -q 2>&1); rc=$?
[ $rc = 1 ] && pass "exit status 1 when a run failed" || fail "exit status 1 when a run failed" "rc=$rc"
echo "$out" | grep -qF "sweep: failed run 1 (a=-1): " && echo "$out" | grep -qF "log $d/s5/run001.log" && [ -s "$d/s5/run001.log" ] &&
  pass "failed combination listed with its log" || fail "failed combination listed" "$out"
[ "$(head -1 "$d/s5/sweep.csv" | cut -d, -f2)" = status ] && pass "CSV status column" || fail "CSV status column" "$(head -1 "$d/s5/sweep.csv")"
out=$($G sweep "$d/r.lua" -D a=1 --partition x -o "$d/s6" 2>&1); rc=$?
[ $rc = 2 ] && echo "$out" | grep -q -- "--partition is a Slurm option: it needs --slurm" && pass "Slurm options need --slurm" ||
  fail "Slurm options need --slurm" "rc=$rc: $out"
# a task Slurm ended: its reason from the log, not the shell's last word
printf 'working\nslurmstepd: error: *** JOB 5 ON n1 CANCELLED AT 2026-01-01T00:00:00 DUE TO TIME LIMIT ***\nTerminated\n' > "$d/run001.log"
got=$(echo "local r = require('gradus.sweep').collect({ combos = { {} } }, 1, '$d/run001', nil) print(r.status .. ': ' .. r.error)" | $G 2>&1 | tail -n 1)
[ "$got" = "failed: slurmstepd: error: *** JOB 5 ON n1 CANCELLED AT 2026-01-01T00:00:00 DUE TO TIME LIMIT ***" ] &&
  pass "Slurm's reason taken from a task's log" || fail "Slurm's reason from the log" "$got"
# a misspelled -D: every run fails, and the summary says which name (not only that nothing was written)
out=$($G sweep recipes/lattice.lua -D hatchx=0.05,0.06 -o "$d/s7" -q 2>&1); rc=$?
[ $rc = 1 ] && echo "$out" | grep -qF "sweep: failed run 1 (hatchx=0.05): gradus: -D hatchx=0.05: recipes/lattice.lua does not declare 'hatchx' (did you mean 'hatch'?)" &&
  pass "a misspelled parameter named in the summary" || fail "a misspelled parameter named in the summary" "rc=$rc: $out"
: > "$d/run001.log"
got=$(echo "local r = require('gradus.sweep').collect({ combos = { {} } }, 1, '$d/run001', nil) print(r.error)" | $G 2>&1 | tail -n 1)
echo "$got" | grep -q "^no exit status" && pass "no status, empty log: said so" || fail "no status, empty log" "$got"
