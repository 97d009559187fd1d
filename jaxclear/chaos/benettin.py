r"""Benettin's method on the tangent dynamics of a mechanism: the traceable core of
:func:`~jaxclear.chaos.lyapunov` (one compiled program; ``jax.vmap`` applies).

The run is cut into ``windows`` intervals of length :math:`\tau`, each renormalised at least once,
at its end (more often where the tangents' growth asks for it, below). The state and ``count``
tangent vectors (perturbations of the state at a step's start) are integrated together by
:class:`~jaxclear.integrate._sensitivity.TangentSystem` with no perturbed parameter: the variational
equation :math:`\dot S = f_y S` with the same Runge-Kutta steps as the state, the tangents in the
step-size control (CVODES ``errconS``), steps ending at every contact onset and separation and at
the friction laws' kinks, and the memory rules' derivatives applied at every accepted step. A
contact force is continuous at an onset and a separation (zero at zero penetration), so the
positions' and velocities' tangents do not jump there; what does jump is the stored approach speed,
whose tangent carries the shift of the onset time (saltation of the memory rule,
:mod:`jaxclear.integrate._sensitivity`).

At the end of each renormalisation step the tangents are projected on the tangent space of the
constraint manifold (:mod:`.manifold`), weighted, and orthonormalised by a QR factorisation
:math:`W P S = Q R`; :math:`\ln|R_{ii}|` is the growth of the ``i``-th direction over the step
(Benettin, Galgani, Giorgilli, Strelcyn, Meccanica 15 (1980) 9-20 and 21-30; Shimada and
Nagashima, Prog. Theor. Phys. 61 (1979) 1605). The next step starts from :math:`W^{-1}Q`, the
memory's tangents transformed by the same :math:`R^{-1}`, those of the entries the motion does
not read set to zero (:func:`~.manifold.live_memory`: outputs such as the contact work are not
states; carried by :math:`R^{-1}` without acting back they grew like :math:`e^{-\lambda_p t}` and
overflowed). The ``i``-th exponent is :math:`\lambda_i = \sum_k \ln|R^{(k)}_{ii}| / (K\tau)` over
the intervals after ``discard``.

The steps adapt to the tangents' growth. The information about the ``i``-th direction is what is
left of a tangent after the larger directions are removed: when the growths within one step spread
by :math:`e^{G}`, a direction :math:`e^{G}` times smaller than the largest is held only to
:math:`e^{G}` times the tolerance, and the smallest exponents are lost (undamped Hertz contact, a
Hamiltonian motion whose exponents sum to zero, renormalised once a revolution: sum +899 1/s; every
eighth of a revolution, where a contact can still spread the growths by :math:`e^{16}`: +7.9). So a
step of length :math:`h` is accepted only when the spread of its log growths and 0, :math:`G =
\max(0, \max_i\ln|R_{ii}|) - \min(0, \min_i\ln|R_{ii}|)`, is at most ``max_growth`` (default
:math:`\ln(0.01/\mathrm{rtol})`, :func:`default_max_growth`; with the 0, a single tangent's own
growth and decay are bounded too); a step that spread them more, or whose tangents overflowed, is
retried shorter, and the next step is :math:`0.9\,h\,G_{\max}/G`, at most twice the last and never
past the interval's end (the rule of a step-size controller, with the growth in place of the error:
the growth of a linear equation's solution is about proportional to the time). Within the interval
the steps are the iterations of a ``lax.while_loop``; the interval's :math:`\ln|R_{ii}|` is their
sum, so the running estimate, the batch means and the output samples are per interval. A
step of :data:`SHORTEST` times the interval is accepted whatever its growth, and overflow there is
the status ``tangent_overflow`` (a :class:`~jaxclear.RESULTS` member). The transfer-matrix method for disordered solids sets the frequency of its
orthonormalisations the same way, by how much a vector's length changes before and after one (A.
MacKinnon, notes on the critical indices,
http://www.cmth.ph.ic.ac.uk/people/a.mackinnon/Research/critind/node3.html); ChaosTools.jl's
``lyapunovspectrum`` takes a fixed ``Δt``.

The intervals are separate solves inside one ``lax.scan`` (each starts at the time it is at: the
solver takes start and end times as arrays, so nothing is recompiled per interval); a member
whose run failed, or whose tangents overflowed, integrates zero-length intervals from then on.
"""

from __future__ import annotations


import equinox as eqx
import jax
import jax.numpy as jnp
from jax.scipy.linalg import solve_triangular

from .._errors import RESULTS
from ..integrate import Settings, State, integrate_system, mechanism_system, start_run, tangent_system
from ..model.mechanism import Mechanism
from . import manifold

#: Largest entry of a tangent at the end of a renormalisation step before the step counts as
#: overflowed (a growth of ``e^575``: within a factor ``1e58`` of the largest float64): the step
#: is retried shorter; at :data:`SHORTEST` it is the status ``tangent_overflow``.
OVERFLOW = 1e250

