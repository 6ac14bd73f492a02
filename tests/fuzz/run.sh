#!/usr/bin/env bash
# Runs the libFuzzer harnesses (built by `make fuzz-build` into build/fuzz/).
#   tests/fuzz/run.sh SECONDS NAME...   fuzz each NAME for SECONDS on its seed
#       corpus tests/fuzz/NAME/; new inputs are kept in build/fuzz/corpus/NAME/,
#       crashes in build/fuzz/crash-NAME-*; prints executions and coverage.
#   tests/fuzz/run.sh --replay RUNS NAME...   replay the seeds and mutate them
#       for a fixed number of runs with a fixed seed (what `make test` does);
#       prints "PASS fuzz NAME" or "FAIL fuzz NAME: why".
cd "$(dirname "$0")/../.." || exit 1
mode=fuzz
if [ "$1" = --replay ]; then mode=replay; shift; fi
amount=$1; shift
# unbounded allocations count as findings: a 1 MiB input never needs 512 MiB
opts=(-rss_limit_mb=1536 -malloc_limit_mb=512 -timeout=20 -max_len=65536)
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
fails=0
for name in "$@"; do
  exe=build/fuzz/fuzz_$name
  if [ ! -x "$exe" ]; then echo "FAIL fuzz $name: $exe not built (make fuzz-build)"; fails=$((fails + 1)); continue; fi
  if [ "$mode" = replay ]; then
    tmp=$(mktemp -d)
    "$exe" "${opts[@]}" -seed=1 -runs="$amount" -artifact_prefix="$tmp/" "$tmp" "tests/fuzz/$name" >"$tmp/log" 2>&1
    rc=$?
    if [ $rc = 0 ]; then
      echo "PASS fuzz $name: $(grep -o 'Done [0-9]* runs' "$tmp/log" | head -1), $(grep -c . <(ls "tests/fuzz/$name")) seeds"
    else
      echo "FAIL fuzz $name: exit $rc"; grep -E 'ERROR|SUMMARY|runtime error' "$tmp/log" | head -5 | sed 's/^/    /'
      fails=$((fails + 1))
    fi
    rm -rf "$tmp"
  else
    mkdir -p "build/fuzz/corpus/$name"
    log=build/fuzz/$name.log
    echo "fuzz $name: $amount s (log $log)"
    "$exe" "${opts[@]}" -max_total_time="$amount" -print_final_stats=1 -artifact_prefix="build/fuzz/crash-$name-" \
      "build/fuzz/corpus/$name" "tests/fuzz/$name" >"$log" 2>&1
    rc=$?
    grep -E '^stat::number_of_executed_units|^stat::peak_rss_mb' "$log" | sed "s/^/  $name /"
    grep -E '#[0-9]+[[:space:]]+(DONE|pulse|NEW|REDUCE).*cov:' "$log" | tail -1 | sed "s/^/  $name last: /"
    if [ $rc != 0 ]; then echo "  $name: FOUND a crash (exit $rc), see $log and build/fuzz/crash-$name-*"; fails=$((fails + 1)); fi
  fi
done
exit $((fails > 0))
