"""The command line shared by the non-adhesive peer runners (``tamaas_signorini.py``,
``cm_signorini.py``): the same inputs, so that ``bench_signorini.py`` calls every peer alike.
Imported by scripts that run in the peer venvs (numpy only)."""
import argparse

import numpy as np


def parse(description: str, tol_help: str, max_iter: int, check_help: str, argv=None):
    """(args, h): the parsed options and the periodic (n, n) separation h read from its .npy
    file; bad input stops with a message naming the option."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("height", help=".npy file with the periodic (n, n) separation h")
    ap.add_argument("--length", type=float, required=True, help="side length L")
    ap.add_argument("--estar", type=float, required=True, help="effective modulus E*")
    ap.add_argument("--mean-pressure", type=float, required=True, help="target mean p")
    ap.add_argument("--tol", type=float, default=1e-8, help=tol_help)
    ap.add_argument("--max-iter", type=int, default=max_iter)
    ap.add_argument("--out", default=None, help=".npz for p, gap, v, h, delta")
    ap.add_argument("--no-check", action="store_true", help=check_help)
    args = ap.parse_args(argv)
    h = np.load(args.height).astype(np.float64)
    if h.ndim != 2 or h.shape[0] != h.shape[1]:
        ap.error(f"expected a square 2-D height field, got shape {h.shape}")
    for name in ("length", "estar", "mean_pressure", "tol"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')} must be > 0, got {getattr(args, name)}")
    return args, h
