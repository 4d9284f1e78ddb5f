"""The multilevel preconditioner of the whole adhesive Newton system (``AdhesiveMLMIPC``).

Truths: with one level the cycle is the dense solve of K + C, and the elimination of the
contact rows is exact, so the preconditioner is the exact inverse of the reduced Jacobian
(an algebraic identity, any law with a diagonal linearisation); a multilevel cycle is the
same linear operator on any number of ranks (serial == MPI).
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactpetsc.solvers.adhesive_mlmi import AdhesiveMLMIPC

from adhesive_setup import sphere_problem


def reduced_jacobian_and_pc(pb):
    """The reduced Jacobian on the solved state's inactive set (contact nodes' q, every a)
    and the MLMI preconditioner set up on it."""
    g = pb.grid
    blocks = pb.blocks(pb._x, readonly=True)
    local = np.arange(blocks.size).reshape(blocks.shape)
    keep = [local[-1].ravel()]
    if pb.hard_wall:
        keep.insert(0, local[0][blocks[0] > 0])
    idx = (np.concatenate(keep) + pb.offset).astype(PETSc.IntType)
    iset = PETSc.IS().createGeneral(idx, comm=g.comm)
    sub = pb._J.createSubMatrix(iset, iset)
    pc = PETSc.PC().create(comm=g.comm)
    pc.setType("python")
    pc.setPythonContext(AdhesiveMLMIPC())
    pc.setOperators(sub, sub)
    pc.setUp()
    return sub, pc


@pytest.mark.parametrize("law", ["hardwall-lj", "lj"])
def test_one_level_cycle_inverts_the_reduced_jacobian(coll, law):
    """mlmi_levels 1 on a 32^2 grid: M J x = x to round-off (on the contact rows, the a rows
    and the gap-form repulsive rows of the full LJ curve)."""
    prefix = f"amlmi_exact_{law.replace('-', '')}_"
    opts = PETSc.Options()
    try:
        pb = sphere_problem(1.0, law=law, n=32, dx=0.5, radius=50.0, prefix=prefix, stability_check=False,
                            preconditioner="spectral")   # the hierarchy is built at the first cycle
        st = pb.solve(approach=0.5)
        assert st.converged
        opts[f"{prefix}mlmi_levels"] = 1   # read when the cycle is first set up
        J, pc = reduced_jacobian_and_pc(pb)
        x, y = J.createVecs()
        rng = np.random.default_rng(3 + coll.rank)
        x.setArray(rng.standard_normal(x.getLocalSize()))
        b, z = J.createVecs()
        J.mult(x, b)
        pc.apply(b, z)
        z.axpy(-1.0, x)
        assert z.norm(PETSc.NormType.INFINITY) < 1e-8 * x.norm(PETSc.NormType.INFINITY)
    finally:
        opts.delValue(f"{prefix}mlmi_levels")


def test_cycle_is_rank_independent(coll):
    """A 4-level cycle applied to the same vector on COMM_SELF and on all ranks: the same result."""
    out = {}
    for name, comm in (("self", PETSc.COMM_SELF), ("world", PETSc.COMM_WORLD)):
        # 48 rows split into 48, 24 or 16 per rank on 1, 2 or 3 ranks: halved rank-locally twice
        pb = sphere_problem(1.0, n=48, dx=0.5, radius=50.0, comm=comm, preconditioner="mlmi",
                            prefix=f"amlmi_ranks_{name}_", stability_check=False)
        st = pb.solve(approach=0.5)
        assert st.converged
        g = pb.grid
        assert len(pb._jac.pc_data.mlmi_levels) >= 3
        # the same right-hand side on both: a smooth field of the global node positions
        j, i = np.mgrid[g.ys:g.ye, 0:g.nx]
        full = np.zeros(pb.blocks(pb._x, readonly=True).shape)
        full[...] = np.sin(0.3 * i + 0.2 * j) + np.cos(0.05 * i * j)
        J, pc = reduced_jacobian_and_pc(pb)
        b, z = J.createVecs()
        J.getPythonContext().from_full(full, b)
        pc.apply(b, z)
        res = np.zeros_like(full)
        J.getPythonContext().to_full(z, res)
        gathered = np.concatenate(comm.tompi4py().allgather(res[-1]), axis=0)
        mask = np.concatenate(comm.tompi4py().allgather(pb.blocks(pb._x, readonly=True)[0] > 0), axis=0)
        out[name] = (gathered, mask)
    (a, ma), (b_, mb) = out["self"], out["world"]
    same_set = np.array_equal(ma, mb)
    assert coll.all(same_set)
    assert coll.max(np.abs(a - b_)) < 1e-9 * max(coll.max(np.abs(a)), 1e-300)
