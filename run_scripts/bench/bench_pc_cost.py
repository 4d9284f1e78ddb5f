#!/usr/bin/env python3
"""Benchmark: the adhesive preconditioners' cost per application and Krylov iterations per grid size.

The rough benchmark heights (``rough_surface.py``, periodic, E* = 1), a law with w = --w E* dx
and range dx (``exponential`` and ``hardwall-lj``: a hard wall; ``lj``: the full curve), one
cold state at the approach giving --area contact (``rough_surface.calibrate``; where its 128^2
sweep cannot resolve the law, with the law of the 128^2 grid, w and z0 in its spacing, and the
area reached then differs more), solved once with every default (``auto`` preconditioner,
nested start, stability check, tangent).  At that state, the Newton Jacobian J_II on the
contact rows and every a (``contact_rows``) and, per preconditioner of
``-<prefix>preconditioner`` (--pcs: ``spectral``, ``mlmi``), a KSP of the Newton steps' type,
PC side and norm.  One JSON line each:

* ``state``: the solve (converged, stable, FFT pairs, CPU s, the auto pick, snap number, the
  size of J_II, the open nodes with q > 0 left out of it and their largest q over the law's
  peak attraction; its pairs split
  at the finest grid's first and last Newton iterates: before = the nested iteration's coarse
  grids and the start, after = stability check and tangent) and the memory it holds in doubles
  per grid point above a baseline taken before the problem was made: ``tracemalloc`` (numpy
  and Python allocations, not PETSc's Vecs nor FFTW's plans; its peak too) and the resident set
  (VmRSS of /proc/self/status: everything, allocator slack included), the latter also after
  both preconditioners are set up.  The solve's CPU s are under tracemalloc, stopped before
  the preconditioners are set up and before any timing;
* ``memory``: the largest allocation sites still held after the solve (file:line, doubles per
  point);
* ``apply`` per preconditioner: FFT pairs per application (``fft_pairs()``: coarse MLMI levels
  weighted by their size, exact), CPU s per application (``process_time``, median of
  --repeats), the same for one bare FFT pair (``HalfSpaceOperator.apply`` on the finest grid)
  and one J_II mult, the set-up (the first, and again at the same state as at every later
  Newton step: the cycle's power iterations) in pairs and CPU s, and the memory the PC object
  holds itself (numpy arrays reachable from it, not what the problem's PCs share: operators,
  grids, Fourier kernel) and its set-up's VmRSS change;
* ``breakdown`` (mlmi): CPU s per application of each level's pieces ((K + C) x with its FFT
  pair, the smoother's correction, the transfers, the residual's subtraction, the coarsest
  solve), their sum, the V-cycle alone (``_cycle``) and the whole application; per level the
  fraction of nodes the cycle keeps, the smoother's damping (theta, from the power iterations)
  and its distributive rows, the rows' largest gains (Jacobi: K_ii / |K_ii + c|; distributive:
  K_ii / lambda, lambda their local diagonal with c) and how many exceed 10, and the weight of
  the power iteration's last vector on the distributive rows, the attractive tail and the
  local rows;
* ``ksp``: Krylov iterations of one solve J_II y = b from y = 0 to each of --rtols (the KSP's
  own norm), b the residual F_I at the state (``residual``) or a fixed random vector
  (``random``), with the true relative residual reached, pairs and CPU s.

    for n in 256 512 1024 2048; do
      OMP_NUM_THREADS=1 .venv/bin/python run_scripts/bench/bench_pc_cost.py --size $n --law exponential
      OMP_NUM_THREADS=1 .venv/bin/python run_scripts/bench/bench_pc_cost.py --size $n --law lj --w 0.2
    done

One rank.
"""
import collections
import gc
import os
import resource
import statistics
import sys
import time
import tracemalloc

import petsc4py

