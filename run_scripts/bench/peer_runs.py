"""Running the peer codes' drivers (``run_scripts/peers``, each in its own venv) from the
benchmarks: ContactMechanics + Adhesion's command line and the JSON lines a driver prints."""
import json
import os
import subprocess

PEERS = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "peers")


def cm_adhesion_command(python, heights, dx, w, z0, potential, approaches, outdir, maxiter,
                        gtol=None, initial=None) -> list:
    """``peers/cm_adhesion.py`` on the heights file ``heights`` (E* = 1) at ``approaches``
    [m], fields saved in ``outdir``; ``initial``: a displacement file to start from."""
    cmd = [python, os.path.join(PEERS, "cm_adhesion.py"), "--surface", heights, "--dx", repr(dx),
           "--e-star", "1", "--w", repr(w), "--z0", repr(z0), "--potential", potential,
           "--offsets=" + ",".join(repr(a) for a in approaches), "--maxiter", str(maxiter),
           "--save-fields", outdir]
    if gtol is not None:
        cmd += ["--gtol", repr(gtol)]
    if initial is not None:
        cmd += ["--initial", initial]
    return cmd


def json_rows(cmd) -> tuple[list, str]:
    """(the JSON lines ``cmd`` printed, the tail of its stderr where it printed none and failed)."""
    res = subprocess.run(cmd, capture_output=True, text=True)
    rows = [json.loads(line) for line in res.stdout.splitlines() if line.startswith("{")]
    return rows, res.stderr[-2000:] if res.returncode != 0 and not rows else ""
