#!/usr/bin/env bash
# gradus run recipes/plate.lua -D plate=FILE -o OUT.cli: a plate of two small
# parts (binary CLI) with its manifest, stats and pictures; a bad plate file
# exits non-zero naming file:line:col, writes nothing and leaves an earlier
# plate's outputs as they were.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_plate: $1"; }
fail() { echo "FAIL test_plate: $1: $2"; }
yget() { echo "print(gradus.yaml.load('$1').$2)" | $G 2>&1 | tail -n 1; }
part='    surface: primitive
    cell: 2
    hatch: 0.1
    thickness: 0.2'
cat > "$d/p.yaml" <<EOP
layer: 0.2
format: binary
res: 8
kb: $d/kb
plate: {lo: [0, 0], hi: [100, 100]}
parts:
  - name: a
    at: [20, 20]
    size: [2, 2, 0.4]
$part
  - name: b
    at: [40, 20]
    rotation: 30
    size: [2, 2, 0.6]
$part
EOP
out=$($G run recipes/plate.lua -q -D plate="$d/p.yaml" -o "$d/p.cli" --stats "$d/p.stats.yaml" 2>&1)
rc=$?
[ $rc -eq 0 ] && echo "$out" | grep -q "2 parts (a 2 layers, b 3 layers), 3 layers" && pass "a plate of two parts runs ($out)" ||
  fail "a plate of two parts runs" "rc $rc: $out"
miss=""
for f in p.cli p.manifest.yaml p.stats.yaml p_plate.svg p_layer1.svg p_layer1.png; do [ -s "$d/$f" ] || miss="$miss $f"; done
[ -z "$miss" ] && pass "CLI, manifest, stats and pictures written" || fail "outputs written" "missing:$miss"
head -c 30 "$d/p.cli" | grep -q BINARY && pass "binary CLI as the plate says" || fail "binary CLI" "$(head -c 40 "$d/p.cli")"
n=$(echo "print(gradus.info('$d/p.cli').layers)" | $G 2>&1 | tail -n 1)
[ "$n" = 3 ] && pass "3 layers in the file" || fail "layers in the file" "$n"
[ "$(yget "$d/p.stats.yaml" 'parts[2].name')" = b ] && pass "stats list the parts" || fail "stats list the parts" "$(yget "$d/p.stats.yaml" 'parts[2].name')"

sum=$(md5sum "$d/p.cli" "$d/p.stats.yaml" "$d/p_plate.svg")
sed 's/    rotation: 30/    rotaton: 30/' "$d/p.yaml" > "$d/bad.yaml"
out=$($G run recipes/plate.lua -q -D plate="$d/bad.yaml" -o "$d/p.cli" --stats "$d/p.stats.yaml" 2>&1)
rc=$?
[ $rc -ne 0 ] && echo "$out" | grep -q "bad.yaml:16:5: unknown key 'rotaton' in part 'b' (did you mean 'rotation'?)" &&
  pass "unknown key refused with file:line:col" || fail "unknown key refused" "rc $rc: $out"
[ "$sum" = "$(md5sum "$d/p.cli" "$d/p.stats.yaml" "$d/p_plate.svg")" ] && pass "the earlier outputs are untouched" ||
  fail "earlier outputs untouched" "changed"
sed 's/at: \[40, 20\]/at: [21, 20]/' "$d/p.yaml" > "$d/over.yaml"
out=$($G run recipes/plate.lua -q -D plate="$d/over.yaml" -o "$d/o.cli" --stats "$d/o.yaml" 2>&1)
rc=$?
left=$(ls "$d" | grep -E '^o[._]')
[ $rc -ne 0 ] && echo "$out" | grep -q "over.yaml:15:5: parts 'a' (.*over.yaml:8:5) and 'b' overlap on the plate" && [ -z "$left" ] &&
  pass "overlapping parts refused, nothing written" || fail "overlapping parts refused" "rc $rc: $out; left: $left"
out=$($G run --sandbox recipes/plate.lua -q -D plate="$d/p.yaml" -o "$d/s.cli" 2>&1)
rc=$?
[ $rc -ne 0 ] && echo "$out" | grep -q "cannot run under --sandbox" && [ ! -e "$d/s.cli" ] &&
  pass "refused under --sandbox (its parts would run outside it)" || fail "refused under --sandbox" "rc $rc: $out"
