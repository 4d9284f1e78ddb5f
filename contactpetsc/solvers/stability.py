"""Stability of a converged adhesive state: a Lanczos estimate.

Equilibria of adhesive contact are stationary points of the elastic plus
interaction energy.  In displacement space, with the contact nodes C held at
zero gap (their pressure is the multiplier), the Hessian on the other nodes N is

    H = (K^-1)_NN - A_N,      A = da/dg (the law's derivative),

and ((K^-1)_NN)^-1 = S = K_NN - K_NC K_CC^-1 K_CN, the compliance of N with C
clamped.  H is positive definite iff every eigenvalue of A S is below one
(congruence with S^1/2).  A S is self-adjoint in the S inner product, so
Lanczos in that inner product (one S product per step) gives its largest
eigenvalue, the well separated end of the spectrum: an instability is a
smooth mode over the attractive zone beyond the force peak, where A > 0.
The reported margin is 1 - lambda_max(A S), the smallest eigenvalue of
S^1/2 H S^1/2: positive = stable, negative = unstable.

S costs one FFT pair, plus (with contact nodes) a CG solve on K_CC
preconditioned by the Fourier inverse.  The nodal law derivative is used
also with element integration (its linearisation is not symmetric).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..lifetime import destroy_at_exit
from .pc_registry import PRECONDITIONERS


class _Compliance:
    """S x on full (ny_loc, nx) arrays vanishing outside N."""

    def __init__(self, problem, contact: np.ndarray):
        self.op, self.grid = problem.op, problem.grid
        grid = self.grid
        self.n_contact = grid.mpi_comm.allreduce(int(contact.sum()))
        self.contact = contact
        self.ksp = None
        if self.n_contact:
            from .reduced import ContactJacobian
            jac = ContactJacobian(self.op, problem.prefix + "stability_")
            J = destroy_at_exit(PETSc.Mat().createPython(
                ((grid.nx * grid.ny_local, grid.nx * grid.ny),) * 2, jac, comm=grid.comm))
            J.setUp()
            local = (np.flatnonzero(contact) + grid.nx * grid.ys).astype(PETSc.IntType)
            self.iset = PETSc.IS().createGeneral(local, comm=grid.comm)
            self.A = J.createSubMatrix(self.iset, self.iset)
            self.J = J
            ksp = self.ksp = PETSc.KSP().create(comm=grid.comm)
            ksp.setOptionsPrefix(problem.prefix + "stability_")
            ksp.setType("cg")
            ksp.setTolerances(rtol=1e-8, max_it=500)
            ksp.getPC().setType("python")
            ksp.getPC().setPythonType(PRECONDITIONERS["spectral"])
            ksp.setOperators(self.A, self.A)
            ksp.setFromOptions()
            self.b, self.y = self.A.createVecs()
            self.ctx = self.A.getPythonContext()
        self.tmp = np.zeros((grid.ny_local, grid.nx))

    def __call__(self, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        self.op.apply(x, out)
        if self.ksp is not None:
            # pressures on C that bring the displacement there back to zero
            self.ctx.from_full(-out, self.b)
            self.ksp.solve(self.b, self.y)
            self.tmp[...] = 0.0
            self.ctx.to_full(self.y, self.tmp)
            out += self.op.apply(self.tmp, np.empty_like(out))
            out[self.contact] = 0.0
        return out

    def destroy(self):
        if self.ksp is not None:
            for obj in (self.ksp, self.A, self.iset, self.b, self.y, self.J):
                obj.destroy()


def stability_margin(problem, gap: np.ndarray, q_rows: np.ndarray | None, steps: int = 30,
                     tol: float = 1e-4) -> float:
    """1 - lambda_max(A S) at the rank's gap rows ``gap`` [m] (ny_loc, nx) of the problem's
    state, contact pressures ``q_rows`` [Pa] (hard wall) or None (see the module doc); collective.

    Sets ``problem.stability_converged``: False when Lanczos ran its ``steps`` without
    the Ritz value settling to ``tol``.  The Ritz value only grows towards lambda_max, so
    an unsettled positive margin is an upper bound: the state may still be unstable
    (seen on rough surfaces, whose top of A S is a cluster of asperity modes)."""
    problem.stability_converged = True
    grid = problem.grid
    comm = grid.mpi_comm
    d = problem.traction.nodal_derivative(gap)
    contact = (q_rows > 0) if q_rows is not None else np.zeros(gap.shape, bool)
    d = np.where(contact, 0.0, d)
    if comm.allreduce(float(d.max()), op=MPI.MAX) <= 0.0:
        return 1.0   # A <= 0: A S has no positive eigenvalue
    S = _Compliance(problem, contact)
    dot = lambda u, w: comm.allreduce(float(np.vdot(u, w)))  # noqa: E731
    # start: the positive part of A (the attractive zone beyond the force peak), varied
    # from node to node by a fixed hash of the global index (rank-count independent), so
    # that it has every Fourier mode: a uniform start is in the null space of the
    # periodic compliance (the mean mode)
    index = (np.arange(grid.ys, grid.ye)[:, None] * grid.nx + np.arange(grid.nx)[None, :]).astype(float)
    v = np.maximum(d, 0.0) * (1.0 + 0.5 * np.modf(np.abs(np.sin(index * 12.9898)) * 43758.5453)[0])
    sv = S(v, np.empty_like(v))
    nrm = np.sqrt(dot(v, sv))
    if not nrm > 0.0:
        return 1.0   # A S vanishes on the positive part of A
    # the plain three-term recurrence, no re-orthogonalisation: only lambda_max is wanted,
    # and lost orthogonality only adds copies of converged Ritz values (Paige); the top
    # one still grows monotonically (T_k is a leading block of T_k+1) and stays below
    # lambda_max.  Two vectors instead of 2 x steps, at a fraction of the cost of full
    # re-orthogonalisation and with the same margins (docs/formulation.md, "Adhesive contact: unknowns and Newton")
    v, sv = v / nrm, sv / nrm
    v_prev = None
    alphas, betas = [], []
    lam, beta = -np.inf, 0.0
    for k in range(steps):
        w = d * sv                           # T v_k = A S v_k
        alpha = dot(sv, w)
        alphas.append(alpha)
        w -= alpha * v
        if v_prev is not None:
            w -= beta * v_prev
        sw = S(w, np.empty_like(w))
        beta2 = dot(w, sw)
        T = np.diag(alphas) + np.diag(betas, 1) + np.diag(betas, -1)
        new = float(np.linalg.eigvalsh(T)[-1])
        # Ritz values grow towards lambda_max: one above 1 already proves instability
        done = (beta2 <= 1e-28 * max(1.0, abs(new)) or new > 1.0
                or abs(new - lam) <= tol * max(1.0, abs(new)))
        lam = new
        if done:
            break
        if k == steps - 1:
            problem.stability_converged = False
        beta = np.sqrt(beta2)
        betas.append(beta)
        v_prev, v, sv = v, w / beta, sw / beta
    S.destroy()
    return 1.0 - lam

