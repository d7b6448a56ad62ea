#!/usr/bin/env bash
# Start a private single-node SLURM cluster on localhost, without systemd.
#
# Everything lives under $GRANPIPE_SLURM_DIR (default /tmp/granpipe-slurm): a munge key and
# socket of its own (the system munge, if any, is not used), slurm.conf, state, logs and pid
# files. Clients find this cluster through SLURM_CONF and through wrappers of the client
# commands in $GRANPIPE_SLURM_DIR/bin (needed inside jobs, see below); env.sh sets both:
#
#     tools/slurm/start.sh && source "${GRANPIPE_SLURM_DIR:-/tmp/granpipe-slurm}/env.sh"
#     sinfo; sbatch --wrap hostname; ...; tools/slurm/stop.sh
#
# No cgroups, no systemd, no accounting database (slurmdbd): use `squeue`, not `sacct`.
# Idempotent: if the daemons recorded in the pid files are alive and the node answers, it only
# prints the status. Must run as root (slurmd launches jobs as the submitting user).
#
# Environment (all optional):
#   GRANPIPE_SLURM_DIR         state/log/config directory        [/tmp/granpipe-slurm]
#   GRANPIPE_SLURM_CTLD_PORT   slurmctld port                    [6817]
#   GRANPIPE_SLURMD_PORT       slurmd port                       [6818]
#   GRANPIPE_SLURM_PARTITION   name of the (default) partition  [debug]
#   GRANPIPE_SLURM_WAIT        seconds to wait for an idle node  [60]
set -euo pipefail

D=${GRANPIPE_SLURM_DIR:-/tmp/granpipe-slurm}
CTLD_PORT=${GRANPIPE_SLURM_CTLD_PORT:-6817}
SLURMD_PORT=${GRANPIPE_SLURMD_PORT:-6818}
PARTITION=${GRANPIPE_SLURM_PARTITION:-debug}
WAIT=${GRANPIPE_SLURM_WAIT:-60}

log() { echo "[slurm/start] $*"; }
die() {
    echo "[slurm/start] ERROR: $*" >&2
    exit 1
}

if [[ $(id -u) -ne 0 ]]; then
    die "must run as root (slurmd starts jobs as the submitting user; munged/slurmd need it)"
fi
for cmd in munged mungekey slurmctld slurmd sinfo scontrol; do
    command -v "$cmd" >/dev/null 2>&1 || die "'$cmd' not found; run tools/slurm/install.sh first"
done
case "$D" in
/ | /tmp | /tmp/ | "") die "GRANPIPE_SLURM_DIR='$D' is not a dedicated directory" ;;
esac

