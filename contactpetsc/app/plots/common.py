"""What every plot shares: the Agg figure, SI prefixes, and reading a run's CSV files (numpy
only: importing this module imports no matplotlib)."""
from __future__ import annotations

import contextlib
import csv
import json

import numpy as np


def require() -> None:
    """ImportError with the remedy when matplotlib is missing (checked before a run starts)."""
    import importlib.util
    if importlib.util.find_spec("matplotlib") is None:
        raise ImportError("output.plots needs matplotlib: pip install matplotlib "
                          "(Debian: apt-get install python3-matplotlib)")


def figure(rows: int = 1, cols: int = 1, size=(6.4, 4.8), **kw):
    """(Figure, axes) on the Agg canvas: no pyplot, no display, no change to the caller's backend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, **kw)


def save(fig, path: str | None):
    if path:
        fig.savefig(path, dpi=120)
    return fig


def prefix(values, unit: str) -> tuple[float, str]:
    """(factor, label) of the SI prefix that puts the largest |value| in [1, 1000)."""
    finite = np.abs(np.asarray(values, float))
    finite = finite[np.isfinite(finite) & (finite > 0)]
    top = finite.max() if finite.size else 1.0
    for exponent, p in ((9, "G"), (6, "M"), (3, "k"), (0, ""), (-3, "m"), (-6, "µ"), (-9, "n"), (-12, "p")):
        if top >= 10.0 ** exponent:
            return 10.0 ** exponent, p + unit
    return 1e-15, "f" + unit


@contextlib.contextmanager
def reading(path: str):
    """Any failure to read ``path`` becomes a ValueError naming the file and its cause (a file
    that is not text, not JSON, truncated, or without a dataset or column the plot needs); one
    that already names the file passes unchanged."""
    try:
        yield
    except Exception as exc:  # noqa: BLE001 - every reader's failure, named
        if str(path) in str(exc):
            raise
        if isinstance(exc, UnicodeDecodeError) or isinstance(exc, csv.Error) and "NUL" in str(exc):
            cause = "not a text file (binary bytes)"
        elif isinstance(exc, json.JSONDecodeError):
            cause = f"not valid JSON ({exc})"
        elif isinstance(exc, KeyError):
            cause = f"no {exc}: the file is damaged or not a contactpetsc output"
        else:
            cause = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
        raise ValueError(f"cannot read {path}: {cause}") from None


def read_json(path: str) -> dict:
    """A run's JSON file (``scene.json``, ``summary.json``); a damaged one is a ValueError naming it."""
    with reading(path), open(path) as f:
        out = json.load(f)
        if not isinstance(out, dict):
            raise ValueError(f"cannot read {path}: a JSON {type(out).__name__}, not an object")
        return out


def read_csv(path: str, numeric: tuple = ()) -> dict:
    """The columns of a CSV file: float arrays where every entry parses (True/False as 1/0),
    lists of strings otherwise.  A row with missing or extra entries, or a ``numeric`` column
    entry that is not a number, is a ValueError naming the file and the row."""
    with reading(path):
        return _read_csv(path, numeric)


def _read_csv(path: str, numeric: tuple = ()) -> dict:
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        header = reader.fieldnames or []
    for n, r in enumerate(rows, 1):
        if None in r or any(r[c] is None for c in header):
            raise ValueError(f"{path}, row {n}: {len([c for c in header if r[c] is not None])} of {len(header)} "
                             "columns: the file is damaged (an interrupted run can leave a partial last row; "
                             "contactpetsc run --restart drops it)")
    out, words_to_numbers = {}, {"True": 1.0, "False": 0.0, "": np.nan}
    for name in header:
        words = [r[name] for r in rows]
        try:
            out[name] = np.array([words_to_numbers[w] if w in words_to_numbers else float(w)
                                  for w in words])
        except ValueError:
            if name in numeric:
                n = next(k for k, w in enumerate(words, 1) if not is_number(w))
                raise ValueError(f"{path}, row {n}: {name} = {words[n - 1]!r} is not a number: the file is "
                                 "damaged") from None
            out[name] = words
    missing = [c for c in numeric if c not in header]
    if missing:
        raise ValueError(f"{path}: no column {', '.join(missing)}")
    return out


def is_number(word: str) -> bool:
    """Whether ``word`` reads as a float (nan and inf included)."""
    try:
        float(word)
    except ValueError:
        return False
    return True