from bench_args import emit, rough_parser

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__)
ap.add_argument("--area", type=float, default=0.05, help="contact fraction of the state")
ap.add_argument("--pcs", nargs="+", default=["spectral", "mlmi"])
ap.add_argument("--rtols", type=float, nargs="+", default=[1e-2, 1e-6])
ap.add_argument("--rhs", nargs="+", default=["residual", "random"], choices=["residual", "random"])
ap.add_argument("--repeats", type=int, default=15, help="timed applications (the median is reported)")
ap.add_argument("--max-it", type=int, default=2000, help="Krylov iterations at most per solve")
ap.add_argument("--mem-sites", type=int, default=10, help="largest allocation sites reported")
ap.add_argument("--budget", type=float, default=900.0, help="wall-time budget of the state's solve [s]")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.pc_registry import ADHESIVE_PRECONDITIONERS  # noqa: E402
from contactpetsc.solvers.transfer import prolong_constant, restrict  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"

PREFIX = "pcc_"


def rss_bytes():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


def median_cpu(fn, repeats, warm=2):
    """Median process_time of fn() over ``repeats`` calls, after ``warm`` untimed ones (plans,
    caches and the first-touch page faults of new work arrays are not a per-application cost)."""
    for _ in range(warm):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return statistics.median(times)


#: attributes that lead to what a PC shares with the problem and its other PCs (the operator,
#: the grid, the Jacobian's context, the MLMI grids and operators, the Fourier kernel)
SHARED = {"ctx", "_data", "base", "op", "grid", "pairs", "parent", "problem"}
OWN_MODULES = ("contactpetsc.solvers.adhesive_mlmi", "contactpetsc.solvers.adhesive_jacobian",
               "contactpetsc.solvers.preconditioners")


def own_bytes(obj, seen=None):
    """Bytes of the numpy arrays a PC context holds itself (its levels' and inner PC's
    included; each buffer once)."""
    seen = set() if seen is None else seen
    if isinstance(obj, np.ndarray):
        owner = obj
        while isinstance(owner.base, np.ndarray):
            owner = owner.base
        if id(owner) in seen:
            return 0
        seen.add(id(owner))
        return owner.nbytes
    if isinstance(obj, (list, tuple)):
        return sum(own_bytes(o, seen) for o in obj)
    if type(obj).__module__ in OWN_MODULES and hasattr(obj, "__dict__") and id(obj) not in seen:
        seen.add(id(obj))
        return sum(own_bytes(v, seen) for k, v in vars(obj).items() if k not in SHARED)
    return 0


def contact_rows(pb):
    """(IS of the unknowns of Newton's system at the state, (open nodes with q > 0 left out,
    their largest q over the law's peak attraction)):
    q where q > 0 on a closed gap (g <= tol z0) or g <= 0, and every a.  The tangent's set
    (``_inactive_set``) and the VI's (zero tolerance 0) take every q > 0: states that went
    through the descent fallback keep tiny positive q on open nodes (1e-9 of the peak
    attraction), which would put contact rows on up to most of the grid."""
    xb = pb.blocks(pb._x, readonly=True)
    local = []
    q_open = (0, 0.0)
    if pb.hard_wall:
        g = pb._gap(xb, np.empty(xb[0].shape))
        rows = ((xb[0] > 0) & (g <= pb.tol * pb.z0)) | (g <= 0)
        left = (xb[0] > 0) & ~rows
        q_open = (int(left.sum()), float(xb[0][left].max()) / pb.pressure_scale if left.any() else 0.0)
        local.append(np.flatnonzero(rows))
    local.append(np.arange(xb[-1].size) + (xb[-1].size if pb.hard_wall else 0))
    idx = (np.concatenate(local) + pb.offset).astype(PETSc.IntType)
    return PETSc.IS().createGeneral(idx, comm=pb.grid.comm), q_open


