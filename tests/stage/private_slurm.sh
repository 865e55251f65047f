# A private single-node Slurm for the tests, sourced: Debian's munged, slurmctld and slurmd with
# their key, config, state, sockets and logs in one temporary folder, on free ports, as the user
# that runs the test (root in CI). slurm_start DIR starts them and waits for the node to be idle;
# slurm_stop stops them by their process ids and waits for them to go. Clients find the cluster
# through SLURM_CONF, which slurm_start exports.
#   SLURM_CPUS: the node's CPUs (default: nproc).

slurm_daemons_installed() {
  command -v munged >/dev/null && command -v slurmctld >/dev/null && command -v slurmd >/dev/null &&
    command -v sbatch >/dev/null
}

# A TCP port nobody listens on, from a range the kernel does not hand out to clients.
slurm_free_port() {
  local port
  while :; do
    port=$((20000 + RANDOM % 10000))
    ss -Htln "sport = :$port" 2>/dev/null | grep -q . || { echo "$port"; return; }
  done
}

slurm_start() {
  SLURM_DIR="$1"
  local dir="$SLURM_DIR" host user cpus memory
  host="$(hostname -s)" user="$(id -un)" cpus="${SLURM_CPUS:-$(nproc)}"
  memory=$(($(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 512))
  mkdir -p "$dir/state" "$dir/spool" "$dir/log"
  chmod 755 "$dir"
  head -c 1024 /dev/urandom >"$dir/munge.key"
  chmod 400 "$dir/munge.key"
  # --force: munged refuses root and a key in a folder others can read without it.
  munged --force --key-file="$dir/munge.key" --socket="$dir/munge.socket" --pid-file="$dir/munged.pid" \
    --log-file="$dir/log/munged.log" --seed-file="$dir/munged.seed"
  # batch_sched_delay=0: a job that waits for a free CPU starts when one frees, not on the next
  # 3-second tick (Slurm's default), since the test's jobs run one after another for a second each.
  cat >"$dir/slurm.conf" <<EOF
ClusterName=facetree-test
SlurmctldHost=$host
SlurmctldPort=$(slurm_free_port)
SlurmdPort=$(slurm_free_port)
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
AuthInfo=socket=$dir/munge.socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
MpiDefault=none
ReturnToService=2
MinJobAge=3600
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
NodeName=$host CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
  export SLURM_CONF="$dir/slurm.conf"
  slurmctld -f "$SLURM_CONF"
  slurmd -f "$SLURM_CONF"
  local i
  for ((i = 0; i < 100; i++)); do
    [ "$(sinfo -h -o %T 2>/dev/null)" = idle ] && return 0
    sleep 0.2
  done
  echo "private slurm: the node did not come up; logs in $dir/log" >&2
  tail -n 20 "$dir/log/"*.log >&2
  return 1
}

slurm_stop() {
  [ -n "${SLURM_DIR:-}" ] || return 0
  local name pid i
  for name in slurmd slurmctld munged; do
    pid="$(cat "$SLURM_DIR/$name.pid" 2>/dev/null)" || continue
    kill "$pid" 2>/dev/null || continue
    for ((i = 0; i < 100; i++)); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.1
    done
    kill -9 "$pid" 2>/dev/null || true
  done
  SLURM_DIR=""
}
