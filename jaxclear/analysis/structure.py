r"""What a mechanism is made of, checked before a simulation: assembly, degrees of freedom,
drivers and clearance joints (``jaxclear check``).

Degrees of freedom are counted at the assembled configuration from the rank of the constraint
Jacobian :math:`D = \partial\Phi/\partial q` (Nikravesh, "Computer-Aided Analysis of Mechanical
Systems", 1988, sec. 3.2; the Gruebler count :math:`3 n_b - \sum` equations only holds without
redundant constraints):

* ``dof`` = :math:`3 n_b - \mathrm{rank}\,D` of the ideal joints and the drivers: the motion
  left to the dynamics. Every revolute clearance joint adds two (the journal's eccentricity),
  so a driven slider-crank with one clearance joint has ``dof = 2``.
* ``mobility`` = the same for the ideal-joint mechanism (each clearance joint a revolute) without
  drivers: the classical mobility (1 for a slider-crank or a four-bar);
  ``driven_mobility`` = with drivers (0: kinematically driven).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..integrate import RANK_TOL, check_assembly
from ..integrate import settings
from ..model import AngleDriver, Mechanism


def _rank(mech: Mechanism, q, constraints) -> int:
    if not constraints:
        return 0
    t = jnp.zeros((), q.dtype)
    d = np.asarray(jax.jacfwd(lambda qq: jnp.concatenate([c.equations(mech, qq, t) for c in constraints]))(q))
    return int(np.linalg.matrix_rank(d, tol=RANK_TOL * max(np.abs(d).max(), 1.0)))


def check_mechanism(mech: Mechanism, allow_free_dof: bool = False) -> dict:
    """Assemble ``mech`` at t = 0 (raising the assembly's errors, the same as
    :func:`~jaxclear.simulate`'s: Newton failure, redundant constraints, and, unless
    ``allow_free_dof``, a driven mechanism with motion that no joint or driver determines) and
    describe it: counts, degrees of freedom, drivers, clearance joints, the assembled ``q``
    [m, rad] and the Newton residual."""
    asm = check_assembly(mech, settings(1.0, allow_free_dof=allow_free_dof))
    q = asm.q
    n = mech.n_coordinates
    ideal = mech.ideal()
    dof = n - _rank(mech, q, mech.constraints)
    mobility = n - _rank(ideal, q, ideal.joints)
    driven = n - _rank(ideal, q, ideal.constraints)
    return {
        "name": mech.name,
        "bodies": [{"name": b.name, "mass_kg": float(b.mass), "inertia_kg_m2": float(b.inertia),
                    "points": sorted(b.points)} for b in mech.bodies],
        "coordinates": n,
        "joints": [c.label for c in mech.joints],
        "constraint_equations": mech.n_constraints,
        "drivers": [_driver_text(d) for d in mech.drivers],
        "clearance_joints": [j.describe() for j in mech.clearance_joints],
        "loads": [c.label for c in mech.loads],
        "gravity_m_s2": np.asarray(mech.gravity).tolist(),
        "roles": dict(mech.roles),
        "dof": dof,
        "mobility": mobility,
        "driven_mobility": driven,
        "assembly_residual": float(asm.residual),
        "q": np.asarray(q).tolist(),
    }


def _driver_text(d) -> str:
    return d.label + (f", {float(d.speed):.6g} rad/s" if isinstance(d, AngleDriver) else "")