def make_ksp(pb, A, name):
    """A KSP like the Newton steps' (type, PC side, norm; the problem's prefix, so that its
    -<prefix>ksp_* options apply too), with PC ``name``."""
    ref = pb.snes().getKSP()
    ksp = PETSc.KSP().create(comm=pb.grid.comm)
    ksp.setOptionsPrefix(PREFIX)
    ksp.setType(ref.getType())
    ksp.setPCSide(ref.getPCSide())
    ksp.setNormType(ref.getNormType())
    pc = ksp.getPC()
    pc.setType("python")
    pc.setPythonType(ADHESIVE_PRECONDITIONERS[name])
    ksp.setOperators(A, A)
    ksp.setTolerances(rtol=args.rtols[0], max_it=args.max_it)
    ksp.setFromOptions()
    return ksp


def mlmi_breakdown(pcctx, x_full, repeats):
    """CPU s of the cycle's pieces per application, level by level (the same calls as
    ``AdhesiveCycle._cycle`` with V(0, 1), on arrays of the right sizes)."""
    rows = []
    b = x_full[-1] * pcctx.inv_beta
    cycle = pcctx.cycle
    for l, lev in enumerate(cycle.levels):
        r = b if l == 0 else restrict(r) * lev.keep
        n = lev.grid.nx * lev.grid.ny
        # the cycle's own state on this level: the coarse nodes it keeps (children of one kind),
        # the smoother's damping from the power iterations, the distributively relaxed rows
        # and the rows' largest gains: Jacobi K_ii / |K_ii + c|, distributive K_ii / lambda
        # (lambda = omega / scale^2, the local diagonal of D (K + C)): a row near its own snap point
        amp = np.abs(lev.jac) * lev.base.k0
        dist = lev.scale ** 2 * lev.base.k0 / lev.base.omega
        row = dict(level=l, nodes=n, keep=float(np.mean(lev.keep)), theta=float(lev.theta),
                   distributive=float(np.mean(lev.kdom)), jacobi_gain_max=float(amp.max()),
                   jacobi_gain_over_10=int((amp > 10).sum()), dist_gain_max=float(dist.max()),
                   dist_gain_over_10=int((dist > 10).sum()))
        if lev.v is not None:
            # where the power iteration's dominant mode lives (what sets theta): its weight on
            # the distributive rows, the attractive tail (c <= -K_ii) and the local rows
            w2 = lev.v ** 2 / float(np.sum(lev.v ** 2))
            row.update(mode_on_distributive=float(w2[lev.kdom].sum()),
                       mode_on_tail=float(w2[~lev.kdom & (lev.c <= -lev.base.k0)].sum()),
                       mode_on_local=float(w2[~lev.kdom & (lev.c > -lev.base.k0)].sum()))
        if l == len(cycle.levels) - 1:
            if lev.dense is not None:
                row["coarse_solve"] = median_cpu(lambda: lev.solve(r, lev.x), repeats)
            else:
                row["coarse_solve"] = median_cpu(
                    lambda: [lev.smooth(r, lev.x, zero_start=k == 0) for k in range(cycle.coarse_sweeps)], repeats)
        else:
            xl = np.zeros_like(r)
            row["apply_k_plus_c"] = median_cpu(lambda: lev.apply(xl, lev.ku), repeats)
            row["smoother"] = median_cpu(lambda: lev.correction(r, lev.s1.copy()), repeats)
            rc = restrict(r)
            row["transfers"] = median_cpu(lambda: prolong_constant(restrict(r) * rc), repeats)
            row["residual_update"] = median_cpu(lambda: np.subtract(b if l == 0 else r, lev.ku, out=lev.r), repeats)
        rows.append(row)
    return rows


