#!/usr/bin/env bash
# Outputs never clobber: only regular files are replaced (a FIFO, a symbolic
# link, a directory are refused by name and left as they were); a job whose
# stats cannot be written replaces no output; temporaries of dead processes
# are removed by the next job in that directory or knowledge base (and it
# says so); Ctrl-C removes the job's temporaries and says where it stopped;
# -D hatch=1e-9 is refused, not a heap overflow (under ASan when built).
G=${GRADUS:-build/gradus}
R=recipes/lattice.lua
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
export GRADUS_CACHE_DIR=$d/cache
A=(-D cells=1,1,1 -D cell=2 -D hatch=0.3 -D layers=1:3 -q)
pass() { echo "PASS test_outputs: $1"; }
fail() { echo "FAIL test_outputs: $1: $2"; }
expect() { # name, pattern, text
  if printf '%s' "$3" | grep -qE -- "$2"; then pass "$1"; else fail "$1" "wanted /$2/ in: $3"; fi
}
dead_pid() { sh -c 'echo $$'; } # a process that has ended

mkfifo "$d/fifo"
out=$($G run $R "${A[@]}" -o "$d/fifo" 2>&1); rc=$?
expect "FIFO refused by name" "cannot write $d/fifo: it is a FIFO \(only regular files are replaced\)" "$out"
[ $rc = 1 ] && [ -p "$d/fifo" ] && pass "FIFO left a FIFO, exit 1" || fail "FIFO kept" "rc=$rc"
echo keep > "$d/target.cli"; ln -s target.cli "$d/link.cli"
out=$($G run $R "${A[@]}" -o "$d/link.cli" 2>&1)
expect "symbolic link refused" "it is a symbolic link" "$out"
[ -L "$d/link.cli" ] && [ "$(cat "$d/target.cli")" = keep ] && pass "link and its target untouched" || fail "link kept" "changed"
mkdir "$d/sdir"
out=$($G run $R "${A[@]}" -o "$d/a.cli" --stats "$d/sdir" 2>&1); rc=$?
expect "stats into a directory refused" "cannot write $d/sdir: it is a directory" "$out"
left=$(ls "$d" | grep -E '^a[._]' | tr '\n' ' ')
[ $rc = 1 ] && [ -z "$left" ] && pass "no CLI, manifest or temporary when the stats fail" || fail "nothing in place" "rc=$rc files: $left"

# a regular file is replaced; stale temporaries of a dead process are removed
echo old > "$d/a.cli"
p=$(dead_pid)
touch "$d/a.cli.tmp$p" "$d/a.yaml.tmp$p.tmp$p" "$d/notes.tmp$p"
out=$($G run $R "${A[@]}" -o "$d/a.cli" --stats "$d/a.yaml" 2>&1); rc=$?
[ $rc = 0 ] && head -c 13 "$d/a.cli" | grep -q HEADERSTART && [ -f "$d/a.yaml" ] && [ -f "$d/a.manifest.yaml" ] \
  && pass "regular file replaced, every output in place" || fail "job" "rc=$rc $out"
expect "stale temporaries reported" "removed 2 temporary file\(s\) that stopped jobs left in $d: a.cli.tmp$p, a.yaml.tmp$p.tmp$p" "$out"
[ ! -e "$d/a.cli.tmp$p" ] && [ -e "$d/notes.tmp$p" ] && pass "stale temporary removed, other files kept" || fail "stale" "$(ls "$d")"
[ -z "$(ls "$d" | grep -E '\.tmp[0-9]+$' | grep -v notes)" ] && pass "no temporary left by the job" || fail "temporaries" "$(ls "$d")"

# knowledge base: a dead writer's temporary is removed by the next job
kbt=$(ls -d "$d"/cache/*/t 2>/dev/null | head -1)
if [ -n "$kbt" ]; then
  touch "$kbt/0123.gtp.tmp-$p-AbCdEf"
  live="$kbt/0124.gtp.tmp-$$-AbCdEf"; touch "$live"
  out=$($G run $R "${A[@]}" -o "$d/b.cli" 2>&1)
  expect "knowledge-base leftovers reported" "knowledge base .*: removed 1 temporary file\(s\) left by stopped jobs" "$out"
  [ ! -e "$kbt/0123.gtp.tmp-$p-AbCdEf" ] && [ -e "$live" ] && pass "dead writer's temporary removed, live one kept" \
    || fail "kb temporaries" "$(ls "$kbt")"
else
  fail "knowledge base" "no t/ directory under $d/cache"
fi

# Ctrl-C: the recipe stops where it is, the job's temporaries go
cat > "$d/loop.lua" <<'L'
gradus.outputs.job(function()
  gradus.write_file(gradus.output("x") .. ".yaml", "a: 1\n")
  local f = io.open(gradus.output("x") .. ".started", "w") f:close()
  while true do end
end)
L
$G run "$d/loop.lua" -o "$d/j" >"$d/int.log" 2>&1 &
pid=$!
for _ in $(seq 1 600); do [ -e "$d/j.started" ] && break; sleep 0.1; done
kill -INT $pid; wait $pid; rc=$?
out=$(cat "$d/int.log")
expect "Ctrl-C says where" "loop.lua:4: interrupted \(Ctrl-C\)" "$out"
expect "Ctrl-C lists the temporaries removed" "stopped by Ctrl-C; no output was replaced; temporaries removed: $d/j.yaml.tmp$pid" "$out"
[ $rc = 130 ] && [ ! -e "$d/j.yaml" ] && [ ! -e "$d/j.yaml.tmp$pid" ] && pass "Ctrl-C exit 130, nothing left" \
  || fail "Ctrl-C" "rc=$rc $(ls "$d")"

# hatch=1e-9 overflowed the shared slice grid (heap overflow): now an error
for exe in $G build/gradus-asan; do
  [ -x "$exe" ] || continue
  out=$($exe run $R -D cells=1,1,1 -D hatch=0.000000001 -q -o "$d/h.cli" 2>&1); rc=$?
  expect "hatch=1e-9 refused ($(basename "$exe"))" "slice grid too large|parameter .hatch. must be a number in" "$out"
  [ $rc = 1 ] && pass "hatch=1e-9 exit 1 ($(basename "$exe"))" || fail "hatch=1e-9 exit" "rc=$rc"
done
