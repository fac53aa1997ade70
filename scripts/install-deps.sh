#!/usr/bin/env bash
# Installs what peridrive needs from Debian 12's archive, only what is missing. Idempotent and
# non-interactive (CI runs it with no standard input). Needs root (or sudo) when something is missing.
set -euo pipefail
packages=(build-essential cmake pkg-config git
  openmpi-bin libopenmpi-dev libpetsc-real-dev libhdf5-openmpi-dev libmetis-dev
  libeigen3-dev libyaml-cpp-dev libgmsh-dev gmsh googletest libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-numpy python3-h5py python3-matplotlib python3-yaml python3-meshio)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -q
"${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
