"""Taking over the lock of a killed run is atomic (contactpetsc/app/rundir.py): of several
processes that find the same stale lock at the same moment exactly one takes it over, the
others are refused naming that one, and none fails otherwise."""
import json
import os
import subprocess
import sys
import time

import pytest

from contactpetsc.app.rundir import LOCK

#: a worker takes the lock of ``out`` once per line on stdin ("go <time>"), starting at that
#: time, and prints what happened; the lock is loaded once per worker, so that a round costs
#: no interpreter start-up and the workers really race
WORKER = r"""
import sys, time, traceback
from contactpetsc.app.rundir import RunDirectoryError, _lock
out = sys.argv[1]
for line in sys.stdin:
    start = float(line.split()[1])
    while time.time() < start:
        pass
    try:
        _lock(out)
        print("won", flush=True)
    except RunDirectoryError as exc:
        print("refused", str(exc).replace("\n", " "), flush=True)
    except BaseException as exc:
        print("error", type(exc).__name__, str(exc).replace("\n", " "), flush=True)
"""

WORKERS, ROUNDS = 3, 40


def dead_pid() -> int:
    """The id of a process that has ended (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.mark.serial
def test_concurrent_take_overs_of_a_stale_lock_have_exactly_one_winner(tmp_path):
    import socket
    lock = tmp_path / LOCK
    env = dict(os.environ, OMP_NUM_THREADS="1")
    workers = [subprocess.Popen([sys.executable, "-c", WORKER, str(tmp_path)], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, text=True, env=env) for _ in range(WORKERS)]
    stale = json.dumps({"host": socket.gethostname(), "pid": dead_pid()})
    tally, bad = {"won": 0, "refused": 0}, []
    try:
        for _ in range(ROUNDS):
            lock.write_text(stale)
            start = time.time() + 0.05
            for w in workers:
                w.stdin.write(f"go {start!r}\n")
                w.stdin.flush()
            results = [w.stdout.readline().split(" ", 1) for w in workers]
            winners = [w.pid for w, r in zip(workers, results) if r[0].strip() == "won"]
            kinds = sorted(r[0].strip() for r in results)
            holder = json.loads(lock.read_text())["pid"] if lock.exists() else None
            for kind, *rest in results:
                tally[kind.strip()] = tally.get(kind.strip(), 0) + 1
            if (kinds != ["refused"] * (WORKERS - 1) + ["won"] or winners != [holder]
                    or not all(f"process {holder}" in r[1] for r in results if r[0] == "refused")):
                bad.append(results)
            lock.unlink(missing_ok=True)
            assert sorted(os.listdir(tmp_path)) == []      # no temporary left behind
    finally:
        for w in workers:
            w.stdin.close()
            w.wait(timeout=60)
    assert not bad, f"{len(bad)} of {ROUNDS} rounds without exactly one winner: {bad[:3]} ({tally})"
    assert tally == {"won": ROUNDS, "refused": ROUNDS * (WORKERS - 1)}
