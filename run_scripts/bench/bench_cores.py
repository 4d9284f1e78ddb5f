"""What two ranks can gain on this machine at all: throughput of independent serial FFT pairs.

Runs the same serial workload -- FFT pairs of an n x n real grid with pyfftw (FFTW
measured plans, one thread), as our elastic operator does on one rank -- first in
one process, then in P processes at once, and prints the throughput ratio
(P x single time / concurrent time; P = perfect, 1 = no gain).  Independent processes
share no data and exchange no messages, so this bounds the speed-up any P-rank solve
can reach here: above it the cores do not deliver, below it the code is to blame.

    .venv/bin/python run_scripts/bench/bench_cores.py [--n 2048] [--pairs 40] [--procs 2] [--repeats 3]

One JSON line: n, pairs, single [s] (median), concurrent [s] (median of the slowest
process), throughput ratio, load average before the run.
"""
import argparse
import json
import multiprocessing as mp
import os
import statistics
import time


def work(n, pairs, start=None):
    import numpy as np
    import pyfftw
    a = pyfftw.empty_aligned((n, n), dtype="float64")
    b = pyfftw.empty_aligned((n, n // 2 + 1), dtype="complex128")
    fwd = pyfftw.FFTW(a, b, axes=(0, 1), flags=("FFTW_MEASURE",), threads=1)
    bwd = pyfftw.FFTW(b, a, axes=(0, 1), direction="FFTW_BACKWARD", flags=("FFTW_MEASURE",), threads=1)
    a[...] = np.random.default_rng(0).random((n, n))
    if start is not None:
        start.wait()
    t = time.perf_counter()
    for _ in range(pairs):
        fwd()
        b *= 0.5     # the kernel multiply of an apply
        bwd()
    return time.perf_counter() - t


def _child(n, pairs, start, queue):
    queue.put(work(n, pairs, start))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=2048)
    ap.add_argument("--pairs", type=int, default=40)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    load = os.getloadavg()[0]
    single, concurrent = [], []
    for _ in range(args.repeats):
        single.append(work(args.n, args.pairs))
        start, queue = mp.Barrier(args.procs), mp.Queue()
        procs = [mp.Process(target=_child, args=(args.n, args.pairs, start, queue)) for _ in range(args.procs)]
        for p in procs:
            p.start()
        times = [queue.get() for _ in procs]
        for p in procs:
            p.join()
        concurrent.append(max(times))
    s, c = statistics.median(single), statistics.median(concurrent)
    print(json.dumps(dict(n=args.n, pairs=args.pairs, procs=args.procs, single_s=s, concurrent_s=c,
                          throughput_ratio=args.procs * s / c, load_before=load)))


if __name__ == "__main__":
    main()
