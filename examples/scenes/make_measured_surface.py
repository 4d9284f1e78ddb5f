"""Write measured_surface.txt: a 64 x 48 text matrix as an AFM export would give it.

A rough surface (random Fourier phases, power spectrum ~ q^-3.6 above a roll-off, seed 7,
about 3 nm rms) on a tilted sample (slope 0.01 along x, 0.004 along y), in nm, with the
comment lines of Gwyddion's "ASCII data matrix" export giving its extent and unit, so that a
scene reads nx, ny, dx, dy and the unit from the file.  Deterministic: rerunning it rewrites
the same file.

    python3 examples/scenes/make_measured_surface.py
"""
import os

import numpy as np

NX, NY, DX = 64, 48, 50.0          # nodes, spacing in nm (a 3.2 x 2.4 um scan)


def heights() -> np.ndarray:
    """(NX, NY) heights [nm], indexed [x, y]."""
    rng = np.random.default_rng(7)
    qx = 2 * np.pi * np.fft.fftfreq(NX, DX)[:, None]
    qy = 2 * np.pi * np.fft.rfftfreq(NY, DX)[None, :]
    q = np.hypot(qx, qy)
    amplitude = np.maximum(q, 2 * np.pi / 800.0) ** -1.8
    amplitude[0, 0] = 0.0
    phases = rng.standard_normal(q.shape) + 1j * rng.standard_normal(q.shape)
    h = np.fft.irfft2(amplitude * phases, s=(NX, NY))
    h *= 3.0 / h.std()
    x, y = np.meshgrid(np.arange(NX) * DX, np.arange(NY) * DX, indexing="ij")
    return h + 0.01 * x + 0.004 * y + 120.0     # the instrument's tilt and height offset


def main() -> None:
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "measured_surface.txt")
    with open(path, "w") as f:
        f.write(f"# Channel: Height\n# Width: {NX * DX / 1000:g} µm\n# Height: {NY * DX / 1000:g} µm\n"
                f"# Value units: nm\n")
        for line in heights().T:                 # one line per y, its columns along x
            f.write("\t".join(f"{v:.2f}" for v in line) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
