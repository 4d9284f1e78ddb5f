"""The stability margin against a dense eigen-solve of the Hessian.

Independent truth: on a 16 x 16 grid the pencil A x = lambda (K^-1)_NN x on W (displacements
vanishing on the contact nodes C and, on a periodic cell, of zero mean) is solved densely with
numpy, K^-1 assembled column by column (the periodic Fourier inverse, or the inverse of the
isolated window's dense K).  The margin is 1 - lambda_max.  Each case is set at a stable and an
unstable scale of the work of adhesion (A is proportional to w): the estimate has the sign of the
truth, and equals it where stable; an unstable estimate may stop at the first Ritz value above
one, which is an upper bound of the margin.  Covered: LOBPCG (periodic, with and without contact
nodes) with each preconditioner (the compliance K; the adhesive cycle on the Hessian's pressure
form, which ``auto`` takes for the exponential law, A >= 0; the displacement-form cycle, which it
takes for the LJ laws), on an isolated window LOBPCG on the padded grid (with contact nodes, as
``auto`` takes it, and without) and Lanczos on A S (S through a CG on K_CC where there is contact).
"""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers.stability import stability_margin

N = 16
pytestmark = pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")  # no solve here


def _gap_field(grid, contact: bool):
    """Gaps [m] (z0 = 1) from 0 to 3 z0 over two bumps, zero (contact) where the bumps
    overlap if ``contact``; the global field, the same on every rank."""
    x = np.arange(grid.nx) * grid.dx
    X, Y = np.meshgrid(x, x)
    L = grid.nx * grid.dx
    g = 1.5 + 1.1 * np.cos(2 * np.pi * X / L) * np.cos(2 * np.pi * Y / L) + 0.4 * np.sin(4 * np.pi * (X + 0.3 * Y) / L)
    g = g - g.min() + (0.0 if contact else 0.6)
    return np.where(g < 0.3, 0.0, g) if contact else g


def _dense_inverse(pb):
    """K^-1 [Pa/m] as a dense (n, n) matrix, the same on every rank (collective): the periodic
    Fourier inverse, or the inverse of the isolated window's dense K."""
    return pb.op.as_dense(inverse=True) if pb.grid.periodic else np.linalg.inv(pb.op.as_dense())


def _dense_margin(kinv, d, contact, periodic):
    free = np.flatnonzero(~contact.reshape(-1))
    m = kinv[np.ix_(free, free)]
    a = np.diag(d.reshape(-1)[free])
    if periodic:   # an orthonormal basis of the zero-mean vectors on N
        q = np.linalg.qr(np.eye(len(free)) - 1.0 / len(free))[0][:, :len(free) - 1]
        m, a = q.T @ m @ q, q.T @ a @ q
    lm = np.linalg.cholesky(0.5 * (m + m.T))
    li = np.linalg.inv(lm)
    return 1.0 - np.linalg.eigvalsh(li @ a @ li.T)[-1]


@pytest.mark.parametrize("periodic,contact,law,preconditioner,method", [
    (True, True, "hardwall-lj", "auto", "auto"), (True, True, "hardwall-lj", "compliance", "auto"),
    (True, True, "exponential", "auto", "auto"), (True, True, "exponential", "multigrid", "auto"),
    (True, False, "lj", "auto", "auto"), (False, True, "exponential", "auto", "auto"),
    (False, True, "hardwall-lj", "auto", "lanczos"), (False, False, "lj", "auto", "padded")])
def test_margin_is_the_dense_pencil_s(coll, periodic, contact, law, preconditioner, method):
    grid = SurfaceGrid(N, N, 1.0, periodic=periodic)
    h = grid.create_vec(0.0)
    length = {"rho" if law == "exponential" else "z0": 1.0}
    gap_all = _gap_field(grid, contact)
    gap = gap_all[grid.ys:grid.ye].copy()
    tag = f"stab_{int(periodic)}{int(contact)}{law[:3]}{preconditioner[:3]}{method[:3]}_"
    truth = {}
    for w in (0.05, None, None):
        if w is None:   # the scales of w putting lambda_max at 0.5 and at 2
            lam0 = 1.0 - truth[0.05]
            w = 0.05 * (0.5 if len(truth) == 1 else 2.0) / lam0
        pb = AdhesiveProblem(grid, h, 1.0, make_law(law, work_of_adhesion=w, **length), prefix=tag,
                             stability_check=False)
        q = np.where(gap == 0.0, 1.0, 0.0) if contact else None
        d_all = pb.traction.nodal_derivative(gap_all)
        truth[w] = _dense_margin(_dense_inverse(pb), np.where(gap_all == 0.0, 0.0, d_all) if contact else d_all,
                                 gap_all == 0.0 if contact else np.zeros_like(gap_all, bool), periodic)
        if len(truth) == 1:
            assert truth[w] < 1.0   # the attractive zone has a positive top eigenvalue to scale
            continue
        margin, settled = stability_margin(pb, gap, q, steps=200, preconditioner=preconditioner, method=method)
        assert coll.all(settled)
        if truth[w] > 0:
            assert coll.max(abs(margin - truth[w])) < 1e-4
        else:
            assert coll.all(truth[w] <= margin < 0.0)
