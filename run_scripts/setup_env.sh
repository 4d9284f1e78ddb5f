#!/usr/bin/env bash
# Idempotent set-up of the contactpetsc environment on Debian 12 (run as root or
# with sudo): the Debian PETSc/OpenMPI stack and a venv in ./.venv that sees it
# (--system-site-packages).  numpy, mpi4py, h5py and petsc4py always come from
# Debian, never from pip (ABI).  A second run checks and returns in seconds.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$here/.venv"
py=/usr/bin/python3

debs=(python3-petsc4py libpetsc-real3.18-dev python3-mpi4py python3-pyfftw
      python3-h5py-mpi python3-numpy python3-venv python3-pip python3-setuptools
      openmpi-bin python3-pytest python3-mpmath python3-hypothesis python3-matplotlib python3-scipy)

source "$here/run_scripts/debian_packages.sh"
ensure_debs setup "${debs[@]}"

stamp="$venv/.contactpetsc-setup"
want="$(cat "$here/pyproject.toml" "$here/run_scripts/setup_env.sh" | sha256sum | cut -d' ' -f1)"
if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi
echo "setup: creating venv $venv (system site packages)"
[ -x "$venv/bin/python" ] || $py -m venv --system-site-packages "$venv"
# --no-deps: every dependency is a Debian package checked above; pip must not
# pull a second numpy/mpi4py/h5py/petsc4py from PyPI.
"$venv/bin/python" -m pip install -q --no-deps --no-build-isolation -e "$here"
"$venv/bin/python" - <<'PY'
import petsc4py, mpi4py, pyfftw, h5py, numpy, contactpetsc
from petsc4py import PETSc
print("setup: PETSc %d.%d.%d, %d-bit indices, contactpetsc %s"
      % (PETSc.Sys.getVersion() + (8 * PETSc.IntType(0).itemsize, contactpetsc.__version__)))
PY
echo "$want" > "$stamp"
