#!/usr/bin/env bash
# The whole test suite: set up (idempotently), then pytest serially and under
# mpirun with 2 and 3 ranks (3 ranks split every test grid unevenly).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$here/run_scripts/setup_env.sh"
venv="${CONTACTPETSC_VENV:-$here/.venv}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
# keep BLAS/FFTW single-threaded so that ranks do not fight over the cores
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
export PY_COLORS=0  # ranks share one terminal: no escape codes in the log
cd "$here"
py="$venv/bin/python"
echo "== pytest, 1 rank"
timeout 1200 "$py" -m pytest -q -p no:cacheprovider tests "$@"
for n in 2 3; do
    echo "== pytest, $n ranks"
    timeout 1200 mpirun -n "$n" "$py" -m pytest -q -p no:cacheprovider -m "not serial" tests "$@"
done
echo "== all test runs passed"
