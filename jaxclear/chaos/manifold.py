r"""The space over which the Lyapunov spectrum of a mechanism is taken: the tangent space of its
constraint manifold, in a weighted metric.

A mechanism's packed state is ``[q (n), qdot (n), memory]`` (:mod:`jaxclear.integrate.state`).
The motion stays on the constraint manifold

.. math:: \mathcal M(t) = \{(q, \dot q):\ \Phi(q, t) = 0,\ \dot\Phi = D(q, t)\,\dot q + \Phi_t(q, t) = 0\},

of dimension :math:`2(n - m)` (``m`` independent constraint equations, joints and drivers): the
mechanism's phase space. Perturbations off it are not motions of the mechanism: Baumgarte's
stabilisation (:mod:`jaxclear.integrate.dynamics`) makes them decay like
:math:`\ddot\Phi + 2\alpha\dot\Phi + \beta^2\Phi = 0`, at rates :math:`-\alpha \pm
\sqrt{\alpha^2 - \beta^2}` that are the solver's gains, not the mechanism's (``-5 1/s``, twice,
per constraint at the default gains). Their exponents would enter a spectrum of the full
``2n``-dimensional state as ``2m`` spurious values, and the sum of the spectrum would not be the
mechanism's phase-space contraction. So the spectrum is taken over the tangent space
:math:`T\mathcal M = \ker G`, :math:`G = \partial(\Phi, \dot\Phi)/\partial(q, \dot q)`
(``2m x 2n``): the linearised position constraint :math:`D\,\delta q = 0` and the linearised
velocity constraint :math:`D\,\delta\dot q + (D\dot q + \Phi_t)_q\,\delta q = 0`. The tangent
flow maps :math:`T\mathcal M(t_0)` onto :math:`T\mathcal M(t)` (the linearised Baumgarte law
keeps :math:`G\,\delta x = 0`), so a basis started in it stays in it up to the integration error,
which :func:`projector` removes at every renormalisation.

The metric: lengths [m] and angles [rad] weigh 1, velocities [m/s, rad/s] weigh a time scale
``T`` (by default the crank's :math:`1/|\omega|`; 1 s without a crank), so that
:math:`\|\delta x\|^2 = \|\delta q\|^2 + T^2\|\delta\dot q\|^2` compares a position and a velocity
change over the mechanism's own time scale. Lyapunov exponents do not depend on the metric (any
two norms on a finite-dimensional space are equivalent, so their logarithms differ by a bounded
amount that vanishes when divided by the time); only how fast the running estimate settles does.

The impact memory (the approach speed and time of the latest onset, counts, peaks, contact work)
and the bristle states of Dahl and LuGre friction are not coordinates of this space: a memory
entry is set from the state at each onset, so a perturbation of it alone is forgotten at the next
onset. Their tangents are carried with every basis vector (the derivative of the stored onset
data along that perturbation, from the memory rules' derivatives) and transformed with it at each
renormalisation, but they are not orthonormalised and not measured.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..integrate import spd_solve
from ..model import constraints
from ..model.drivers import crank_driver
from ..model.mechanism import Mechanism


def dimension(mech: Mechanism) -> int:
    """Dimension :math:`2(n - m)` of the mechanism's phase space (the constraint manifold)."""
    return 2 * (mech.n_coordinates - mech.n_constraints)


def time_scale(mech: Mechanism):
    """The default time scale [s] of the metric: :math:`1/|\\omega|` of the crank
    (:func:`~jaxclear.model.drivers.crank_driver`), 1 s without one."""
    found = crank_driver(mech)
    if found is None:
        return jnp.asarray(1.0)
    w = jnp.abs(jnp.asarray(found[1].speed, float))
    return jnp.where(w > 0, 1.0 / jnp.where(w > 0, w, 1.0), 1.0)


def weights(mech: Mechanism, scale) -> jax.Array:
    """The metric's weights (2n,): 1 on the positions, ``scale`` [s] on the velocities."""
    n = mech.n_coordinates
    return jnp.concatenate([jnp.ones(n), jnp.full(n, 1.0) * scale])


def constraint_gradient(mech: Mechanism, t, q, qdot) -> jax.Array:
    r""":math:`G = \partial(\Phi, \dot\Phi)/\partial(q, \dot q)` (2m, 2n) at ``(t, q, qdot)``."""
    n = mech.n_coordinates

    def g(x):
        value, rate, _ = constraints.velocity_terms(mech, x[:n], x[n:], t)
        return jnp.concatenate([value, rate])

    return jax.jacfwd(g)(jnp.concatenate([q, qdot]))


def projector(mech: Mechanism, t, q, qdot, w) -> jax.Array:
    r"""Orthogonal projector (2n, 2n) onto :math:`T\mathcal M` in the weighted coordinates
    :math:`x_w = w\,x`: :math:`P = I - G_w^T (G_w G_w^T)^{-1} G_w`, :math:`G_w = G\,W^{-1}`
    (:func:`~jaxclear.integrate.spd_solve`: no LAPACK call, so it batches like the engine)."""
    size = 2 * mech.n_coordinates
    eye = jnp.eye(size, dtype=q.dtype)
    if mech.n_constraints == 0:
        return eye
    gw = constraint_gradient(mech, t, q, qdot) / w[None, :]
    a = gw @ gw.T
    x = jax.vmap(lambda col: spd_solve(a, col), in_axes=1, out_axes=1)(gw)
    return eye - gw.T @ x


def tangent_basis(mech: Mechanism, t, q, qdot, w, count: int) -> jax.Array:
    """``count`` orthonormal vectors (2n, count) of :math:`T\\mathcal M` in the weighted
    coordinates: the projections (:func:`projector`) of the coordinate directions
    :math:`e_1, e_2, \\dots` (positions, then velocities), orthonormalised in that order (Gram-Schmidt,
    twice for rounding), a direction that adds less than ``1e-6`` of its length skipped. So the
    basis is the same for the same state (a start basis an independent implementation can repeat:
    for a body on a slide, its position and velocity along the slide)."""
    size = 2 * mech.n_coordinates
    proj = projector(mech, t, q, qdot, w)
    basis = jnp.zeros((size, count), q.dtype)
    kept = jnp.zeros((), jnp.int32)
    for i in range(size):
        v = proj[:, i]
        for _ in range(2):
            v = v - basis @ (basis.T @ v)
        norm = jnp.sqrt(jnp.sum(v**2))
        keep = (norm > 1e-6) & (kept < count)
        column = jnp.where(keep, v / jnp.where(norm > 0, norm, 1.0), basis[:, jnp.minimum(kept, count - 1)])
        basis = basis.at[:, jnp.minimum(kept, count - 1)].set(column)
        kept = kept + keep.astype(jnp.int32)
    return basis
