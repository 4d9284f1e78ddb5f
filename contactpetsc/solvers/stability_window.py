"""The stability check on an isolated window (``stability.py``'s module doc): LOBPCG on the
padded grid, where the window has contact nodes and whole rows per rank, and Lanczos on A S
elsewhere; ``stability.stability_margin`` chooses between them."""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..lifetime import destroy_at_exit
from .descent_space import PaddedWindow
from .pc_registry import PRECONDITIONERS
from .stability import _lobpcg, preconditioner_choice
from .stability_pc import DisplacementCycle, padded_levels

#: iterations a window's LOBPCG (``auto``) takes with the compliance before the cycle: on the
#: hard-wall sphere's paths the compliance settles within them at Tabor 0.1-0.5 (dx = z0), and
#: an iteration of the cycle costs about two of the compliance's (docs/performance.md)
COMPLIANCE_FIRST = 8

#: the CG on K_CC inside S (Lanczos on a window) stops at this times Lanczos' tolerance
INNER_RTOL = 0.1


class _Compliance:
    """S x on full (ny_loc, nx) arrays vanishing outside N."""

    def __init__(self, problem, contact: np.ndarray, rtol: float):
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
            ksp.setTolerances(rtol=rtol, max_it=500)
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


def lanczos(problem, comm, d, contact, v, steps, tol):
    """(lambda_max estimate, settled) of A S by Lanczos in the S inner product from ``v``."""
    # S's relative error moves the Ritz value by about as much: a tenth of the stopping test's
    # tolerance keeps it below what Lanczos itself leaves
    S = _Compliance(problem, contact, rtol=INNER_RTOL * tol)
    dot = lambda u, w: comm.allreduce(float(np.vdot(u, w)))  # noqa: E731
    sv = S(v, np.empty_like(v))
    nrm = np.sqrt(dot(v, sv))
    if not nrm > 0.0:
        S.destroy()
        return 0.0, True   # A S vanishes on the positive part of A
    # the plain three-term recurrence, no re-orthogonalisation: only lambda_max is wanted,
    # and lost orthogonality only adds copies of converged Ritz values (Paige); the top
    # one still grows monotonically (T_k is a leading block of T_k+1) and stays below
    # lambda_max.  Two vectors instead of 2 x steps, at a fraction of the cost of full
    # re-orthogonalisation and with the same margins (docs/formulation.md, "Adhesive contact: unknowns and Newton")
    v, sv = v / nrm, sv / nrm
    v_prev = None
    alphas, betas = [], []
    lam, beta, settled = -np.inf, 0.0, True
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
        # Ritz values grow towards lambda_max: one above 1 already proves instability (to the
        # inner CG's tolerance)
        done = (beta2 <= 1e-28 * max(1.0, abs(new)) or new > 1.0
                or abs(new - lam) <= tol * max(1.0, abs(new)))
        lam = new
        if done:
            break
        if k == steps - 1:
            settled = False
        beta = np.sqrt(beta2)
        betas.append(beta)
        v_prev, v, sv = v, w / beta, sw / beta
    S.destroy()
    return lam, settled


def padded_lobpcg(problem, d, contact, steps, residual_tol, preconditioner="auto"):
    """(lambda_max estimate, settled) of a window's pencil by LOBPCG on its padded grid: the
    energy over the displacement u of the whole padded grid, 1/2 u . C^-1 u on it and the law on
    the window only, has on u = 0 at C the Hessian C^-1 - A; its minimum over the nodes outside
    the window is the window's own (K_w^-1)_NN - A (``descent_space`` module doc), so the pencil
    A x = lambda C^-1 x on the padded W has the window's lambda_max, and C^-1 is diagonal in
    Fourier space: no inner solve.  Preconditioned (``preconditioner``) by the compliance C, by
    the displacement cycle on the padded H = C^-1 - A (``multigrid``), or (``auto``) by C for
    ``COMPLIANCE_FIRST`` iterations and the cycle after them."""
    preconditioner = preconditioner_choice(preconditioner, "stability preconditioner")
    if preconditioner == "mlmi":
        raise ValueError("stability preconditioner 'mlmi' needs a periodic grid; a window's check takes "
                         "auto, compliance or multigrid")
    space = PaddedWindow(problem)
    shape = (space.grid.ny_local, space.grid.nx)
    d_pad, held = np.zeros(shape), np.zeros(shape, bool)
    d_pad[space.window] = space.from_problem(d)
    held[space.window] = space.from_problem(contact.astype(float)) > 0.5
    # A lives on the window's rows: its products there only
    rows = space.window[0]
    on_a = slice(rows.start * shape[1], rows.stop * shape[1])
    cycle = None
    if preconditioner != "compliance":
        after = COMPLIANCE_FIRST if preconditioner == "auto" else 0
        cycle = _CycleAfter(lambda: DisplacementCycle(padded_levels(problem, space), d_pad, held), after)
    try:
        return _lobpcg(space, problem.grid.mpi_comm, d_pad, held, steps, residual_tol,
                       precondition=cycle, project_mean=False, on_a=on_a)
    finally:
        if cycle is not None:
            cycle.release()


class _CycleAfter:
    """LOBPCG's preconditioner: the compliance (which ``_lobpcg`` has applied to the residual
    already) for the first ``after`` iterations, then the cycle ``make()`` builds.  LOBPCG
    takes a new preconditioner at any iteration: each Rayleigh-Ritz step only adds a direction."""

    def __init__(self, make, after: int):
        self.make, self.after, self.cycle = make, after, None

    def __call__(self, r, out):
        if self.after > 0:
            self.after -= 1
            return out
        if self.cycle is None:
            self.cycle = self.make()
        return self.cycle(r, out)

    def release(self):
        if self.cycle is not None:
            self.cycle.release()
            self.cycle = None
