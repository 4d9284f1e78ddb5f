"""Tabor 5 rough sphere (the paper's case, examples/studies/rough_sphere.py) at n^2: loading in
approach steps of 1 z0 from -5 z0, every solve's outcome and reason printed: a study of the grid
the paper's case needs (docs/studies.md).  The failure it shows on a grid too coarse, a loud one
from which the path goes on, is a test: tests/test_under_resolved_jump_in.py.

    python run_scripts/checks/tabor5_steps.py N RMS_Z0 BUDGET_S [PETSc options]
    python run_scripts/checks/tabor5_steps.py 384 0 420      # fails at -4 z0, the jump-in (docs/studies.md)
    python run_scripts/checks/tabor5_steps.py 512 0 1500     # loads through the jump-in to 0.05 mN
    python run_scripts/checks/tabor5_steps.py 512 1 1500 -mu5_max_it 400   # rms = z0: jump-in at -3 z0
"""
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, "examples", "studies"))
import petsc4py; petsc4py.init(sys.argv[4:])
import warnings; warnings.simplefilter("ignore")
import rough_sphere as rs
from contactpetsc.geometry import surfaces
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
n, rms, budget = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
grid, res = rs.make_grid(n, 5.0)
w = rs.work_for(5.0)
h = surfaces.rough_sphere(grid, rs.R, surfaces.scale_to_rms(grid, rs.roughness(grid), rms * rs.Z0))
pb = AdhesiveProblem(grid, h, rs.E_STAR, make_law("lj", work_of_adhesion=w, z0=rs.Z0), prefix="mu5_",
                     element_integration=True)
print(f"n={n} rms={rms} z0 dx={grid.dx*1e9:.2f} nm snap K_ii max da/dg={pb.snap_number:.2f} p_peak dx/(E* z0)={res:.2f}", flush=True)
t0 = time.time()
for a in np.arange(-5.0, 30.0, 1.0):
    t = time.time()
    st = pb.solve(approach=a * rs.Z0, raise_on_failure=False)
    print(f"approach {a:5.1f} z0: converged {st.converged} stable {st.stable} W/load {st.force / rs.LOAD:8.4f} "
          f"W* {st.force / (2*np.pi*rs.R*w):8.4f} contact {st.contact_fraction:.4f} solver {st.solver} "
          f"fallback {st.fallback} newton {st.newton_iterations} fft {st.fft_pairs:.0f} {time.time()-t:.1f} s "
          f"errors {st.complementarity_error:.1e} {st.adhesive_error:.1e}\n    reason: {st.reason}", flush=True)
    if st.force >= rs.LOAD or time.time() - t0 > budget:
        break
