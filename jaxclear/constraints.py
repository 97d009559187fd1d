r"""Holonomic constraints :math:`\Phi(q, t) = 0` of ideal joints and drivers, and the terms of
the acceleration equation obtained from them by automatic differentiation (nobody writes
Jacobians by hand).

Reference: Nikravesh, "Computer-Aided Analysis of Mechanical Systems" (1988), ch. 3 and 6.

* :math:`D = \partial\Phi/\partial q` (m, n)
* :math:`\dot\Phi = D\dot q + \Phi_t`
* :math:`\gamma = -(D\dot q)_q\dot q - 2\Phi_{qt}\dot q - \Phi_{tt}`, which equals minus the second
  directional derivative of :math:`\Phi` along :math:`(\dot q, 1)` in :math:`(q, t)`; that is how
  it is computed here (two nested ``jax.jvp``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .mechanism import (
    AngleDriver,
    Fixed,
    FunctionDriver,
    Mechanism,
    Revolute,
    Translational,
    perp,
    point_position,
    rotate,
)

_COORD = {"x": 0, "y": 1, "phi": 2}


def _angle(mech, q, body):
    return mech.pose(q, body)[1]


def joint_equations(mech: Mechanism, joint, q, t):
    """Constraint equations of one ideal joint or driver."""
    if isinstance(joint, Revolute):
        return point_position(mech, q, joint.body_i, joint.point_i) - point_position(
            mech, q, joint.body_j, joint.point_j
        )
    if isinstance(joint, Translational):
        p_i = point_position(mech, q, joint.body_i, joint.point_i)
        p_j = point_position(mech, q, joint.body_j, joint.point_j)
        normal = rotate(_angle(mech, q, joint.body_i), perp(joint.axis))
        rel = _angle(mech, q, joint.body_j) - _angle(mech, q, joint.body_i) - joint.angle
        d = p_j - p_i
        return jnp.stack([rel, normal[0] * d[0] + normal[1] * d[1]])
    if isinstance(joint, Fixed):
        d = point_position(mech, q, joint.body_i, joint.point_i) - point_position(
            mech, q, joint.body_j, joint.point_j
        )
        rel = _angle(mech, q, joint.body_j) - _angle(mech, q, joint.body_i) - joint.angle
        return jnp.concatenate([d, rel[None]])
    if isinstance(joint, AngleDriver):
        rel = _angle(mech, q, joint.body) - _angle(mech, q, joint.relative_to)
        return (rel - joint.angle0 - joint.speed * t)[None]
    if isinstance(joint, FunctionDriver):
        i = mech.body_index(joint.body)
        return (q[3 * i + _COORD[joint.coordinate]] - joint.function(t))[None]
    raise TypeError(f"not a joint or driver: {type(joint).__name__}")


def constraint_labels(mech: Mechanism, extra=()) -> list[str]:
    """One human-readable label per constraint row (for error messages)."""
    labels = []
    for j in (*mech.joints, *mech.drivers, *extra):
        name = type(j).__name__
        bodies = (
            f"{j.body_i}-{j.body_j}" if hasattr(j, "body_i") else getattr(j, "body", getattr(j, "name", ""))
        )
        labels += [f"{name}({bodies})[{k}]" for k in range(j.n_equations)]
    return labels


def phi(mech: Mechanism, q, t, extra=()):
    r""":math:`\Phi(q, t)` (m,) stacking all joints, then all drivers, then ``extra`` equations
    (used by the initial-condition solve to hold clearance joints at a given eccentricity)."""
    parts = [joint_equations(mech, j, q, t) for j in (*mech.joints, *mech.drivers)]
    parts += [e.equations(mech, q, t) for e in extra]
    if not parts:
        return jnp.zeros((0,), q.dtype)
    return jnp.concatenate(parts)


def jacobian(mech: Mechanism, q, t, extra=()):
    """:math:`D = \\partial\\Phi/\\partial q` (m, n) by forward-mode autodiff."""
    return jax.jacfwd(lambda qq: phi(mech, qq, t, extra))(q)


def velocity_terms(mech: Mechanism, q, qdot, t, extra=()):
    r"""Return :math:`(\Phi, \dot\Phi, \gamma)`, each (m,).

    :math:`\dot\Phi` and :math:`-\gamma` are the first and second derivatives of
    :math:`s \mapsto \Phi(q + s\dot q, t + s)` at :math:`s = 0`.
    """
    one = jnp.ones((), q.dtype)

    def along(s):
        return phi(mech, q + s * qdot, t + s, extra)

    def first(s):
        return jax.jvp(along, (s,), (one,))

    (value, rate), (_, second) = jax.jvp(first, (jnp.zeros((), q.dtype),), (one,))
    return value, rate, -second


def time_derivative(mech: Mechanism, q, t, extra=()):
    r""":math:`\Phi_t` (m,)."""
    return jax.jvp(lambda tt: phi(mech, q, tt, extra), (t,), (jnp.ones((), q.dtype),))[1]
