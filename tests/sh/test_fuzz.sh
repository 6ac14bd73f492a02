#!/usr/bin/env bash
# The libFuzzer harnesses replay their seed corpora (tests/fuzz/NAME/, which
# hold every crasher found so far) and mutate them for a fixed number of runs
# with a fixed seed: a regression check, not a search (`make fuzz` searches).
cd "$(dirname "$0")/../.." || exit 1
names=$(ls tests/fuzz/fuzz_*.c | sed 's|.*/fuzz_||; s|\.c$||')
if ! ls build/fuzz/fuzz_* >/dev/null 2>&1; then
  if ! command -v clang >/dev/null 2>&1; then
    echo "SKIP fuzz: clang is not installed (apt-get install clang libclang-rt-14-dev, or make deps)"
    exit 0
  fi
  make -s fuzz-build >/dev/null || { echo "FAIL fuzz: make fuzz-build failed"; exit 1; }
fi
bash tests/fuzz/run.sh --replay 5000 $names
