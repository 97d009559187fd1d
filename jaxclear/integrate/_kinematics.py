r"""Kinematic analysis of a mechanism whose drivers determine its motion (no integration).

A mechanism without force elements whose joints and drivers give as many independent equations
as it has coordinates (``m = n``, the Jacobian :math:`D` square and regular) has one motion,
whatever its masses and loads: at each time :math:`t`

.. math::
    \Phi(q, t) = 0, \qquad D\dot q = -\Phi_t, \qquad D\ddot q = \gamma, \qquad
    D^T\lambda = g(q, \dot q, t) - M\ddot q

(position, velocity and acceleration analysis, then the reactions from the equations of motion of
:mod:`~jaxclear.integrate._dynamics`; Nikravesh, *Computer-Aided Analysis of Mechanical Systems*,
1988, ch. 3 and 6). The ideal-joint counterpart of a driven mechanism with clearance joints
(:meth:`~jaxclear.model.Mechanism.ideal`) is such a mechanism: the command line's ideal-joint
overlay is its kinematic solution, a far smaller program than an integration (compiled in a
fraction of the time) and exact to the Newton tolerance, where the integrated ideal run carries
the integrator's error (about ``rtol``).

Positions: Newton's method :math:`q \leftarrow q - D^{-1}\Phi` from the previous sample (the first
sample from :func:`~jaxclear.integrate.assemble`), :data:`NEWTON_ITERATIONS` iterations per
sample, in a ``lax.scan`` over the samples; a sample whose residual stays above
:data:`~jaxclear.integrate._assembly.NEWTON_TOL` makes the status ``assembly_failed``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._errors import RESULTS, is_concrete
from ..model import constraints
from ..model.mechanism import Mechanism
from ._assembly import NEWTON_TOL, assemble
from ._compile import jit
from ._dynamics import applied_forces
from ._settings import Settings
from ._simulate import output_grid, raise_for_status, solution_structure
from ._solution import Solution

#: Newton iterations per output sample (from the previous sample's positions: at the default
#: 2000 samples per crank revolution the first iteration leaves ~1e-9 of the residual, the
#: second rounding).
NEWTON_ITERATIONS = 4


def is_kinematic(mech: Mechanism) -> bool:
    """Whether the drivers determine the motion: no force elements, at least one driver, and as
    many constraint equations as coordinates (independence is checked by the assembly)."""
    return not mech.clearance_joints and bool(mech.drivers) and mech.n_constraints == mech.n_coordinates


def _sample(mech: Mechanism, q, t):
    """Positions (Newton from ``q``), velocities, accelerations, reactions and ``|Phi|`` at ``t``."""
    for _ in range(NEWTON_ITERATIONS):
        q = q - jnp.linalg.solve(constraints.jacobian(mech, q, t), constraints.phi(mech, q, t))
    d = constraints.jacobian(mech, q, t)
    qdot = jnp.linalg.solve(d, -constraints.time_derivative(mech, q, t))
    value, _, gamma = constraints.velocity_terms(mech, q, qdot, t)
    qddot = jnp.linalg.solve(d, gamma)
    g = applied_forces(mech, t, q, qdot)
    lam = jnp.linalg.solve(d.T, g - mech.mass_matrix_diagonal().astype(q.dtype) * qddot)
    return q, (q, qdot, qddot, lam, jnp.linalg.norm(value))


@jit
def _kinematic_run(mech: Mechanism, s: Settings) -> Solution:
    asm = assemble(mech, s.t_start)
    _, _, ts = output_grid(s, asm.q.dtype)
    _, (q, qdot, qddot, lam, drift) = jax.lax.scan(lambda q, t: _sample(mech, q, t), asm.q, ts)
    finite = jnp.all(jnp.isfinite(q)) & jnp.all(jnp.isfinite(qdot)) & jnp.all(jnp.isfinite(qddot))
    result = RESULTS.where(finite, RESULTS.successful, RESULTS.nonfinite_state)
    result = RESULTS.where(jnp.all(drift <= NEWTON_TOL), result, RESULTS.assembly_failed)
    valid = mech.check()  # masses and inertias enter the reactions
    result = RESULTS.where(valid == RESULTS.successful, result, valid)
    t_count, zero = ts.shape[0], jnp.zeros((), jnp.int32)
    empty = jnp.zeros((t_count, 0), ts.dtype)
    return Solution(ts=ts, q=q, qdot=qdot, qddot=qddot, reactions=lam, drift=drift,
                    ecc=jnp.zeros((t_count, 0, 2), ts.dtype), penetration=empty, normal_force=empty,
                    friction_force=empty, mode=empty.astype(jnp.int32), element_states=(), num_steps=zero,
                    num_accepted_steps=zero, num_rejected_steps=zero,
                    status=jnp.asarray(result._value, jnp.int32))


def kinematics_at(mech: Mechanism, q, t):
    """Positions, velocities and accelerations ``(q, qdot, qddot)`` (each ``(n,)``) of a
    kinematically driven mechanism (:func:`is_kinematic`) at time ``t`` [s], by
    :data:`NEWTON_ITERATIONS` Newton iterations from the guess ``q`` (a nearby configuration: the
    previous sample, or the coordinates of the same mechanism with clearance, which lie within a
    clearance of the ideal joint's). Traceable and differentiable; no status (the residual is not
    checked: a guess far from the motion can converge elsewhere)."""
    _, (q, qdot, qddot, _, _) = _sample(mech, q, t)
    return q, qdot, qddot


def kinematic_solution(mech: Mechanism, s: Settings) -> Solution:
    """The motion of a kinematically driven mechanism (:func:`is_kinematic`) on the output grid
    of ``s`` (``t_start``, ``t_end``, ``n_out``; the integration settings do not apply), as a
    :class:`Solution` without clearance-joint outputs and with zero solver steps. Status
    ``assembly_failed`` if Newton's method did not converge at some sample (a dead centre or a
    driver beyond the mechanism's reach). Pure: ``jit``, ``vmap`` and ``grad`` apply.

    Raises:
        ValueError: ``mech`` is not kinematically driven (use :func:`jaxclear.simulate`).
        ParameterError, SolverError: with concrete inputs and ``s.throw``, a status other than
            successful (:func:`~jaxclear.integrate.raise_for_status`).
    """
    if not is_kinematic(mech):
        raise ValueError(f"{mech.name!r} is not kinematically driven ({mech.n_constraints} constraint equations "
                         f"for {mech.n_coordinates} coordinates, {len(mech.clearance_joints)} force elements): "
                         "simulate it instead")
    sol = _kinematic_run.stored("kinematics", lambda: solution_structure(mech), mech, s)
    if s.throw and is_concrete(sol.status):
        raise_for_status(sol, s, f" (kinematic analysis of {mech.name!r})", mech=mech)
    return sol


__all__ = ["NEWTON_ITERATIONS", "is_kinematic", "kinematic_solution", "kinematics_at"]
