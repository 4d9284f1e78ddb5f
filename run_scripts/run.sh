#!/usr/bin/env bash
# The main job: set up (idempotently), then run the built-in default scene on
# NP ranks (default 2).  Extra arguments go to `contactpetsc run`, e.g. a scene
# file or PETSc options:  bash run_scripts/run.sh -snes_monitor
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -z "${CONTACTPETSC_VENV:-}" ]; then   # else a stack the user set up (docs/install.md)
    bash "$here/run_scripts/setup_env.sh"
fi
venv="${CONTACTPETSC_VENV:-$here/.venv}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_mpi_yield_when_idle=1
np="${NP:-2}"
exec mpirun -n "$np" "$venv/bin/contactpetsc" run "$@"
