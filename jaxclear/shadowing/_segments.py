r"""One segment of NILSS: the state, its tangents and their time integrals, integrated together
by diffrax, and the renormalisation at the segment's end.

The augmented state of a segment of length :math:`\Delta T` is

* :math:`u` (``n``), the primal, :math:`\dot u = f(u, s)`;
* :math:`W` (``n x n_u``), homogeneous tangents, :math:`\dot W = f_u W`;
* :math:`V` (``n x p``), one inhomogeneous tangent per parameter, :math:`\dot v_j = f_u v_j +
  \partial f/\partial s_j`;
* the integrals over the segment that the least-squares problem and the derivative need:
  :math:`C = \int W^{\perp\top}W^\perp`, :math:`D = \int W^{\perp\top}V^\perp`,
  :math:`\int J_u W`, :math:`\int (J_u V + J_s)` and :math:`\int J`, where :math:`x^\perp = x -
  f\,(f^\top x)/(f^\top f)` is the part of a tangent normal to the flow.

The tangent right-hand sides are Jacobian-vector products of :math:`(f, J)` along every column
of :math:`W` and :math:`V` (with the unit direction of the parameter for :math:`V`), one
``jax.linearize`` and one ``vmap``: no Jacobian is formed, by hand or otherwise. The integrals
are states of the same solve, so they are as accurate as the tangents (the step-size control
sees them all).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import diffrax
import jax
import jax.numpy as jnp

#: Below this squared speed :math:`|f|^2` the flow direction is not projected out (a state at
#: rest has no neutral direction).
STILL = 1e-200


class SegmentConfig(NamedTuple):
    """What every segment's solve needs (static: hashable, part of the compiled program's key)."""

    f: Callable
    objective: Callable
    n_unstable: int
    segment_time: float
    solver: diffrax.AbstractSolver
    rtol: float
    atol: float
    steps_per_segment: int | None  # a fixed step ``segment_time / steps`` where given, else PID
    max_steps: int
    neutral: bool  # project the flow direction out of the tangents


class Integrals(NamedTuple):
    """The time integrals of one segment (states of its solve, zero at its start)."""

    C: jax.Array      # (n_u, n_u)
    D: jax.Array      # (n_u, p)
    JW: jax.Array     # (n_u,)   int J_u W dt
    JV: jax.Array     # (p,)     int (J_u V + J_s) dt
    J: jax.Array      # ()       int J dt


class SegmentRecord(NamedTuple):
    """What the least-squares problem and the derivative keep of one segment."""

    integrals: Integrals
    R: jax.Array        # (n_u, n_u) renormalisation at the segment's end: W_end^perp = Q R
    b: jax.Array        # (n_u, p)   Q^T V_end^perp
    xi_W: jax.Array     # (n_u,)     f^T W_end / |f|^2: the flow component of W at the end
    xi_V: jax.Array     # (p,)       f^T V_end / |f|^2
    J_end: jax.Array    # ()         J(u_end)
    steps: jax.Array    # ()         accepted steps of the solve
    ok: jax.Array       # ()         the solve succeeded


def flow_projector(fu, neutral: bool):
    """``x -> x - f (f^T x) / |f|^2`` (identity where ``neutral`` is False or the state is at
    rest), and ``x -> f^T x / |f|^2`` (the flow component, zero in the same cases)."""
    ff = fu @ fu
    moving = ff > STILL if neutral else jnp.asarray(False)
    inv = jnp.where(moving, 1.0 / jnp.where(moving, ff, 1.0), 0.0)

    def component(x):
        return (fu @ x) * inv

    def perp(x):
        return x - jnp.outer(fu, component(x)) if x.ndim == 2 else x - fu * component(x)

    return perp, component


def _directions(s, n_unstable: int, n: int, W, V):
    """The tangent directions in ``(u, s)``: the columns of W (``s`` fixed), then those of V
    each with its parameter's unit direction."""
    p = V.shape[1]
    du = jnp.concatenate([W.T, V.T])
    ds = jnp.concatenate([jnp.zeros((n_unstable,) + s.shape, s.dtype),
                          jnp.eye(p, dtype=s.dtype).reshape((p,) + s.shape)])
    return du, ds


