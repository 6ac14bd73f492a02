#!/usr/bin/env bash
# Runs every test: C tests (plain and under ASan+UBSan), Lua tests through the
# gradus host, and shell tests of the command line (one of them runs whole
# jobs with the host built under ASan+UBSan, build/gradus-asan). Each test prints
# "PASS name" or "FAIL name: why"; a test program that crashes or exits
# non-zero without a FAIL line counts as one failure. Last line:
# "N passed, M failed".
# Tests run TEST_JOBS at a time (default: the number of CPUs, at most 4), each
# with its own knowledge-base cache directory so that no test sees another's
# templates; results are printed in the order of the list below.
cd "$(dirname "$0")/.." || exit 1
export GRADUS=$PWD/build/gradus
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
jobs_max=${TEST_JOBS:-$(nproc 2>/dev/null || echo 1)}
[[ "$jobs_max" =~ ^[1-9][0-9]*$ ]] || { echo "TEST_JOBS must be a positive integer, got '$jobs_max'" >&2; exit 2; }
[ "$jobs_max" -gt 4 ] && [ -z "$TEST_JOBS" ] && jobs_max=4
tmp=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; wait; rm -rf "$tmp"' EXIT

# the tests: label, a tab and the command (shell-quoted), one per entry
tests=()
add() { local label=$1; shift; tests+=("$label	$(printf '%q ' "$@")"); }
for t in build/tests/test_*; do [ -x "$t" ] && add "$t" "$t"; done
for t in build/asan/tests/test_*; do [ -x "$t" ] && add "$t" "$t"; done
for t in tests/lua/test_*.lua; do [ -f "$t" ] && add "$t" "$GRADUS" run "$t"; done
for t in tests/sh/test_*.sh; do [ -f "$t" ] && add "$t" bash "$t"; done

# run test i: its report lines to $tmp/out.i, "passed failed" to $tmp/n.i
run_one() {
  local i=$1 label=${tests[$1]%%	*} cmd=${tests[$1]#*	}
  local log="$tmp/log.$i" t0=$(date +%s%N) cache="$tmp/cache.$i"
  mkdir -p "$cache"
  (export GRADUS_CACHE_DIR=$cache; eval "$cmd") >"$log" 2>&1
  local rc=$? p f
  p=$(grep -c '^PASS ' "$log"); f=$(grep -c '^FAIL ' "$log")
  {
    grep -E '^(FAIL|    )' "$log"
    if [ "$rc" != 0 ] && [ "$f" = 0 ]; then
      echo "FAIL $label: exit status $rc"; tail -n 20 "$log" | sed 's/^/    /'; f=1
    fi
    local ms=$((($(date +%s%N) - t0) / 1000000))
    echo "$label: $p passed, $f failed ($((ms / 1000)).$(printf %03d $((ms % 1000))) s)"
  } >"$tmp/out.$i"
  rm -rf "$cache" "$log"
  echo "$p $f" >"$tmp/n.$i"
}

n=${#tests[@]} next=0 shown=0 running=0 pass=0 fail=0
while [ "$shown" -lt "$n" ]; do
  while [ "$running" -lt "$jobs_max" ] && [ "$next" -lt "$n" ]; do
    run_one "$next" &
    next=$((next + 1)) running=$((running + 1))
  done
  wait -n
  running=$((running - 1))
  # print finished tests in list order
  while [ "$shown" -lt "$n" ] && [ -f "$tmp/n.$shown" ]; do
    cat "$tmp/out.$shown"
    read -r p f <"$tmp/n.$shown"
    pass=$((pass + p)) fail=$((fail + f))
    shown=$((shown + 1))
  done
done
echo "$pass passed, $fail failed"
[ "$fail" = 0 ]
