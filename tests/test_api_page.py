"""docs/api.md is the reference of the public API: every name of ``contactpetsc.__all__`` is on
it, and its blocks marked ``python runnable`` run as written (their asserts check closed forms
and units), in order and in one namespace, serially and under ``mpirun -n 2`` (collective)."""
import re
import warnings
from pathlib import Path

import contactpetsc

PAGE = Path(__file__).resolve().parent.parent / "docs" / "api.md"
BLOCK = re.compile(r"^```python runnable\n(.*?)^```", re.S | re.M)


def test_every_public_name_is_on_the_page():
    text = PAGE.read_text()
    # named as code: in backticks, called or imported (not a word of the prose: "sweep", "sphere")
    missing = [name for name in contactpetsc.__all__
               if not re.search(rf"`{name}\b|\b{name}\(|import [^\n]*\b{name}\b", text)]
    assert not missing, f"docs/api.md lacks {missing}"


def test_the_runnable_blocks_run(coll):
    blocks = BLOCK.findall(PAGE.read_text())
    assert len(blocks) >= 8
    namespace = {}
    failure = None
    with warnings.catch_warnings():
        warnings.simplefilter("error")     # an example that warns is not the behaviour it shows
        for k, code in enumerate(blocks):
            try:
                exec(compile(code, f"{PAGE.name}, runnable block {k + 1}", "exec"), namespace)
            except Exception as exc:  # noqa: BLE001 - reported collectively below
                failure = f"block {k + 1}: {type(exc).__name__}: {exc}\n{code}"
                break
    assert coll.all(failure is None), failure
