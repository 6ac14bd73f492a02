#!/usr/bin/env bash
# Runs every benchmark: bench/bench_*.c (C programs) and bench/bench_*.lua
# (recipes run through the gradus host). Prints the machine first.
cd "$(dirname "$0")/.." || exit 1
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(free -g | awk '/Mem:/{print $2}') GiB"
for c in bench/bench_*.c; do
  [ -f "$c" ] || continue
  b=build/bench/$(basename "$c" .c)
  make -s "$b" && "$b"
done
for l in bench/bench_*.lua; do
  [ -f "$l" ] && ./build/gradus run "$l"
done
