"""Elastic half-space operators and the slab FFT, checked against closed forms.

Truths used: Love's / Johnson's rectangle formula evaluated with mpmath, the
Westergaard sinusoid, Hertz's pressure-displacement pair, the symmetry and
definiteness of an elastic compliance, a padded circulant built here with
numpy, numpy's FFT, and serial == MPI.
"""
import mpmath
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.fft import SlabRFFT
from contactpetsc.grid import SurfaceGrid
from contactpetsc.operators import IsolatedHalfSpace, PeriodicHalfSpace, love_displacement

E_STAR = 2.0e11          # Pa
PLANNER = "estimate"     # no FFTW_MEASURE planning time in the tests


# -- helpers ------------------------------------------------------------------
def johnson(x, y, a, b, e_star):
    """Johnson, Contact Mechanics eq. 3.25 (log-ratio form, 4 terms), 30 digits.

    Displacement at (x, y) under unit pressure on |x'| <= a, |y'| <= b; a term
    whose factor is exactly zero is zero (its logarithm's argument may vanish).
    """
    with mpmath.workdps(30):
        x, y, a, b = (mpmath.mpf(float(v)) for v in (x, y, a, b))

        def r(u, v):
            return mpmath.sqrt(u * u + v * v)

        def term(c, num, den):
            return mpmath.mpf(0) if c == 0 else c * mpmath.log(num / den)

        s = (term(x + a, (y + b) + r(x + a, y + b), (y - b) + r(x + a, y - b))
             + term(y + b, (x + a) + r(x + a, y + b), (x - a) + r(x - a, y + b))
             + term(x - a, (y - b) + r(x - a, y - b), (y + b) + r(x - a, y + b))
             + term(y - b, (x - a) + r(x - a, y - b), (x + a) + r(x + a, y - b)))
        return s / (mpmath.pi * mpmath.mpf(float(e_star)))


def apply_mat(mat, grid, array):
    """Gathered (nx, ny) result of mat * array (array: the same global array on every rank)."""
    x = grid.vec_from_array(array)
    y = grid.create_vec()
    mat.mult(x, y)
    return grid.gather(y)


def random_field(shape, seed):
    """The same global random array on every rank (rank-independent input)."""
    return np.random.default_rng(seed).standard_normal(shape)


def make_op(kind, nx, ny, dx, dy, comm=None):
    g = SurfaceGrid(nx, ny, dx, dy, periodic=(kind == "periodic"), comm=comm)
    cls = PeriodicHalfSpace if kind == "periodic" else IsolatedHalfSpace
    return g, cls(g, E_STAR, planner=PLANNER)


def rel_max(a, ref):
    return np.max(np.abs(a - ref)) / np.max(np.abs(ref))


# -- 1. Love's rectangle -----------------------------------------------------------
def test_love_displacement_matches_johnson(coll):
    """love_displacement == eq. 3.25 at 30 digits, incl. axes, element edges and corners."""
    a, b = 0.65e-6, 0.35e-6            # half-widths of a dx != dy element
    units = [(0, 0), (0.5, 0), (0, 0.5), (1, 0), (0, 1), (-1, 0), (0, -3), (1, 1), (0.3, 0.7),
             (1, 0.2), (0.4, 1), (1, 1), (-1, -1), (1, -1), (3, 0), (0, 7), (2, 3), (-5, 2),
             (0.9999, 1.0001), (39 * 2, 0), (0, 31 * 2), (39 * 2, 31 * 2), (-50, 34), (25, -61)]
    pts = [(ua * a, ub * b) for ua, ub in units]      # (1, 0) = edge x = a, (1, 1) = corner
    pts += [(0.0, b * (1 + 1e-9)), (a * (1 - 1e-9), 0.0)]   # just outside / inside an edge
    x, y = np.array(pts).T
    got = love_displacement(x, y, a, b, E_STAR)
    ref = np.array([float(johnson(xi, yi, a, b, E_STAR)) for xi, yi in pts])
    assert coll.max(np.abs(got - ref) / ref) <= 1e-12
    # Even in x and y; p/(pi E*) scaling; far field -> point load P/(pi E* r), P = 4ab
    assert coll.max(np.abs(love_displacement(-x, -y, a, b, E_STAR) - got) / got) <= 1e-15
    assert coll.max(np.abs(love_displacement(x, y, a, b, 1.0) / E_STAR - got) / got) <= 1e-15
    r = np.array([1e3, 1e4]) * a
    point = 4 * a * b / (np.pi * E_STAR * r)
    assert coll.max(np.abs(love_displacement(r, 0 * r, a, b, E_STAR) / point - 1)) <= 1e-6


