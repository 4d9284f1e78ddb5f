"""Tamaas' solve, timed, with its iteration count read from its log (the peer runners'
shared part; run in the peer venv)."""
import os
import re
import sys
import tempfile
import time


def solve_logged(solver, target):
    """(Tamaas' error, iterations, wall s, CPU s, the log) of ``solver.solve(target)``; the log
    (``tm.set_log_level(tm.LogLevel.info)``) is read from fd 2, captured outside the timed region."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as logf:
        os.dup2(logf.fileno(), 2)
        try:
            t, c = time.perf_counter(), time.process_time()
            err = solver.solve(float(target))
            t, c = time.perf_counter() - t, time.process_time() - c
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        logf.seek(0)
        log = logf.read().decode(errors="replace")
    idx = [int(m.group(1)) for m in re.finditer(r"^\s*(\d+)\s+\S+\s+\S+\s*$", log, re.M)]
    # the loop is `do {...} while (err > tol && n++ < max_iter)`: the last logged index is the
    # last iteration's on convergence, and one past it when max_iter stops the loop (checked
    # with a gdb count of the FFTs, tamaas_signorini.py)
    iterations = idx[-1] + (1 if err <= solver.tolerance else 0) if idx else None
    return float(err), iterations, t, c, log
