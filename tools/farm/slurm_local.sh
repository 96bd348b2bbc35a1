#!/usr/bin/env bash
# A throwaway single-node Slurm on this machine, to try the array recipe
# (tools/farm/slurm_array.sh, docs/farm.md) under a real scheduler.
#
#   bash tools/farm/slurm_local.sh start   # installs slurm-wlm and munge if missing
#   export SLURM_CONF=/tmp/pathdensity-slurm/slurm.conf   # printed by start
#   sbatch --array=0-3 tools/farm/slurm_array.sh 'shots/*.pds' out
#   bash tools/farm/slurm_local.sh stop    # kills its daemons, removes its state
#
# Everything lives in PATHDENSITY_SLURM_DIR (default /tmp/pathdensity-slurm):
# slurm.conf, a munge key and socket, state, spool, logs, pid files. Its own
# munged (on its own socket), slurmctld and slurmd run as root (directly or
# through `sudo -n`), on ports 16817/16818. It refuses to start when a
# slurmctld it did not start is running. Both commands are idempotent.
# Debian/Ubuntu (apt-get) only for the install; PATHDENSITY_SLURM_INSTALL=0
# fails instead of installing.
set -euo pipefail
# The daemons are in /usr/sbin, off a Debian user's PATH.
export PATH=$PATH:/usr/sbin:/sbin
dir=${PATHDENSITY_SLURM_DIR:-/tmp/pathdensity-slurm}
timeout=${PATHDENSITY_SLURM_TIMEOUT:-60}
conf=$dir/slurm.conf

die() {
  echo "slurm_local.sh: $*" >&2
  exit 1
}

if [ "$(id -u)" -eq 0 ]; then
  as_root() { "$@"; }
elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
  as_root() { sudo -n "$@"; }
else
  as_root() { die "needs root or password-less sudo"; }
fi

# The pid in $dir/NAME.pid if that process is alive (/proc: kill -0 fails
# on root's processes for a user).
ours() {
  local pid
  pid=$(cat "$dir/$1.pid" 2>/dev/null) || return 1
  [ -n "$pid" ] && [ -d "/proc/$pid" ] && echo "$pid"
}

stop() {
  local name pid
  for name in slurmd slurmctld munged; do
    if pid=$(ours "$name"); then
      as_root kill "$pid" 2>/dev/null || true
      for _ in $(seq 50); do
        [ -d "/proc/$pid" ] || break
        sleep 0.1
      done
      as_root kill -KILL "$pid" 2>/dev/null || true
    fi
  done
  if [ -d "$dir" ]; then
    as_root rm -rf "$dir"
  fi
}

install() {
  if command -v slurmctld >/dev/null && command -v slurmd >/dev/null &&
    command -v sbatch >/dev/null && command -v munged >/dev/null; then
    return
  fi
  [ "${PATHDENSITY_SLURM_INSTALL:-1}" != 0 ] || die "slurm-wlm and munge are not installed (and PATHDENSITY_SLURM_INSTALL=0)"
  command -v apt-get >/dev/null || die "slurm-wlm and munge are missing and there is no apt-get"
  local t0=$SECONDS
  as_root apt-get update -q >/dev/null
  # Under systemd the packages' own services need /etc/slurm/slurm.conf
  # and do not start; a system munged on its default socket is left alone.
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q slurm-wlm munge >/dev/null ||
    die "apt-get install slurm-wlm munge failed"
  echo "installed slurm-wlm munge in $((SECONDS - t0)) s"
}

start() {
  if ours slurmctld >/dev/null && ours slurmd >/dev/null && ours munged >/dev/null; then
    echo "already running; export SLURM_CONF=$conf"
    return
  fi
  # A half-started or dead instance of ours: clear it first.
  stop
  if pgrep -x slurmctld >/dev/null; then
    die "a slurmctld is already running (not started by this script); refusing to touch it"
  fi
  install
  local t0=$SECONDS host cpus mem user
  host=$(hostname -s)
  user=root
  as_root mkdir -p "$dir"/{state,spool,munge}
  as_root chmod 755 "$dir"
  as_root chmod 700 "$dir/munge"
  # One node as slurmd sees it: CPUs, sockets, cores, threads, memory.
  local node
  node=$(as_root slurmd -C | head -n 1) || die "slurmd -C failed"
  node=${node/NodeName=* CPUs/NodeName=$host CPUs}
  as_root dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  as_root chmod 400 "$dir/munge/munge.key"
  as_root munged --force \
    --key-file="$dir/munge/munge.key" \
    --socket="$dir/munge/munge.socket" \
    --pid-file="$dir/munged.pid" \
    --log-file="$dir/munged.log" \
    --seed-file="$dir/munge/munge.seed" ||
    die "munged did not start (see $dir/munged.log)"
  as_root chmod 755 "$dir/munge"
  as_root tee "$conf" >/dev/null <<EOF
# Written by tools/farm/slurm_local.sh: one node, no accounting, no cgroups.
ClusterName=pathdensity
SlurmctldHost=$host
SlurmctldPort=16817
SlurmdPort=16818
SlurmUser=$user
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
# cred_expire: a requeued job waits this long (default 120 s) to start again.
AuthInfo=cred_expire=10,socket=$dir/munge/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool/%n
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
JobRequeue=1
KillWait=5
MinJobAge=600
$node State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
  export SLURM_CONF=$conf
  as_root env SLURM_CONF="$conf" slurmctld || die "slurmctld did not start (see $dir/slurmctld.log)"
  as_root env SLURM_CONF="$conf" slurmd || die "slurmd did not start (see $dir/slurmd.log)"
  local state=""
  while [ $((SECONDS - t0)) -lt "$timeout" ]; do
    state=$(sinfo -h -n "$host" -o %T 2>/dev/null || true)
    [ "$state" = idle ] && break
    sleep 0.5
  done
  if [ "$state" != idle ]; then
    echo "slurm_local.sh: node $host is '${state:-not answering}', not idle, after $timeout s; last log lines:" >&2
    tail -n 5 "$dir/slurmctld.log" "$dir/slurmd.log" >&2 || true
    exit 1
  fi
  echo "started in $((SECONDS - t0)) s: node $host idle; export SLURM_CONF=$conf"
}

case ${1:-} in
  start) start ;;
  stop) stop ;;
  *)
    echo "usage: bash tools/farm/slurm_local.sh start|stop" >&2
    exit 2
    ;;
esac