CONF=$D/slurm.conf
MUNGE_DIR=$D/munge
SOCKET=$MUNGE_DIR/munge.socket
((${#SOCKET} < 108)) || die "socket path $SOCKET too long for a unix socket; shorten GRANPIPE_SLURM_DIR"
export SLURM_CONF=$CONF

# alive NAME: true if the pid in $D/run/NAME.pid is a live process running binary NAME.
alive() {
    local pidfile=$D/run/$1.pid pid
    [[ -s $pidfile ]] || return 1
    pid=$(<"$pidfile")
    [[ -d /proc/$pid ]] || return 1
    [[ $(readlink -f "/proc/$pid/exe" 2>/dev/null) == */"$1"* ]]
}

node_state() { { timeout 10 sinfo -h -N -o '%T' 2>/dev/null || true; } | head -n1; }

status() {
    log "SLURM_CONF=$CONF"
    sinfo -N -o '%N %P %T %c %m' || true
    log "to use it: source $D/env.sh   (sets SLURM_CONF=$CONF and puts $D/bin first on PATH)"
}

if alive munged && alive slurmctld && alive slurmd; then
    case "$(node_state)" in
    idle* | mix* | alloc*)
        log "already running under $D"
        status
        exit 0
        ;;
    esac
fi

mkdir -p "$D" "$D/run" "$D/log" "$D/state/ctld" "$D/state/slurmd" "$MUNGE_DIR/key"
touch "$D/.granpipe-slurm" # marker: stop.sh only deletes directories carrying it
# munged insists: socket directory world-executable, key directory private.
chmod 755 "$D" "$MUNGE_DIR"
chmod 700 "$MUNGE_DIR/key"

# --- munge ------------------------------------------------------------------------------------
KEY=$MUNGE_DIR/key/munge.key
if [[ ! -s $KEY ]]; then
    log "creating munge key $KEY"
    mungekey --create --bits=1024 --keyfile="$KEY"
    chmod 400 "$KEY"
fi
if alive munged; then
    log "munged already running (pid $(<"$D/run/munged.pid"))"
else
    log "starting munged (socket $SOCKET)"
    rm -f "$SOCKET" "$SOCKET.lock"
    munged --socket="$SOCKET" --key-file="$KEY" --pid-file="$D/run/munged.pid" \
        --log-file="$D/log/munged.log" --seed-file="$MUNGE_DIR/munged.seed" \
        </dev/null >>"$D/log/munged.log" 2>&1 ||
        die "munged failed to start; see $D/log/munged.log"
fi

# --- slurm.conf ---------------------------------------------------------------------------------
NODE=$(uname -n) # = `hostname`, which minimal containers may lack; slurm wants the short name
NODE=${NODE%%.*}
# Let slurmd report what it will validate against (sockets/cores/threads, memory in MiB).
HW=$(slurmd -C 2>/dev/null | head -n1 || true)
hw_field() { sed -n "s/.*[[:space:]]$1=\([0-9]*\).*/\1/p" <<<"$HW"; }
CPUS=$(hw_field CPUs)
CPUS=${CPUS:-$(nproc)}
MEM=$(hw_field RealMemory)
MEM=${MEM:-$(awk '/MemTotal/ {print int($2 / 1024)}' /proc/meminfo)}
TOPO=""
if [[ -n $(hw_field SocketsPerBoard) ]]; then
    TOPO="Boards=$(hw_field Boards) SocketsPerBoard=$(hw_field SocketsPerBoard)"
    TOPO+=" CoresPerSocket=$(hw_field CoresPerSocket) ThreadsPerCore=$(hw_field ThreadsPerCore)"
fi

if alive slurmctld || alive slurmd; then
    log "a daemon is still running from an earlier start; keeping its $CONF"
else
    log "writing $CONF (node $NODE: CPUs=$CPUS RealMemory=${MEM}MiB)"
    cat >"$CONF" <<EOF
# Written by granpipe tools/slurm/start.sh: single-node test cluster on localhost.
ClusterName=granpipe
SlurmctldHost=$NODE(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCKET
MpiDefault=none
# No cgroups, no systemd: track job processes through /proc, bind nothing.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
# No slurmdbd: sacct cannot answer, so Snakemake polls job states with squeue, which sees
# finished jobs for MinJobAge seconds (must exceed the plugin's 180 s maximum poll interval).
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MinJobAge=600
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=1000
ReturnToService=2
MailProg=/bin/true
KillWait=5
InactiveLimit=0
StateSaveLocation=$D/state/ctld
SlurmdSpoolDir=$D/state/slurmd
SlurmctldPidFile=$D/run/slurmctld.pid
SlurmdPidFile=$D/run/slurmd.pid
SlurmctldLogFile=$D/log/slurmctld.log
SlurmdLogFile=$D/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$CPUS $TOPO RealMemory=$MEM State=UNKNOWN
PartitionName=$PARTITION Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
fi

# Client wrappers that pin this cluster's config. snakemake-executor-plugin-slurm-jobstep
# strips every SLURM_* variable except the job's identity (SLURM_CONF included) before the
# nested `srun` it runs inside each job; without SLURM_CONF, srun falls back to
# /etc/slurm/slurm.conf or DNS SRV and fails ("Could not establish a configuration source").
# PATH survives (sbatch --export=ALL), so $D/bin first on PATH keeps jobs on this cluster.
mkdir -p "$D/bin"
for cmd in srun sbatch squeue scancel sinfo scontrol sacct sacctmgr sshare salloc; do
    real=$(PATH=${PATH//"$D/bin:"/} command -v "$cmd" || true)
    [[ -n $real ]] || continue
    printf '#!/bin/sh\nSLURM_CONF=%q exec %q "$@"\n' "$CONF" "$real" >"$D/bin/$cmd"
    chmod 755 "$D/bin/$cmd"
done
printf 'export SLURM_CONF=%q\nexport PATH=%q:"$PATH"\n' "$CONF" "$D/bin" >"$D/env.sh"

# --- daemons ------------------------------------------------------------------------------------
# port_busy PORT: something (another slurmctld/slurmd?) already listens on 127.0.0.1:PORT.
port_busy() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
# failed NAME: the daemon is gone; show why.
failed() {
    echo "[slurm/start] ERROR: $1 exited; last lines of $D/log/$1.log:" >&2
    tail -n 15 "$D/log/$1.log" >&2 || true
    exit 1
}

if alive slurmctld; then
    log "slurmctld already running (pid $(<"$D/run/slurmctld.pid"))"
else
    port_busy "$CTLD_PORT" && die "port $CTLD_PORT is in use (another slurmctld?); set GRANPIPE_SLURM_CTLD_PORT"
    log "starting slurmctld"
    # -c: forget jobs from an earlier run of this test cluster.
    slurmctld -c -f "$CONF" </dev/null >>"$D/log/slurmctld.log" 2>&1 ||
        die "slurmctld failed to start; see $D/log/slurmctld.log"
fi
if alive slurmd; then
    log "slurmd already running (pid $(<"$D/run/slurmd.pid"))"
else
    port_busy "$SLURMD_PORT" && die "port $SLURMD_PORT is in use (another slurmd?); set GRANPIPE_SLURMD_PORT"
    log "starting slurmd"
    slurmd -f "$CONF" -N "$NODE" </dev/null >>"$D/log/slurmd.log" 2>&1 ||
        die "slurmd failed to start; see $D/log/slurmd.log"
fi

# --- wait for the node --------------------------------------------------------------------------
t0=$SECONDS
state=""
while ((SECONDS - t0 < WAIT)); do
    # (grace period: a daemon writes its pid file just after forking)
    if ((SECONDS - t0 >= 2)); then
        alive slurmctld || failed slurmctld
        alive slurmd || failed slurmd
    fi
    state=$(node_state)
    case "$state" in
    idle* | mix* | alloc*) break ;;
    down* | drain* | fail*)
        # ReturnToService=2 makes a healthy node come back on its own; nudge it once.
        scontrol update NodeName="$NODE" State=RESUME >/dev/null 2>&1 || true
        ;;
    esac
    sleep 0.5
done
case "$state" in
idle* | mix* | alloc*) log "node $NODE is $state after $((SECONDS - t0)) s" ;;
*)
    echo "[slurm/start] ERROR: node not idle after ${WAIT} s (state '${state:-none}')" >&2
    tail -n 20 "$D/log/slurmctld.log" "$D/log/slurmd.log" >&2 || true
    exit 1
    ;;
esac
status
