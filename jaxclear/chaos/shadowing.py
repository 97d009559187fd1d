r"""Derivatives of a mechanism's steady operation: non-intrusive least-squares shadowing (NILSS,
Ni and Wang, J. Comput. Phys. 347 (2017) 56-77) on the engine's own tangents.

The objective is the long-time average :math:`\langle J\rangle` of a function
:math:`J(t, q, \dot q, \ddot q; \theta)` along the steady (possibly chaotic) running of a driven
mechanism; :func:`steady_derivatives` returns :math:`d\langle J\rangle/d\theta` for named
parameters :math:`\theta`. The algorithm is :func:`jaxclear.shadowing.nilss`'s (its least
squares and derivative formula, :func:`jaxclear.shadowing.derivative_terms`); what differs is
where the tangents come from and which space they live in:

* **The tangents are the engine's** (:func:`~jaxclear.integrate.tangent_system`): ``n_unstable``
  homogeneous tangents :math:`W` and one inhomogeneous tangent per name :math:`v^*_j`
  (:math:`\dot v^*_j = f_y v^*_j + f_\theta\,\theta'_j`, the name's direction with derived values
  following, :func:`jaxclear.params.derivatives.directions`), integrated with the state in one
  error-controlled solve, steps ending at every contact onset, the impact memory's saltation
  applied at every step (as for the sensitivities and the Lyapunov exponents).
* **Time is a state.** A driven mechanism is not autonomous; with :math:`t` as a state
  :math:`u = (y, t)`, :math:`\dot u = (f(t, y), 1)` is, and its flow direction is neutral. A tangent
  is :math:`(v_y, v_t)`; within a segment :math:`v_t` is constant and :math:`\tilde v = v_y -
  v_t f` obeys the engine's tangent equation without a time part (:math:`\dot{\tilde v} = f_y
  \tilde v + f_\theta`), so the engine integrates :math:`\tilde v` and :math:`v_y = \tilde v +
  v_t f` is rebuilt wherever it is read. This is what lets the crank speed be a parameter: its
  perturbation shifts the crank's phase linearly in time.
* **Samples at fixed crank angles.** The samples lie at fixed crank angles (uniform in time at
  the constant crank speed), and a tangent is read there moved along the flow :math:`(f, 1)` to
  keep the crank's angle: :math:`v - c\,(f, 1)`, :math:`c = e^\top v_y / e^\top f` with
  :math:`e^\top y` the crank's angle. A shadowing tangent is defined up to such a flow
  component (the time dilation), and this one makes every statistic of the samples a function
  of states at fixed crank angles, differentiated sample by sample with no dilation term: the
  mean (the long-time average) and each revolution's largest sample, whose sample lies beside
  the continuous peak, where a tangent's arbitrary phase would be read through :math:`dJ/dt
  \ne 0`. (On the forced pendulum of the tests the crank speed's derivative of the mean agrees
  with central differences to 4e-4 this way and to 1.4-23 % with the time dilation's end terms,
  depending on the segments and samples.)
* **The metric** of the least squares and of the flow-normal projection is the Lyapunov
  exponents' (:mod:`.manifold`): positions weighed 1, velocities by :math:`1/|\omega|`, the memory
  by 0, :math:`v_t` by :math:`c_t = |f|` at the transient's end. The homogeneous tangents are
  projected on the constraint manifold's tangent space at every renormalisation; the memory
  entries the motion does not read (:func:`.manifold.live_memory`: records such as the contact
  work) are outputs and set to zero there.
* **The integrals** (:math:`\int W^{\perp\top}W^\perp`, :math:`\int W^{\perp\top}v^{*\perp}`,
  :math:`\int J_u W`, :math:`\int (J_u v^* + J_\theta)`, :math:`\int J`) are sums over
  ``samples_per_segment`` uniform samples a segment (the right end points): the averages are those
  of the sampled signal, as a measurement's (triggered by a crank encoder) are (the statistics in
  ``benchmarks/bench_steady_averages.py`` are of 100 samples a revolution).
* **The error** is the spread of batch means: the segments after ``discard`` are cut into
  ``blocks`` consecutive blocks (every segment or revolution in one, sizes differing by at most
  one), each block's share of the derivative taken as an independent
  estimate (the motion forgets its state in a few e-folding times :math:`1/\lambda_1`, 2.3 ms on
  the benchmark; a block is many revolutions).

Theory, assumptions and the validation on the benchmark slider-crank: docs/theory/shadowing.md.
"""