#: The default bound on the spread of one renormalisation step's log growths is
#: :math:`\ln(\text{GROWTH\_ACCURACY}/\text{rtol})` (:func:`default_max_growth`): a direction
#: :math:`e^{G}` times smaller than the largest is held to rtol :math:`e^{G}` of itself, 1 %.
GROWTH_ACCURACY = 0.01


def default_max_growth(rtol):
    r"""The default ``max_growth``, :math:`\ln(0.01/\mathrm{rtol})` [-] (:data:`GROWTH_ACCURACY`):
    9.2 at rtol 1e-6, 13.8 at 1e-8 (module docstring; measured: docs/theory/chaos.md)."""
    return jnp.log(GROWTH_ACCURACY / rtol)


#: The shortest renormalisation step, as a fraction of the interval: a step this short is
#: accepted whatever its growth.
SHORTEST = 1e-6

#: The status of a run whose tangents overflowed (``LyapunovResult.status``).
_OVERFLOWED = int(RESULTS.tangent_overflow._value)


#: What an old spelling of the chaos-only ``STATUS`` warns (its codes 0/1/2 are now RESULTS codes).
STATUS_DEPRECATED = ("{} is deprecated: LyapunovResult.status now holds a jaxclear.RESULTS code (the run's own code "
                     "for a failed run, RESULTS.tangent_overflow for an overflow), whose message is jaxclear.STATUS; "
                     "it will be removed in the next release")


