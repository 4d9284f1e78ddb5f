"""The sweep's command line (run_scripts/checks/adversarial_sweep.py)."""
from __future__ import annotations

import argparse
import concurrent.futures
import json
from pathlib import Path

from . import harness
from . import __doc__ as package_doc
from .catalogue import all_cases
from .harness import OK, markdown, run_case, summary_line


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=package_doc.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--only", default=None, help="run the cases whose name contains this")
    ap.add_argument("--class", dest="klass", default=None, help="run the cases of these classes (comma-separated; the list's column)")
    ap.add_argument("--timeout", type=float, default=harness.TIMEOUT, help="wall-time bound per process [s]")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once")
    ap.add_argument("--markdown", default=None, help="write the table to this file")
    ap.add_argument("--keep", action="store_true", help="keep each case's directory")
    args = ap.parse_args(argv)
    harness.TIMEOUT = args.timeout
    cases = [c for c in all_cases() if (args.only is None or args.only in c.name)
             and (args.klass is None or c.issue_class in args.klass.split(","))]
    if args.list:
        for c in cases:
            print(f"{c.name:40s} class {c.issue_class:4s} np{c.ranks}  {c.description}")
        return 0
    results = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for r in pool.map(lambda c: run_case(c, args.keep), cases):
            print(json.dumps(r), flush=True)
            results.append(r)
    if args.markdown:
        Path(args.markdown).write_text(markdown(results))
    print(summary_line(results))
    return 0 if all(r["outcome"] == OK for r in results) else 1