from __future__ import annotations

import inspect
import math
import warnings
from functools import partial
from typing import Callable, NamedTuple, Sequence

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import solve_triangular

from .._errors import RESULTS, ParameterError, SolverError, check_integer, function_name
from ..integrate import (Settings, State, assemble, check_assembly, check_settings, flat_vector_field,
                         integrate_system, mechanism_system, settings, start_run, tangent_system)
from ..model.drivers import crank_driver, crank_period
from ..model.mechanism import Mechanism
from .. import params
from ..shadowing import Integrals, SegmentRecord, ShadowingResult, coefficients, derivative_terms, positive_qr
from . import manifold


def _crank_angle(mech, size: int, dtype):
    """The row ``e`` (size,) with ``e @ y`` the crank's angle (:func:`~jaxclear.model.drivers.
    crank_driver`: its body's angle less its reference body's)."""
    driver = crank_driver(mech)[1]
    e = jnp.zeros((size,), dtype).at[3 * mech.body_index(driver.body) + 2].set(1.0)
    reference = mech.body_index(driver.relative_to)
    return e if reference < 0 else e.at[3 * reference + 2].add(-1.0)


def _segments(mech, s, along, objective, transient, segment_time, segments: int, samples: int, n_unstable: int):
    """Traceable: the transient, then ``segments`` segments in one ``lax.scan``. Returns the
    segments' records (stacked :class:`~jaxclear.shadowing.SegmentRecord`), the steps and whether
    every solve succeeded."""
    begin = start_run(mech, s, None)
    y = begin.packed
    dtype = y.dtype
    size, n = y.shape[0], mech.n_coordinates
    p = jax.tree_util.tree_leaves(along)[0].shape[0]
    count = n_unstable + p
    t0 = jnp.asarray(s.t_start, dtype)
    t_a = t0 + transient
    pre = integrate_system(mechanism_system(mech, s), s, t0, t_a, t_a[None], y)
    y = pre.samples[-1]
    ok0 = (begin.assembled & (begin.valid == RESULTS.successful) & (pre.result == diffrax.RESULTS.successful)
           & jnp.all(jnp.isfinite(y)))

    w = manifold.weights(mech, manifold.time_scale(mech)).astype(dtype)  # (2n,)
    wm = jnp.concatenate([w, jnp.zeros(size - 2 * n, dtype)])  # memory weighs nothing
    basis = manifold.tangent_basis(mech, t_a, y[:n], y[n:2 * n], w, n_unstable)
    W = jnp.zeros((n_unstable, size), dtype).at[:, :2 * n].set((basis / w[:, None]).T)
    V = jnp.zeros((p, size), dtype)
    zero_rows = jax.tree_util.tree_map(lambda d: jnp.zeros((n_unstable,) + d.shape[1:], d.dtype), along)
    dirs = jax.tree_util.tree_map(lambda z, d: jnp.concatenate([z, d]), zero_rows, along)
    reference = manifold.tangent_reference(w)
    system = tangent_system(mech, s, size=size, count=count, span=segment_time, reference=reference, along=dirs)
    fractions = jnp.arange(1, samples + 1, dtype=dtype) / samples
    crank = _crank_angle(mech, size, dtype)
    fixed = jax.tree_util.tree_map(jnp.zeros_like, system.point)

    with_states = reads_states(objective)

    def rate_and_objective(t, yy, point):
        m, ss, _ = system.rebuild(point)
        rate = flat_vector_field(t, yy, (m, ss.baumgarte))
        extra = (State.unpack(yy, m).elements,) if with_states else ()
        return rate, jnp.asarray(objective(t, yy[:n], yy[n:2 * n], rate[n:2 * n], m, *extra), dtype)

    def measure(t, yy, S, times):
        """At one sample: the rate, J, the tangents v_y = S + v_t f and their J_u v (+ J_theta),
        each tangent moved along the flow (f, 1) to keep the crank's angle (module docstring)."""
        (rate, J), lin = jax.linearize(rate_and_objective, t, yy, system.point)
        full = S + times[:, None] * rate[None]
        _, dJ = jax.vmap(lin)(times, full, system.directions)
        rising = lin(jnp.ones((), dtype), rate, fixed)[1]
        return rate, J, full, dJ - (full @ crank) / (rate @ crank) * rising

    rate_a = flat_vector_field(t_a, y, (mech, s.baumgarte))
    ct = jnp.sqrt(rate_a @ (wm**2 * rate_a))  # the metric's weight of a time shift [state/s]

    def perp(rate, full, times):
        """The flow-normal parts (in the metric, time weighed ``ct``) of the tangents ``(full,
        times)`` of ``u = (y, t)``, whose flow direction is ``(rate, 1)``, and their flow
        components xi."""
        xi = (full @ (wm**2 * rate) + ct**2 * times) / (rate @ (wm**2 * rate) + ct**2)
        return full - xi[:, None] * rate[None], times - xi, xi

    def weighted(full, times):
        """The tangents' coordinates in the metric (count, 2n + 1): positions, velocities, time."""
        return jnp.concatenate([full[:, :2 * n] * w, ct * times[:, None]], axis=1)

    def segment(carry, i):
        y, rate0, W, V, wt, vt, ok = carry  # rate0: the vector field at (ta, y), the last segment's end
        ta = t_a + i * segment_time
        tb = ta + segment_time
        ts = ta + segment_time * fractions
        times = jnp.concatenate([wt, vt])
        S0 = jnp.concatenate([W, V]) - times[:, None] * rate0[None]
        run = integrate_system(system, s, ta, tb, ts, jnp.concatenate([y, S0.reshape(-1)]))
        ys, Ss = run.samples[:, :size], run.samples[:, size:].reshape(samples, count, size)
        rates, Js, fulls, dJs = jax.vmap(lambda t, yy, S: measure(t, yy, S, times))(ts, ys, Ss)
        h = segment_time / samples
        P = jax.vmap(lambda r, f: weighted(*perp(r, f, times)[:2]))(rates, fulls)  # (samples, count, 2n + 1)
        Wp, Vp = P[:, :n_unstable], P[:, n_unstable:]
        integrals = Integrals(C=h * jnp.einsum("kus,kvs->uv", Wp, Wp), D=h * jnp.einsum("kus,kps->up", Wp, Vp),
                              JW=h * jnp.sum(dJs[:, :n_unstable], 0), JV=h * jnp.sum(dJs[:, n_unstable:], 0),
                              J=h * jnp.sum(Js))
        # the segment's end: flow-normal parts; W's state part (v_y - v_t f, at fixed time) on the
        # constraint manifold's tangent space; QR of W; V less its part along Q
        y1, rate1 = ys[-1], rates[-1]
        fp, tp, xi = perp(rate1, fulls[-1], times)
        proj = manifold.projector(mech, tb, y1[:n], y1[n:2 * n], w)
        still = fp[:n_unstable, :2 * n] - tp[:n_unstable, None] * rate1[None, :2 * n]
        on = (proj @ (w[:, None] * still.T)).T / w + tp[:n_unstable, None] * rate1[None, :2 * n]
        fp = fp.at[:n_unstable, :2 * n].set(on)
        X = weighted(fp, tp)
        Q, R = positive_qr(X[:n_unstable].T)  # (2n + 1, n_u), (n_u, n_u)
        good = run.result == diffrax.RESULTS.successful
        good = good & jnp.all(jnp.isfinite(run.samples)) & jnp.all(jnp.abs(jnp.diagonal(R)) > 0)
        safe_R = jnp.where(good, R, jnp.eye(n_unstable, dtype=dtype))
        live = manifold.live_memory(mech, s.baumgarte, tb, y1)
        memory = solve_triangular(safe_R.T, fp[:n_unstable, 2 * n:], lower=True) * live
        W1 = jnp.concatenate([(Q[:2 * n] / w[:, None]).T, memory], axis=1)
        wt1 = Q[2 * n] / ct
        b = Q.T @ X[n_unstable:].T  # (n_u, p)
        V1 = fp[n_unstable:] - b.T @ W1
        V1 = V1.at[:, 2 * n:].multiply(live)
        vt1 = tp[n_unstable:] - b.T @ wt1
        record = SegmentRecord(integrals=integrals, R=safe_R, b=b, xi_W=xi[:n_unstable], xi_V=xi[n_unstable:],
                               J_end=Js[-1], steps=run.num_accepted_steps, ok=good)
        top = jnp.argmax(Js)  # the segment's largest sample
        keep = ok & good
        new = (*(jnp.where(keep, a, b) for a, b in ((y1, y), (rate1, rate0), (W1, W), (V1, V), (wt1, wt), (vt1, vt))),
               keep)
        return new, (record, Peak(Js[top], dJs[top, :n_unstable], dJs[top, n_unstable:]))

    zeros = jnp.zeros((n_unstable,), dtype), jnp.zeros((p,), dtype)
    (*_, ok), (records, peaks) = jax.lax.scan(segment, (y, rate_a, W, V, *zeros, ok0), jnp.arange(segments))
    return records, peaks, jnp.sum(records.steps) + pre.num_accepted_steps, ok


