r"""Non-intrusive least-squares shadowing (NILSS): the derivative of a long-time average of an
ODE :math:`\dot u = f(u, s)` with respect to its parameters, where the motion is chaotic and the
derivative of a finite-time average is not (Ni and Wang, J. Comput. Phys. 347 (2017) 56-77;
least-squares shadowing: Wang, Hu and Blonigan, J. Comput. Phys. 267 (2014) 210-224).

One trajectory (:func:`_member`) is traced once: the transient, then ``segments`` segments inside
one ``lax.scan`` (:mod:`._segments`: the state, ``n_unstable`` homogeneous tangents, one
inhomogeneous tangent per parameter and their integrals, renormalised at every segment's end),
then the least-squares problem (:mod:`._least_squares`) and the derivative

.. math::

    \frac{d\langle J\rangle}{ds} \approx \frac1T \sum_{i=0}^{K-1}\Big[\int_{t_i}^{t_{i+1}}
    (J_u v_i + J_s)\,dt + \xi_i\,\big(\bar J - J(u(t_{i+1}))\big)\Big],
    \qquad v_i = v^*_i + W_i a_i,\quad \xi_i = \frac{f^\top v_i}{f^\top f}\Big|_{t_{i+1}},

the second term the time dilation: each segment's tangent restarts normal to the flow, and the
flow component :math:`\xi_i f` it drops there is a shift of time whose effect on the average is
:math:`\xi_i (\bar J - J)`. :func:`nilss` runs ``members`` trajectories from perturbed starts
with ``jax.vmap`` in one compiled program and takes their spread as the error.
"""

from __future__ import annotations

import math
from functools import partial

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import SolverError, function_name
from . import _checks
from ._least_squares import shadowing_coefficients
from ._result import ShadowingResult
from ._segments import SegmentConfig, primal_solve, segment, start_basis


def coefficients(records):
    """The shadowing coefficients ``a`` (K, n_u, p) of every segment from the segments' records
    (:class:`SegmentRecord`, stacked ``K`` deep): segment ``i``'s shadowing tangent is
    :math:`v_i = v^*_i + W_i a_i` (the least squares of :func:`shadowing_coefficients`)."""
    I = records.integrals
    return shadowing_coefficients(I.C, I.D, records.R[:-1], records.b[:-1])


def derivative_terms(records, discard: int, segment_time, dilation: bool = True):
    """The pieces of the derivative from the segments' records (:class:`SegmentRecord`, stacked
    ``K`` deep): ``(average, contributions (K, p), exponents (n_u,), T)``, with the derivative
    ``contributions.sum(0) / T``; segment ``i``'s contribution is its term of the sum in the module
    docstring (zero for the first ``discard``, which still enter the least squares), so that
    sums over blocks of segments give batch means. ``T``: the averaging time. ``dilation=False``
    leaves out the time dilation's term: for integrals of tangents that already keep a phase of
    the motion (the mechanisms' tangents at fixed crank angle, :mod:`jaxclear.chaos.shadowing`),
    whose flow components read nothing."""
    I = records.integrals
    K = I.J.shape[0]
    kept = (jnp.arange(K) >= discard).astype(I.J.dtype)
    T = (K - discard) * segment_time
    average = jnp.sum(kept * I.J) / T
    a = coefficients(records)  # (K, n_u, p)
    along = I.JV + jnp.einsum("ku,kup->kp", I.JW, a)
    if dilation:
        xi = records.xi_V + jnp.einsum("ku,kup->kp", records.xi_W, a)
        along = along + (average - records.J_end)[:, None] * xi
    contributions = kept[:, None] * along
    growth = jnp.log(jnp.abs(jnp.diagonal(records.R, axis1=1, axis2=2)))
    return average, contributions, kept @ growth / T, T


def _derivative(records, discard: int, segment_time: float):
    """One member's ``(average, derivative (p,), exponents (n_u,))`` from its segments' records,
    averaged over the segments after the first ``discard`` (all of them enter the least squares)."""
    average, contributions, exponents, T = derivative_terms(records, discard, segment_time)
    return average, jnp.sum(contributions, axis=0) / T, exponents


def _member(config: SegmentConfig, segments: int, discard: int, chunks: int, chunk_time, u0, s, key):
    """One trajectory: transient, segments, least squares. Traceable; ``vmap`` over ``u0, key``."""
    ok = jnp.asarray(True)
    if chunks:
        def transient(u, _):
            u_next, good = primal_solve(config, u, s, chunk_time)
            return u_next, good

        u0, goods = jax.lax.scan(transient, u0, None, length=chunks)
        ok = jnp.all(goods)
    p = max(s.size, 1)
    W = start_basis(config, u0, s, key)
    V = jnp.zeros((u0.shape[0], p), u0.dtype)

    def step(carry, _):
        return segment(config, *carry, s)

    _, records = jax.lax.scan(step, (u0, W, V), None, length=segments)
    average, derivative, exponents = _derivative(records, discard, config.segment_time)
    return average, derivative.reshape(s.shape), exponents, jnp.sum(records.steps), ok & jnp.all(records.ok)


@partial(jax.jit, static_argnames=("member", "config", "segments", "discard", "chunks"))
def _members(member, config, segments, discard, chunks, chunk_time, starts, s, keys):
    return jax.vmap(lambda u, k: member(config, segments, discard, chunks, chunk_time, u, s, k))(starts, keys)