def test_love_displacement_far_field(coll):
    """Far from the element the 4-corner sum cancels (terms ~ r, result ~ ab/r): the relative
    error grows ~ (r/a)^2 (4e-10 at 700 x 700 elements), but relative to the self-influence,
    the scale of the matrix, it stays below 1e-12 out to 10^4 elements."""
    a, b = 0.65e-6, 0.35e-6
    pts = [(1000 * 2 * a, 2 * b), (10000 * 2 * a, 3 * 2 * b), (700 * 2 * a, 700 * 2 * b),
           (-3000 * 2 * a, 2000 * 2 * b)]
    x, y = np.array(pts).T
    got = love_displacement(x, y, a, b, E_STAR)
    ref = np.array([float(johnson(xi, yi, a, b, E_STAR)) for xi, yi in pts])
    k00 = float(johnson(0, 0, a, b, E_STAR))
    assert coll.max(np.abs(got - ref) / ref) <= 1e-8
    assert coll.max(np.abs(got - ref) / k00) <= 1e-12


def test_isolated_single_element_matches_johnson(coll):
    """Unit pressure on one element of a 40 x 32 grid (dx != dy): near and far displacements."""
    nx, ny, dx, dy = 40, 32, 1.3e-6, 0.7e-6
    g, op = make_op("isolated", nx, ny, dx, dy)
    i0, j0 = 2, 1
    p = np.zeros((nx, ny))
    p[i0, j0] = 1.0
    u = apply_mat(op.as_mat(), g, p)
    near = [(i0 + di, j0 + dj) for di in (-1, 0, 1) for dj in (-1, 0, 1)]
    far = [(nx - 1, ny - 1), (nx - 1, 0), (0, ny - 1), (nx // 2, ny - 1)]
    errs = []
    for i, j in near + far:
        ref = float(johnson((i - i0) * dx, (j - j0) * dy, dx / 2, dy / 2, E_STAR))
        errs.append(abs(u[i, j] - ref) / ref)
    assert coll.max(errs) <= 1e-12
    # the whole window, against the library's own coefficient function (FFT round-off only)
    ii, jj = np.meshgrid(np.arange(nx) - i0, np.arange(ny) - j0, indexing="ij")
    coeff = love_displacement(ii * dx, jj * dy, dx / 2, dy / 2, E_STAR)
    assert coll.max(np.abs(u - coeff) / coeff) <= 1e-13
    assert coll.max(abs(op.self_influence - float(johnson(0, 0, dx / 2, dy / 2, E_STAR)))
                    / op.self_influence) <= 1e-13


def test_isolated_equals_dense_love_matrix(coll):
    """K p == sum_j K(x_i - x_j) p_j with the dense matrix of Love coefficients (ny = 11, uneven)."""
    nx, ny, dx, dy = 7, 11, 0.9, 0.4
    g, op = make_op("isolated", nx, ny, dx, dy)
    xi, yj = np.meshgrid(np.arange(nx) * dx, np.arange(ny) * dy, indexing="ij")
    X, Y = xi.ravel(), yj.ravel()
    dense = love_displacement(X[:, None] - X[None, :], Y[:, None] - Y[None, :], dx / 2, dy / 2, E_STAR)
    p = random_field((nx, ny), 3)
    u = apply_mat(op.as_mat(), g, p)
    assert coll.max(rel_max(u.ravel(), dense @ p.ravel())) <= 1e-13


# -- 2. Westergaard sinusoid --------------------------------------------------------
@pytest.mark.parametrize("mx, my", [(1, 0), (0, 1), (1, 1), (3, -2), (5, 7), (12, 7), (7, -6)])
def test_periodic_sinusoid_exact(coll, mx, my):
    """p0 cos(qx x + qy y) -> (2 p0 / (E* |q|)) cos(qx x + qy y) on a 24 x 15 cell, dx != dy."""
    nx, ny, dx, dy, p0 = 24, 15, 0.4e-6, 0.9e-6, 3.0e6
    g, op = make_op("periodic", nx, ny, dx, dy)
    lx, ly = g.lengths
    qx, qy = 2 * np.pi * mx / lx, 2 * np.pi * my / ly
    x, y = np.meshgrid(np.arange(nx) * dx, np.arange(ny) * dy, indexing="ij")
    phase = qx * x + qy * y
    u = apply_mat(op.as_mat(), g, p0 * np.cos(phase))
    amp = 2 * p0 / (E_STAR * np.hypot(qx, qy))
    assert coll.max(np.abs(u - amp * np.cos(phase)) / amp) <= 1e-12


def test_periodic_uniform_pressure_gives_zero(coll):
    nx, ny, dx, dy, p0 = 24, 15, 0.4e-6, 0.9e-6, 3.0e6
    g, op = make_op("periodic", nx, ny, dx, dy)
    u = apply_mat(op.as_mat(), g, np.full((nx, ny), p0))
    scale = 2 * p0 / (E_STAR * 2 * np.pi / max(g.lengths))   # the lowest mode's response
    assert coll.max(np.abs(u) / scale) <= 1e-14


# -- 3. Hertz ------------------------------------------------------------------------
def hertz_errors(n, a=1.0e-5, p0=1.0e8):
    """Max and rms error of the isolated operator on the Hertz pressure, inside and outside
    the contact, relative to u(0), for dx = dy = a/n on a window of about 2.5a x 2.5a."""
    dx = a / n
    nx = 2 * int(np.ceil(1.25 * n)) + 1
    ny = nx + 2
    g, op = make_op("isolated", nx, ny, dx, dx)
    x = (np.arange(nx) - nx // 2) * dx
    y = (np.arange(ny) - ny // 2) * dx
    r = np.hypot(x[:, None], y[None, :])
    p = p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0.0, None))
    u = apply_mat(op.as_mat(), g, p)
    inside = r <= a
    u_in = np.pi * p0 * (2 * a ** 2 - r ** 2) / (4 * a * E_STAR)
    # Johnson eq. 3.42b for r > a (tends to P/(pi E* r), P = 2 pi p0 a^2 / 3)
    ro = np.where(inside, 2 * a, r)
    u_out = p0 / (2 * a * E_STAR) * ((2 * a ** 2 - ro ** 2) * np.arcsin(a / ro)
                                    + a * np.sqrt(ro ** 2 - a ** 2))
    u0 = np.pi * p0 * a / (2 * E_STAR)
    e_in = (u - u_in)[inside] / u0
    e_out = (u - u_out)[~inside] / u0
    return (np.max(np.abs(e_in)), np.sqrt(np.mean(e_in ** 2)),
            np.max(np.abs(e_out)), np.sqrt(np.mean(e_out ** 2)))


def test_hertz_convergence(coll):
    """Hertz pressure -> Hertz displacement, converging with dx = a/8 ... a/64.

    The nodal pressure acts as a piecewise constant on elements and has a square-root
    edge, so one expects ~1.5 in rms and ~1 in max.  Observed (this discretisation,
    errors relative to u(0)): max-norm order 1.39 inside, 1.30 outside; rms order 1.98
    inside, 1.95 outside; finest max error 7.7e-4 u(0) inside, 7.4e-4 outside.
    """
    ns = np.array([8, 16, 32, 64])
    errs = np.array([hertz_errors(n) for n in ns])          # columns: max_in, rms_in, max_out, rms_out
    errs = np.array([[coll.max(e) for e in row] for row in errs])
    orders = [-np.polyfit(np.log(ns), np.log(errs[:, k]), 1)[0] for k in range(4)]
    assert orders[0] >= 1.3, orders      # max norm inside
    assert orders[1] >= 1.85, orders     # rms inside
    assert orders[2] >= 1.2, orders      # max norm outside
    assert orders[3] >= 1.85, orders     # rms outside
    assert np.all(np.diff(errs, axis=0) < 0), errs           # monotone
    assert errs[-1, 0] < 1e-3 and errs[-1, 2] < 1e-3, errs   # finest: < 0.1 % of u(0)


# -- 4. symmetry and definiteness --------------------------------------------------------
@pytest.mark.parametrize("kind", ["periodic", "isolated"])
def test_symmetric_positive(coll, kind):
    """<Kx, y> = <x, Ky> and <x, Kx> > 0 (periodic: zero-mean x; <1, K1> = 0)."""
    nx, ny, dx, dy = 20, 37, 0.5e-6, 0.8e-6
    g, op = make_op(kind, nx, ny, dx, dy)
    K = op.as_mat()
    sym_err, energies = [], []
    for seed in range(4):
        x, y = random_field((nx, ny), seed), random_field((nx, ny), 100 + seed)
        if kind == "periodic":
            x -= x.mean()
            y -= y.mean()
        vx, vy = g.vec_from_array(x), g.vec_from_array(y)
        kx, ky = g.create_vec(), g.create_vec()
        K.mult(vx, kx)
        K.mult(vy, ky)
        exx, eyy = kx.dot(vx), ky.dot(vy)
        sym_err.append(abs(kx.dot(vy) - vx.dot(ky)) / np.sqrt(exx * eyy))
        energies.append(exx / (vx.dot(vx) * op.self_influence))
    assert coll.max(sym_err) <= 1e-13
    assert -coll.max(-np.array(energies)) > 1e-3      # min over rank and samples: strictly positive
    one = g.create_vec(1.0)
    k1 = g.create_vec()
    K.mult(one, k1)
    e1 = k1.dot(one) / (g.nx * g.ny * op.self_influence)
    if kind == "periodic":
        assert coll.max(abs(e1)) <= 1e-14
    else:
        assert -coll.max(-e1) > 0.1
    # the Mat reports its symmetry, and its transpose product equals its product
    kt = g.create_vec()
    K.multTranspose(one, kt)
    assert K.isSymmetricKnown()[1] and kt.equal(k1)


@pytest.mark.parametrize("kind", ["periodic", "isolated"])
def test_diagonal_is_self_influence(coll, kind):
    """The Mat's diagonal = (K e_k)_k: the displacement of a loaded node itself."""
    nx, ny, dx, dy = 12, 9, 0.5, 0.8
    g, op = make_op(kind, nx, ny, dx, dy)
    K = op.as_mat()
    d = g.create_vec()
    K.getDiagonal(d)
    diag = g.gather(d)
    errs = []
    for (i, j) in [(0, 0), (5, 4), (11, 8)]:
        e = np.zeros((nx, ny))
        e[i, j] = 1.0
        errs.append(abs(diag[i, j] - apply_mat(K, g, e)[i, j]) / abs(diag[i, j]))
    assert coll.max(errs) <= 1e-13 and coll.max(np.ptp(diag) / diag.max()) == 0.0


# -- 5. inverses -----------------------------------------------------------------------
def test_periodic_inverse(coll):
    """K K^-1 = K^-1 K = I on zero-mean fields; K^-1 returns zero-mean pressures."""
    nx, ny, dx, dy = 18, 37, 0.5e-6, 0.3e-6
    g, op = make_op("periodic", nx, ny, dx, dy)
    K, Kinv = op.as_mat(), op.as_mat(inverse=True)
    x = random_field((nx, ny), 11)
    x -= x.mean()
    kkinv = apply_mat(K, g, apply_mat(Kinv, g, x))
    kinvk = apply_mat(Kinv, g, apply_mat(K, g, x))
    assert coll.max(rel_max(kkinv, x)) <= 1e-12 and coll.max(rel_max(kinvk, x)) <= 1e-12
    p = apply_mat(Kinv, g, random_field((nx, ny), 12) + 5.0)
    assert coll.max(abs(p.mean()) / np.abs(p).max()) <= 1e-13


def padded_circulant_hat(nx, ny, dx, dy, e_star):
    """Spectrum of the 2nx x 2ny circulant of Love coefficients, built directly with numpy."""
    sx = np.arange(2 * nx)
    sy = np.arange(2 * ny)
    sx = np.where(sx <= nx, sx, sx - 2 * nx) * dx     # signed offsets: Love is even in x and y
    sy = np.where(sy <= ny, sy, sy - 2 * ny) * dy
    c = love_displacement(sx[:, None], sy[None, :], dx / 2, dy / 2, e_star)
    return np.fft.rfft2(c)


def test_isolated_inverse_is_padded_circulant_inverse(coll):
    """apply_inverse == irfft2(rfft2(pad x) / C_hat) on the window; C_hat > 0 everywhere."""
    nx, ny, dx, dy = 12, 9, 0.6e-6, 1.1e-6
    g, op = make_op("isolated", nx, ny, dx, dy)
    c_hat = padded_circulant_hat(nx, ny, dx, dy, E_STAR)
    assert coll.max(np.abs(c_hat.imag) / np.abs(c_hat.real).max()) <= 1e-14   # symmetric circulant
    c_hat = c_hat.real
    x = random_field((nx, ny), 21)
    pad = np.zeros((2 * nx, 2 * ny))
    pad[:nx, :ny] = x
    ref_inv = np.fft.irfft2(np.fft.rfft2(pad) / c_hat, s=pad.shape)[:nx, :ny]
    ref_fwd = np.fft.irfft2(np.fft.rfft2(pad) * c_hat, s=pad.shape)[:nx, :ny]
    got_inv = apply_mat(op.as_mat(inverse=True), g, x)
    got_fwd = apply_mat(op.as_mat(), g, x)
    assert coll.max(rel_max(got_inv, ref_inv)) <= 1e-12
    assert coll.max(rel_max(got_fwd, ref_fwd)) <= 1e-13
    # all eigenvalues of the padded circulant are positive; min_eigenvalue is numpy's min
    assert c_hat.min() > 0 and op.min_eigenvalue > 0
    assert coll.max(abs(op.min_eigenvalue - c_hat.min()) / c_hat.max()) <= 1e-13


# -- 6. rank independence -------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["periodic", "isolated"])
def test_operator_rank_independent(coll, kind):
    """COMM_WORLD (1, 2 or 3 ranks, ny = 37 split unevenly) == COMM_SELF to 1e-12, over a
    sequence of products (K, K^-1 on a displacement-sized field, K again): no state leaks
    from one FFT pair into the next, so repeating a product repeats its result."""
    nx, ny, dx, dy = 16, 37, 0.7e-6, 0.45e-6
    p1, p2 = random_field((nx, ny), 5), random_field((nx, ny), 6)
    results = {}
    for name, comm in (("world", PETSc.COMM_WORLD), ("self", PETSc.COMM_SELF)):
        g, op = make_op(kind, nx, ny, dx, dy, comm=comm)
        K, Kinv = op.as_mat(), op.as_mat(inverse=True)
        u1 = apply_mat(K, g, p1)
        q = apply_mat(Kinv, g, u1[::-1, ::-1].copy())   # a displacement, not the one just made
        u2 = apply_mat(K, g, p2)
        u1_again = apply_mat(K, g, p1)
        results[name] = (u1, q, u2, u1_again, op.self_influence)
    w, s = results["world"], results["self"]
    errs = [rel_max(a, b) for a, b in zip(w[:4], s[:4])]
    assert coll.max(errs) <= 1e-12, errs
    assert coll.max(rel_max(w[3], w[0])) == 0.0 and coll.max(rel_max(s[3], s[0])) == 0.0
    assert coll.max(abs(w[4] - s[4]) / s[4]) <= 1e-13


# -- the slab FFT under the operators ------------------------------------------------------
@pytest.mark.parametrize("pad", [False, True])
def test_slab_fft_matches_numpy(coll, pad):
    """forward == numpy's rfft2 (in spectral_layout), backward(forward) == Nx Ny x identity,
    wavevectors == 2 pi k / L, and Parseval with hermitian_weights; ny = 37 split unevenly."""
    nx, ny, lx, ly = 10, 37, 3.0, 5.0
    g = SurfaceGrid(nx, ny, lx / nx, ly / ny)
    f = SlabRFFT(g.mpi_comm, nx, ny, g.y_ranges, pad=pad, planner=PLANNER)
    a = random_field((nx, ny), 9)
    full = np.zeros((f.Nx, f.Ny))
    full[:nx, :ny] = a
    ref = np.fft.rfft2(full.T).T[f.kx0:f.kx1]                 # [kx, ky]
    spec = f.forward(np.ascontiguousarray(a[:, g.ys:g.ye].T)).copy()
    err_fwd = np.max(np.abs(spec - f.spectral_layout(ref)), initial=0)
    lxp, lyp = (2 * lx, 2 * ly) if pad else (lx, ly)
    qx, qy = f.wavevectors(lxp, lyp)
    kx = np.arange(f.kx0, f.kx1)[:, None] + 0 * np.arange(f.Ny)[None, :]
    ky = np.fft.fftfreq(f.Ny, 1.0 / f.Ny)[None, :] + 0 * kx
    err_q = max(np.max(np.abs(qx - f.spectral_layout(2 * np.pi * kx / lxp)), initial=0),
                np.max(np.abs(qy - f.spectral_layout(2 * np.pi * ky / lyp)), initial=0))
    parseval = g.mpi_comm.allreduce(float(np.sum(f.hermitian_weights() * np.abs(spec) ** 2)))
    out = np.empty((g.ny_local, nx))
    f.backward(out)
    err_bwd = np.max(np.abs(out / (f.Nx * f.Ny) - a[:, g.ys:g.ye].T), initial=0)
    assert coll.max(err_fwd / np.sqrt(nx * ny)) <= 1e-14     # |a_hat| ~ sqrt(N) for unit noise
    assert coll.max(err_q) <= 1e-13
    assert coll.max(abs(parseval / (f.Nx * f.Ny) / np.sum(a ** 2) - 1)) <= 1e-13
    assert coll.max(err_bwd) <= 1e-14



def test_fft_reads_and_writes_any_rows_alike(coll):
    """The transform's real-side plan runs in place on suitable rows (C order, aligned like a
    PETSc Vec's array, read-only allowed) and through its own buffers otherwise: the same plan,
    so the same bits either way, on any number of ranks; the inverse to round-off."""
    ny, nx = 48, 40
    g = SurfaceGrid(nx, ny, 1.0, 1.0)
    f = SlabRFFT(g.mpi_comm, nx, ny, g.y_ranges, planner=PLANNER)
    a = random_field((ny, nx), 4)[g.ys:g.ye]
    m = a.shape[0]
    base = np.empty(m * nx + 3)
    kinds = {"aligned": a.copy(), "offset by one double": base[1:m * nx + 1].reshape(m, nx),
             "strided": np.asfortranarray(a), "read-only": a.copy()}
    kinds["offset by one double"][...] = a
    kinds["read-only"].flags.writeable = False
    vec = g.create_vec()
    kinds["PETSc Vec"] = g.rows(vec)
    kinds["PETSc Vec"][...] = a
    spectra = {k: f.forward(rows).copy() for k, rows in kinds.items()}
    outs = {}
    for k, rows in kinds.items():
        out = np.empty((m, nx)) if k == "read-only" else rows
        f.spectrum[...] = spectra["aligned"]
        outs[k] = f.backward(out).copy()
    assert coll.all(all(np.array_equal(s_, spectra["aligned"]) for s_ in spectra.values()))
    assert coll.all(all(np.array_equal(o, outs["aligned"]) for o in outs.values()))
    assert coll.max(np.max(np.abs(outs["aligned"] / (nx * ny) - a))) <= 1e-14
    vec.destroy()


def test_fft_threads_auto_and_checked(coll):
    """-elastic_fft_threads auto: between 1 and the rank's cores, and K p equal to the
    single-threaded one to round-off; a bad value is refused naming the option."""
    import os

    from contactpetsc.operators.elastic import fft_threads
    g = SurfaceGrid(24, 20, 0.1)
    n = fft_threads(g.mpi_comm, "auto")
    assert coll.all(1 <= n <= len(os.sched_getaffinity(0)))
    p = np.random.default_rng(2).standard_normal(g.local_shape)
    one, auto = np.empty_like(p), np.empty_like(p)
    PeriodicHalfSpace(g, 1.0, threads=1, planner=PLANNER).apply(p, one)
    PeriodicHalfSpace(g, 1.0, threads=n, planner=PLANNER).apply(p, auto)
    assert coll.max(np.max(np.abs(auto - one)) / np.max(np.abs(one))) < 1e-14
    coll.raises(ValueError, ["elastic_fft_threads", "auto"], fft_threads, g.mpi_comm, "two",
                "elastic_fft_threads")
