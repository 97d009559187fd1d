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

from ..integrate.assembly import RANK_TOL, check_assembly
from ..integrate.settings import settings
from ..elements import AbstractJournalJoint, LubricatedJoint, PinSlotJoint, TranslationalClearanceJoint
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
        "clearance_joints": [_joint_text(j) for j in mech.clearance_joints],
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


def _joint_text(j) -> str:
    text = f"{j.label}: bodies {' and '.join(j.bodies())}"
    laws = f"law {j.law.name}, c_r = {float(j.law.restitution):.3g}, mu = {float(j.friction.coefficient):.3g}"
    if isinstance(j, AbstractJournalJoint):
        text = (f"{j.label}: bearing {j.bearing_body}.{j.bearing_point}, journal {j.journal_body}.{j.journal_point}, "
                f"R_B = {float(j.bearing_radius) * 1e3:.4g} mm, c = {float(j.clearance) * 1e6:.4g} um, {laws}")
        if isinstance(j, LubricatedJoint):
            text += f", oil film: viscosity {float(j.viscosity):.4g} Pa s, film width (length) {float(j.length) * 1e3:.4g} mm"
        if isinstance(j, PinSlotJoint):
            text += f", slot length {float(j.slot_length) * 1e3:.4g} mm"
    elif isinstance(j, TranslationalClearanceJoint):
        text = (f"{j.label}: guide {j.guide_body}.{j.guide_point}, slider {j.slider_body}.{j.slider_point}, block "
                f"{float(j.slider_length) * 1e3:.4g} x {float(j.slider_height) * 1e3:.4g} mm, guide width "
                f"{float(j.guide_width) * 1e3:.4g} mm, c = {float(j.clearance) * 1e6:.4g} um per side, {laws}")
    return text