class Peak(NamedTuple):
    """A segment's largest sample of the objective and its derivative terms there: ``value``,
    ``JW`` (n_u,) :math:`J_u W` and ``JV`` (p,) :math:`J_u v^* + J_\theta` at that sample."""

    value: jax.Array
    JW: jax.Array
    JV: jax.Array


#: The statistics of the objective's samples that :func:`steady_derivatives` differentiates.
STATISTICS = ("mean", "revolution_peak")


def reads_states(objective) -> bool:
    """Whether ``objective`` takes a sixth positional argument (the force elements' states)."""
    try:
        parameters = inspect.signature(objective).parameters.values()
    except (TypeError, ValueError):  # a builtin or a callable without a signature
        return False
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    positional = [q for q in parameters if q.kind in kinds]
    return len(positional) >= 6 or any(q.kind is inspect.Parameter.VAR_POSITIONAL for q in parameters)


def _blocks(values, contributions, blocks: int):
    """Batch means of consecutive ``values`` (N,) and ``contributions`` (N, p): ``(B,), (B, p)``.
    Every entry lies in one block (entry ``i`` in block ``floor(i B / N)``: sizes ``N // B`` or one
    more), so the blocks hold all that the derivative sums: a remainder left out of the blocks
    could hold a grazing contact's jump that the derivative has and its error does not see."""
    n = values.shape[0]
    ids = (np.arange(n) * blocks) // n  # static
    counts = np.bincount(ids, minlength=blocks).astype(float)
    return (jax.ops.segment_sum(values, ids, blocks) / counts,
            jax.ops.segment_sum(contributions, ids, blocks) / counts[:, None])


