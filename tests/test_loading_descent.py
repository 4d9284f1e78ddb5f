"""A window's loading steps descended after Newton fails on one (``-<prefix>loading_descent``,
``AdhesiveProblem.solve``).

Independent truth: the same path under the plain Newton strategy, whose failed steps the
fallback's descent reaches: with the option every state is that path's (forces, contact
fractions, stability), the loading steps after the jump on are descended from the last state
(``descent+``), and after the approach falls Newton from the tangent's prediction comes first
again.  The same on one rank as on all.  Units: z0 = 1, E* = 1 (the hard-wall sphere at Tabor 2
of docs/performance.md on a window of 48 z0).
"""
import pytest
from petsc4py import PETSc

from adhesive_setup import sphere_problem

#: loading across the jump on (between -2.61 and -2.36) into contact, then one step back
PATH = (-2.86, -2.61, -2.36, -2.11, -1.86, -1.61, -1.36, -1.61)


def _path(loading_descent, tag):
    pb = sphere_problem(2.0, law="hardwall-lj", n=96, dx=0.5, radius=100.0, prefix=f"loading_{tag}_",
                        petsc_options={"loading_descent": loading_descent})
    states = [pb.solve(approach=d) for d in PATH]
    out = [(st.solver, st.force, st.contact_fraction, st.stable) for st in states]
    for st in states:
        st.release_fields()
    pb.destroy()
    return out


def test_loading_steps_after_a_failed_newton_are_descended_to_newtons_states(coll):
    plain, descended = _path("false", "plain"), _path("true", "descended")
    peak = max(abs(f) for _, f, _, _ in plain)
    for (s0, f0, c0, stable0), (s1, f1, c1, stable1) in zip(plain, descended):
        assert abs(f1 - f0) <= 1e-8 * peak and c1 == c0 and stable0 and stable1
    assert not any(s.startswith("descent") for s, *_ in plain)
    # the jump on fails Newton (the fallback descends); the loading steps after it descend first
    jump = next(i for i, (s, *_) in enumerate(descended) if s.endswith("+descent"))
    assert 0 < jump < len(PATH) - 2
    assert all(s.startswith("descent+") for s, *_ in descended[jump + 1:-1])
    assert descended[-1][0].startswith("newton")      # the approach fell: Newton first again
    assert all(s == p for (s, *_), (p, *_) in zip(descended[:jump + 1], plain[:jump + 1]))


def test_the_default_is_on_for_a_windows_hard_wall_only():
    hard, smooth = (sphere_problem(2.0, law=law, n=16, dx=0.5, radius=100.0, prefix=f"ldd_{law}_")
                    for law in ("hardwall-lj", "lj"))
    for pb in (hard, smooth):
        pb.descends    # builds the solvers
    assert hard.loading_descent and not smooth.loading_descent
    with pytest.raises(PETSc.Error):     # PETSc's own: "Unknown logical value: maybe"
        sphere_problem(2.0, law="hardwall-lj", n=16, dx=0.5, radius=100.0, prefix="ldd_bad_",
                       petsc_options={"loading_descent": "maybe"}).descends


def test_a_sweep_locating_the_jump_on_keeps_descending_the_loading_steps(coll):
    """``paths.sweep`` bisects the jump on from snapshots of the old branch (Newton first, as
    then) and steps back to the new one; the loading steps after it still descend first, and a
    snapshot brings back whether they do."""
    from contactpetsc import paths
    pb = sphere_problem(2.0, law="hardwall-lj", n=96, dx=0.5, radius=100.0, prefix="loading_sweep_",
                        petsc_options={"loading_descent": "true"})
    path = paths.sweep(pb, PATH, refine=4)
    assert [j.kind for j in path.jumps] == ["jump-on"]
    solvers = [p.solver for p in path.points]
    jump = next(i for i, s in enumerate(solvers) if s.endswith("+descent"))
    assert all(s.startswith("descent+") for s in solvers[jump + 1:-1]) and solvers[-1].startswith("newton")
    assert not pb.descending_loading          # the last step lowered the approach
    pb.descending_loading = True
    snap = pb.snapshot()
    pb.descending_loading = False
    pb.restore(snap)
    assert pb.descending_loading
    snap.destroy()
    pb.destroy()
