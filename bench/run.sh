#!/usr/bin/env bash
# Runs every benchmark: bench/bench_*.c (C programs) and bench/bench_*.lua
# (recipes run through the gradus host). Prints the machine first.
cd "$(dirname "$0")/.." || exit 1
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(free -g | awk '/Mem:/{print $2}') GiB"
failed=""
for c in bench/bench_*.c; do
  [ -f "$c" ] || continue
  b=build/bench/$(basename "$c" .c)
  make -s "$b" && "$b" || failed="$failed $c"
done
for l in bench/bench_*.lua; do
  [ -f "$l" ] && { ./build/gradus run "$l" || failed="$failed $l"; }
done
# a benchmark that did not build or run is an error, not a silent gap in the figures
if [ -n "$failed" ]; then echo "benchmarks failed:$failed" >&2; exit 1; fi
