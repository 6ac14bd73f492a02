#!/usr/bin/env bash
# Design by density on the command line: conflicting targets are refused
# before any work, with a non-zero exit and no output left behind; a bad
# field file is named with its index.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_density: $1"; }
fail() { echo "FAIL test_density: $1: $2"; }
expect() { # name, pattern, text
  if printf '%s' "$3" | grep -qE -- "$2"; then pass "$1"; else fail "$1" "wanted /$2/ in: $3"; fi
}
export GRADUS_CACHE_DIR="$d/cache"
out=$($G run recipes/lattice.lua -D density=0.3 -D thickness=0.1 -D cells=1,1,1 -o "$d/a.cli" 2>&1); rc=$?
expect "thickness and density together refused" "give thickness or density, not both" "$out"
[ $rc != 0 ] && pass "non-zero exit" || fail "non-zero exit" "rc=$rc"
[ ! -e "$d/a.cli" ] && pass "no CLI left" || fail "no CLI left" "$d/a.cli exists"
out=$($G run recipes/lattice.lua -D density=0.3 -D porosity=0.7 -D cells=1,1,1 -o "$d/a.cli" 2>&1)
expect "density and porosity together refused" "give density or porosity, not both" "$out"
printf '# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\nORIGIN 0 0 0\nSPACING 2 2 2\nPOINT_DATA 8\nSCALARS r float\nLOOKUP_TABLE default\n0.3 0.3 0.3 0.3 0.3\n' > "$d/t.vtk"
out=$($G run recipes/lattice.lua -D density="$d/t.vtk" -D cells=1,1,1 -o "$d/a.cli" 2>&1); rc=$?
expect "truncated field file named with the index" "t.vtk:[0-9]+: value 6 of 8 \(index 1, 0, 1\) missing" "$out"
[ $rc != 0 ] && pass "bad file: non-zero exit" || fail "bad file: non-zero exit" "rc=$rc"