def _core(mech, s, along, objective, transient, segment_time, segments: int, samples: int, n_unstable: int,
          discard: int, blocks: int, per_revolution: int):
    """Traceable: :func:`_segments`, the least squares and the blocks' derivatives. Returns
    ``(statistics, exponents (n_u,), steps, ok)``, ``statistics`` a dict over :data:`STATISTICS` of
    ``(average, derivative (p,), block averages (B,), block derivatives (B, p))``.

    The samples lie at fixed crank angles and the tangents read there keep the crank's angle
    (:func:`_segments`), so every statistic of the samples is differentiated sample by sample,
    with no time-dilation term. ``"mean"``: the samples' mean, its derivative the NILSS sum of
    :math:`J_u v + J_\theta` with :math:`v = v^* + W a`. ``"revolution_peak"``: the mean over
    revolutions of each revolution's largest sample; a revolution's peak lies in one segment,
    whose :math:`J_u v + J_\theta` at that sample is its derivative."""
    records, peaks, steps, ok = _segments(mech, s, along, objective, transient, segment_time, segments, samples,
                                          n_unstable)
    average, contributions, exponents, T = derivative_terms(records, discard, segment_time, dilation=False)
    per_segment = records.integrals.J[discard:] / segment_time
    mean = (average, jnp.sum(contributions, 0) / T, *_blocks(per_segment, contributions[discard:] * (
        (segments - discard) / T), blocks))
    a = coefficients(records)  # (K, n_u, p)
    top = discard + per_revolution * jnp.arange((segments - discard) // per_revolution) + jnp.argmax(
        peaks.value[discard:].reshape(-1, per_revolution), axis=1)
    values = peaks.value[top]
    slopes = peaks.JV[top] + jnp.einsum("ru,rup->rp", peaks.JW[top], a[top])
    peak = (jnp.mean(values), jnp.mean(slopes, 0), *_blocks(values, slopes, blocks))
    return {"mean": mean, "revolution_peak": peak}, exponents, steps, ok


