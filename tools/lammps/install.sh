#!/usr/bin/env bash
# Install Debian's LAMMPS with its Python module (for benchmarks/lammps_reference.py), if
# missing: lammps (the GRANULAR package is in Debian's build), python3-lammps (ctypes
# wrapper, pure Python) and liblammps-dev (the unversioned liblammps.so it dlopens).
#
# Idempotent. Usage: tools/lammps/install.sh   (as root, or as a user with sudo)
set -euo pipefail

PACKAGES=(lammps python3-lammps liblammps-dev)
missing=()
for pkg in "${PACKAGES[@]}"; do
    status=$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)
    [[ "$status" == "install ok installed" ]] || missing+=("$pkg")
done
if [[ ${#missing[@]} -eq 0 ]]; then
    dpkg-query -W -f='[lammps/install] ${Package} ${Version}\n' "${PACKAGES[@]}"
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "[lammps/install] ERROR: apt-get not found (Debian/Ubuntu only); install" \
        "${missing[*]} by other means" >&2
    exit 2
fi
SUDO=()
if [[ $(id -u) -ne 0 ]]; then SUDO=(sudo -n); fi
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${missing[@]}"
dpkg-query -W -f='[lammps/install] ${Package} ${Version}\n' "${PACKAGES[@]}"
