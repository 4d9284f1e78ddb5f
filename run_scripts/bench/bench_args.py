"""What the rough-benchmark scripts share on their command line and output, importable before
``petsc4py.init`` (no PETSc import): the parser with the benchmark's size and law, and the
one-JSON-line-per-row output."""
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
