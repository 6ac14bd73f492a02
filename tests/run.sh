#!/usr/bin/env bash
# Runs every test: C tests (plain and under ASan+UBSan), Lua tests through the
# gradus host, and shell tests of the command line (one of them runs whole
# jobs with the host built under ASan+UBSan, build/gradus-asan). Each test prints
# "PASS name" or "FAIL name: why"; a test program that crashes or exits
# non-zero without a FAIL line counts as one failure. Last line:
# "N passed, M failed".
cd "$(dirname "$0")/.." || exit 1
export GRADUS=$PWD/build/gradus
export GRADUS_CACHE_DIR=$(mktemp -d)
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp" "$GRADUS_CACHE_DIR"' EXIT
pass=0; fail=0
run() { # label, command...
  local label=$1; shift
  local log="$tmp/log" t0=$(date +%s%N)
  "$@" >"$log" 2>&1
  local rc=$?
  local p f
  p=$(grep -c '^PASS ' "$log"); f=$(grep -c '^FAIL ' "$log")
  grep -E '^(FAIL|    )' "$log"
  if [ "$rc" != 0 ] && [ "$f" = 0 ]; then
    echo "FAIL $label: exit status $rc"; tail -n 20 "$log" | sed 's/^/    /'; f=1
  fi
  local ms=$((($(date +%s%N) - t0) / 1000000))
  echo "$label: $p passed, $f failed ($((ms / 1000)).$(printf %03d $((ms % 1000))) s)"
  pass=$((pass + p)); fail=$((fail + f))
}
for t in build/tests/test_*; do [ -x "$t" ] && run "$t" "$t"; done
for t in build/asan/tests/test_*; do [ -x "$t" ] && run "$t" "$t"; done
for t in tests/lua/test_*.lua; do [ -f "$t" ] && run "$t" "$GRADUS" run "$t"; done
for t in tests/sh/test_*.sh; do [ -f "$t" ] && run "$t" bash "$t"; done
echo "$pass passed, $fail failed"
[ "$fail" = 0 ]
