"""Solved states: ``ContactState`` and the ``AdhesiveState`` that extends it (fields with
units; docs/outputs.md lists the curve columns built from them)."""
from __future__ import annotations

from dataclasses import dataclass, fields

from petsc4py import PETSc


@dataclass
class ContactState:
    """A converged (or failed) contact state.  Vecs live on the problem's grid."""
    pressure: PETSc.Vec       #: p [Pa], compressive positive
    gap: PETSc.Vec            #: g = h + v - delta [m]
    displacement: PETSc.Vec   #: v = K p [m]
    approach: float           #: delta [m]
    mean_pressure: float      #: [Pa]
    force: float              #: total normal force [N] = mean_pressure * area
    contact_fraction: float   #: fraction of nodes with p > 0
    complementarity_error: float  #: max |min(K_ii p, g)| / length_scale (adhesion: in z0)
    #: max |min(K_ii p, g)| / min(length_scale, delta - min h): the measure converged to tol (NaN with adhesion)
    interference_error: float
    load_error: float         #: |mean p - target| / target (load control), else NaN
    converged: bool
    reason: str               #: SNES converged/diverged reason
    newton_iterations: int
    linear_iterations: int
    fft_pairs: float          #: fine-grid FFT pairs of this solve (coarse levels weighted)
    wall_time: float          #: [s]
    plastic_fraction: float = 0.0          #: fraction of nodes at the hardness, p = H (0 without one)
    plastic_volume: float = 0.0            #: [m^3] sum of -g over the nodes at p = H times dx dy
    max_plastic_displacement: float = 0.0  #: [m] max of -g over the nodes at p = H

    def release_fields(self) -> None:
        """Drop the state's grid fields (its Vecs are None after), keeping its numbers: a run's
        earlier states held three to five grid-sized Vecs each for the run's life (a step that
        writes a step file keeps its fields there)."""
        for f in fields(self):
            if isinstance(getattr(self, f.name), PETSc.Vec):
                setattr(self, f.name, None)


@dataclass
class AdhesiveState(ContactState):
    """A solved adhesive contact state; Vecs on the problem's grid (``pressure`` is p = q + a)."""
    contact_pressure: PETSc.Vec = None   #: q >= 0 [Pa] (zero for the full LJ curve)
    adhesive_pressure: PETSc.Vec = None  #: a [Pa] (the full LJ curve: the ``pressure`` Vec itself)
    central_gap: float = float("nan")    #: gap at the control node [m]
    adhesive_force: float = 0.0          #: sum of the negative pressures times the element area [N]
    adhesive_error: float = float("nan")  #: max K_ii |a - a(g)| [z0]
    #: max of |a - a(g)| / (P + |a(g)|) and |min(q / P, g / z0)|, P the law's peak attraction [-]
    pressure_error: float = float("nan")
    total_error: float = float("nan")    #: the paper's E_Total [z0]
    stable: bool | None = None           #: None when not checked
    stability_margin: float = float("nan")  #: 1 - lambda_max(A S): > 0 stable, < 0 unstable
    #: tangent dF/d delta [N/m] (displacement control); NaN if not computed (-<prefix>stiffness false)
    stiffness: float = float("nan")
    check_time: float = 0.0       #: [s] of wall_time spent on the stability check and the tangent
    #: False when the stability estimate had not settled after -<prefix>stability_steps: a positive
    #: margin is then an upper bound (None when not checked)
    stability_converged: bool | None = None
    solver: str = "newton"
    fallback: bool = False        #: Newton from the previous state failed: a relaxation path was followed
    #: the increments the energy descent took the step in (``descent_step.descend_step``; 0: no descent)
    descent_increments: int = 0
    #: total potential energy at the prescribed approach [J]: the elastic energy 1/2 sum p v dA plus
    #: the interaction energy sum Phi(g) dA (Phi the law's energy per area, nodal rule).  At an
    #: equilibrium d(energy)/d(approach) = force; states reached at one approach compare by it.
    #: NaN with element integration (its energy is not the nodal sum)
    energy: float = float("nan")
