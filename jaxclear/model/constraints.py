r"""Holonomic constraints :math:`\Phi(q, t) = 0` of a mechanism and the terms of the acceleration
equation, all by automatic differentiation of the joints' equations (nobody writes Jacobians
by hand).

Reference: Nikravesh, "Computer-Aided Analysis of Mechanical Systems" (1988), ch. 3 and 6.

* :math:`D = \partial\Phi/\partial q` (m, n)
* :math:`\dot\Phi = D\dot q + \Phi_t`
* :math:`\gamma = -(D\dot q)_q\dot q - 2\Phi_{qt}\dot q - \Phi_{tt}`, which equals minus the second
  directional derivative of :math:`\Phi` along :math:`(\dot q, 1)` in :math:`(q, t)`; that is how
  it is computed here (two nested ``jax.jvp``).

``extra`` holds further equation providers (anything with ``n_equations``, ``label`` and
``equations(mech, q, t)``): the initial-condition solve uses it to hold force elements at their
initial offsets.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .mechanism import Mechanism


def constraint_labels(mech: Mechanism, extra=()) -> list[str]:
    """One human-readable label per constraint row (for error messages)."""
    return [f"{c.label}[{k}]" for c in (*mech.constraints, *extra) for k in range(c.n_equations)]


def phi(mech: Mechanism, q, t, extra=()):
    r""":math:`\Phi(q, t)` (m,) stacking all joints, then all drivers, then ``extra``."""
    parts = [c.equations(mech, q, t) for c in (*mech.constraints, *extra)]
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
