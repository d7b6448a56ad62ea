#!/usr/bin/env bash
# Install Debian's SLURM (slurmctld, slurmd, client tools) and munge, if missing.
#
# Idempotent: packages already installed are left alone and nothing is fetched.
# Daemons are NOT started by the packages (see policy-rc.d below); tools/slurm/start.sh
# runs its own munged/slurmctld/slurmd on a private config instead.
#
# Usage: tools/slurm/install.sh          (as root, or as a user with sudo)
set -euo pipefail

# slurm-wlm is the metapackage (slurmctld + slurmd + slurm-client); list the parts too so
# that a partial install is completed and the check below is exact.
PACKAGES=(slurm-wlm slurmctld slurmd slurm-client slurm-wlm-basic-plugins munge)

log() { echo "[slurm/install] $*"; }

missing=()
for pkg in "${PACKAGES[@]}"; do
    status=$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)
    if [[ "$status" != "install ok installed" ]]; then
        missing+=("$pkg")
    fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
    log "already installed: ${PACKAGES[*]}"
    dpkg-query -W -f='[slurm/install]   ${Package} ${Version}\n' "${PACKAGES[@]}"
    exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
    log "ERROR: apt-get not found; this script supports Debian/Ubuntu only." >&2
    log "Install slurmctld, slurmd, slurm-client and munge by other means." >&2
    exit 2
fi

SUDO=()
if [[ $(id -u) -ne 0 ]]; then
    if command -v sudo >/dev/null 2>&1; then
        SUDO=(sudo -n)
        log "not root: using 'sudo -n' (fails if sudo needs a password)"
    else
        log "ERROR: must run as root (or with sudo available) to apt-get install:" >&2
        log "  ${missing[*]}" >&2
        exit 2
    fi
fi

# Keep the packages' maintainer scripts from starting daemons (munge, slurmctld, slurmd
# with the stock /etc/slurm config): policy-rc.d exit 101 = "action forbidden". Docker's
# Debian images already ship such a file; otherwise put one in place for the install only.
POLICY=/usr/sbin/policy-rc.d
created_policy=0
if [[ ! -e $POLICY ]]; then
    printf '#!/bin/sh\nexit 101\n' | "${SUDO[@]}" tee "$POLICY" >/dev/null
    "${SUDO[@]}" chmod 755 "$POLICY"
    created_policy=1
    log "temporarily installed $POLICY (exit 101) so no daemon starts during install"
fi
cleanup() {
    if [[ $created_policy -eq 1 ]]; then "${SUDO[@]}" rm -f "$POLICY"; fi
}
trap cleanup EXIT

export DEBIAN_FRONTEND=noninteractive
log "missing: ${missing[*]}"
log "running: apt-get update"
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
log "running: apt-get install -y --no-install-recommends ${missing[*]}"
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
    -o Dpkg::Options::=--force-confdef -o Dpkg::Options::=--force-confold "${missing[@]}"

log "installed:"
dpkg-query -W -f='[slurm/install]   ${Package} ${Version}\n' "${PACKAGES[@]}"
