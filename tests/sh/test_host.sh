#!/usr/bin/env bash
# The gradus command line: errors point at recipe lines, unknown -D names are
# reported, YAML errors carry line and column, the REPL reads stdin.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_host: $1"; }
fail() { echo "FAIL test_host: $1: $2"; }
expect() { # name, pattern, text
  if printf '%s' "$3" | grep -qE -- "$2"; then pass "$1"; else fail "$1" "wanted /$2/ in: $3"; fi
}

cat > "$d/r.lua" <<'L'
local n = gradus.param("n", 3)
local mode = gradus.param("mode", "a")
if mode == "bad_arg" then gradus.yaml.decode(42, {}) end
if mode == "yaml" then gradus.yaml.decode("a: [1,\nb: 2\n", "p.yaml") end
if mode == "global" then print(undefined_thing) end
if mode == "error" then
  error("custom failure")
end
print("n=" .. n)
L
out=$($G run "$d/r.lua" -D n=7 2>&1); rc=$?
expect "run prints" "^n=7$" "$out"; [ $rc = 0 ] && pass "run exit 0" || fail "run exit 0" "rc=$rc"
out=$($G run "$d/r.lua" -D mode=error 2>&1); rc=$?
expect "error names recipe line" "r.lua:7: custom failure" "$out"; [ $rc != 0 ] && pass "error exit non-zero" || fail "error exit" "rc=$rc"
out=$($G run "$d/r.lua" -D mode=bad_arg 2>&1)
expect "C error points at the recipe line" "r.lua:3: bad argument" "$out"
out=$($G run "$d/r.lua" -D mode=yaml 2>&1)
expect "YAML error line and column" "p.yaml:[0-9]+:[0-9]+: " "$out"
out=$($G run "$d/r.lua" -D mode=global 2>&1)
expect "undeclared global" "r.lua:5: read of undeclared global 'undefined_thing'" "$out"
out=$($G run "$d/r.lua" -D nn=4 2>&1); rc=$?
expect "unknown -D reported" "-D nn=4: .*r.lua does not declare 'nn' \(did you mean 'n'\?\)" "$out"
[ $rc != 0 ] && pass "unknown -D exit non-zero" || fail "unknown -D exit non-zero" "rc=$rc"
out=$($G run "$d/r.lua" -D n=abc 2>&1); rc=$?
expect "bad -D value" "parameter 'n': a finite number is expected, got 'abc'" "$out"; [ $rc != 0 ] && pass "bad -D exit" || fail "bad -D exit" "rc=$rc"
out=$(printf '1+2\nlocal t = {\n  a = 5 }\nprint(t == nil)\nmath.sqrt(16)\n' | $G 2>&1)
expect "REPL evaluates stdin" "^3$" "$out"; expect "REPL multi-line + expression" "^4.0$" "$out"
out=$($G --version); expect "version" "^gradus [0-9]+\.[0-9]+\.[0-9]+" "$out"
out=$($G help); expect "help" "usage: gradus run RECIPE" "$out"
out=$($G frobnicate 2>&1); rc=$?
expect "unknown command" "unknown command 'frobnicate'" "$out"; [ $rc != 0 ] && pass "unknown command exit" || fail "unknown command exit" "rc=$rc"
out=$($G run /nonexistent.lua 2>&1); rc=$?
expect "missing recipe" "cannot open recipe /nonexistent.lua" "$out"
# stock lua5.4 can require the C module
if command -v lua5.4 >/dev/null; then
  out=$(cd "$d" && LUA_CPATH="$OLDPWD/build/?.so" lua5.4 -e 'local g = require "gradus"; print(g.version, type(g.param), g.param("x", 5))' 2>&1)
  expect "require from stock lua5.4" "^[0-9.]+	function	5$" "$out"
fi
# a full disk while writing (simulated by a file size limit: writes fail with
# EFBIG as they would with ENOSPC): an error naming the file, no output left
mkdir -p "$d/full"
out=$( (trap '' XFSZ; ulimit -f 200; $G run recipes/lattice.lua -D cells=2,2,1 -D kb=off -o "$d/full/out.cli" -q) 2>&1); rc=$?
expect "full disk names the file" "cannot write $d/full/out.cli" "$out"
[ $rc != 0 ] && pass "full disk exit non-zero" || fail "full disk exit" "rc=$rc"
left=$(ls -A "$d/full")
[ -z "$left" ] && pass "full disk leaves no partial file" || fail "full disk leaves no partial file" "$left"
# the knowledge base's disk full (its writer thread fails on a 1 MB record
# while the small CLI would fit): the job fails naming the record, no CLI
# left, no temporary record left
mkdir -p "$d/kbfull"
out=$( (trap '' XFSZ; ulimit -f 200; $G run recipes/lattice.lua -D cells=2,2,1 -D kb="$d/kbfull/kb" -D kb_store=all \
  -D layers=1:2 -o "$d/kbfull/out.cli" -q) 2>&1); rc=$?
expect "full knowledge base names the record" "cannot write $d/kbfull/kb/t/[0-9a-f]{64}\.gtp" "$out"
[ $rc != 0 ] && pass "full knowledge base exit non-zero" || fail "full knowledge base exit" "rc=$rc"
left=$( (ls -A "$d/kbfull"; ls -A "$d/kbfull/kb/t") | grep -E "^out|\.tmp-")
[ -z "$left" ] && pass "full knowledge base leaves no partial file" || fail "full knowledge base leaves no partial file" "$left"
# a laser profile whose fields do not cover the part, and a malformed profile:
# errors naming the profile and the field, no output
cat > "$d/far.yaml" <<'YAML'
name: far-lasers
lasers:
  - name: a
    field: {lo: [100, 100], hi: [200, 200]}
