"""Adversarial sweep: bad scenes, bad files, kills, full disks, concurrent runs, extreme physics
and API misuse, each case run through the product's front doors (``contactpetsc run``,
``contactpetsc plot``, the Python API) in a process of its own under a wall-time bound.

Every case has an expected outcome of its own, computed here without the package: the law
summed over a rigid sphere's gap (F = sum p(h - delta) dx dy, the laws of docs/formulation.md
written out below), the flat periodic cell (F = A p(-delta), pull-off -A times the law's peak),
Hertz (F = 4/3 E* R^1/2 delta^3/2) on a big window, a sphere kept 10 z0 away (no jumps, no
pull-off), an uninterrupted run (kill and restart), a second process (two runs into one
directory), the signature of PETSc's random vector (a failed step's pressure uniform in [0, 1)),
strict JSON, and the axis round trip of a step file fed back as ``kind = "file"``.

Outcomes:
  OK            the right answer within the stated tolerance, or a loud refusal (exit 1 or 2 and
                a message naming the offending key or file)
  SILENT-WRONG  exit 0 (or "converged") with a wrong or mixed answer, or bad input accepted
  LOST-WORK     finished results missing after a kill and --restart
  CRASH         a signal, a traceback instead of a message, an exit code outside {0, 1, 2, 3}
  HANG          the wall-time bound was reached
  UNCLEAR       refused, but the message names no key or file (or names internals)
  FAILED-LOUD   valid input that should give an answer ended with a non-zero exit instead
  SLOW          the per-step cost grows along a run (bookkeeping)

    python run_scripts/checks/adversarial_sweep.py --list
    python run_scripts/checks/adversarial_sweep.py --only flat --timeout 60 --markdown sweep.md
    python run_scripts/checks/adversarial_sweep.py --jobs 2 --markdown sweep.md    # all cases

One JSON line per case on stdout, then the counts; the exit status is 0 only when every case
is OK.  Cases under mpirun (2 ranks) run one at a time.
"""
