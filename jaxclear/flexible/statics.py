r"""Static equilibrium and natural frequencies of a supported beam.

Equilibrium (:func:`static_equilibrium`): the stationary point of the potential energy under
the supports, the Karush-Kuhn-Tucker equations

.. math:: \nabla U(e) - \lambda\,f + D(e)^T\mu = 0, \qquad \Phi(e) = 0,

(:math:`f`: the point loads' and gravity's generalized force, constant; :math:`\mu`: the
support reactions, one per equation, [N] or [N m]) solved by Newton's method on
:math:`(e, \mu)` with the exact Jacobian (forward-mode differentiation of the residual), the
load raised in ``steps`` equal increments :math:`\lambda = 1/\mathrm{steps} \dots 1`, each
converged by ``iterations`` Newton steps from the last (the large deflections of the elastica
need the path; the program is one ``lax.scan`` of one ``fori_loop``).

Natural frequencies (:func:`natural_frequencies`): the undamped free vibration about a
configuration :math:`e^*` (the straight reference by default) of the linearised equations
:math:`M\ddot u + K u = 0`, :math:`D u = 0`, with the tangent stiffness
:math:`K = \nabla^2 U(e^*)` (exact second derivatives) and the constant mass matrix. With
:math:`Z` an orthonormal basis of the null space of :math:`D` (singular value decomposition),
:math:`\omega^2` are the eigenvalues of :math:`(Z^T M Z)^{-1} Z^T K Z`, computed as the
symmetric eigenproblem of :math:`L^{-1} Z^T K Z L^{-T}`, :math:`L L^T = Z^T M Z`. The supports'
own curvature (:math:`\mu^T\Phi_{ee}`) is left out: exact for supports linear in :math:`e`
(pins, clamps, lines) or about an unloaded configuration. Differentiable with respect to the
beam's numbers (:math:`D` is held constant: the supports do not depend on them).
"""

from __future__ import annotations

from typing import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, Float, Scalar
from .beam import AncfBeam
from .supports import AbstractSupport, BeamLoad, check_supports


def support_equations(beam: AncfBeam, supports: Sequence[AbstractSupport], e, t) -> Float[Array, " m"]:
    r""":math:`\Phi(e, t)` (m,), the supports' rows in order."""
    parts = [c.equations(beam, e, t) for c in supports]
    return jnp.concatenate(parts) if parts else jnp.zeros((0,), e.dtype)


def applied_force(beam: AncfBeam, loads: Sequence[BeamLoad] = (), gravity=(0.0, 0.0), mass=None):
    """Generalized force (n,) of the point loads and gravity [m/s^2] (constant)."""
    total = beam.gravity_force(gravity, mass)
    for load in loads:
        total = total + load.generalized_force(beam)
    return total


class StaticResult(eqx.Module):
    """An equilibrium: coordinates ``e`` (n,), support reactions ``reactions`` (m,), the final
    residual norm ``residual`` (of the KKT equations, [N])."""

    e: Float[Array, " n"]
    reactions: Float[Array, " m"]
    residual: Scalar


@eqx.filter_jit
def static_equilibrium(beam: AncfBeam, supports: Sequence[AbstractSupport], loads: Sequence[BeamLoad] = (),
                       gravity=(0.0, 0.0), steps: int = 10, iterations: int = 12, start=None) -> StaticResult:
    """The equilibrium under ``loads`` and ``gravity`` (module docstring); ``start``: the
    coordinates to start from (default the reference). Compiled once per beam layout
    (``equinox.filter_jit``); traceable and differentiable (the derivative of the converged
    solution follows the Newton iterations)."""
    check_supports(beam, supports, loads)
    e0 = beam.reference() if start is None else start
    n = beam.n_coordinates
    m = sum(c.n_equations for c in supports)
    force = applied_force(beam, loads, gravity)
    t = jnp.zeros((), e0.dtype)

    def residual(x, factor):
        e, mu = x[:n], x[n:]
        phi, pull = jax.vjp(lambda ee: support_equations(beam, supports, ee, t), e)
        return jnp.concatenate([-beam.elastic_force(e) - factor * force + pull(mu)[0], phi])

    def newton(x, factor):
        def step(_, x):
            return x - jnp.linalg.solve(jax.jacfwd(residual)(x, factor), residual(x, factor))
        return jax.lax.fori_loop(0, iterations, step, x), None

    factors = jnp.arange(1, steps + 1, dtype=e0.dtype) / steps
    x, _ = jax.lax.scan(newton, jnp.concatenate([e0, jnp.zeros(m, e0.dtype)]), factors)
    return StaticResult(x[:n], x[n:], jnp.linalg.norm(residual(x, 1.0)))


@eqx.filter_jit
def natural_frequencies(beam: AncfBeam, supports: Sequence[AbstractSupport] = (), e=None, t=0.0,
                        count: int | None = None) -> Float[Array, " k"]:
    """Circular natural frequencies [rad/s], ascending, of the beam linearised about ``e``
    (default the reference) under ``supports`` (module docstring); the first ``count``, or all
    ``n - m``. Unsupported directions give zero frequencies (rigid motions)."""
    check_supports(beam, supports)
    e = beam.reference() if e is None else e
    t = jnp.asarray(t, e.dtype)
    if supports:
        d = jax.lax.stop_gradient(jax.jacfwd(lambda ee: support_equations(beam, supports, ee, t))(e))
        z = jnp.linalg.svd(d, full_matrices=True)[2][d.shape[0]:].T
    else:
        z = jnp.eye(beam.n_coordinates, dtype=e.dtype)
    k = z.T @ jax.hessian(beam.strain_energy)(e) @ z
    mr = z.T @ beam.mass_matrix() @ z
    chol = jnp.linalg.cholesky(mr)
    half = jax.scipy.linalg.solve_triangular(chol, k, lower=True)
    a = jax.scipy.linalg.solve_triangular(chol, half.T, lower=True)
    w2 = jnp.linalg.eigvalsh(0.5 * (a + a.T))
    w = jnp.sqrt(jnp.clip(w2, 0.0))
    return w if count is None else w[:count]
