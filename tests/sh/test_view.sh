#!/usr/bin/env bash
# gradus view: the self-contained page (checked in headless Chromium against
# the CLI reader by tests/lua/view_check.lua), the served mode (layers over
# HTTP on a port the system picks, 404 out of range, Ctrl-C), and bad input
# (truncated or non-CLI file: an error and no HTML). The server is killed by
# its pid whatever happens; Chromium runs under timeout(1), which kills its
# whole process group.
G=${GRADUS:-build/gradus}
d=$(mktemp -d)
spid=""
cleanup() { [ -n "$spid" ] && kill -KILL "$spid" 2>/dev/null; rm -rf "$d"; }
trap cleanup EXIT
pass() { echo "PASS test_view: $1"; }
fail() { echo "FAIL test_view: $1: $2"; }
expect() { # name, pattern, text
  if printf '%s' "$3" | grep -qE -- "$2"; then pass "$1"; else fail "$1" "wanted /$2/ in: $3"; fi
}

# two small jobs: binary with two lasers (the page), ASCII with one (served)
$G run recipes/lattice.lua -D cells=2,2,1 -D lasers=2 -D kb=off -D layer=0.25 -D format=binary \
  -o "$d/two.cli" --stats "$d/two.yaml" -q >/dev/null 2>&1 || fail "job" "the two-laser job failed"
$G run recipes/lattice.lua -D cells=2,1,1 -D kb=off -D layer=0.4 -D format=ascii -o "$d/asc.cli" -q >/dev/null 2>&1 ||
  fail "job" "the ASCII job failed"

out=$($G view "$d/two.cli" -o "$d/two.html" 2>&1); rc=$?
expect "view writes the page" "-> $d/two.html" "$out"; [ $rc = 0 ] && pass "view exit 0" || fail "view exit 0" "rc=$rc"
ext=$(grep -oE '(src|href)="?(https?:)?//[^" >]*' "$d/two.html" | head -3)
[ -z "$ext" ] && pass "page loads nothing from the network" || fail "page loads nothing from the network" "$ext"
grep -q '"manifest":{' "$d/two.html" && grep -q '"stats":{' "$d/two.html" && pass "manifest and stats in the page" ||
  fail "manifest and stats in the page" "not found"

# bad input: an error naming the problem, no HTML left behind
size=$(stat -c %s "$d/two.cli"); head -c $((size - 7)) "$d/two.cli" > "$d/cut.cli"
out=$($G view "$d/cut.cli" -o "$d/cut.html" 2>&1); rc=$?
expect "truncated file names the byte" "cut.cli: byte [0-9]+: .*(truncated|past the end)" "$out"
[ $rc != 0 ] && [ ! -e "$d/cut.html" ] && pass "truncated: exit non-zero, no HTML" || fail "truncated: no HTML" "rc=$rc"
printf 'solid x\nendsolid x\n' > "$d/not.cli"
out=$($G view "$d/not.cli" -o "$d/not.html" 2>&1); rc=$?
expect "non-CLI file refused" "not.cli:1: not a CLI file" "$out"
[ $rc != 0 ] && [ ! -e "$d/not.html" ] && pass "non-CLI: exit non-zero, no HTML" || fail "non-CLI: no HTML" "rc=$rc"
out=$($G view "$d/none.cli" 2>&1); rc=$?
expect "missing file" "cannot read $d/none.cli" "$out"; [ $rc != 0 ] && pass "missing: exit non-zero" || fail "missing" "rc=$rc"
case "$out" in *.lua:*) fail "missing file: no source position" "$out" ;; *) pass "missing file: no source position in the message" ;; esac
out=$($G view "$d/two.cli" --frob 2>&1); rc=$?
expect "unknown option" "unknown option --frob" "$out"; [ $rc = 2 ] && pass "bad option exit 2" || fail "bad option" "rc=$rc"

# served mode on a port the system picks
$G view "$d/asc.cli" --serve --port 0 > "$d/serve.log" 2>&1 &
spid=$!
url=""
for _ in $(seq 1 600); do
  url=$(grep -oE 'http://127\.0\.0\.1:[0-9]+/' "$d/serve.log" | head -1)
  [ -n "$url" ] || ! kill -0 "$spid" 2>/dev/null && break
  sleep 0.1
done
if [ -z "$url" ]; then
  fail "server starts" "$(cat "$d/serve.log")"
else
  pass "server prints its URL"
  n=$(grep -c '^\$\$LAYER/' "$d/asc.cli")
  code=$(curl -s --max-time 60 -o "$d/l2.bin" -w '%{http_code}' "${url}layer/2")
  [ "$code" = 200 ] && pass "layer 2 answered" || fail "layer 2 answered" "HTTP $code"
  $G run tests/lua/view_check.lua -D mode=served_layer -D cli="$d/asc.cli" -D blob="$d/l2.bin" -D layer=2
  for k in 0 $((n + 1)) abc; do
    body=$(curl -s --max-time 60 -o "$d/oor.txt" -w '%{http_code}' "${url}layer/$k"; echo " $(cat "$d/oor.txt")")
    expect "layer $k: 404 naming the range" "^404 layer $k is out of range: .*asc.cli has $n layers \(1\.\.$n\)" "$body"
  done
  code=$(curl -s --max-time 60 -o "$d/index.html" -w '%{http_code}' "$url")
  [ "$code" = 200 ] && grep -q '"served":true' "$d/index.html" && pass "page served at /" || fail "page served at /" "HTTP $code"
fi

# the pages in Chromium (embedded and served)
$G run tests/lua/view_check.lua -D mode=browser -D cli="$d/two.cli" -D html="$d/two.html" -D dir="$d" \
  -D url="$url" -D served_cli="$d/asc.cli"

if [ -n "$spid" ]; then
  kill -INT "$spid"
  for _ in $(seq 1 300); do kill -0 "$spid" 2>/dev/null || break; sleep 0.1; done
  if kill -0 "$spid" 2>/dev/null; then
    fail "Ctrl-C ends the server" "still running"
  else
    wait "$spid"; rc=$?
    spid=""
    [ $rc = 0 ] && grep -q "stopped" "$d/serve.log" && pass "Ctrl-C ends the server cleanly" ||
      fail "Ctrl-C ends the server cleanly" "rc=$rc: $(cat "$d/serve.log")"
  fi
fi
