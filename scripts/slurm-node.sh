#!/usr/bin/env bash
# A private single-node Slurm cluster in one directory, for the Slurm launcher's tests
# (and for trying `fulcrum experiment --launcher slurm` on one machine):
#
#   scripts/slurm-node.sh start DIR [CTLD_PORT SLURMD_PORT]   prints DIR/slurm.conf
#   SLURM_CONF=DIR/slurm.conf sbatch ... / squeue / scontrol ...
#   scripts/slurm-node.sh stop DIR
#
# Its own munge key and socket, state, spool, logs and ports (default 16817, 16818),
# all under DIR: nothing in /etc is read or changed and no system daemon is touched.
# Needs root (slurmd runs jobs as their users) and Debian's packages slurm-wlm and
# munge (`apt-get install slurm-wlm munge`); says which is missing.
set -euo pipefail

cmd=${1:-}
dir=${2:-}
if [[ -z $cmd || -z $dir ]]; then
  echo "usage: $0 start|stop DIR [CTLD_PORT SLURMD_PORT]" >&2
  exit 2
fi

stop() {
  for f in slurmd slurmctld munged; do
    pidf=$dir/$f.pid
    [[ $f == munged ]] && pidf=$dir/munge/munged.pid
    if [[ -f $pidf ]]; then
      kill "$(cat "$pidf")" 2>/dev/null || true
    fi
  done
  # Give them a moment, then make sure.
  for _ in $(seq 50); do
    alive=0
    for f in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
      [[ -f $f ]] && kill -0 "$(cat "$f")" 2>/dev/null && alive=1
    done
    [[ $alive == 0 ]] && return 0
    sleep 0.1
  done
  for f in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
    [[ -f $f ]] && kill -9 "$(cat "$f")" 2>/dev/null || true
  done
}

case $cmd in
stop)
  stop
  exit 0
  ;;
start) ;;
*)
  echo "$0: unknown command '$cmd' (start or stop)" >&2
  exit 2
  ;;
esac

if [[ $(id -u) != 0 ]]; then
  echo "$0: a Slurm node needs root (slurmd starts jobs as their users); run as root" >&2
  exit 1
fi
for b in munged mungekey slurmctld slurmd sbatch; do
  if ! command -v "$b" >/dev/null 2>&1 && [[ ! -x /usr/sbin/$b ]]; then
    echo "$0: $b not found: install Debian's slurm-wlm and munge (apt-get install slurm-wlm munge)" >&2
    exit 1
  fi
done
export PATH=$PATH:/usr/sbin

ctld_port=${3:-16817}
slurmd_port=${4:-16818}
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
chmod 700 "$dir/munge"
host=$(hostname -s)

[[ -f $dir/munge/munge.key ]] || mungekey --create --keyfile="$dir/munge/munge.key" --force
chmod 600 "$dir/munge/munge.key"
munged --force --socket="$dir/munge/socket" --key-file="$dir/munge/munge.key" \
  --pid-file="$dir/munge/munged.pid" --seed-file="$dir/munge/seed" \
  --log-file="$dir/log/munged.log"

cat >"$dir/slurm.conf" <<EOF
# A private single-node cluster (scripts/slurm-node.sh).
ClusterName=fulcrum
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
# cred_expire also delays a requeued job before it may start again (default 120 s).
AuthInfo=socket=$dir/munge/socket,cred_expire=10
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
ReturnToService=2
JobRequeue=1
MpiDefault=none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF

export SLURM_CONF=$dir/slurm.conf
slurmctld -i
slurmd
for _ in $(seq 100); do
  if sinfo -h -o '%t' 2>/dev/null | grep -qx idle; then
    echo "$dir/slurm.conf"
    exit 0
  fi
  sleep 0.2
done
echo "$0: the node did not come up within 20 s; logs in $dir/log" >&2
tail -n 5 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 || true
stop
exit 1
