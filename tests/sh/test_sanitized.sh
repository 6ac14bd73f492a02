#!/usr/bin/env bash
# The whole pipeline under AddressSanitizer + UndefinedBehaviorSanitizer: the
# host built with the sanitized core (build/gradus-asan) runs small but
# complete jobs (templates with verification and thin walls, knowledge base,
# two lasers, binary and ASCII writers, the reader, a trimmed domain with a
# skin, islands). Any sanitizer report or non-zero exit fails.
cd "$(dirname "$0")/../.." || exit 1
G=$PWD/build/gradus-asan
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
export GRADUS_CACHE_DIR=$d/cache
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
pass() { echo "PASS test_sanitized: $1"; }
fail() { echo "FAIL test_sanitized: $1: $2"; }
job() { # name, command...
  local name=$1; shift
  local out rc
  out=$("$@" 2>&1); rc=$?
  if [ $rc != 0 ] || echo "$out" | grep -qE "ERROR: AddressSanitizer|runtime error|LeakSanitizer"; then
    fail "$name" "rc=$rc $(echo "$out" | grep -m3 -E 'ERROR|runtime error|SUMMARY|error')"
  else
    pass "$name"
  fi
}
[ -x "$G" ] || { fail "build" "no $G"; exit 1; }
job "gyroid sheet, verified templates, knowledge base, 2 lasers, binary" \
  $G run recipes/lattice.lua -D cells=3,2,1 -D surface=gyroid -D qualify=true -D kb="$d/kb" -D lasers=2 \
  -D format=binary -D split=true -o "$d/a.cli" --stats "$d/a.yaml" -q
job "the same from the knowledge base, ASCII" \
  $G run recipes/lattice.lua -D cells=3,2,1 -D surface=gyroid -D kb="$d/kb" -D lasers=2 -o "$d/b.cli" -q
job "cli info of both" sh -c "'$G' cli info '$d/a.cli' && '$G' cli info '$d/b.cli'"
job "the same as OVF, info, convert OVF -> CLI -> OVF" \
  sh -c "'$G' run recipes/lattice.lua -D cells=3,2,1 -D surface=gyroid -D kb='$d/kb' -D lasers=2 -o '$d/b.ovf' -q &&
         '$G' info '$d/b.ovf' >/dev/null && '$G' convert '$d/b.ovf' '$d/o.cli' && '$G' convert '$d/o.cli' '$d/o.ovf'"
job "trimmed sphere domain with skin, islands, direct" \
  $G run recipes/lattice.lua -D cells=2,2,2 -D kb=off -D "domain=(x-2)^2+(y-2)^2+(z-2)^2-3" -D skin=0.2 \
  -D pattern=island -D layers=20:40 -o "$d/c.cli" -q
job "kb list, verify, prune" sh -c "'$G' kb list '$d/kb' && '$G' kb verify '$d/kb' && '$G' kb prune '$d/kb'"
