#!/usr/bin/env bash
# A second, self-built stack: the newest PETSc/petsc4py release compiled from the PyPI
# source distributions, with mpi4py and an MPI-enabled h5py built against the system MPI
# and HDF5, pyfftw and numpy from PyPI, in a venv outside the repository.  This is what a
# cluster user with a module PETSc (or a pip-only user) runs; CI keeps the Debian stack.
#
#   bash run_scripts/setup_petsc_stack.sh               # PETSc 3.26.1, 32-bit indices
#   INDEX_BITS=64 bash run_scripts/setup_petsc_stack.sh # --with-64-bit-indices
#   bash run_scripts/setup_petsc_stack.sh --print-venv  # where the venv is (nothing built)
#
# Idempotent: a second run with the same versions returns at once.  Needs a C compiler,
# the MPI compiler wrappers (mpicc) and parallel HDF5 headers (Debian: build-essential,
# gfortran, libopenmpi-dev, libhdf5-openmpi-dev, liblapack-dev; installed here when missing
# and we are root or have sudo).  The build of PETSc itself takes about half an hour on two
# cores (docs/install.md).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
petsc_version="${PETSC_VERSION:-3.26.1}"
bits="${INDEX_BITS:-32}"
cache="${CONTACTPETSC_STACK_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/contactpetsc}"
venv="$cache/petsc-$petsc_version-int$bits"
[ "${1:-}" = "--print-venv" ] && { echo "$venv"; exit 0; }
case "$bits" in 32|64) ;; *) echo "INDEX_BITS must be 32 or 64, got $bits" >&2; exit 2 ;; esac

# the versions verified with this stack (docs/install.md); change them together
pins=(numpy==2.4.6 mpi4py==4.1.2 h5py==3.16.0 pyFFTW==0.15.1 pytest==9.2.0 hypothesis==6.170.17
      mpmath==1.4.1 matplotlib==3.11.2 scipy==1.17.1 cython==3.3.1 setuptools==84.2.1 wheel)
stamp="$venv/.contactpetsc-stack"
want="petsc=$petsc_version bits=$bits ${pins[*]}"
if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi

if command -v dpkg-query >/dev/null; then
    source "$here/run_scripts/debian_packages.sh"
    ensure_debs stack build-essential gfortran libopenmpi-dev openmpi-bin libhdf5-openmpi-dev liblapack-dev \
        libblas-dev python3-venv python3-dev pkg-config patchelf
fi

echo "stack: building PETSc $petsc_version ($bits-bit indices) into $venv"
mkdir -p "$cache"
[ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv "$venv"
py="$venv/bin/python"
export PATH="$venv/bin:$PATH"   # the build runs tools it installs (cython)
"$py" -m pip install -q --upgrade pip
"$py" -m pip install -q "${pins[@]}" --no-binary mpi4py
export CC=mpicc
# the PyPI petsc package runs PETSc's configure with these options (plus its own defaults:
# shared libraries, the MPI of mpicc); optimised, no debugging, no downloads
export PETSC_CONFIGURE_OPTIONS="--with-debugging=0 COPTFLAGS=-O2 CXXOPTFLAGS=-O2 FOPTFLAGS=-O2 \
--with-fortran-bindings=0 $( [ "$bits" = 64 ] && echo --with-64-bit-indices )"
t0=$(date +%s)
# --no-cache-dir: pip would otherwise reuse a wheel built with other configure options
"$py" -m pip install -v --no-cache-dir --no-build-isolation "petsc==$petsc_version" > "$venv/petsc-build.log" 2>&1 || {
    echo "stack: the PETSc build failed; the log is $venv/petsc-build.log" >&2; tail -30 "$venv/petsc-build.log" >&2; exit 1; }
"$py" -m pip install -q --no-cache-dir --no-build-isolation "petsc4py==$petsc_version"
echo "stack: PETSc and petsc4py built in $(( $(date +%s) - t0 )) s"
hdf5_dir="${HDF5_DIR:-}"
if [ -z "$hdf5_dir" ] && [ -d /usr/lib/x86_64-linux-gnu/hdf5/openmpi ]; then
    hdf5_dir=/usr/lib/x86_64-linux-gnu/hdf5/openmpi
fi
HDF5_MPI=ON HDF5_DIR="$hdf5_dir" "$py" -m pip install -q --no-build-isolation --no-binary h5py --force-reinstall --no-deps \
    "$(printf '%s\n' "${pins[@]}" | grep '^h5py')"
"$py" -m pip install -q --no-deps --no-build-isolation -e "$here"
"$py" -m contactpetsc --version
echo "$want" > "$stamp"
echo "stack: ready: $venv (use CONTACTPETSC_VENV=$venv bash run_scripts/test.sh)"
