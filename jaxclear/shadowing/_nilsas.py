r"""Non-intrusive least-squares adjoint shadowing (NILSAS): the derivative of a long-time
average of an ODE :math:`\dot u = f(u, s)` with respect to all its parameters at the cost of
:math:`n_u + 1` adjoint solutions, however many parameters there are (Ni and Talnikar, J. Comput.
Phys. 395 (2019) 690-709). :func:`~jaxclear.shadowing.nilss` integrates one tangent per
parameter; NILSAS is the choice where the parameters outnumber the unstable directions.

**The adjoint shadowing direction.** With :math:`\rho = \langle J\rangle`, let :math:`w(t)` solve

.. math::

    -\dot w = f_u^\top w + J_u^\top, \qquad w^\top f = \rho - J, \qquad w \text{ bounded}.

The second condition is kept by the equation itself (:math:`\tfrac{d}{dt}(w^\top f) = -J_u f =
-\dot J`), so it is imposed once at the end and restored at every segment boundary. For any
bounded shadowing tangent :math:`\dot v = f_u v + f_s + \eta f` (:mod:`._nilss`), integrating
:math:`w^\top v` by parts turns :math:`\langle J_u v + \eta (J - \rho)\rangle` into
:math:`\langle w^\top f_s\rangle` (the time dilation cancels because of the second condition; the
boundary terms are of order :math:`1/T`):

.. math::

    \frac{d\langle J\rangle}{ds} = \big\langle J_s + w^\top f_s\big\rangle,

one vector-Jacobian product :math:`(w, 1) \mapsto f_s^\top w + J_s` a sample for every parameter
at once.

**Non-intrusive.** The adjoint equation integrated backwards grows along the adjoints of the
unstable directions. As in NILSS, the solution is a particular one plus a combination of
:math:`n_u` homogeneous ones: on every segment, backwards from its end, the inhomogeneous adjoint
:math:`w^*_i` and the homogeneous :math:`W_i` (``n x n_u``, normal to the flow: a homogeneous
adjoint keeps :math:`W^\top f` constant, zero here), with :math:`w_i = w^*_i + W_i a_i`. At the
segment's start :math:`t_i` (the backward solve's end) :math:`W_i(t_i) = Q_i R_i` and the next
(earlier) segment starts from :math:`Q_i` and from :math:`w^*_i(t_i) - Q_i b_i`,
:math:`b_i = Q_i^\top w^*_i(t_i)`; continuity of :math:`w` reads :math:`a_{i-1} = R_i a_i + b_i`.
The coefficients minimise :math:`\sum_i \int |w^*_i + W_i a_i|^2 dt`: NILSS's least squares
(:func:`~jaxclear.shadowing.shadowing_coefficients`) with the segments in reverse order.

**The primal inside a segment** is solved again from the segment's start (kept by a first
forward pass) with diffrax's dense output, which the backward solve reads: memory of one segment,
not of the run.

**End effects.** The adjoint starts at the run's end with only its flow component; its components
that shrink backwards (the adjoints of the stable directions) reach the shadowing adjoint at the
slowest contraction rate, so ``discard`` segments at the *end* of the run enter the least squares
but not the averages (NILSS leaves out segments at the start, where its tangents begin).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import diffrax
import jax
import jax.numpy as jnp
import optimistix as optx

from ._least_squares import shadowing_coefficients
from ._nilss import shadow
from ._result import ShadowingResult
from ._segments import SegmentConfig, _controller, flow_projector, positive_qr, primal_solve, start_basis


class AdjointRecord(NamedTuple):
    """What the least squares and the derivative keep of one segment's backward solve."""

    C: jax.Array        # (n_u, n_u) int W^T W dt
    d: jax.Array        # (n_u, 1)   int W^T w* dt
    sW: jax.Array       # (n_u, p)   int f_s^T W dt
    sw: jax.Array       # (p,)       int (f_s^T w* + J_s) dt
    R: jax.Array        # (n_u, n_u) W(t_i) = Q_i R_i at the segment's start
    b: jax.Array        # (n_u, 1)   Q_i^T w*(t_i)
    steps: jax.Array    # ()         accepted steps of the two solves
    ok: jax.Array       # ()


