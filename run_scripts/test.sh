#!/usr/bin/env bash
# The whole test suite: set up (idempotently), then pytest serially and under
# mpirun with 2 and 3 ranks (3 ranks split every test grid unevenly: the grid, operator, solver and
# output tests; tests/conftest.py, TWO_RANK_MODULES).
#
#   TEST_TIMEOUT=1800 bash run_scripts/test.sh   # seconds per stage (default 1200)
#   CONTACTPETSC_VENV=DIR bash run_scripts/test.sh   # another stack's venv (docs/install.md)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -n "${CONTACTPETSC_VENV:-}" ]; then   # a stack the user set up (docs/install.md): used as it is
    [ -x "$CONTACTPETSC_VENV/bin/python" ] || { echo "CONTACTPETSC_VENV=$CONTACTPETSC_VENV has no bin/python" >&2; exit 2; }
else
    bash "$here/run_scripts/setup_env.sh"
fi
venv="${CONTACTPETSC_VENV:-$here/.venv}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
# oversubscribed ranks that spin in MPI waits starve the rank doing the work: yield instead
export OMPI_MCA_mpi_yield_when_idle=1
limit="${TEST_TIMEOUT:-1200}"
case "$limit" in ''|*[!0-9]*) echo "TEST_TIMEOUT must be a number of seconds, got '$limit'" >&2; exit 2 ;; esac
# keep BLAS/FFTW single-threaded so that ranks do not fight over the cores
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
export PY_COLORS=0  # ranks share one terminal: no escape codes in the log
cd "$here"
py="$venv/bin/python"
"$py" -m contactpetsc --version   # the stack the suite runs on
stage() {   # NAME COMMAND...: one stage under the time limit, and a message if the limit ends it
    local name="$1"; shift
    echo "== pytest, $name (time limit ${limit} s, TEST_TIMEOUT)"
    local status=0
    timeout "$limit" "$@" || status=$?
    if [ "$status" = 124 ]; then
        echo "== pytest, $name: stopped by the time limit of ${limit} s (a slow or busy machine: raise TEST_TIMEOUT)" >&2
    fi
    return "$status"
}
one_rank() {   # the 1-rank pass on both cores: two pytest sessions side by side, one core each
    # (tests/conftest.py, CONTACTPETSC_TEST_GROUP: about half of the time each), then the tests
    # that launch mpirun jobs alone (their ranks need both cores); each session with its own
    # temporary root (pytest prunes old numbered directories per root), their reports in turn
    local tmp a b sa=0 sb=0 sm=0
    tmp="$(mktemp -d "${TMPDIR:-/tmp}/contactpetsc-one-rank-XXXXXX")"
    # the time limit (timeout signals the whole group): the reports so far
    trap 'echo "-- stopped: the reports so far"; cat "$tmp"/*.log; rm -rf "$tmp"; exit 124' TERM
    CONTACTPETSC_TEST_GROUP=a "$py" -m pytest -q -p no:cacheprovider --durations=8 --basetemp="$tmp/a" \
        -m "not mpirun" tests "$@" >"$tmp/a.log" 2>&1 & a=$!
    CONTACTPETSC_TEST_GROUP=b "$py" -m pytest -q -p no:cacheprovider --durations=8 --basetemp="$tmp/b" \
        -m "not mpirun" tests "$@" >"$tmp/b.log" 2>&1 & b=$!
    wait "$a" || sa=$?
    wait "$b" || sb=$?
    "$py" -m pytest -q -p no:cacheprovider --durations=8 --basetemp="$tmp/mpirun" -m mpirun tests "$@" \
        >"$tmp/mpirun.log" 2>&1 || sm=$?
    echo "-- group a (exit status $sa)"
    cat "$tmp/a.log"
    echo "-- group b: the modules of tests/conftest.py GROUP_B_MODULES (exit status $sb)"
    cat "$tmp/b.log"
    echo "-- the tests that launch mpirun jobs, alone (exit status $sm)"
    cat "$tmp/mpirun.log"
    rm -rf "$tmp"
    [ "$sa" = 0 ] && [ "$sb" = 0 ] && [ "$sm" = 0 ]
}
export -f one_rank
export py
stage "1 rank" bash -c 'one_rank "$@"' one_rank "$@"
for n in 2 3; do
    stage "$n ranks" mpirun -n "$n" "$py" -m pytest -q -p no:cacheprovider -m "not serial" tests "$@"
done
echo "== all test runs passed"