@partial(jax.jit, static_argnames=("objective", "segments", "samples", "n_unstable", "discard", "blocks",
                                   "per_revolution"))
def _compiled(mech, s, along, transient, segment_time, *, objective, segments, samples, n_unstable, discard, blocks,
              per_revolution):
    return _core(mech, s, along, objective, transient, segment_time, segments, samples, n_unstable, discard, blocks,
                 per_revolution)


class ShadowingWarning(UserWarning):
    """A shadowing derivative that its own blocks do not resolve (:func:`steady_derivatives`)."""


#: A derivative whose standard error exceeds this fraction of its size is not resolved.
UNRESOLVED = 0.5
#: Blocks are heavy-tailed when the farthest lies more than this many robust standard deviations
#: (1.4826 times the median absolute deviation) from their median, and more than a tenth of the
#: derivative: batch means of a finite-variance quantity over 4-16 blocks lie within about 3.
HEAVY_TAIL = 10.0


def unresolved(names, derivative, error, blocks, exponents) -> str:
    """The warning's text for the names whose derivative its blocks do not resolve (standard error
    above :data:`UNRESOLVED` of its size, or blocks heavy-tailed, :data:`HEAVY_TAIL`), or ``""``."""
    lines = []
    for k, name in enumerate(names):
        b = blocks[:, k]
        med = np.median(b)
        mad = 1.4826 * np.median(np.abs(b - med))
        far = np.max(np.abs(b - med))
        tail = far / mad if mad > 0 and far > 0.1 * abs(derivative[k]) else 0.0  # material outliers only
        if error[k] > UNRESOLVED * abs(derivative[k]) or tail > HEAVY_TAIL:
            lines.append(f"{name}: {derivative[k]:.4g} +- {error[k]:.2g}, blocks from {np.min(b):.3g} to {np.max(b):.3g}"
                         + (f" (heavy-tailed: one {tail:.0f} robust deviations from their median)"
                            if tail > HEAVY_TAIL else ""))
    if not lines:
        return ""
    rates = ", ".join(f"{x:.4g}" for x in exponents)
    return ("steady_derivatives: the shadowing derivative is not resolved by its blocks for " + "; ".join(lines)
            + f". The homogeneous tangents grow at {rates} 1/s: n_unstable must hold every positive Lyapunov "
            "exponent (jaxclear.lyapunov(..., count=...)); longer runs shrink a finite-variance error like "
            "T^-1/2, but an impacting motion's shadowing tangents can have no finite variance (grazing contacts "
            "stretch them without bound); compare with finite differences of long-time averages "
            "(docs/theory/shadowing.md, 'Mechanisms')")


