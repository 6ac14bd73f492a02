#!/usr/bin/env bash
# gradus on a real one-node Slurm cluster started here (tests/slurm/cluster.sh:
# munged, slurmctld, slurmd with their own key, ports, state and logs in a
# temporary directory, stopped by pid whatever happens): a 2 x 2 sweep gives
# the rows of a local sweep; a 4-range split job merges into the CLI of a
# local run, byte for byte; a task cancelled on purpose is reported with
# its log, and the rerun submits only that one. Also: --slurm without Slurm
# says how to install it.
G=${GRADUS:-build/gradus}
case $G in /*) ;; *) G=$PWD/$G ;; esac
T="timeout -k 10 600" # a stuck queue fails the test instead of hanging it
here=$(cd "$(dirname "$0")/.." && pwd)
d=$(mktemp -d /tmp/gradus-slurm.XXXXXX)
# same bytes but the $$DATE digits (the files may be written either side of midnight)
same() { [ -s "$1" ] && [ -s "$2" ] && cmp -s <(LC_ALL=C sed '1,20s/^\$\$DATE\/[0-9]*$/$$DATE\/0/' "$1") <(LC_ALL=C sed '1,20s/^\$\$DATE\/[0-9]*$/$$DATE\/0/' "$2"); }
pass() { echo "PASS test_slurm: $1"; }
fail() { echo "FAIL test_slurm: $1: $2"; }
. "$here/slurm/cluster.sh"
cleanup() { touch "$d/h.release"; cluster_stop; rm -rf "$d"; }
trap cleanup EXIT
trap 'exit 1' INT TERM HUP
cd "$here/.." || exit 1

# without Slurm: says so and how to install it, submits nothing
out=$(PATH=/nonexistent "$G" run recipes/lattice.lua -o "$d/none.cli" --slurm 2 2>&1); rc=$?
[ $rc = 1 ] && echo "$out" | grep -q "apt-get install slurm-wlm munge" && [ ! -e "$d/none.parts" ] &&
  pass "--slurm without Slurm says how to install it" || fail "--slurm without Slurm" "rc=$rc: $out"

if ! cluster_start "$d/cluster" 2>"$d/why"; then
  fail "a one-node Slurm cluster starts" "$(tr '\n' ' ' < "$d/why" | cut -c1-1500)"
  exit 1
fi
pass "a one-node Slurm cluster starts ($(sinfo -h -o '%P %D %T'))"

# a 2 x 2 sweep: the same rows as a local sweep (all but the seconds column)
SW=(recipes/lattice.lua -D cells=1,1,1 -D res=12 -D layer=0.1 -D thickness=0.1,0.12 -D hatch=0.05,0.06 -D kb="$d/kb")
"$G" sweep "${SW[@]}" -o "$d/local" -q >"$d/local.out" 2>&1
out=$($T "$G" sweep "${SW[@]}" -o "$d/slurm" --slurm -q 2>&1); rc=$?
[ $rc = 0 ] && echo "$out" | grep -q "submitted job" && [ -s "$d/slurm/sweep.sbatch" ] &&
  pass "sweep through sbatch (script kept beside the results)" || fail "sweep through sbatch" "rc=$rc: $out"
nosec() { sed -E 's/,[^,]*,[^,]*$//' "$1"; } # all but the last two columns (seconds, error)
if [ "$(nosec "$d/local/sweep.csv")" = "$(nosec "$d/slurm/sweep.csv")" ] && [ "$(grep -c ',ok,' "$d/slurm/sweep.csv")" = 4 ]; then
  pass "Slurm sweep CSV rows = local sweep's (4 ok)"
else
  fail "Slurm sweep CSV rows = local" "$(diff <(nosec "$d/local/sweep.csv") <(nosec "$d/slurm/sweep.csv") | head -5)"
fi
for n in 1 2 3 4; do same "$d/local/run00$n.cli" "$d/slurm/run00$n.cli" || { fail "sweep CLI $n = local" "differs"; n=x; break; }; done
[ "$n" = 4 ] && pass "the 4 CLI files = the local sweep's"

# a 4-range split job: byte-identical to a local run, stats added up
RUN=(recipes/lattice.lua -D cells=1,1,2 -D res=12 -D layer=0.1 -D kb="$d/kb2")
"$G" run "${RUN[@]}" -q -o "$d/one.cli" --stats "$d/one.yaml" -D kb="$d/kb3" >/dev/null 2>&1
out=$($T "$G" run "${RUN[@]}" -q -o "$d/split.cli" --stats "$d/split.yaml" --slurm 4 2>&1); rc=$?
[ $rc = 0 ] && [ "$(ls "$d"/split.parts/part0?.cli 2>/dev/null | wc -l)" = 4 ] && pass "split job: templates stage + 4 layer tasks" ||
  fail "split job" "rc=$rc: $out"
same "$d/one.cli" "$d/split.cli" && pass "merged CLI = one local run, byte for byte" ||
  fail "merged CLI = one local run" "$(cmp "$d/one.cli" "$d/split.cli" 2>&1)"
grep -q "1 built" "$d/split.parts/templates.log" && grep -q "reused: 1" "$d/split.parts/part03.yaml" &&
  pass "templates built once, read by the layer tasks" || fail "templates built once" "$(cat "$d/split.parts/templates.log")"
[ -s "$d/split.manifest.yaml" ] && diff <(grep -v '^cli:' "$d/one.manifest.yaml") <(grep -v '^cli:' "$d/split.manifest.yaml") >/dev/null &&
  pass "merged manifest = local run's" || fail "merged manifest" "$(diff "$d/one.manifest.yaml" "$d/split.manifest.yaml" 2>&1 | head -5)"
yget() { echo "print(gradus.yaml.load('$1').$2)" | "$G" 2>&1 | tail -n 1; }
for k in layers vectors.hatch.count jumps.count; do
  a=$(yget "$d/split.yaml" $k); b=$(yget "$d/one.yaml" $k)
  [ -n "$a" ] && [ "$a" = "$b" ] && pass "split stats $k = local ($a)" || fail "split stats $k" "$a vs $b"
done
# a lost part: the rerun submits only it
rm -f "$d/split.parts/part02."* "$d/split.cli"
out=$($T "$G" run "${RUN[@]}" -q -o "$d/split.cli" --slurm 4 2>&1); rc=$?
[ $rc = 0 ] && echo "$out" | grep -q "3 of 4 parts finished earlier" && echo "$out" | grep -q "layers --array=2 of 4" &&
  ! echo "$out" | grep -q "templates (" && same "$d/one.cli" "$d/split.cli" &&
  pass "split rerun submits only the missing part" || fail "split rerun" "rc=$rc: $out"

# a task cancelled on purpose: reported with its log; the rerun runs only it
cat > "$d/hang.lua" <<'L'
local a = gradus.param("a", 1.0)
local b = gradus.param("b", 1.0)
local hang = gradus.param("hang", "")
if a == 2 and b == 2 and hang ~= "" then
  io.open(hang .. ".running", "w"):close()
  while not io.open(hang .. ".release") do os.execute("sleep 0.2") end
end
gradus.write_stats({ relative_density = a * b, build_time_s = a + b, seconds = { total = 0 } })
L
K=("$d/hang.lua" -D a=1,2 -D b=1,2 -D hang="$d/h" -o "$d/kill" --slurm -q)
$T "$G" sweep "${K[@]}" >"$d/kill.out" 2>&1 &
sp=$!
cluster_wait "[ -e '$d/h.running' ]" 1200
job=$(squeue -h -r -o '%i %j' | awk '$2=="gradus-sweep"{print $1}' | grep '_4$')
# the same command again while that job is in the queue: it waits for it, never runs a task twice
# (its resubmission may truncate run004.log before the first command reads Slurm's CANCELLED line
# there: then the first one says "no exit status")
$T "$G" sweep "${K[@]}" >"$d/again.out" 2>&1 &
sp2=$!
cluster_wait "grep -q 'still in the queue' '$d/again.out'" 1200
if [ -n "$job" ]; then scancel "$job"; fi
wait $sp; rc=$?
out=$(cat "$d/kill.out")
[ -n "$job" ] && [ $rc = 1 ] && echo "$out" | grep -Eq "sweep: failed run 4 \(a=2 b=2\): (.*JOB ${job%_*}.* CANCELLED|no exit status)" &&
  echo "$out" | grep -qF "log $d/kill/run004.log" && pass "cancelled task reported with its log, exit 1" ||
  fail "cancelled task reported" "job=$job rc=$rc: $out"
[ "$(grep -c ',ok,' "$d/kill/sweep.csv")" = 3 ] && pass "the other 3 collected" || fail "the other 3 collected" "$(cat "$d/kill/sweep.csv")"
touch "$d/h.release"
wait $sp2; rc=$?
out=$(cat "$d/again.out")
[ $rc = 0 ] && echo "$out" | grep -q "job ${job%_*} from an earlier submission is still in the queue" &&
  echo "$out" | grep -q "3 of 4 combinations finished earlier; submitting 1" && echo "$out" | grep -q -- "--array=4$" &&
  [ "$(grep -c ',ok,' "$d/kill/sweep.csv")" = 4 ] && pass "rerun waits for the queued job, submits only the cancelled one, then 4 ok" ||
  fail "rerun submits only the cancelled one" "rc=$rc: $out"
out=$($T "$G" sweep "${K[@]}" 2>&1); rc=$?
[ $rc = 0 ] && echo "$out" | grep -q "4 of 4 combinations finished earlier; submitting 0" && ! echo "$out" | grep -q "still in the queue" &&
  pass "a third run submits nothing" || fail "a third run submits nothing" "rc=$rc: $out"