def main():
    n = args.size
    load0 = os.getloadavg()[0]
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    approaches = calibrate(grid, h, law, [args.area], max_n=128)
    approach_from = "calibrate"
    if approaches is None:
        # the 128^2 sweep under-resolves the law from 1024^2 on (z0 = dx / 8 there: the full
        # LJ sweep converges nowhere); the law of the 128^2 grid (w and z0 in its dx) is resolved
        from contactpetsc.solvers.transfer import halved
        coarse = grid
        while coarse.nx > 128:
            coarse = halved(coarse)
        approaches = calibrate(grid, h, adhesive_law(coarse, args.w, 1.0, name=args.law), [args.area], max_n=128)
        approach_from = "calibrate, the 128^2 grid's law"
    approach = float(approaches[0])
    opts = PETSc.Options(PREFIX)
    opts.setValue("time_budget", args.budget)

    gc.collect()
    rss0 = rss_bytes()
    tracemalloc.start(8)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=PREFIX)
    t0 = time.process_time()
    st = pb.solve(approach=approach, raise_on_failure=False)
    solve_cpu = time.process_time() - t0
    gc.collect()
    unit = n * n * 8.0
    mem_solve = (tracemalloc.get_traced_memory()[0] / unit, (rss_bytes() - rss0) / unit)
    peak_solve = tracemalloc.get_traced_memory()[1] / unit
    sites = collections.Counter()
    for tr in tracemalloc.take_snapshot().traces:
        # numpy's dispatch hides the caller: the innermost frame of ours names the site
        fr = next((fr for fr in reversed(tr.traceback) if "contactpetsc" in fr.filename
                   or "run_scripts" in fr.filename), tr.traceback[-1])
        name = fr.filename
        name = name[name.rfind("contactpetsc"):] if "contactpetsc" in name else os.path.basename(name)
        sites[f"{name}:{fr.lineno}"] += tr.size
    # off before the PCs are set up: the block PC's set-up makes object arrays (a Python float
    # per node), one traced allocation each
    tracemalloc.stop()

    # the Jacobian at the state itself (the SNES's last one is the previous iterate's)
    pb._jacobian(None, pb._x, None, None)
    f = pb.create_unknown()
    pb._residual(None, pb._x, f)
    iset, q_open = contact_rows(pb)
    A = pb._J.createSubMatrix(iset, iset)
    actx = A.getPythonContext()
    b_res, y = A.createVecs()
    full = np.array(pb.blocks(f, readonly=True))
    actx.from_full(full, b_res)
    b_rand = b_res.duplicate()
    b_rand.setArray(np.random.default_rng(0).standard_normal(b_rand.getLocalSize()))
    rhs = {"residual": b_res, "random": b_rand}

    kspec, setup = {}, {}
    for name in args.pcs:
        ksp = make_ksp(pb, A, name)
        gc.collect()
        r0 = rss_bytes()
        p0, c0 = pb.fft_pairs(), time.process_time()
        ksp.setUp()
        setup[name] = [pb.fft_pairs() - p0, time.process_time() - c0]
        gc.collect()
        setup[name] += [own_bytes(ksp.getPC().getPythonContext()) / unit, (rss_bytes() - r0) / unit]
        kspec[name] = ksp
    gc.collect()
    rss_pcs = (rss_bytes() - rss0) / unit

    # where the solve's pairs went: before the finest grid's first Newton iterate (the nested
    # iteration's coarse grids, the start), the finest grid's iterations, after (check, tangent)
    recs = pb.history.records
    split = dict(pairs_before_fine=recs[0].fft_pairs, pairs_fine=recs[-1].fft_pairs - recs[0].fft_pairs,
                 linear_fine=recs[-1].linear_iterations - recs[0].linear_iterations,
                 pairs_after_fine=st.fft_pairs - recs[-1].fft_pairs) if recs else {}
    emit(kind="state", n=n, law=args.law, w=args.w, area=args.area, approach=approach,
         converged=st.converged, stable=st.stable, margin=st.stability_margin, solver=st.solver,
         contact_fraction=st.contact_fraction,
         newton=st.newton_iterations, linear=st.linear_iterations, fft_pairs=st.fft_pairs,
         cpu=solve_cpu, snap_number=pb.snap_number, zone_nodes=pb.zone_nodes, auto_pick=pb.preconditioner,
         inactive=A.getSize()[0], unknowns=pb.n_global, q_open=q_open[0],
         q_open_max=q_open[1], **split,
         mem_solve_tracemalloc=mem_solve[0], mem_solve_rss=mem_solve[1], mem_solve_peak_tracemalloc=peak_solve,
         mem_pcs_rss=rss_pcs, approach_from=approach_from,
         maxrss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
         reason="" if st.converged else st.reason[:200], load=load0)

    emit(kind="memory", n=n, law=args.law, w=args.w,
         sites={site: size / unit for site, size in sites.most_common(args.mem_sites)})

    arr = np.random.default_rng(1).standard_normal((grid.ny_local, grid.nx))
    out = np.empty_like(arr)
    cpu_pair = median_cpu(lambda: pb.op.apply(arr, out), args.repeats)
    x = b_rand.copy()
    cpu_jmult = median_cpu(lambda: A.mult(x, y), args.repeats)

    for name, ksp in kspec.items():
        pc = ksp.getPC()
        pcctx = pc.getPythonContext()
        # every later Newton step sets the PC up again on the next J_II: the same state here
        p0 = pb.fft_pairs()
        setup_cpu = median_cpu(lambda: pcctx.setUp(pc), 3, warm=0)
        setup_pairs = (pb.fft_pairs() - p0) / 3
        p0 = pb.fft_pairs()
        cpu_apply = median_cpu(lambda: pc.apply(x, y), args.repeats)
        pairs_apply = (pb.fft_pairs() - p0) / (args.repeats + 2)
        levels = pcctx.cycle.levels if hasattr(pcctx, "cycle") else None
        emit(kind="apply", n=n, law=args.law, w=args.w, pc=name, pairs_apply=pairs_apply,
             cpu_apply=cpu_apply, cpu_pair=cpu_pair, apply_over_pair=cpu_apply / cpu_pair,
             cpu_jmult=cpu_jmult, jmult_over_pair=cpu_jmult / cpu_pair,
             setup_pairs_first=setup[name][0], setup_cpu_first=setup[name][1],
             setup_pairs=setup_pairs, setup_cpu=setup_cpu,
             mem_pc_own=setup[name][2], mem_pc_rss=setup[name][3],
             levels=[lev.grid.nx for lev in levels] if levels else None,
             coarsest=("dense" if levels[-1].dense is not None else "sweeps") if levels else None,
             repeats=args.repeats, load=os.getloadavg()[0])
        if name == "mlmi":
            full[...] = 0.0
            actx.to_full(x, full)
            parts = mlmi_breakdown(pcctx, full, args.repeats)
            total = sum(v for row in parts for k, v in row.items()
                        if k in ("apply_k_plus_c", "smoother", "transfers", "residual_update", "coarse_solve"))
            f0 = full[-1] * pcctx.inv_beta
            # the rest of an application: the reduced <-> full copies and the contact rows' da
            cpu_cycle = median_cpu(lambda: pcctx.cycle._cycle(0, f0), args.repeats)
            emit(kind="breakdown", n=n, law=args.law, w=args.w, pc=name, levels=parts,
                 sum_parts=total, cpu_cycle=cpu_cycle, cpu_apply=cpu_apply, cpu_pair=cpu_pair)
        for kind in args.rhs:
            b = rhs[kind]
            for rtol in args.rtols:
                ksp.setTolerances(rtol=rtol, max_it=args.max_it)
                y.set(0.0)
                p0, c0 = pb.fft_pairs(), time.process_time()
                ksp.solve(b, y)
                cpu, pairs = time.process_time() - c0, pb.fft_pairs() - p0
                its = ksp.getIterationNumber()
                r = b.duplicate()
                A.mult(y, r)
                r.aypx(-1.0, b)
                emit(kind="ksp", n=n, law=args.law, w=args.w, pc=name, rhs=kind, rtol=rtol, its=its,
                     reason=int(ksp.getConvergedReason()), true_rel_residual=r.norm() / b.norm(),
                     pairs=pairs, cpu=cpu, pairs_per_it=pairs / max(its, 1), cpu_per_it=cpu / max(its, 1),
                     ksp_type=ksp.getType(), load=os.getloadavg()[0])
                r.destroy()


main()
