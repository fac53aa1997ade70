# Sourced by the scripts: lets Open MPI run as root (containers, CI) and keeps runs reproducible.
if [ "$(id -u)" -eq 0 ]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
# Debian's python3 (with python3-h5py, python3-matplotlib), not a user-installed interpreter.
PERI_PYTHON=/usr/bin/python3