def _forward(config: SegmentConfig, u0, s, segments: int):
    """The primal over the segments: every segment's start ``(K, n)``, its integral of J ``(K,)``,
    the end state, the steps and whether every solve succeeded."""
    controller, dt0 = _controller(config)
    term = diffrax.ODETerm(lambda t, y, a: (config.f(y[0], a), jnp.asarray(config.objective(y[0], a), y[0].dtype)))

    def step(u, _):
        sol = diffrax.diffeqsolve(term, config.solver, t0=0.0, t1=config.segment_time, dt0=dt0,
                                  y0=(u, jnp.zeros((), u.dtype)), args=s, stepsize_controller=controller,
                                  saveat=diffrax.SaveAt(t1=True), max_steps=config.max_steps,
                                  adjoint=diffrax.ForwardMode(), throw=False)
        ok = sol.result == diffrax.RESULTS.successful
        return sol.ys[0][-1], (u, sol.ys[1][-1], sol.stats["num_accepted_steps"], ok)

    u_end, (starts, integrals, steps, ok) = jax.lax.scan(step, u0, None, length=segments)
    return starts, integrals, u_end, jnp.sum(steps), jnp.all(ok)


def _flow_part(config: SegmentConfig, u, s, rho):
    r"""The flow component every adjoint ``w*`` must have at ``u``, :math:`f\,(\rho - J) / |f|^2`
    (zero where the flow is not projected, or at rest), and the projector normal to ``f``."""
    fu = config.f(u, s)
    perp, component = flow_projector(fu, config.neutral)
    gate = component(fu)  # 1 where the flow direction is projected out, else 0
    ff = fu @ fu
    J = jnp.asarray(config.objective(u, s), u.dtype)
    return fu * (gate * (rho - J) / jnp.where(ff > 0, ff, 1.0)), perp


def _backward_segment(config: SegmentConfig, s, rho, carry, u_start):
    """One segment backwards from its end, ``carry = (w*, W)`` there; renormalised at its start."""
    w, W = carry
    n_u = config.n_unstable
    p = max(s.size, 1)
    controller, dt0 = _controller(config)
    primal = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: config.f(y, a)), config.solver, t0=0.0, t1=config.segment_time, dt0=dt0,
        y0=u_start, args=s, stepsize_controller=controller, saveat=diffrax.SaveAt(dense=True),
        max_steps=config.max_steps, adjoint=diffrax.ForwardMode(), throw=False)

    def f_and_j(u_, s_):
        return config.f(u_, s_), jnp.asarray(config.objective(u_, s_), u_.dtype)

    def field(t, y, args):
        w_, W_, _ = y
        u = primal.evaluate(t)
        _, pullback = jax.vjp(f_and_j, u, s)
        cot_u = jnp.concatenate([w_[None], W_.T])  # (1 + n_u, n)
        cot_j = jnp.zeros((1 + n_u,), u.dtype).at[0].set(1.0)
        gu, gs = jax.vmap(pullback)((cot_u, cot_j))
        gs = gs.reshape(1 + n_u, p)
        integrands = (W_.T @ W_, W_.T @ w_[:, None], gs[1:], gs[0])
        # d/dt of the adjoints, and minus the integrands: the solve runs from the segment's end
        # to its start, so the integrals (zero at the end) arrive at their integrals over it
        return -gu[0], -gu[1:].T, jax.tree_util.tree_map(jnp.negative, integrands)

    if dt0 is None:  # the error control reads the adjoints and the least squares' integrals, not the
        # parameters' (quadratures on the same steps): the steps, and so the derivative, do not
        # change with the number of parameters
        controller = diffrax.PIDController(rtol=config.rtol, atol=config.atol,
                                           norm=lambda e: optx.rms_norm((e[0], e[1], e[2][:2])))
    dtype = u_start.dtype
    zeros = (jnp.zeros((n_u, n_u), dtype), jnp.zeros((n_u, 1), dtype), jnp.zeros((n_u, p), dtype),
             jnp.zeros((p,), dtype))
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(field), config.solver, t0=config.segment_time, t1=0.0,
        dt0=None if dt0 is None else -dt0, y0=(w, W, zeros), args=None, stepsize_controller=controller,
        saveat=diffrax.SaveAt(t1=True), max_steps=config.max_steps, adjoint=diffrax.ForwardMode(), throw=False)
    w0, W0, (C, d, sW, sw) = jax.tree_util.tree_map(lambda x: x[-1], sol.ys)
    flow, perp = _flow_part(config, u_start, s, rho)
    w0 = perp(w0) + flow
    if n_u:
        Q, R = positive_qr(perp(W0))
    else:
        Q, R = W0, jnp.zeros((0, 0), dtype)
    b = Q.T @ w0[:, None]
    ok = (primal.result == diffrax.RESULTS.successful) & (sol.result == diffrax.RESULTS.successful)
    record = AdjointRecord(C=C, d=d, sW=sW, sw=sw, R=R, b=b, ok=ok,
                           steps=primal.stats["num_accepted_steps"] + sol.stats["num_accepted_steps"])
    return (w0 - (Q @ b)[:, 0], Q), record