def vector_field(config: SegmentConfig):
    """The augmented right-hand side ``(t, (u, W, V, integrals), s) -> derivative``."""

    def field(t, y, s):
        u, W, V, _ = y
        n_u = config.n_unstable

        def f_and_j(u_, s_):
            return config.f(u_, s_), jnp.asarray(config.objective(u_, s_), u_.dtype)

        (fu, J), linear = jax.linearize(f_and_j, u, s)
        du, ds = _directions(s, n_u, u.shape[0], W, V)
        df, dJ = jax.vmap(linear)(du, ds)
        perp, _ = flow_projector(fu, config.neutral)
        w_perp, v_perp = perp(W), perp(V)
        integrals = Integrals(C=w_perp.T @ w_perp, D=w_perp.T @ v_perp, JW=dJ[:n_u], JV=dJ[n_u:], J=J)
        return fu, df[:n_u].T, df[n_u:].T, integrals

    return field


def _controller(config: SegmentConfig):
    if config.steps_per_segment is not None:
        return diffrax.ConstantStepSize(), config.segment_time / config.steps_per_segment
    return diffrax.PIDController(rtol=config.rtol, atol=config.atol), None


def primal_solve(config: SegmentConfig, u, s, duration):
    """The state after ``duration`` (no tangents): the transient. Returns ``(u, ok)``."""
    controller, dt0 = _controller(config)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: config.f(y, a)), config.solver, t0=0.0, t1=duration, dt0=dt0, y0=u,
        args=s, stepsize_controller=controller, saveat=diffrax.SaveAt(t1=True), max_steps=config.max_steps,
        adjoint=diffrax.ForwardMode(), throw=False)
    return sol.ys[-1], sol.result == diffrax.RESULTS.successful


def segment(config: SegmentConfig, u, W, V, s):
    """Integrate one segment from ``(u, W, V)`` and renormalise at its end.

    Returns ``((u_end, W_next, V_next), SegmentRecord)``: the next segment starts from the
    orthonormal basis ``Q`` of the flow-normal parts of the homogeneous tangents
    (:math:`W^\\perp_{end} = Q R`, the diagonal of ``R`` made positive) and from the flow-normal
    part of the inhomogeneous tangents less their components on ``Q``,
    :math:`V_{next} = V^\\perp_{end} - Q b`, :math:`b = Q^\\top V^\\perp_{end}`."""
    n_u, p = W.shape[1], V.shape[1]
    zeros = Integrals(C=jnp.zeros((n_u, n_u)), D=jnp.zeros((n_u, p)), JW=jnp.zeros(n_u), JV=jnp.zeros(p),
                      J=jnp.zeros(()))
    controller, dt0 = _controller(config)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field(config)), config.solver, t0=0.0, t1=config.segment_time, dt0=dt0,
        y0=(u, W, V, zeros), args=s, stepsize_controller=controller, saveat=diffrax.SaveAt(t1=True),
        max_steps=config.max_steps, adjoint=diffrax.ForwardMode(), throw=False)
    u_end, W_end, V_end, integrals = jax.tree_util.tree_map(lambda x: x[-1], sol.ys)
    fu = config.f(u_end, s)
    perp, component = flow_projector(fu, config.neutral)
    w_perp, v_perp = perp(W_end), perp(V_end)
    if n_u:
        Q, R = positive_qr(w_perp)
    else:
        Q, R = w_perp, jnp.zeros((0, 0), w_perp.dtype)
    b = Q.T @ v_perp
    record = SegmentRecord(
        integrals=integrals, R=R, b=b, xi_W=component(W_end), xi_V=component(V_end),
        J_end=jnp.asarray(config.objective(u_end, s), u_end.dtype), steps=sol.stats["num_accepted_steps"],
        ok=sol.result == diffrax.RESULTS.successful)
    return (u_end, Q, v_perp - Q @ b), record


def positive_qr(x):
    """``(Q, R)`` with ``x = Q R`` (``x`` (m, k), ``Q`` (m, k) orthonormal columns) and the
    diagonal of ``R`` made non-negative: the renormalisation of NILSS's homogeneous tangents, whose
    log diagonal is their growth."""
    Q, R = jnp.linalg.qr(x)
    sign = jnp.where(jnp.diagonal(R) < 0, -1.0, 1.0)
    return Q * sign, R * sign[:, None]


def start_basis(config: SegmentConfig, u, s, key):
    """A random orthonormal basis of ``n_unstable`` flow-normal directions at ``u`` (the
    homogeneous tangents' start)."""
    n = u.shape[0]
    perp, _ = flow_projector(config.f(u, s), config.neutral)
    W = perp(jax.random.normal(key, (n, config.n_unstable), u.dtype))
    return jnp.linalg.qr(W)[0] if config.n_unstable else W
