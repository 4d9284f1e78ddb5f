"""Bytes the distributed FFT's transposes pass to MPI per operator apply, from the decomposition
alone (the model the measured counters of ``SlabRFFT``/``PencilRFFT`` are checked against).

Slab (P ranks, rows ny_r, Fourier columns nkx_r): every rank sends its rows' columns of every
other rank, once forward and once backward,

    B = 2 * 16 B * (N_kx * N_y - sum_r nkx_r * ny_r).

Pencil (px x py blocks; rank (a, b) with block (ny_a, nx_b), x-pencil rows m_ab, Fourier
x-block nkx_b and its sub-block w_ab): forward, rank (a, b) sends

    8 B * nx_b * (ny_a - m_ab)            (block -> x-pencil, real)
    16 B * m_ab * (N_kx - nkx_b)          (x-pencil spectrum -> band)
    16 B * ny_a * (nkx_b - w_ab)          (band -> y-pencil)

and backward the same sum over the ranks.  Self-blocks are never sent.
"""
from __future__ import annotations


def slab_bytes(fft) -> int:
    nkx = [b - a for a, b in fft.kx_ranges]
    ny = [b - a for a, b in fft.y_ranges]
    return 2 * 16 * (fft.nkx * fft.ny - sum(k * h for k, h in zip(nkx, ny)))


def pencil_bytes(fft) -> int:
    from contactpetsc.fft import split_range
    total = 0
    for a, (ys, ye) in enumerate(fft.y_ranges):
        ny_a = ye - ys
        subs = split_range(ny_a, fft.px)
        for b, (xs, xe) in enumerate(fft.x_ranges):
            k0, k1 = fft.kxb_ranges[b]
            w = split_range(k1 - k0, fft.py)[a]
            m = subs[b][1] - subs[b][0]
            total += (8 * (xe - xs) * (ny_a - m) + 16 * m * (fft.nkx - (k1 - k0))
                      + 16 * ny_a * ((k1 - k0) - (w[1] - w[0])))
    return 2 * total


def transpose_bytes(fft) -> int:
    """Bytes all ranks pass to MPI per apply (forward + backward), self-blocks excluded."""
    if fft.size == 1:
        return 0
    return pencil_bytes(fft) if hasattr(fft, "px") else slab_bytes(fft)
