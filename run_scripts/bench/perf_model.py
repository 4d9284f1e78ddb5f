#!/usr/bin/env python3
"""Performance model of one non-adhesive rough solve on P ranks (slab or pencil FFT): its
calibration on this machine or a cluster node, and its predictions.

Model (periodic n x n grid, P ranks, c of them per node; one operator apply = one FFT pair):

    t_apply(n, P) = t_fft + t_copy + t_comm
    t_fft  = k_fft n^2 log2(n^2) / P               1-D FFT batches at the rate of a busy core
    t_copy = (w_local + w_t) * 8 B n^2 / P / b(P)  rank-local passes over the local arrays
    t_comm = 2 * sum over the transposes of one transform of (m alpha + V / beta)

b(P) = min(b_core, B_node / min(P, c)): bytes copied per second by one rank while every rank
of its node copies too.  w_local = 3 passes (copy in, kernel multiply, copy out); w_t = 2 (2 -
1/P) for the slab (per direction: pack the other ranks' columns, copy the own block, unpack)
and 8 for pencils (two row stages of one pass each and a column stage of two, per direction).
Transposes per transform: slab one all-to-all among the P ranks (m = P - 1 messages, V =
8 B n^2/P (1 - 1/P) bytes per rank); pencil px x py two among the px ranks of a row (m = px -
1, V = 8 B n^2/P (1 - 1/px)) and one among the py ranks of a column (m = py - 1, V = 8 B n^2/P
(1 - 1/py)).  Of a group's peers, those on the rank's node cost alpha_shm and beta_shm = b(P)/2
(shared-memory MPI copies in and out), the others alpha_net and beta_net = B_net / min(P, c)
(every rank of a node sends at once through the node's port).  Row groups are consecutive ranks
(on one node while px <= c), column groups are px apart.

One solve: T = A_fine t_apply(n) + A_coarse t_apply(n/2) + N_newton t_newton + N_krylov t_red,
with the fine-grid applies A_fine and the coarse grids' applies lumped at n/2 (A_coarse = 4
(pairs - A_fine)), t_newton = q_vec n^2 / P / b(P) + t_step the VI's vector work per Newton
step (q_vec bytes per point) and its fixed cost (PETSc index sets and scatters, Python), t_red
= 3 log2(P) alpha_net the Krylov iteration's reductions.

Usage::

    mpirun -n P python perf_model.py calibrate [--n 1024] [--repeats 5]     # one JSON line
    python perf_model.py predict [--calibration cal.json] [--markdown]
    python perf_model.py check [--calibration cal.json] --solves solves.jsonl  # model vs solves

``calibrate`` measures, on every rank at once: FFTW 1-D batches of the slab's x stage (k_fft),
array copies (b_core, or B_node with every rank copying), MPI_Alltoall of one double per peer
(alpha_shm on one node), and the elastic operator's apply on slabs and (P > 1) on the most
square block grid, each with the model's figure.  ``check`` puts the model beside
``bench_scaling.py`` JSON lines (time and counts) from the same machine; ``predict`` prints
strong and weak scaling of 8192^2 and 16384^2 on 16-1024 ranks of the cluster below.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

#: this machine (docs/performance.md#machine), from the quiet stage timings of a 2048^2
#: periodic apply (docs/journal/performance.md, 2026-11-22): 1-D FFT batches 19.4 ms per rank
#: on 2 ranks; a 16.8 MB copy 2.3 ms per rank with both cores copying (7.3 GB/s), 3.3 ms for
#: 33.5 MB alone (10 GB/s); Alltoallv 8.4 MB per rank in 2.3 ms (3.6 GB/s = b(2)/2); the VI's
#: per-Newton-step work fitted to the quiet 1-rank solves at 1024^2 (6.7 s) and 2048^2 (26.8 s)
HERE = dict(k_fft=19.4e-3 * 2 / (2048 ** 2 * 22), b_core=10e9, B_node=14.6e9, cores_per_node=2,
            alpha_shm=1.0e-6, alpha_net=1.0e-6, B_net=14.6e9, w_local=3.0,
            q_vec=425.0, t_step=1.5e-3)

#: a typical cluster: nodes of 2 x 32 x86 cores (c = 64) with ~350 GB/s of memory traffic
#: (B_node = 120 GB/s copied, read + write-allocate + write), one HDR InfiniBand port per node (200 Gb/s, B_net ~ 20 GB/s
#: achieved) on a full-bisection fat tree, ~2 us per all-to-all message between nodes and
#: ~0.5 us within one; FFT rate per core, single-core copy rate and per-step costs as here
CLUSTER = dict(HERE, B_node=120e9, cores_per_node=64, alpha_shm=0.5e-6, alpha_net=2.0e-6,
               B_net=20e9)

#: counts of the benchmark solve (docs/performance.md, counts and memory): FFT pairs weighted
#: by size, fine-grid applies, Newton and Krylov iterations; 2048^2 and 4096^2 fine applies
#: at the 1024^2 and 8192^2 share (0.85); 16384^2 extrapolated (x1.39 pairs, +15 Newton,
#: x1.25 Krylov per doubling, as from 4096^2 to 8192^2)
COUNTS = {1024: (203.9, 168, 96, 467), 2048: (242.1, 205, 84, 457), 4096: (303.7, 258, 95, 543),
          8192: (424.3, 360, 110, 722), 16384: (590.0, 500, 125, 900)}


def bandwidth(m: dict, P: int) -> float:
    """b(P): bytes one rank copies per second while the ranks of its node copy too."""
    return min(m["b_core"], m["B_node"] / min(P, m["cores_per_node"]))


def groups(P: int, px: int) -> list[tuple[int, int, int]]:
    """The transposes of one transform: (group size, stride of its ranks, how many)."""
    if px == 1:
        return [(P, 1, 1)]
    return [(px, 1, 2), (P // px, px, 1)]


def t_alltoall(m: dict, n: int, P: int, size: int, stride: int) -> float:
    """One all-to-all of the transpose among ``size`` ranks ``stride`` apart, per rank [s]."""
    if size == 1:
        return 0.0
    c = m["cores_per_node"]
    volume = 8.0 * n * n / P * (1.0 - 1.0 / size)          # bytes each rank sends
    same_node = max(1, min(size, c // stride))              # group members on one node
    frac_shm = (same_node - 1) / (size - 1)                 # of the peers and bytes
    beta_shm = bandwidth(m, P) / 2.0
    beta_net = m["B_net"] / min(P, c)
    return ((size - 1) * (frac_shm * m["alpha_shm"] + (1 - frac_shm) * m["alpha_net"])
            + volume * (frac_shm / beta_shm + (1 - frac_shm) / beta_net))


def t_apply(m: dict, n: int, P: int, px: int = 1) -> float:
    """Model time of one operator apply [s] on P ranks, px ranks along x (1: slabs)."""
    pts = float(n) * n
    t_fft = m["k_fft"] * pts * math.log2(pts) / P
    w_t = 0.0 if P == 1 else (2.0 * (2.0 - 1.0 / P) if px == 1 else 8.0)
    t_copy = (m["w_local"] + w_t) * 8.0 * pts / P / bandwidth(m, P)
    t_comm = 2.0 * sum(k * t_alltoall(m, n, P, size, stride) for size, stride, k in groups(P, px))
    return t_fft + t_copy + t_comm


def t_solve(m: dict, n: int, P: int, px: int = 1, counts=None) -> float:
    """Model time of one solve [s] (counts: FFT pairs, fine applies, Newton, Krylov)."""
    pairs, fine, newton, krylov = counts or COUNTS[n]
    coarse = max(pairs - fine, 0.0) * 4.0
    t_newton = m["q_vec"] * float(n) * n / P / bandwidth(m, P) + m["t_step"]
    t_red = 3.0 * math.log2(P) * m["alpha_net"] if P > 1 else 0.0
    return (fine * t_apply(m, n, P, px) + coarse * t_apply(m, n // 2, P, px)
            + newton * t_newton + krylov * t_red)


def pencil_options(n: int, P: int) -> list[int]:
    """px > 1 of the block grids that fit an n x n grid on P ranks (rows per y-block >= px,
    Fourier columns per x-block >= py)."""
    return [px for px in range(2, P + 1)
            if P % px == 0 and n // (P // px) >= px and (n // 2 + 1) // px >= P // px]


def best_pencil(m: dict, n: int, P: int, what=t_solve):
    """(px, time) of the fastest block grid by ``what``, None if none fits."""
    opts = [(px, what(m, n, P, px)) for px in pencil_options(n, P)]
    return min(opts, key=lambda o: o[1]) if opts else None


# -- calibration (under MPI) ---------------------------------------------------------------
def calibrate(args) -> None:
    import statistics
    import time

    import petsc4py
    petsc4py.init([sys.argv[0]] + args.petsc)
    import numpy as np
    import pyfftw
    from mpi4py import MPI
    from petsc4py import PETSc

    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.operators.elastic import PeriodicHalfSpace

    comm = PETSc.COMM_WORLD.tompi4py()
    P, rank, n = comm.Get_size(), comm.Get_rank(), args.n

    def timed(f, reps=args.repeats, together=True):
        """Median over ``reps`` of the slowest rank; ``together=False``: rank 0 alone."""
        ts = []
        for _ in range(reps):
            comm.Barrier()
            t = time.perf_counter()
            if together or rank == 0:
                f()
            ts.append(comm.allreduce(time.perf_counter() - t, op=MPI.MAX))
        return statistics.median(ts)

    # the slab's x stage on every rank at once: n/P rows of n points (the y stage is alike)
    rows = max(n // P, 1)
    a = pyfftw.empty_aligned((rows, n), "float64")
    s = pyfftw.empty_aligned((rows, n // 2 + 1), "complex128")
    fwd = pyfftw.FFTW(a, s, axes=(1,), flags=("FFTW_MEASURE",))
    bwd = pyfftw.FFTW(s, a, axes=(1,), direction="FFTW_BACKWARD", flags=("FFTW_MEASURE",))
    a[...] = np.random.default_rng(rank).random((rows, n))
    t_rows = timed(lambda: (fwd(), bwd()))
    # a pair along x and along y is twice this, for n^2/P points
    k_fft = 2 * t_rows / (rows * n * math.log2(float(n) * n))
    src = np.ones(max(n * n // P, 2 ** 23))     # >= 64 MB: beyond the caches
    dst = np.empty_like(src)
    b_core = src.nbytes / timed(lambda: np.copyto(dst, src), together=False)
    b_all = src.nbytes / timed(lambda: np.copyto(dst, src))
    res = dict(ranks=P, n=n, k_fft=k_fft, b_core=b_core, b_all=b_all,
               load=float(open("/proc/loadavg").read().split()[0]))
    import os
    cores = len(os.sched_getaffinity(0))
    shared = max(1.0, P / cores)           # ranks beyond the cores time-share them
    m = dict(HERE, k_fft=k_fft / shared, b_core=b_core, B_node=b_all * P, cores_per_node=cores)
    if P > 1:
        one, out = np.zeros(P), np.zeros(P)
        reps = 200
        alpha = timed(lambda: [comm.Alltoall(one, out) for _ in range(reps)]) / reps / (P - 1)
        res["alpha_shm"] = alpha
        m.update(alpha_shm=alpha, alpha_net=alpha)
    res["apply"] = {}
    options = pencil_options(n, P)
    for px in [1] + ([min(options, key=lambda p: abs(math.log(p / (P // p))))] if options else []):
        g = SurfaceGrid(n, n, 1.0 / n, px=px)
        op = PeriodicHalfSpace(g, 1.0)
        x = np.random.default_rng(1).random(g.local_shape)
        y = np.empty_like(x)
        res["apply"][f"{px}x{P // px}"] = dict(measured=timed(lambda: op.apply(x, y)),
                                               model=t_apply(m, n, P, px) * shared)
    if rank == 0:
        print(json.dumps(res), flush=True)


# -- predictions -----------------------------------------------------------------------------
def machine(args, base: dict, cores: int | None = None) -> dict:
    """``base`` with the constants of a calibration file, if one is given: the FFT rate and
    single-core copy rate always; with ``cores`` per node also the node's copy bandwidth and
    the shared-memory latency of the calibration run (ranks on one node)."""
    m = dict(base)
    if args.calibration:
        with open(args.calibration) as f:
            cal = [json.loads(line) for line in f if line.startswith("{")]
        one = min(cal, key=lambda c: c["ranks"])
        m.update(k_fft=one["k_fft"], b_core=one["b_core"])
        if cores:
            full = max(cal, key=lambda c: c["ranks"])
            m.update(cores_per_node=cores, B_node=full["b_all"] * min(full["ranks"], cores))
            if "alpha_shm" in full:
                m.update(alpha_shm=full["alpha_shm"])
    return m


def predict(args) -> None:
    m = machine(args, CLUSTER)
    print(f"cluster: {m['cores_per_node']} cores per node, B_node {m['B_node'] / 1e9:g} GB/s copied, "
          f"B_net {m['B_net'] / 1e9:g} GB/s per node, alpha {m['alpha_shm'] * 1e6:g} / "
          f"{m['alpha_net'] * 1e6:g} us (node / network), k_fft {m['k_fft']:.3g} s\n")
    print("Strong scaling, one solve [s]; speed-up against 16 ranks; pencil: the best px x py\n")
    print("| n | P | slab [s] | speed-up | slab apply [ms] | pencil [s] | px x py | pencil apply [ms] | faster |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for n in (8192, 16384):
        base = t_solve(m, n, 16)
        for P in (16, 32, 64, 128, 256, 512, 1024):
            ts, pen = t_solve(m, n, P), best_pencil(m, n, P)
            cells = ([f"{pen[1]:.1f}", f"{pen[0]} x {P // pen[0]}", f"{1e3 * t_apply(m, n, P, pen[0]):.2f}",
                      "pencil" if pen[1] < ts else "slab"] if pen else ["-", "-", "-", "slab"])
            print(f"| {n} | {P} | {ts:.1f} | {base / ts * 1:.2f} | {1e3 * t_apply(m, n, P):.2f} | "
                  + " | ".join(cells) + " |")
    print("\nWeak scaling, 4.2 M points per rank; one fine-grid apply [ms] and its efficiency "
          "against one full node (64 ranks), the FFT's log factor taken out\n")
    print("| n | P | slab apply [ms] | efficiency | pencil apply [ms] | px x py | efficiency |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    ref = t_apply(m, 16384, 64) * math.log2(8192.0 ** 2) / math.log2(16384.0 ** 2)
    for n, P in ((8192, 16), (16384, 64), (32768, 256), (65536, 1024)):
        ts, pen = t_apply(m, n, P), best_pencil(m, n, P, t_apply)
        log = math.log2(float(n) * n) / math.log2(8192.0 ** 2)
        print(f"| {n} | {P} | {1e3 * ts:.1f} | {ref * log / ts:.2f} | {1e3 * pen[1]:.1f} | "
              f"{pen[0]} x {P // pen[0]} | {ref * log / pen[1]:.2f} |")


def check(args) -> None:
    """Model beside measured solves; ranks beyond the cores of a node share them (time x P/c)."""
    m = machine(args, HERE, args.cores_per_node)
    c = m["cores_per_node"]
    print("| n | ranks | px | measured [s] | model [s] | model / measured |")
    print("|---:|---:|---:|---:|---:|---:|")
    with open(args.solves) as f:
        for line in f:
            if not line.startswith("{"):
                continue
            r = json.loads(line)
            counts = (r["fft_pairs"], r["fine_applies"], r["newton"], r["krylov"])
            P, px = r["ranks"], r.get("px", 1)
            model = t_solve(m, r["n"], P, px, counts) * max(1.0, P / c)
            print(f"| {r['n']} | {P} | {px} | {r['time']:.2f} | {model:.2f} | {model / r['time']:.2f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("calibrate")
    c.add_argument("--n", type=int, default=1024)
    c.add_argument("--repeats", type=int, default=5)
    p = sub.add_parser("predict")
    p.add_argument("--calibration", default=None)
    k = sub.add_parser("check")
    k.add_argument("--calibration", default=None, help="calibrate output (default: the constants HERE)")
    k.add_argument("--solves", required=True)
    k.add_argument("--cores-per-node", type=int, default=None,
                   help="cores per node of the solves' machine (default: this machine's)")
    args, rest = ap.parse_known_args()
    args.petsc = rest
    if args.cmd == "check" and args.cores_per_node is None:
        import os
        args.cores_per_node = len(os.sched_getaffinity(0))
    {"calibrate": calibrate, "predict": predict, "check": check}[args.cmd](args)


if __name__ == "__main__":
    main()