def __getattr__(name: str):
    """``STATUS`` (the old chaos-only codes), deprecated: :data:`jaxclear.STATUS`."""
    if name == "STATUS":
        import warnings

        from .._errors import STATUS as RUN_STATUS

        warnings.warn(STATUS_DEPRECATED.format(f"{__name__}.STATUS"), DeprecationWarning, stacklevel=2)
        return RUN_STATUS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
        status: a :class:`~jaxclear.RESULTS` code (:data:`jaxclear.STATUS` its message): 0 ok,
            the run's own code where the run failed, ``tangent_overflow`` where the tangents
            overflowed within the shortest renormalisation step; the exponents are then the
            running estimate up to the last good interval (NaN if none).
        run_status: the run's :class:`~jaxclear.RESULTS` code (0 where only the tangents
            overflowed).
        t_end: the time the run reached [s].
        ts: (T,) output times [s] (``samples`` per interval) and
        packed: (T, N) the packed states at them (the trajectory; empty with ``keep=False``).
        renormalisations: (W,) QR renormalisations in every interval (at least 1; more where the
            tangents' log growths spread by more than ``max_growth`` within an interval).
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
    renormalisations: jax.Array
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
             samples: int, count: int, scale, max_growth=None, keep: bool = True) -> LyapunovResult:
    """The Lyapunov exponents of ``mech`` (see the module docstring): the run starts at
    ``s.t_start`` (assembled, or from ``y0``), runs ``transient`` [s] without tangents, then
    ``windows`` intervals of ``interval`` [s] with ``count`` tangents, ``samples`` output samples
    per interval; the first ``discard`` intervals do not count; ``scale`` [s] is the metric's time
    scale. ``keep``: return the trajectory's samples."""
    begin = start_run(mech, s, y0)
    dtype = begin.packed.dtype
    size = begin.packed.shape[0]
    n = mech.n_coordinates
    ok0 = (begin.valid == RESULTS.successful) & begin.assembled
    t0 = jnp.asarray(s.t_start, dtype)
    interval = jnp.asarray(interval, dtype)
    t_a = t0 + jnp.where(ok0, jnp.asarray(transient, dtype), 0.0)

    # the transient, without tangents
    pre = integrate_system(mechanism_system(mech, s), s, t0, t_a, t_a[None], begin.packed)
    y = pre.samples[-1]
    code = jnp.where(ok0, _run_status(pre.result, jnp.all(jnp.isfinite(y))),
                     jnp.asarray(jnp.where(begin.valid == RESULTS.successful, RESULTS.assembly_failed._value,
                                           begin.valid._value), jnp.int32))
    w = manifold.weights(mech, scale).astype(dtype)
    basis = manifold.tangent_basis(mech, t_a, y[:n], y[n:2 * n], w, count)  # (2n, count), weighted
    tangents = jnp.zeros((count, size), dtype).at[:, :2 * n].set((basis / w[:, None]).T)

    # the tangents' absolute tolerance grows with them (TangentSystem.weigh_error)
    reference = manifold.tangent_reference(w)
    system = tangent_system(mech, s, size=size, count=count, span=interval, reference=reference)
    fractions = jnp.arange(1, samples + 1, dtype=dtype) / samples
    bound = jnp.asarray(default_max_growth(s.rtol) if max_growth is None else max_growth, dtype)
    shortest = SHORTEST * interval

    def renormalise(tb, y1, s1):
        """QR of the projected, weighted tangents; the live memory's tangents by R^-1."""
        proj = manifold.projector(mech, tb, y1[:n], y1[n:2 * n], w)
        q, r = jnp.linalg.qr(proj @ (w[:, None] * s1[:, :2 * n].T))
        diag = jnp.abs(jnp.diagonal(r))
        ok = jnp.all(jnp.isfinite(s1)) & (jnp.max(jnp.abs(s1)) < OVERFLOW) & jnp.all(diag > 0)
        safe_r = jnp.where(ok, r, jnp.eye(count, dtype=dtype))
        live = manifold.live_memory(mech, s.baumgarte, tb, y1)
        memory = solve_triangular(safe_r.T, s1[:, 2 * n:], lower=True) * live
        logs = jnp.log(jnp.where(ok, diag, 1.0))
        return jnp.concatenate([(q / w[:, None]).T, memory], axis=1), logs, ok

    def step(c, ts, tb):
        """One renormalisation step of the window ending at ``tb``: integrate ``[t, t + h]``,
        renormalise, accept when the log growths spread no more than ``bound``."""
        t, y, tangents, h, logs, buf, steps, code, overflow, taken = c
        t1 = jnp.minimum(t + h, tb)
        run = integrate_system(system, s, t, t1, jnp.clip(ts, t, t1), jnp.concatenate([y, tangents.reshape(-1)]))
        end = run.samples[-1]
        y1, s1 = end[:size], end[size:].reshape(count, size)
        finite_state = jnp.all(jnp.isfinite(y1))
        renormed, lg, ok = renormalise(t1, y1, s1)
        growth = jnp.maximum(jnp.max(lg), 0.0) - jnp.minimum(jnp.min(lg), 0.0)
        last = (t1 - t) <= shortest * (1 + 1e-9)
        # tangents beyond OVERFLOW, or non-finite ones (they stop the solve like a non-finite
        # state, and the samples past the stop are inf): retried shorter; at the shortest step an
        # overflow with a finite state is tangent_overflow, a non-finite state a failed run
        raw = _run_status(run.result, finite_state)
        retry = ~ok & ((raw == 0) | (raw == RESULTS.nonfinite_state._value)) & ~last
        new_code = jnp.where(retry | (finite_state & ~ok), 0, raw)
        good = (new_code == 0) & ok & ((growth <= bound) | last)
        overflow = (new_code == 0) & ~ok & last
        # the next step: the growth is about proportional to the step's length
        length = t1 - t
        target = 0.9 * bound * length / jnp.maximum(growth, 1e-30 * bound)
        upper = jnp.where(good, 2.0 * jnp.maximum(h, length), 0.9 * length)
        h_next = jnp.clip(jnp.where(ok, jnp.clip(target, 0.1 * length, upper), 0.1 * length), shortest, interval)
        inside = (ts > t) & (ts <= t1) & good
        samples_ = run.samples[:, :size] if keep else buf
        return (jnp.where(good, t1, t), jnp.where(good, y1, y), jnp.where(good, renormed, tangents), h_next,
                logs + jnp.where(good, lg, 0.0), jnp.where(inside[:, None], samples_, buf) if keep else buf,
                steps + run.num_accepted_steps + run.num_rejected_steps, jnp.where(new_code != 0, new_code, code),
                overflow, taken + good.astype(jnp.int32))

    def window(carry, k):
        y, tangents, h, code, status = carry
        go = (code == 0) & (status == 0)
        ta = t_a + k * interval
        tb = jnp.where(go, ta + interval, ta)
        ts = ta + (tb - ta) * fractions
        buf = jnp.zeros((samples if keep else 0, size), dtype)
        zero = jnp.zeros((), jnp.int32)
        c0 = (ta, y, tangents, h, jnp.zeros((count,), dtype), buf, zero, zero, jnp.asarray(False), zero)

        def more(c):
            t, code_, overflow = c[0], c[7], c[8]
            return (t < tb) & (code_ == 0) & ~overflow

        t, y1, renormed, h, lg, buf, steps, new_code, overflow, steps_taken = jax.lax.while_loop(
            more, lambda c: step(c, ts, tb), c0)
        new_code = jnp.where(go, new_code, code)
        new_status = jnp.where(go & overflow, _OVERFLOWED, jnp.where(go & (new_code != 0), new_code, status))
        good = go & (new_status == 0)
        logs = jnp.where(good, lg, jnp.nan)
        carry = (jnp.where(good, y1, y), jnp.where(good, renormed, tangents), h, new_code, new_status)
        return carry, (logs, buf, ts, steps, jnp.where(go, steps_taken, 0))

    (y_end, _, _, code, status), (logs, packed, ts, steps, renormalisations) = jax.lax.scan(
        window, (y, tangents, interval, code, code.astype(jnp.int32)), jnp.arange(windows))
    status = jnp.where((code != 0) & (status == 0), code, status)
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
        packed=packed.reshape(-1, size), renormalisations=renormalisations,
        num_steps=jnp.sum(steps) + pre.num_accepted_steps + pre.num_rejected_steps)
