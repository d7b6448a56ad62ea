#!/usr/bin/env bash
# Stop the private SLURM cluster started by tools/slurm/start.sh and remove its directory.
#
# Only processes recorded in $GRANPIPE_SLURM_DIR/run/*.pid are signalled (after checking that
# the pid still runs the expected binary), plus job step daemons (slurmstepd) whose environment
# names this cluster's SLURM_CONF. Safe to call twice, or when nothing is running.
#
# Environment:
#   GRANPIPE_SLURM_DIR          as for start.sh                          [/tmp/granpipe-slurm]
#   GRANPIPE_SLURM_KEEP_LOGS=1  keep $GRANPIPE_SLURM_DIR/log (for post-mortems); default: remove
set -euo pipefail

D=${GRANPIPE_SLURM_DIR:-/tmp/granpipe-slurm}
CONF=$D/slurm.conf

log() { echo "[slurm/stop] $*"; }

if [[ ! -d $D ]]; then
    log "nothing to stop: $D does not exist"
    exit 0
fi
if [[ ! -e $D/.granpipe-slurm ]]; then
    echo "[slurm/stop] ERROR: $D was not created by tools/slurm/start.sh; leaving it alone" >&2
    exit 1
fi

# pid_of NAME: pid from $D/run/NAME.pid if that process is alive and runs binary NAME.
pid_of() {
    local pidfile=$D/run/$1.pid pid
    [[ -s $pidfile ]] || return 1
    pid=$(<"$pidfile")
    [[ -d /proc/$pid ]] || return 1
    [[ $(readlink -f "/proc/$pid/exe" 2>/dev/null) == */"$1"* ]] || return 1
    echo "$pid"
}

# stop_pids NAME:PID...: SIGTERM to all at once (each daemon takes 1-2 s to notice), wait up
# to 10 s for all of them, then SIGKILL the rest.
stop_pids() {
    local item pids=() i pid left
    for item in "$@"; do
        log "stopping ${item%%:*} (pid ${item##*:})"
        kill -TERM "${item##*:}" 2>/dev/null && pids+=("${item##*:}")
    done
    for ((i = 0; i < 100; i++)); do
        left=0
        for pid in "${pids[@]}"; do [[ -d /proc/$pid ]] && left=1; done
        ((left)) || return 0
        sleep 0.1
    done
    for pid in "${pids[@]}"; do
        if [[ -d /proc/$pid ]]; then
            log "pid $pid ignored SIGTERM; sending SIGKILL"
            kill -KILL "$pid" 2>/dev/null || true
        fi
    done
}

# Cancel jobs still queued or running on this cluster (it is private: all jobs are ours).
if pid_of slurmctld >/dev/null && [[ -f $CONF ]]; then
    jobs=$(SLURM_CONF=$CONF timeout 10 squeue -h -o '%i' 2>/dev/null || true)
    if [[ -n $jobs ]]; then
        log "cancelling jobs: $(echo $jobs)"
        # shellcheck disable=SC2086
        SLURM_CONF=$CONF timeout 10 scancel $jobs 2>/dev/null || true
        for ((i = 0; i < 50; i++)); do
            [[ -z $(SLURM_CONF=$CONF timeout 10 squeue -h -t R,CG -o '%i' 2>/dev/null) ]] && break
            sleep 0.2
        done
    fi
fi

# Daemons, and the step daemons (slurmstepd) that outlive slurmd by design: only those whose
# environment names this cluster's SLURM_CONF.
targets=()
for name in slurmd slurmctld munged; do
    if pid=$(pid_of "$name"); then
        targets+=("$name:$pid")
    else
        log "$name not running"
    fi
done
for proc in /proc/[0-9]*; do
    [[ $(cat "$proc/comm" 2>/dev/null) == slurmstepd ]] || continue
    if tr '\0' '\n' 2>/dev/null <"$proc/environ" | grep -qxF "SLURM_CONF=$CONF"; then
        targets+=("slurmstepd:${proc#/proc/}")
    fi
done
if ((${#targets[@]})); then stop_pids "${targets[@]}"; fi

if [[ ${GRANPIPE_SLURM_KEEP_LOGS:-0} == 1 ]]; then
    log "removing $D (keeping $D/log)"
    find "$D" -mindepth 1 -maxdepth 1 ! -name log ! -name .granpipe-slurm -exec rm -rf {} +
else
    log "removing $D"
    rm -rf "$D"
fi
