"""Nested iteration (full multigrid) of ``ContactProblem``: the first solve starts from the
same problem solved on the 2x coarser grid (heights averaged over 2 x 2 blocks), recursively
down to ``-<prefix>fmg_min_size`` nodes, each coarse solve to complementarity error
``-<prefix>fmg_tol``; its pressure is prolonged (piecewise constant or bilinear,
``transfer.py``) and the coarse problems are freed."""
from __future__ import annotations

from petsc4py import PETSc

from .base import weighted_pairs
from .options import code_default
from .transfer import can_halve, halved, prolong_bilinear, prolong_constant, restrict


class NestedIteration:
    """Mixin of ``ContactProblem``: the coarse problem, the initial guess prolonged from its
    solution, and the release of the coarse problems once used."""

    def _nested_options(self, opts: PETSc.Options) -> None:
        """Read ``-<prefix>fmg``, ``fmg_min_size``, ``fmg_tol`` and ``fmg_prolong`` (code defaults first)."""
        self.fmg = opts.getBool("fmg", self._default("fmg"))
        self.fmg_min_size = opts.getInt("fmg_min_size", code_default("contact", "fmg_min_size"))
        self.fmg_tol = opts.getReal("fmg_tol", code_default("contact", "fmg_tol"))
        self.fmg_prolong = opts.getString("fmg_prolong", code_default("contact", "fmg_prolong")).lower()
        if self.fmg_prolong not in ("bilinear", "constant"):
            raise ValueError(f"-{self.prefix}fmg_prolong must be bilinear or constant, got {self.fmg_prolong!r}")

    def _coarse_problem(self):
        """The same problem on the 2x coarser grid (h averaged over 2 x 2 blocks), or None."""
        if self._coarse is not None:
            return self._coarse or None
        self._coarse = False
        grid = self.grid
        if (not self.fmg or not can_halve(grid) or max(grid.nx, grid.ny) // 2 < self.fmg_min_size
                or min(grid.nx, grid.ny) // 2 < 2):
            return None
        levels = self._levels
        if levels and len(levels) > 1:
            gc, op = levels[1].grid, levels[1].op
        else:
            gc = halved(grid)
            # FFTW_MEASURE planning would cost more than the coarse solves themselves
            op = self.op.on_grid(gc, prefix=self.prefix, planner="estimate")
        hc = gc.create_vec()
        gc.rows(hc)[...] = restrict(grid.rows(self.heights, readonly=True))
        d = dict(self._defaults, preconditioner=self.preconditioner, fmg=True)
        coarse = type(self)(gc, hc, self.e_star, prefix=self.prefix, length_scale=self.length_scale,
                            operator=op, hardness=self.hardness, petsc_options=self.petsc_options,
                            _root=self._root, **d)
        coarse._levels = levels[1:] if levels and len(levels) > 1 else None
        coarse._build()
        coarse.tol, coarse.load_tol = max(self.fmg_tol, self.tol), max(self.fmg_tol, self.load_tol)
        coarse.fmg, coarse.fmg_min_size, coarse.fmg_tol = self.fmg, self.fmg_min_size, self.fmg_tol
        self._coarse = coarse
        return coarse

    def _nested_guess(self, approach, mean_pressure) -> bool:
        """Initial (p, delta) from the coarse problem's solution, prolonged; False if none.

        The coarse dp/d delta (load control) is prolonged too: it starts the
        first fine slope solve."""
        coarse = self._coarse_problem()
        if coarse is None:
            return False
        st = coarse.solve(approach=approach, mean_pressure=mean_pressure, raise_on_failure=False)
        self._newton += st.newton_iterations
        self._linear += st.linear_iterations
        if not st.converged:
            self._release_coarse()
            return False
        grid = self.grid
        if self.fmg_prolong == "bilinear":
            prolong = lambda a: prolong_bilinear(a, coarse.grid)  # noqa: E731
        else:
            prolong = prolong_constant
        grid.rows(self._pressure)[...] = prolong(coarse.grid.rows(st.pressure, readonly=True))
        if coarse._slope_cache is not None and self.slope_warm:
            # the coarse dp/d delta: the initial guess of the first fine slope solve
            z = grid.create_vec()
            grid.rows(z)[...] = prolong(coarse.grid.rows(coarse._slope_cache[2], readonly=True))
            self._z_guess = z
        self._approach = st.approach
        self._release_coarse()
        return True

    def _release_coarse(self) -> None:
        """Free the coarse problems of the nested iteration once their solution is prolonged.

        They are used once, on the first solve; kept, they would hold a third
        of the fine problem's memory through every later solve.  Their FFT
        pairs stay counted (``_retired_pairs``); the MLMI levels they share
        with the fine problem stay alive.  Collective.
        """
        coarse = self._coarse
        if not coarse:
            return
        root = self._root
        kept = {id(lev.op) for lev in (self._levels or [])}
        gone = [op for k, op in coarse._operators().items() if k not in kept]
        root._retired_pairs += weighted_pairs(gone, root.grid)
        coarse._destroy_solvers()
        self._coarse = False
        PETSc.garbage_cleanup(self.grid.comm)

