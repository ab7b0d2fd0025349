#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for the scale-out tests (docs/scale-out.md):
#
#   scripts/local-slurm.sh start [DIR]   install slurm-wlm + munge if missing, start munged,
#                                        slurmctld and slurmd with their state under DIR, print
#                                        the SLURM_CONF line to export
#   scripts/local-slurm.sh stop [DIR]    stop what start started (by pid files)
#
# DIR defaults to $LBLIGHT_SLURM_DIR or /tmp/lblight-slurm. Needs root (the daemons run as root;
# no systemd needed). Exit code 77 when Slurm cannot be installed or started here: tests skip then.
# Settings and pitfalls: docs/scale-out.md ("A cluster on one machine").
set -uo pipefail

cmd=${1:-}
dir=${2:-${LBLIGHT_SLURM_DIR:-/tmp/lblight-slurm}}
conf=$dir/slurm.conf
cannot() { echo "local-slurm: $*" >&2; exit 77; }

stop() {
  local name pid
  for name in slurmd slurmctld munged; do
    [ -f "$dir/$name.pid" ] || continue
    pid=$(cat "$dir/$name.pid" 2>/dev/null)
    if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
      kill "$pid"
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -0 "$pid" 2>/dev/null && kill -9 "$pid"
    fi
    rm -f "$dir/$name.pid"
  done
}

install_missing() {
  command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null && return 0
  command -v apt-get >/dev/null || cannot "slurm-wlm is not installed and there is no apt-get to install it"
  echo "local-slurm: installing slurm-wlm and munge (Debian packages, ~4 s)" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null 2>&1 ||
    { apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null 2>&1; } ||
    cannot "could not install slurm-wlm and munge with apt-get"
}

# munged: started here unless one already answers (it then stays as it was).
start_munge() {
  if munge -n </dev/null 2>/dev/null | unmunge >/dev/null 2>&1; then return 0; fi
  [ -f /etc/munge/munge.key ] || mungekey -c >/dev/null 2>&1 || cannot "no munge key and mungekey -c failed"
  install -d -o munge -g munge -m 0755 /run/munge
  runuser -u munge -- /usr/sbin/munged || cannot "munged did not start"
  for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
  cp /run/munge/munged.pid "$dir/munged.pid" 2>/dev/null
  munge -n </dev/null 2>/dev/null | unmunge >/dev/null 2>&1 || cannot "munged started but does not answer"
}

write_conf() {
  local host mem cpus
  host=$(hostname -s)
  cpus=$(nproc)
  mem=$(($(free -m | awk '/^Mem:/ {print $2}') - 1024))
  ((mem > 512)) || mem=512
  cat >"$conf" <<EOF
# One node, root, no systemd, no accounting database (scripts/local-slurm.sh).
ClusterName=lblight-local
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=${LBLIGHT_SLURMCTLD_PORT:-6817}
SlurmdPort=${LBLIGHT_SLURMD_PORT:-6818}
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
# Tiny jobs start at once (the default batches them every ~3 s).
SchedulerParameters=batch_sched_delay=0
# Without it an afterok job behind a failed one pends forever (ignored under SchedulerParameters).
DependencyParameters=kill_invalid_depend
MailProg=/bin/true
ReturnToService=2
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$dir/jobcomp.txt
MinJobAge=3600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
}

case "$cmd" in
  start)
    [ "$(id -u)" -eq 0 ] || cannot "needs root (the daemons run as root)"
    install_missing
    stop
    rm -rf "$dir"  # a stale state (another ClusterName) is fatal to slurmctld
    mkdir -p "$dir/state" "$dir/spool"
    start_munge
    write_conf
    export SLURM_CONF=$conf
    slurmctld -f "$conf" || cannot "slurmctld did not start (see $dir/slurmctld.log)"
    slurmd -f "$conf" || cannot "slurmd did not start (see $dir/slurmd.log)"
    for _ in $(seq 100); do
      state=$(sinfo -h -o %t 2>/dev/null)
      case "$state" in idle*|mix*|alloc*) echo "export SLURM_CONF=$conf"; exit 0 ;; esac
      sleep 0.1
    done
    stop
    cannot "the node did not become idle within 10 s (state '${state:-none}'; see $dir/slurmctld.log)"
    ;;
  stop)
    stop
    ;;
  *)
    echo "usage: $0 start|stop [DIR]" >&2
    exit 2
    ;;
esac