YAML
out=$($G run recipes/lattice.lua -D cells=2,2,1 -D kb=off -D machine="$d/far.yaml" -o "$d/far.cli" -q 2>&1); rc=$?
expect "laser fields that miss the part" "laser fields of 'far-lasers' do not cover the part" "$out"
[ $rc != 0 ] && [ ! -e "$d/far.cli" ] && pass "uncovered part: exit non-zero, no CLI" || fail "uncovered part" "rc=$rc"
printf 'name: bad\nlasers:\n  - name: a\n    field: {lo: [10, 0], hi: [0, 5]}\n' > "$d/bad.yaml"
out=$($G run recipes/lattice.lua -D cells=1,1,1 -D kb=off -D machine="$d/bad.yaml" -o "$d/bad.cli" -q 2>&1); rc=$?
expect "inverted laser field named" "bad.yaml.*lasers\[1\]\.field.*lo must be below hi" "$out"
[ $rc != 0 ] && [ ! -e "$d/bad.cli" ] && pass "bad profile: exit non-zero, no CLI" || fail "bad profile" "rc=$rc"
# gradus kb: the directory positional or as --dir; show, verify, prune; bad arguments
$G run recipes/lattice.lua -D cells=1,1,1 -D kb="$d/kbc" -D kb_store=all -D layers=1:3 -o "$d/kbc.cli" -q >/dev/null 2>&1
out=$($G kb list "$d/kbc" 2>&1); expect "kb list DIR" "knowledge base $d/kbc: 1 templates" "$out"
out=$($G kb list --dir "$d/kbc" 2>&1); expect "kb list --dir DIR" "knowledge base $d/kbc: 1 templates" "$out"
key=$($G kb list "$d/kbc" | awk 'NR==2{print $1}')
out=$($G kb show "$key" "$d/kbc" 2>&1); expect "kb show KEY DIR" "^signature: .*surface: primitive" "$out"
out=$($G kb verify "$d/kbc" 2>&1); rc=$?; expect "kb verify" "^ok: 1" "$out"; [ $rc = 0 ] && pass "kb verify exit 0" || fail "kb verify exit" "rc=$rc"
out=$($G kb prune --older-than 1 "$d/kbc" 2>&1); expect "kb prune keeps a new template" "^removed: 0" "$out"
out=$($G kb prune --older-than 0 "$d/kbc" 2>&1); expect "kb prune --older-than 0 removes it" "^removed: 1" "$out"
out=$($G kb list "$d/kbtypo" 2>&1); rc=$?; expect "kb list of a missing directory" "no knowledge base at $d/kbtypo \(no such directory\)" "$out"
[ $rc = 1 ] && [ ! -e "$d/kbtypo" ] && pass "kb list of a missing directory: exit 1, nothing created" || fail "kb list of a missing directory" "rc=$rc, $(ls "$d")"
out=$($G kb list --frob 2>&1); rc=$?; expect "kb unknown option" "unknown option --frob" "$out"; [ $rc = 2 ] && pass "kb bad option exit 2" || fail "kb bad option exit" "rc=$rc"
out=$($G kb prune --older-than soon "$d/kbc" 2>&1); rc=$?; expect "kb prune bad days" "--older-than needs a number of days" "$out"; [ $rc = 2 ] && pass "kb bad days exit 2" || fail "kb bad days exit" "rc=$rc"
# gradus cli info: a binary CLI written by a run, then the same file truncated, and a missing file
$G run recipes/lattice.lua -D cells=1,1,1 -D kb=off -D layers=2:4 -D format=binary -o "$d/info.cli" --stats "$d/info.yaml" -q >/dev/null 2>&1
out=$($G cli info "$d/info.cli" 2>&1); rc=$?
expect "cli info layers" "^layers: 3$" "$out"; expect "cli info format" "^format: binary(-short)?$" "$out"
expect "cli info z range" "^bounds: \[.*, 0.08, .*, 0.16\]$" "$out"; [ $rc = 0 ] && pass "cli info exit 0" || fail "cli info exit" "rc=$rc"
hatches=$(awk '/^vectors:/{v=1} v&&/^  hatch:/{h=1} h&&/count:/{print $2; exit}' "$d/info.yaml")
expect "cli info hatch count = the run's stats ($hatches)" "vectors: $hatches$" "$out"
size=$(stat -c %s "$d/info.cli"); head -c $((size - 7)) "$d/info.cli" > "$d/cut.cli"
out=$($G cli info "$d/cut.cli" 2>&1); rc=$?
expect "cli info truncated names the byte" "$d/cut.cli: byte [0-9]+: .*(truncated|past the end)" "$out"; [ $rc != 0 ] && pass "truncated exit non-zero" || fail "truncated exit" "rc=$rc"
out=$($G cli info "$d/none.cli" 2>&1); rc=$?
expect "cli info missing file" "cannot read $d/none.cli" "$out"; [ $rc != 0 ] && pass "missing exit non-zero" || fail "missing exit" "rc=$rc"
