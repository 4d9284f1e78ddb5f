"""Projected preconditioned CG: the Newton step of load control, K_II y = b + mu 1 with sum(y) = c.

Under load control the approach delta is the Lagrange multiplier of the load constraint
sum(p) = n W (docs/formulation.md, "Controls").  One Newton step of the joint problem in
(p, delta) on the inactive set I solves the saddle-point system

    K_II y - mu 1 = b,      1^T y = c,

(b the gap on I, c = sum(p) - n W, the step p <- p - y, delta <- delta + mu), which is the
energy minimisation of 1/2 y^T K_II y - b^T y on the affine plane 1^T y = c.  CG on that plane
(Gould, Hribar and Nocedal 2001) needs only the projected preconditioner

    M~ r = M r - u (1^T M r) / (1^T u),      u = M 1,

whose range has zero sum, so every search direction stays in the plane; the start
y0 = c u / (1^T u) is in it.  The residual r = b - K_II y would tend to -mu 1, invisible to
M~: it is kept free of that multiple at every step, and convergence is judged on the
preconditioned norm |M~ r|.  Cost: one FFT pair per iteration
for K_II and one for M, plus two per solve (u and the start's residual).
"""
from __future__ import annotations

from petsc4py import PETSc


class ProjectedCG:
    """Python-context KSP (``KSPPYTHON``): CG on {1^T y = c}; ``constraint()`` gives c."""

    def __init__(self, constraint, forcing=None, keep_u=None):
        self.constraint = constraint   #: callable -> (c, the |c| below which the start is y = 0)
        self.forcing = forcing         #: callable (rtol) -> this step's rtol, or None: the KSP's
        self.keep_u = keep_u           #: callable (A, u), given each solve's u = M 1, or None

    def setUp(self, ksp):
        pass

    def view(self, ksp, viewer=None):
        if viewer is not None and viewer.getType() == "ascii":
            viewer.printfASCII("  contactpetsc ProjectedCG: CG on sum(y) = c (load control's Newton step)\n")

    def solve(self, ksp, b, y):
        A, _ = ksp.getOperators()
        pc = ksp.getPC()
        rtol, atol, _, max_it = ksp.getTolerances()
        if self.forcing is not None:
            rtol = self.forcing(rtol)

        ones, u = b.duplicate(), b.duplicate()
        r, z, d, q = b.duplicate(), b.duplicate(), b.duplicate(), b.duplicate()
        try:
            ones.set(1.0)
            pc.apply(ones, u)
            s = ones.dot(u)
            if self.keep_u is not None:
                self.keep_u(A, u)
            c, negligible = self.constraint()
            # the start on the plane; its residual b - K_II y0
            y.set(0.0)
            if abs(c) <= negligible:
                c = 0.0
            if c:
                y.axpy(c / s, u)
                A.mult(y, r)
                r.aypx(-1.0, b)
            else:
                b.copy(r)

            def project(res, out):
                # M~ r = M (r - t 1), t = 1^T M r / s; r itself is replaced by r - t 1 (the same
                # M~ r and r^T z), so the growing multiple of 1 in r cannot swamp its projection
                # in round-off (Gould, Hribar and Nocedal's residual update)
                pc.apply(res, out)
                t = ones.dot(out) / s
                out.axpy(-t, u)
                res.shift(-t)

            project(r, z)
            rz = r.dot(z)
            norm0 = z.norm()
            ksp.setResidualNorm(norm0)
            z.copy(d)
            its, reason = 0, PETSc.KSP.ConvergedReason.CONVERGED_ITERATING
            if norm0 <= atol:
                reason = PETSc.KSP.ConvergedReason.CONVERGED_ATOL
            while reason == PETSc.KSP.ConvergedReason.CONVERGED_ITERATING:
                if its >= max_it:
                    reason = PETSc.KSP.ConvergedReason.DIVERGED_MAX_IT
                    break
                A.mult(d, q)
                dq = d.dot(q)
                if not dq > 0:
                    reason = PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_MAT
                    break
                alpha = rz / dq
                y.axpy(alpha, d)
                r.axpy(-alpha, q)
                project(r, z)
                its += 1
                norm = z.norm()
                ksp.setResidualNorm(norm)
                if norm <= max(rtol * norm0, atol):
                    reason = PETSc.KSP.ConvergedReason.CONVERGED_RTOL
                    break
                rz_new = r.dot(z)
                d.aypx(rz_new / rz, z)
                rz = rz_new
            # the sum exact: the round-off the directions gather along u (at round-off level)
            y.axpy((c - ones.dot(y)) / s, u)
            ksp.setIterationNumber(its)
            ksp.setConvergedReason(reason)
        finally:
            for v in (ones, u, r, z, d, q):
                v.destroy()