def check_options(revolutions, transient_revolutions, segments_per_revolution, samples_per_segment, blocks,
                  discard_revolutions, prefix: str = "") -> tuple[int, ...]:
    """:func:`steady_derivatives`' options of length and sampling as ints in their ranges, in
    that order, else a :class:`ParameterError` naming the option (``prefix`` before its name:
    ``"steady."`` for :class:`jaxclear.SteadyOperation`)."""
    revolutions = check_integer(prefix + "revolutions", revolutions, 1, None, "crank revolutions averaged")
    transient = check_integer(prefix + "transient_revolutions", transient_revolutions, 0, None, "revolutions first")
    spr = check_integer(prefix + "segments_per_revolution", segments_per_revolution, 1, None,
                        "renormalisations a revolution")
    samples = check_integer(prefix + "samples_per_segment", samples_per_segment, 1, None, "samples a segment")
    blocks = check_integer(prefix + "blocks", blocks, 2, None, "batch means for the errors")
    discard = check_integer(prefix + "discard_revolutions", discard_revolutions, 0, None, "revolutions left out")
    if revolutions * spr < 2 * blocks:
        raise ParameterError(f"{prefix}revolutions = {revolutions} with {spr} segments a revolution is too short for "
                             f"{prefix}blocks = {blocks}: at least {2 * blocks} segments (allowed range of "
                             f"{prefix}revolutions: [{math.ceil(2 * blocks / spr)}, inf))")
    return revolutions, transient, spr, samples, blocks, discard


