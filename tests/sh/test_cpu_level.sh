#!/usr/bin/env bash
# The vector unit a build is made for (Makefile: ARCH, x86-64-v3 where the
# building machine has it): on an older processor, emulated by qemu-user
# (Westmere: SSE4.2, no AVX), such a build stops with a clear message and
# exit status 1, writing nothing, instead of dying of an illegal
# instruction; on a processor that has x86-64-v3 (Haswell) it starts.
G=${GRADUS:-build/gradus}
d=$(mktemp -d); trap 'rm -rf "$d"' EXIT
pass() { echo "PASS test_cpu_level: $1"; }
fail() { echo "FAIL test_cpu_level: $1: $2"; }
Q=$(command -v qemu-x86_64)
if [ "$(uname -m)" != x86_64 ] || [ -z "$Q" ]; then fail "qemu-user" "qemu-x86_64 missing (make deps installs qemu-user)"; exit 0; fi
v3=0; grep -q -- '-march=x86-64-v3' build/flags 2>/dev/null && v3=1
if [ $v3 = 1 ]; then
  out=$("$Q" -cpu Westmere "$G" run recipes/lattice.lua -D cells=1,1,1 -D layers=1:2 -D kb=off -q -o "$d/old.cli" 2>&1); rc=$?
  [ $rc = 1 ] && pass "x86-64-v3 build on an older processor: exit 1" || fail "exit 1 on an older processor" "rc=$rc: $out"
  echo "$out" | grep -q 'x86-64-v3 instructions (AVX2, FMA, BMI2), which this processor lacks' && echo "$out" | grep -q 'make ARCH=' \
    && pass "the message names the instructions and the rebuild" || fail "message" "$out"
  [ ! -e "$d/old.cli" ] && pass "nothing written" || fail "nothing written" "$(ls "$d")"
else
  out=$("$Q" -cpu Westmere "$G" --version 2>&1); rc=$?
  [ $rc = 0 ] && echo "$out" | grep -q '^gradus' && pass "a plain x86-64 build starts on an older processor" || fail "plain build on an older processor" "rc=$rc: $out"
fi
out=$("$Q" -cpu Haswell "$G" --version 2>&1); rc=$?
[ $rc = 0 ] && echo "$out" | grep -q '^gradus' && pass "starts on a processor with x86-64-v3" || fail "starts on Haswell" "rc=$rc: $out"
