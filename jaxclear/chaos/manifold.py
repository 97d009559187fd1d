r"""The space over which the Lyapunov spectrum of a mechanism is taken: the tangent space of its
constraint manifold, in a weighted metric.

A mechanism's packed state is ``[q (n), qdot (n), memory]`` (:mod:`jaxclear.integrate._state`).
The motion stays on the constraint manifold

.. math:: \mathcal M(t) = \{(q, \dot q):\ \Phi(q, t) = 0,\ \dot\Phi = D(q, t)\,\dot q + \Phi_t(q, t) = 0\},

of dimension :math:`2(n - m)` (``m`` independent constraint equations, joints and drivers): the
mechanism's phase space. Perturbations off it are not motions of the mechanism: Baumgarte's
stabilisation (:mod:`jaxclear.integrate._dynamics`) makes them decay like
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

The impact memory and the bristle states of Dahl and LuGre friction are not coordinates of this
space: the exponents are the growth rates of perturbations of :math:`(q, \dot q)`, and the
memory is a function of the perturbed motion's past (the approach speed is set from the state at
each onset, the records accumulate it). A basis vector's memory part is therefore the derivative
of the memory along that perturbation (from the memory rules' derivatives); it is carried with the
vector and transformed with it at each renormalisation, never orthonormalised or measured. Only
the entries the motion reads are carried (:func:`live_memory`): an entry no force and no rate
depends on (the work, the running peaks, the onset time, the impact count, and the approach
speed out of contact or under an elastic law) is an output, not a state, and its tangent is set
to zero. Carried by the renormalisations' :math:`R^{-1}` it would grow like
:math:`e^{-\lambda_p t}` (the contracting directions' inverse growth) without ever acting back, and
overflow; an entry that is read acts back on the positions and velocities and grows no faster
than they do.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..integrate import spd_solve
from ..integrate import flat_vector_field
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


def tangent_reference(w) -> jax.Array:
    """The size ``()`` of a tangent just after renormalising, in the coordinates' units: a unit
    vector of the metric ``w`` (:func:`weights`) spread over the 2n coordinates, its largest entry
    (``reference`` of :func:`~jaxclear.integrate.tangent_system`: above it a tangent's absolute
    tolerance grows with it)."""
    return jnp.max(1.0 / w) / jnp.sqrt(w.shape[0])


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
    :math:`e_1, e_2, \\dots` (positions, then velocities), orthonormalised by Gram-Schmidt with
    column pivoting: each vector is the projected direction that keeps the longest part after the
    vectors before it are removed (the first such on a tie), twice for rounding. So the basis is
    the same for the same state (a start basis an independent implementation can repeat: for a
    body on a slide, its position and velocity along the slide), and a direction the constraints
    nearly remove (a projection of length :math:`10^{-6}`, known only to the projector's rounding,
    :math:`10^{-11}` on the benchmark) is not taken before a long one: taken in coordinate order, such
    a remnant became a start vector off the manifold."""
    proj = projector(mech, t, q, qdot, w)
    basis = jnp.zeros((proj.shape[0], count), q.dtype)
    rest = proj
    for k in range(count):
        norms = jnp.sqrt(jnp.sum(rest**2, axis=0))
        i = jnp.argmax(norms)
        v = proj[:, i]
        for _ in range(2):
            v = v - basis @ (basis.T @ v)
        v = v / jnp.maximum(jnp.sqrt(jnp.sum(v**2)), jnp.finfo(q.dtype).tiny)
        basis = basis.at[:, k].set(v)
        rest = rest - jnp.outer(v, v @ rest)
    return basis


def live_memory(mech: Mechanism, baumgarte, t, y) -> jax.Array:
    r"""Which entries of the memory part ``y[2n:]`` of the packed state ``y`` the motion reads
    at ``(t, y)`` (1.0) and which it does not (0.0): entry ``j`` is read when some component of
    the vector field :math:`f(t, y)` (:func:`~jaxclear.integrate.flat_vector_field`:
    accelerations and memory rates) has a non-zero derivative :math:`\partial f/\partial y_j`
    (``jax.jacfwd``). Read: the approach speed inside a contact whose law damps with it, the
    bristle states. Not read: the records (work, peaks, onset time, impact count: outputs) and
    the approach speed out of contact (the next accepted step overwrites it) or under an elastic
    law. One exception is not seen: a dissipative force clipped to zero at ``t`` (the journal
    leaving faster than :math:`\dot\delta^{(-)}/\hat\chi`) reads the approach speed again if it
    pushes later in the same contact."""
    size = 2 * mech.n_coordinates
    if y.shape[0] == size:
        return jnp.zeros((0,), y.dtype)

    def field(memory):
        return flat_vector_field(t, jnp.concatenate([y[:size], memory]), (mech, baumgarte))

    jac = jax.jacfwd(field)(y[size:])
    return jnp.any(jac != 0, axis=0).astype(y.dtype)

