r"""Benettin's method on the tangent dynamics of a mechanism: the traceable core of
:func:`~jaxclear.chaos.lyapunov` (one compiled program; ``jax.vmap`` applies).

The run is cut into ``windows`` renormalisation intervals of length :math:`\tau`. In each, the
state and ``count`` tangent vectors (perturbations of the state at the interval's start) are
integrated together by :class:`~jaxclear.integrate.sensitivity.TangentSystem` with no perturbed
parameter: the variational equation :math:`\dot S = f_y S` with the same Runge-Kutta steps as the
state, the tangents in the step-size control (CVODES ``errconS``), steps ending at every contact
onset and separation and at the friction laws' kinks, and the memory rules' derivatives applied
at every accepted step. A contact force is continuous at an onset and a separation (zero at zero
penetration), so the positions' and velocities' tangents do not jump there; what does jump is the
stored approach speed, whose tangent carries the shift of the onset time (saltation of the memory
rule, :mod:`jaxclear.integrate.sensitivity`).

At the end of each interval the tangents are projected on the tangent space of the constraint
manifold (:mod:`.manifold`), weighted, and orthonormalised by a QR factorisation
:math:`W P S = Q R`; :math:`\ln|R_{ii}|` is the growth of the ``i``-th direction over the
interval (Benettin, Galgani, Giorgilli, Strelcyn, Meccanica 15 (1980) 9-20 and 21-30; Shimada and
Nagashima, Prog. Theor. Phys. 61 (1979) 1605). The next interval starts from :math:`W^{-1}Q`,
the memory's tangents transformed by the same :math:`R^{-1}` (those of the memory's records,
the work and the running peaks, which no force reads, set to zero:
:data:`~jaxclear.elements.memory.RECORDS`; a record never refreshed would grow by the inverse of
the most contracting direction's growth every interval and overflow, at the benchmark's
:math:`\lambda_4 \approx -1100` 1/s after about 40 one-revolution intervals). The ``i``-th exponent is
:math:`\lambda_i = \sum_k \ln|R^{(k)}_{ii}| / (K\tau)` over the intervals after ``discard``.

The windows are separate solves inside one ``lax.scan`` (each starts at the time it is at: the
solver takes start and end times as arrays, so nothing is recompiled per window); a member whose
run failed, or whose tangents overflowed, integrates zero-length windows from then on.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.scipy.linalg import solve_triangular

from .._errors import RESULTS
from ..elements.memory import record_mask
from ..integrate import Settings, State
from ..integrate import solve
from ..integrate.sensitivity import DTMIN_FRACTION, Rebuild, TangentSystem
from ..integrate.system import MechanismSystem
from ..model.mechanism import Mechanism
from . import manifold

#: Largest entry of a tangent at the end of an interval before the run counts as overflowed
#: (a growth of ``e^575``: within a factor ``1e58`` of the largest float64): status
#: ``tangent_overflow``.
OVERFLOW = 1e250

#: Lyapunov status codes (``LyapunovResult.status``) and their messages.
STATUS = {
    0: "ok",
    1: "the run failed (its status is in run_status)",
    2: "the tangents overflowed within a renormalisation interval (a growth beyond 1e250 over one interval): "
       "shorten the interval",
}


class LyapunovResult(eqx.Module):
    r"""The Lyapunov spectrum of a run and its convergence (all arrays; batched under ``vmap``).

    Attributes:
        exponents: (p,) the exponents [1/s], in the order of the QR factorisation (largest
            first once the basis has aligned); ``p`` = ``count``.
        running: (K, p) the running estimate after each interval that counts (after ``discard``).
        times: (K,) the end times [s] of those intervals.
        log_growth: (W, p) :math:`\ln|R_{ii}|` of every interval (the discarded ones included).
        interval: the renormalisation interval [s].
        spread: (p,) the largest minus the smallest running estimate over the last half of the
            counted intervals [1/s]: how far the estimate still moves.
        stderr: (p,) standard error of the exponents from batch means (8 batches of the counted
            intervals' finite-time exponents) [1/s].
        status: 0 ok, 1 the run failed (``run_status``), 2 tangents overflowed (:data:`STATUS`);
            the exponents are then the running estimate up to the last good interval (NaN if none).
        run_status: the run's :class:`~jaxclear.RESULTS` code.
        t_end: the time the run reached [s].
        ts: (T,) output times [s] (``samples`` per interval) and
        packed: (T, N) the packed states at them (the trajectory; empty with ``keep=False``).
        num_steps: accepted and rejected steps of all intervals.
    """

    exponents: jax.Array
    running: jax.Array
    times: jax.Array
    log_growth: jax.Array
    interval: jax.Array
    spread: jax.Array
    stderr: jax.Array
    status: jax.Array
    run_status: jax.Array
    t_end: jax.Array
    ts: jax.Array
    packed: jax.Array
    num_steps: jax.Array

    @property
    def largest(self):
        """The largest exponent [1/s]."""
        return jnp.max(self.exponents, axis=-1)

    @property
    def sum(self):
        """The sum of the exponents [1/s]: the mean rate of phase-space volume contraction
        (negative for a dissipative motion)."""
        return jnp.sum(self.exponents, axis=-1)


def _run_status(result, finite) -> jax.Array:
    """A window's :class:`RESULTS` code from diffrax's result and the state's finiteness."""
    import diffrax

    code = RESULTS.where(finite, RESULTS.successful, RESULTS.nonfinite_state)
    code = RESULTS.where(result == diffrax.RESULTS.successful, code, RESULTS.solver_failed)
    code = RESULTS.where(result == diffrax.RESULTS.dt_min_reached, RESULTS.nonfinite_state, code)
    code = RESULTS.where(result == diffrax.RESULTS.max_steps_reached, RESULTS.max_steps_reached, code)
    return jnp.asarray(code._value, jnp.int32)


def _batch_stderr(finite_time, counted: int):
    """Standard error of the mean of the rows of ``finite_time`` (K, p) from 8 batch means
    (fewer when K < 8; zero rows when K < 2): correlated samples of a chaotic run are averaged
    in batches first (Flyvbjerg and Petersen, J. Chem. Phys. 91 (1989) 461)."""
    batches = min(8, counted)
    if batches < 2:
        return jnp.full(finite_time.shape[1:], jnp.nan)
    size = counted // batches
    means = finite_time[counted - batches * size:].reshape(batches, size, -1).mean(axis=1)
    return jnp.std(means, axis=0, ddof=1) / jnp.sqrt(batches)


def benettin(mech: Mechanism, s: Settings, y0: State | None, *, transient, interval, windows: int, discard: int,
             samples: int, count: int, scale, keep: bool = True) -> LyapunovResult:
    """The Lyapunov exponents of ``mech`` (see the module docstring): the run starts at
    ``s.t_start`` (assembled, or from ``y0``), runs ``transient`` [s] without tangents, then
    ``windows`` intervals of ``interval`` [s] with ``count`` tangents, ``samples`` output samples
    per interval; the first ``discard`` intervals do not count; ``scale`` [s] is the metric's time
    scale. ``keep``: return the trajectory's samples."""
    begin = solve.start(mech, s, y0)
    dtype = begin.packed.dtype
    size = begin.packed.shape[0]
    n = mech.n_coordinates
    ok0 = (begin.valid == RESULTS.successful) & begin.assembled
    t0 = jnp.asarray(s.t_start, dtype)
    interval = jnp.asarray(interval, dtype)
    t_a = t0 + jnp.where(ok0, jnp.asarray(transient, dtype), 0.0)

    # the transient, without tangents
    pre = solve.integrate(MechanismSystem(mech, s.baumgarte), s, t0, t_a, t_a[None], begin.packed)
    y = pre.samples[-1]
    code = jnp.where(ok0, _run_status(pre.result, jnp.all(jnp.isfinite(y))),
                     jnp.asarray(jnp.where(begin.valid == RESULTS.successful, RESULTS.assembly_failed._value,
                                           begin.valid._value), jnp.int32))
    w = manifold.weights(mech, scale).astype(dtype)
    carried = jnp.concatenate([jnp.zeros((0,), dtype)] + [
        e.state_to_vector(record_mask(e.state_init(dtype))).astype(dtype) for e in mech.clearance_joints])
    basis = manifold.tangent_basis(mech, t_a, y[:n], y[n:2 * n], w, count)  # (2n, count), weighted
    tangents = jnp.zeros((count, size), dtype).at[:, :2 * n].set((basis / w[:, None]).T)

    leaves, treedef = jax.tree_util.tree_flatten((mech, s, None))
    # the tangents' absolute tolerance grows with them (TangentSystem.weigh_error): the reference
    # is the size of a tangent just after renormalising (a unit vector of the metric spread over
    # the 2n coordinates: its largest entry in the coordinates' units)
    reference = jnp.max(1.0 / w) / jnp.sqrt(w.shape[0])
    system = TangentSystem(mech, s.baumgarte, Rebuild(leaves, treedef, ()), (), (),
                           DTMIN_FRACTION * interval, size, count, reference)
    fractions = jnp.arange(1, samples + 1, dtype=dtype) / samples

    def window(carry, k):
        y, tangents, code, status = carry
        go = (code == 0) & (status == 0)
        ta = t_a + k * interval
        tb = jnp.where(go, ta + interval, ta)
        ts = ta + (tb - ta) * fractions
        run = solve.integrate(system, s, ta, tb, ts, jnp.concatenate([y, tangents.reshape(-1)]))
        end = run.samples[-1]
        y1, s1 = end[:size], end[size:].reshape(count, size)
        # renormalisation: project on the manifold's tangent space, weight, QR
        proj = manifold.projector(mech, tb, y1[:n], y1[n:2 * n], w)
        x = proj @ (w[:, None] * s1[:, :2 * n].T)
        q, r = jnp.linalg.qr(x)
        diag = jnp.abs(jnp.diagonal(r))
        finite = jnp.all(jnp.isfinite(s1)) & (jnp.max(jnp.abs(s1)) < OVERFLOW) & jnp.all(diag > 0)
        new_code = jnp.where(go, _run_status(run.result, jnp.all(jnp.isfinite(y1))), code)
        # a non-finite tangent stops the solve like a non-finite state: tell the two apart
        overflow = go & ~finite & jnp.all(jnp.isfinite(y1))
        new_status = jnp.where(overflow, 2, jnp.where(go & (new_code != 0), 1, status))
        new_code = jnp.where(overflow, 0, new_code)
        good = go & (new_status == 0)
        safe_r = jnp.where(good, r, jnp.eye(count, dtype=dtype))
        memory = solve_triangular(safe_r.T, s1[:, 2 * n:], lower=True) * carried  # records' tangents dropped
        renormed = jnp.concatenate([(q / w[:, None]).T, memory], axis=1)
        logs = jnp.where(good, jnp.log(jnp.where(good, diag, 1.0)), jnp.nan)
        carry = (jnp.where(good, y1, y), jnp.where(good, renormed, tangents), new_code, new_status)
        out = (logs, run.samples[:, :size] if keep else jnp.zeros((0, size), dtype), ts,
               run.num_accepted_steps + run.num_rejected_steps)
        return carry, out

    (y_end, _, code, status), (logs, packed, ts, steps) = jax.lax.scan(
        window, (y, tangents, code, jnp.where(code == 0, 0, 1).astype(jnp.int32)), jnp.arange(windows))
    status = jnp.where((code != 0) & (status == 0), 1, status)
    counted = logs[discard:]
    finite_time = counted / interval
    cumulative = jnp.cumsum(counted, axis=0)
    elapsed = interval * jnp.arange(1, windows - discard + 1, dtype=dtype)
    running = cumulative / elapsed[:, None]
    good_rows = jnp.all(jnp.isfinite(running), axis=1)
    last = jnp.max(jnp.where(good_rows, jnp.arange(running.shape[0]), -1))
    exponents = jnp.where(last >= 0, running[jnp.maximum(last, 0)], jnp.nan)
    half = running[(windows - discard) // 2:]
    spread = jnp.max(half, axis=0) - jnp.min(half, axis=0)
    times = t_a + interval * jnp.arange(discard + 1, windows + 1, dtype=dtype)
    return LyapunovResult(
        exponents=exponents, running=running, times=times, log_growth=logs, interval=interval, spread=spread,
        stderr=_batch_stderr(finite_time, windows - discard), status=status.astype(jnp.int32),
        run_status=code.astype(jnp.int32), t_end=ts[-1, -1] if windows else t_a,
        ts=ts.reshape(-1) if keep else jnp.zeros((0,), dtype),
        packed=packed.reshape(-1, size), num_steps=jnp.sum(steps) + pre.num_accepted_steps + pre.num_rejected_steps)