def steady_derivatives(mech: Mechanism, names: Sequence[str], objective: Callable, s: Settings | None = None, *,
                       revolutions: int = 200, transient_revolutions: int = 20, segments_per_revolution: int = 16,
                       samples_per_segment: int = 8, n_unstable: int = 1, blocks: int = 4,
                       discard_revolutions: int = 2, statistic: str = "mean") -> ShadowingResult:
    r"""The derivative of the long-time average of ``objective`` (or of its largest value each
    revolution) over a driven mechanism's steady running with respect to the named parameters,
    by least-squares shadowing (NILSS; the module docstring says how the engine's tangents enter
    it, docs/theory/shadowing.md when to trust it).

    Args:
        mech: a mechanism with a crank (:class:`~jaxclear.AngleDriver`): the segments are
            fractions of its revolution.
        names: names of :mod:`jaxclear.params` (:func:`jaxclear.differentiable_names`); as in
            :func:`jaxclear.sensitivities`, derived values follow their sources.
        objective: ``objective(t, q, qdot, qddot, mech) -> scalar`` [its unit], traceable by JAX
            (``q``, ``qdot``, ``qddot`` of shape ``(n,)``; ``mech`` the mechanism at the
            parameters, so that what the objective reads of it is differentiated too); with a
            sixth positional parameter ``states`` it also gets the force elements' states (a
            tuple over ``mech.clearance_joints``: their memories, which a contact force reads,
            e.g. ``mech.clearance_joints[0].forces(mech, t, q, qdot, states[0])[2].normal_force``
            [N]). Its time average :math:`\langle J\rangle` is differentiated; for an RMS take
            the mean square and :math:`d\sqrt{\langle J\rangle} = d\langle J\rangle /
            (2\sqrt{\langle J\rangle})`.
        s: the integration settings (tolerances, solver; ``t_start`` is the run's start, its
            ``t_end`` is not used); default ``jc.settings(1.0)``.
        revolutions: crank revolutions averaged (after the transient), >= 1.
        transient_revolutions: revolutions run first without tangents (to reach the steady
            running), >= 0. The derivative holds the state at its end: where the average depends
            on the start (a lasting contact whose damping reads the approach speed stored in the
            transient) it is the derivative of the average from that state.
        segments_per_revolution: renormalisations a revolution, >= 1: the tangents grow by
            :math:`e^{\lambda_1 T/N}` within a segment (the benchmark at 5000 rpm: 443 1/s, 16 a
            revolution: e^0.33 on average, more in a contact).
        samples_per_segment: samples a segment of the averages and integrals, >= 1.
        n_unstable: homogeneous tangents, at least the positive Lyapunov exponents
            (:func:`jaxclear.lyapunov`), 1 .. the phase space's dimension.
        blocks: batch means for the standard errors, >= 2.
        discard_revolutions: revolutions after the transient that enter the least squares but not
            the averages (the inhomogeneous tangents start at zero), >= 0.
        statistic: ``"mean"``: the time average of the objective's samples; ``"revolution_peak"``:
            the mean over revolutions of each revolution's largest sample (the mean peak contact
            force a revolution, with a force as the objective), differentiated at the sample
            that holds it (raise ``samples_per_segment`` until the samples resolve the peaks; the
            blocks are then groups of whole revolutions).

    Returns:
        A :class:`~jaxclear.shadowing.ShadowingResult`: ``derivative`` ``(len(names),)`` [unit of
        J per SI unit of each name; ``speed_rpm`` per rpm], ``average`` (the ``statistic``'s
        value), their standard errors from
        the blocks (``member_*``: the blocks' values), ``exponents`` (the homogeneous tangents'
        growth rates [1/s]: where the last is clearly positive, raise ``n_unstable``).

    Raises:
        ParameterError: an option outside its range, an unknown name, no crank.
        SolverError: a segment's solve failed.

    Warns:
        ShadowingWarning: a derivative its blocks do not resolve (standard error above half its
            size, or heavy-tailed blocks), with the growth rates and what to check.
    """
    s = settings(1.0) if s is None else s
    check_settings("steady_derivatives", s, required=True, name="s")
    names = params.check_names(mech, names)
    revolutions, transient_revolutions, spr, samples, blocks, discard_revolutions = check_options(
        revolutions, transient_revolutions, segments_per_revolution, samples_per_segment, blocks, discard_revolutions)
    n_unstable = check_integer("n_unstable", n_unstable, 1, manifold.dimension(mech),
                               "homogeneous tangents, at most the phase space's dimension")
    if statistic not in STATISTICS:
        raise ParameterError(f"statistic = {statistic!r} is not one of {', '.join(map(repr, STATISTICS))}")
    if statistic == "revolution_peak" and revolutions < blocks:
        raise ParameterError(f"revolutions = {revolutions} is too short for blocks = {blocks} of whole revolutions "
                             f"(statistic 'revolution_peak'; allowed range of revolutions: [{blocks}, inf))")
    if not callable(objective):
        raise ParameterError(f"objective must be a function (t, q, qdot, qddot, mech) -> scalar, got {objective!r}")
    at, along = params.directions(mech, names)
    check_assembly(at, s, assemble(at, s.t_start))  # the structure's own messages (free motion, redundancy)
    x = np.asarray([float(params.get(at, n)) for n in names])
    scale = np.where(x != 0, np.abs(x), 1.0)
    along = jax.tree_util.tree_map(lambda d: d * jnp.asarray(scale).reshape((-1,) + (1,) * (d.ndim - 1)), along)
    period = float(crank_period(at))
    discard = discard_revolutions * spr
    segments = discard + revolutions * spr
    statistics, exponents, steps, ok = jax.device_get(_compiled(
        at, s, along, transient_revolutions * period, period / spr, objective=objective, segments=segments,
        samples=samples, n_unstable=n_unstable, discard=discard, blocks=blocks, per_revolution=spr))
    average, derivative, block_averages, block_derivatives = statistics[statistic]
    if not bool(ok):
        raise SolverError(f"steady_derivatives: a segment's solve failed (max_steps = {s.max_steps}, or a non-finite "
                          f"state or tangent; objective {function_name(objective)}); raise max_steps, tighten "
                          "rtol/atol or use more segments_per_revolution")
    derivative = np.asarray(derivative) / scale
    block_derivatives = np.asarray(block_derivatives) / scale
    error = np.std(block_derivatives, 0, ddof=1) / math.sqrt(blocks)
    message = unresolved(names, derivative, error, block_derivatives, np.asarray(exponents))
    if message:
        warnings.warn(message, ShadowingWarning, stacklevel=2)
    return ShadowingResult(
        derivative=jnp.asarray(derivative), derivative_error=jnp.asarray(error),
        average=jnp.asarray(average), average_error=jnp.asarray(np.std(block_averages, ddof=1) / math.sqrt(blocks)),
        member_derivatives=jnp.asarray(block_derivatives), member_averages=jnp.asarray(block_averages),
        exponents=jnp.asarray(exponents)[None], steps=jnp.asarray(steps)[None],
        time=revolutions * period, segments=segments, discard=discard, segment_time=period / spr,
        n_unstable=n_unstable, blocks=True)
