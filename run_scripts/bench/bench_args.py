"""What the rough-benchmark scripts share on their command line and output, importable before
``petsc4py.init`` (no PETSc import): the parser with the benchmark's size and law, the path's
arguments, the one-JSON-line-per-row output, and the process's memory counters."""
import argparse
import json

LAWS = ["exponential", "hardwall-lj", "lj"]


def rough_parser(doc: str, law: str = "exponential") -> argparse.ArgumentParser:
    """A parser described by ``doc``'s first line, with --size (grid nodes a side), --law (the
    benchmark's laws, default ``law``) and --w (work of adhesion / (E* dx))."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--law", default=law, choices=LAWS)
    ap.add_argument("--w", type=float, default=0.05, help="work of adhesion / (E* dx)")
    return ap


def emit(**row) -> None:
    """One JSON line, flushed (benchmarks are read while they run)."""
    print(json.dumps(row), flush=True)


def add_path_arguments(ap: argparse.ArgumentParser) -> None:
    """--states, --areas and --calibrate-max-n of a load-unload path on the rough benchmark
    (``bench_adhesion_path.py``); checked by ``check_path_arguments``."""
    ap.add_argument("--states", type=int, default=10, help="states on the path (>= 2), half loading, half unloading")
    ap.add_argument("--areas", type=float, nargs=2, default=[0.01, 0.10],
                    help="contact areas at the path's ends (start and turning point)")
    ap.add_argument("--calibrate-max-n", type=int, default=256)


def check_path_arguments(ap: argparse.ArgumentParser, args) -> None:
    if args.states < 2:
        ap.error(f"--states must be at least 2, got {args.states}")
    if not 0.0 < args.areas[0] < args.areas[1] < 1.0:
        ap.error(f"--areas must satisfy 0 < start < turning point < 1, got {args.areas}")


def status_kb(field: str) -> int:
    """A field of /proc/self/status in kB (VmRSS, VmHWM)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise KeyError(field)


def reset_peak() -> None:
    """Reset VmHWM to the current resident size (Linux >= 4.0: write 5 to clear_refs)."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def timed_margin(pb, method: str, **kw):
    """(margin, settled, FFT pairs, CPU s) of the stability check's ``method`` at the state in the
    adhesive problem ``pb``'s unknowns (``stability.stability_margin``; imported here, after
    ``petsc4py.init``)."""
    import time
    from contactpetsc.solvers.stability import stability_margin
    xb = pb.blocks(pb._x, readonly=True)
    gap = pb._gap(xb, pb._g)
    p0, t0 = pb.fft_pairs(), time.process_time()
    m, settled = stability_margin(pb, gap, xb[0] if pb.hard_wall else None, method=method, **kw)
    return m, settled, pb.fft_pairs() - p0, time.process_time() - t0
