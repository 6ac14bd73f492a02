#!/usr/bin/env bash
# gradus cli cat: parts of one job written with -D layers=a:b merge into the
# file a single run writes, byte for byte (ASCII and binary), given in any
# order; the merged stats add up; a gap, an overlap, parts of another job or
# a broken part are refused with the layer numbers / file, nothing written.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
# same bytes but the $$DATE digits (the files may be written either side of midnight)
same() { [ -s "$1" ] && [ -s "$2" ] && cmp -s <(LC_ALL=C sed '1,20s/^\$\$DATE\/[0-9]*$/$$DATE\/0/' "$1") <(LC_ALL=C sed '1,20s/^\$\$DATE\/[0-9]*$/$$DATE\/0/' "$2"); }
pass() { echo "PASS test_clicat: $1"; }
fail() { echo "FAIL test_clicat: $1: $2"; }
job() { # out layers format [more -D]
  local out=$1 layers=$2 fmt=$3; shift 3
  $G run recipes/lattice.lua -q -D cells=1,1,2 -D res=12 -D layer=0.1 -D kb="$d/kb" -D format="$fmt" \
    ${layers:+-D layers=$layers} -o "$d/$out.cli" --stats "$d/$out.yaml" "$@" >/dev/null 2>&1
}
yget() { echo "print(gradus.yaml.load('$1').$2)" | $G 2>&1 | tail -n 1; }
for fmt in ascii binary; do
  job "full_$fmt" "" $fmt && job "a_$fmt" 1:13 $fmt && job "b_$fmt" 14:27 $fmt && job "c_$fmt" 28:40 $fmt ||
    { fail "jobs ($fmt)" "a gradus run failed"; continue; }
  out=$($G cli cat "$d/c_$fmt.cli" "$d/a_$fmt.cli" "$d/b_$fmt.cli" -o "$d/m_$fmt.cli" --stats "$d/m_$fmt.yaml" 2>&1)
  if same "$d/m_$fmt.cli" "$d/full_$fmt.cli"; then pass "3 parts out of order = one run ($fmt, byte for byte)"
  else fail "3 parts = one run ($fmt)" "$out; $(cmp "$d/m_$fmt.cli" "$d/full_$fmt.cli" 2>&1)"; fi
  echo "$out" | grep -q "40 layers (1-40, 0.1 mm) from 3 parts" && pass "reports layers 1-40 ($fmt)" || fail "reports layers ($fmt)" "$out"
done
for k in layers vectors.hatch.count vectors.contour.count jumps.count; do
  a=$(yget "$d/m_ascii.yaml" $k); b=$(yget "$d/full_ascii.yaml" $k)
  [ -n "$a" ] && [ "$a" = "$b" ] && pass "merged stats $k = one run's ($a)" || fail "merged stats $k" "merged $a, one run $b"
done
a=$(yget "$d/m_ascii.yaml" vectors.hatch.length); b=$(yget "$d/full_ascii.yaml" vectors.hatch.length)
awk -v a="$a" -v b="$b" 'BEGIN{exit !(a > 0 && (a-b)/b < 1e-9 && (b-a)/b < 1e-9)}' &&
  pass "merged hatch length = one run's" || fail "merged hatch length" "$a vs $b"
grep -q "layers: 40" "$d/m_ascii.manifest.yaml" && grep -q "cli: $d/m_ascii.cli" "$d/m_ascii.manifest.yaml" &&
  pass "merged manifest" || fail "merged manifest" "$(cat "$d/m_ascii.manifest.yaml" 2>&1 | head -3)"
# refusals: nothing written
refused() { # name expected-text parts...
  local name=$1 want=$2; shift 2
  rm -f "$d/x.cli"
  out=$($G cli cat "$@" -o "$d/x.cli" 2>&1); rc=$?
  if [ $rc != 0 ] && echo "$out" | grep -qF -- "$want" && [ ! -e "$d/x.cli" ]; then pass "$name"
  else fail "$name" "rc=$rc: $out"; fi
}
refused "gap refused with its layers" "layers 14-27 are missing" "$d/a_ascii.cli" "$d/c_ascii.cli"
job o_ascii 10:20 ascii
refused "overlap refused with its layers" "overlap in layers 10-13" "$d/o_ascii.cli" "$d/a_ascii.cli"
cp "$d/b_binary.cli" "$d/nb.cli" # no stats beside it: the CLI files alone
refused "ASCII with binary refused" "is ASCII but" "$d/a_ascii.cli" "$d/nb.cli"
job h_ascii 14:27 ascii -D hatch=0.07
refused "another job's part refused (its stats)" "is 0.025 in one and 0.035 in the other (their stats)" "$d/a_ascii.cli" "$d/h_ascii.cli"
job w_ascii 14:27 ascii -D cells=2,1,2
rm -f "$d/w_ascii.yaml"
refused "another job's part refused (its header)" 'are not parts of one job: their $$DIMENSION x, y extents differ' "$d/a_ascii.cli" "$d/w_ascii.cli"
head -c 3000 "$d/b_ascii.cli" > "$d/t.cli"
refused "a truncated part refused by name" "$d/t.cli" "$d/a_ascii.cli" "$d/t.cli"
cp "$d/a_ascii.cli" "$d/keep.cli"
out=$($G cli cat "$d/a_ascii.cli" "$d/b_ascii.cli" -o "$d/a_ascii.cli" 2>&1); rc=$?
[ $rc != 0 ] && echo "$out" | grep -q "is also a part" && same "$d/a_ascii.cli" "$d/keep.cli" &&
  pass "the output may not be a part" || fail "the output may not be a part" "rc=$rc: $out"