def member(config: SegmentConfig, segments: int, discard: int, chunks: int, chunk_time, u0, s, key):
    """One trajectory: transient, the primal's forward pass, the adjoints' backward pass, the least
    squares and the derivative. Traceable; ``vmap`` over ``u0, key``. Returns ``(average,
    derivative (s.shape), exponents (n_u,), steps, ok)`` as :func:`._nilss._member` does."""
    ok = jnp.asarray(True)
    if chunks:
        u0, goods = jax.lax.scan(lambda u, _: primal_solve(config, u, s, chunk_time), u0, None, length=chunks)
        ok = jnp.all(goods)
    starts, J, u_end, steps, ok_forward = _forward(config, u0, s, segments)
    kept = (jnp.arange(segments) < segments - discard).astype(u0.dtype)
    T = (segments - discard) * config.segment_time
    rho = kept @ J / T
    flow, _ = _flow_part(config, u_end, s, rho)
    W = start_basis(config, u_end, s, key)
    _, records = jax.lax.scan(partial(_backward_segment, config, s, rho), (flow, W), starts, reverse=True)
    # the least squares over the segments in reverse order: a_{i-1} = R_i a_i + b_i
    a = shadowing_coefficients(records.C[::-1], records.d[::-1], records.R[1:][::-1], records.b[1:][::-1])[::-1]
    along = records.sw + jnp.einsum("kup,ku->kp", records.sW, a[..., 0])  # (K, p)
    derivative = kept @ along / T
    growth = jnp.log(jnp.abs(jnp.diagonal(records.R[1:], axis1=1, axis2=2)))  # the adjoints' growth backwards
    exponents = jnp.sum(growth, axis=0) / ((segments - 1) * config.segment_time)
    return (rho, derivative.reshape(s.shape), exponents, steps + jnp.sum(records.steps),
            ok & ok_forward & jnp.all(records.ok))


def nilsas(f, u0, s, objective, *, n_unstable: int, segment_time: float, segments: int, members: int = 4,
           transient: float = 0.0, discard: int = 0, rtol: float = 1e-8, atol: float = 1e-8,
           steps_per_segment: int | None = None, solver: diffrax.AbstractSolver | None = None, max_steps: int = 4096,
           neutral: bool = True, spread: float = 1e-3, seed: int = 0) -> ShadowingResult:
    r"""The derivative of the long-time average :math:`\langle J\rangle` of
    :math:`\dot u = f(u, s)` with respect to every entry of ``s`` by non-intrusive least-squares
    adjoint shadowing (module docstring; theory: docs/theory/shadowing.md): :math:`n_u + 1`
    adjoint solutions whatever the number of parameters, where :func:`~jaxclear.shadowing.nilss`
    integrates :math:`n_u + p` tangents. The same derivative as :func:`~jaxclear.shadowing.nilss`
    (both approximate the shadowing derivative; on a finite run they differ by terms of order
    :math:`1/T`), the same arguments and result, but for ``discard``.

    ``f``, ``u0``, ``s``, ``objective``, ``n_unstable``, ``segment_time``, ``segments``, ``members``,
    ``transient``, ``rtol``, ``atol``, ``steps_per_segment``, ``solver``, ``max_steps``, ``neutral``,
    ``spread`` and ``seed`` are :func:`~jaxclear.shadowing.nilss`'s (the tolerances apply to the
    forward solves and to the backward solves of the adjoints; ``max_steps`` to each solve).

    Args:
        discard: segments at the *end* left out of the averages (they still enter the least
            squares): the adjoints start there from their flow component alone, and their parts
            that shrink backwards in time reach the shadowing adjoint at the slowest contraction
            rate :math:`|\lambda_s|`; ``0 .. segments - 2``.

    Returns:
        A :class:`ShadowingResult` (``method`` ``"NILSAS"``; ``exponents`` the homogeneous
        adjoints' growth backwards in time: the largest Lyapunov exponents).

    Raises:
        ParameterError: an input outside its range (named, with the range).
        SolverError: a solve failed (``max_steps`` reached, or the solver's own failure).
    """
    return shadow("nilsas", member, f, u0, s, objective, n_unstable=n_unstable, segment_time=segment_time,
                  segments=segments, members=members, transient=transient, discard=discard, rtol=rtol, atol=atol,
                  steps_per_segment=steps_per_segment, solver=solver, max_steps=max_steps, neutral=neutral,
                  spread=spread, seed=seed)