def nilss(f, u0, s, objective, *, n_unstable: int, segment_time: float, segments: int, members: int = 4,
          transient: float = 0.0, discard: int = 0, rtol: float = 1e-8, atol: float = 1e-8,
          steps_per_segment: int | None = None, solver: diffrax.AbstractSolver | None = None, max_steps: int = 4096,
          neutral: bool = True, spread: float = 1e-3, seed: int = 0) -> ShadowingResult:
    r"""The derivative of the long-time average :math:`\langle J\rangle` of
    :math:`\dot u = f(u, s)` with respect to ``s``, by non-intrusive least-squares shadowing
    (theory: docs/theory/shadowing.md).

    Args:
        f: the vector field ``f(u, s) -> du/dt`` (autonomous, traceable by JAX; its Jacobians are
            taken by autodiff).
        u0: a start state, ``(n,)``; the members start from it perturbed by ``spread``.
        s: the parameters, a scalar or ``(p,)``: the derivative has its shape.
        objective: ``J(u, s) -> scalar``, whose time average is differentiated.
        n_unstable: homogeneous tangents, at least the number of positive Lyapunov exponents
            (the flow direction's zero is projected out and not counted), ``0 .. n - 1``; 0 for a
            stable equilibrium or limit cycle.
        segment_time: the length of a segment, between renormalisations (short enough that the
            tangents grow by at most a few e-folds: :math:`\lambda_1 \Delta T \lesssim 1`).
        segments: segments per member, at least 2; the averaging time is ``segments *
            segment_time``.
        members: independent trajectories (at least 2), batched with ``jax.vmap``; the error is
            their standard error.
        transient: time integrated before the segments, to reach the attractor.
        discard: segments at the start left out of the averages (they still enter the least
            squares): the inhomogeneous tangents start at zero, and their stable components
            approach the forced response only at the slowest contraction rate :math:`|\lambda_s|`,
            an error of order :math:`1/(|\lambda_s| T)` unless :math:`|\lambda_s|` ``discard *
            segment_time`` is a few units; ``0 .. segments - 2``.
        rtol, atol: tolerances of diffrax's PID step-size controller (on the state, the
            tangents and their integrals).
        steps_per_segment: a fixed step ``segment_time / steps_per_segment`` instead.
        solver: the diffrax solver (default ``diffrax.Tsit5()``).
        max_steps: the most steps of one segment's solve (and of each transient piece).
        neutral: project the flow direction out of the tangents (an autonomous flow's neutral
            direction); False where the attractor is an equilibrium, which has none.
        spread: the members' start perturbation, relative to ``1 + |u0|``.
        seed: the random starts and homogeneous tangents.

    Returns:
        A :class:`ShadowingResult`.

    Raises:
        ParameterError: an input outside its range (named, with the range).
        SolverError: a solve failed (``max_steps`` reached, or the solver's own failure).
    """
    return shadow("nilss", _member, f, u0, s, objective, n_unstable=n_unstable, segment_time=segment_time,
                  segments=segments, members=members, transient=transient, discard=discard, rtol=rtol, atol=atol,
                  steps_per_segment=steps_per_segment, solver=solver, max_steps=max_steps, neutral=neutral,
                  spread=spread, seed=seed)


def shadow(name: str, member, f, u0, s, objective, *, n_unstable, segment_time, segments, members, transient,
           discard, rtol, atol, steps_per_segment, solver, max_steps, neutral, spread, seed) -> ShadowingResult:
    """The driver of :func:`nilss` and :func:`~jaxclear.shadowing.nilsas` (``name``): the checks,
    the members' starts, one compiled program of ``member`` (:func:`_member` or the adjoint's)
    batched over them, the result."""
    u0 = _checks.check_state(u0)
    s = _checks.check_parameters(s)
    n_unstable, segments, members, steps_per_segment, max_steps = _checks.check_options(
        n=u0.shape[0], n_unstable=n_unstable, segments=segments, segment_time=segment_time, members=members,
        transient=transient, rtol=rtol, atol=atol, steps_per_segment=steps_per_segment, max_steps=max_steps,
        spread=spread)
    discard = _checks.check_integer("discard", discard, 0, segments - 2, "segments left out of the averages")
    _checks.check_functions(f, objective, u0, s)
    config = SegmentConfig(f=f, objective=objective, n_unstable=n_unstable, segment_time=float(segment_time),
                           solver=diffrax.Tsit5() if solver is None else solver, rtol=float(rtol), atol=float(atol),
                           steps_per_segment=steps_per_segment, max_steps=max_steps, neutral=bool(neutral))
    chunks = math.ceil(float(transient) / float(segment_time)) if transient > 0 else 0
    chunk_time = float(transient) / chunks if chunks else 0.0
    key_start, key_basis = jax.random.split(jax.random.key(seed))
    noise = jax.random.normal(key_start, (members,) + u0.shape, u0.dtype)
    starts = u0 + spread * (1.0 + jnp.abs(u0)) * noise
    keys = jax.random.split(key_basis, members)
    averages, derivatives, exponents, steps, ok = _members(member, config, segments, discard, chunks, chunk_time,
                                                           starts, s, keys)
    failed = np.flatnonzero(~np.asarray(ok))
    if failed.size:
        raise SolverError(f"{name}: the solve of member {int(failed[0])} (of {members}) failed: max_steps = {max_steps} "
                          f"per segment reached or the solver stopped (f = {function_name(f)}); raise max_steps "
                          "(allowed >= 1), shorten segment_time or loosen rtol/atol")
    root_m = math.sqrt(members)
    return ShadowingResult(
        derivative=jnp.mean(derivatives, axis=0), derivative_error=jnp.std(derivatives, axis=0, ddof=1) / root_m,
        average=jnp.mean(averages), average_error=jnp.std(averages, ddof=1) / root_m,
        member_derivatives=derivatives, member_averages=averages, exponents=exponents, steps=steps,
        time=(segments - discard) * float(segment_time), segments=segments, discard=discard,
        segment_time=float(segment_time), n_unstable=n_unstable, method=name.upper())
