#!/usr/bin/env bash
# A real one-node Slurm cluster on localhost for the tests, started by hand:
#   . tests/slurm/cluster.sh; cluster_start DIR || exit; ...; cluster_stop
# munged, slurmctld and slurmd run in the foreground (in the background of
# this shell) with their own key, socket, state, spool and logs under DIR,
# on free ports chosen now; their pids are recorded, and cluster_stop stops
# exactly those pids. Exports SLURM_CONF so sbatch/squeue/scancel find it.
# On failure cluster_start prints why (the daemons' logs) and returns 1.
CLUSTER_PIDS=()
CLUSTER_DIR=

# a TCP port nobody listens on (checked with ss, else by connecting)
cluster_free_port() {
  local p tries=0
  while [ $tries -lt 200 ]; do
    p=$((20000 + RANDOM % 40000)); tries=$((tries + 1))
    if command -v ss >/dev/null; then
      ss -Htan 2>/dev/null | awk '{print $4}' | grep -q "[:.]$p\$" && continue
    elif (exec 3<>/dev/tcp/127.0.0.1/$p) 2>/dev/null; then continue; fi
    case " ${CLUSTER_PORTS:-} " in *" $p "*) continue ;; esac
    CLUSTER_PORTS="${CLUSTER_PORTS:-} $p"
    echo $p; return 0
  done
  return 1
}

cluster_why() {
  echo "cluster: $1" >&2
  local f
  for f in "$CLUSTER_DIR"/log/*.log; do
    [ -s "$f" ] && { echo "--- $f (last lines)" >&2; tail -n 15 "$f" >&2; }
  done
}

# wait up to $2 tenths of a second for command $1 to succeed
cluster_wait() {
  local i=0
  while [ $i -lt "$2" ]; do eval "$1" >/dev/null 2>&1 && return 0; sleep 0.1; i=$((i + 1)); done
  return 1
}

cluster_start() {
  CLUSTER_DIR=$1
  local d=$1 host cpus mem tmpl
  tmpl="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/slurm.conf.in"
  for x in munged slurmctld slurmd sbatch squeue scontrol; do
    command -v $x >/dev/null || { echo "cluster: $x not found (apt-get install slurm-wlm munge)" >&2; return 1; }
  done
  mkdir -p "$d/munge" "$d/state" "$d/spool" "$d/log" || return 1
  chmod 700 "$d" "$d/munge"
  host=$(hostname -s); cpus=$(nproc); mem=$(awk '/MemTotal/{print int($2/1024/2)}' /proc/meminfo)
  # munge: a fresh random key of our own, our own socket
  dd if=/dev/urandom of="$d/munge/munge.key" bs=1024 count=1 2>/dev/null && chmod 400 "$d/munge/munge.key"
  munged --foreground --force --socket="$d/munge/munge.socket" --key-file="$d/munge/munge.key" \
    --log-file="$d/log/munged.log" --pid-file="$d/munge/munged.pid" --seed-file="$d/munge/munged.seed" \
    >>"$d/log/munged.log" 2>&1 &
  CLUSTER_PIDS+=($!)
  cluster_wait "[ -S '$d/munge/munge.socket' ]" 100 || { cluster_why "munged did not start"; return 1; }
  local cp sp
  cp=$(cluster_free_port) && sp=$(cluster_free_port) || { cluster_why "no free port"; return 1; }
  sed -e "s|@DIR@|$d|g" -e "s|@HOST@|$host|g" -e "s|@CTLD_PORT@|$cp|g" -e "s|@SLURMD_PORT@|$sp|g" \
    -e "s|@CPUS@|$cpus|g" -e "s|@MEM@|$mem|g" "$tmpl" > "$d/slurm.conf"
  export SLURM_CONF="$d/slurm.conf"
  slurmctld -D -i -f "$SLURM_CONF" >>"$d/log/slurmctld.out" 2>&1 &
  CLUSTER_PIDS+=($!)
  cluster_wait "scontrol ping | grep -q UP" 600 || { cluster_why "slurmctld does not answer"; return 1; }
  slurmd -D -N gradus1 -f "$SLURM_CONF" >>"$d/log/slurmd.out" 2>&1 &
  CLUSTER_PIDS+=($!)
  cluster_wait "sinfo -h -N -o %T | grep -Eq '^(idle|mixed|allocated)'" 900 ||
    { sinfo -N >&2; cluster_why "the node did not come up"; return 1; }
  return 0
}

# stop the daemons this shell started, by pid, newest first
cluster_stop() {
  local i pid
  # first the jobs still there (ours: SLURM_CONF is this cluster's), so no task outlives it
  if [ ${#CLUSTER_PIDS[@]} -gt 0 ] && [ -n "${SLURM_CONF:-}" ]; then
    scancel -u "$(id -un)" >/dev/null 2>&1
    cluster_wait "[ -z \"\$(squeue -h -o %i 2>/dev/null)\" ]" 100
  fi
  for ((i = ${#CLUSTER_PIDS[@]} - 1; i >= 0; i--)); do
    pid=${CLUSTER_PIDS[$i]}
    kill -TERM "$pid" 2>/dev/null
    for _ in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20; do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
    kill -KILL "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
  done
  CLUSTER_PIDS=()
}
