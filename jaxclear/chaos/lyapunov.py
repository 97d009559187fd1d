r"""Lyapunov exponents of a mechanism from its tangent dynamics: :func:`lyapunov` (one operating
point, its running estimate and convergence), :func:`lyapunov_map` (many operating points in one
compiled, batched program: a bifurcation map coloured by the largest exponent) and
:func:`trajectory` (the run's :class:`~jaxclear.Solution`, for any named channel).

Method: :mod:`.benettin`; the space: :mod:`.manifold`; theory: docs/theory/chaos.md.
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import params
from .._checkpoint import Work, key as work_key
from .._errors import JaxclearError, ParameterError, is_concrete
from .._results import deprecated
from ..analysis.channels import channel
from ..integrate import Settings, Solution, State, stored_solution
from ..integrate import check_settings, default_settings, jit
from ..integrate import raise_for_status as _raise_run_status
from ..model import Mechanism, crank_driver, crank_period
from ..sweep.devices import DEFAULT_RUNS_PER_DEVICE, make_mesh
from ..sweep.lanes import on_devices, over_lanes, round_chunk, run_lanes
from . import manifold
from .benettin import LyapunovResult, benettin

#: Fewest renormalisation intervals that count (after ``discard``): a running estimate and its
#: spread over the last half need at least this many.
MIN_INTERVALS = 4


class LyapunovError(JaxclearError):
    """The Lyapunov exponents could not be computed as asked: the run failed, its tangents
    overflowed, or the estimate did not converge to the requested tolerance."""


def _check_interval(interval):
    if interval is None or not is_concrete(interval):
        return
    value = float(interval)
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"interval = {value:g} s (the renormalisation interval) is outside the allowed range "
                             "(0, inf) s")


def check_count(mech: Mechanism, count, name: str = "count") -> int:
    """How many exponents: ``count`` checked against :math:`2(n - m)` (``None``: all); the error
    names the parameter as ``name`` (the command line's ``--count``)."""
    p = manifold.dimension(mech)
    if p < 1:
        raise ParameterError(f"mechanism {mech.name!r} has no free motion (2(n - m) = {p}): no Lyapunov exponent")
    if count is None:
        return p
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= p:
        raise ParameterError(f"{name} = {count!r} exponents is outside the allowed range [1, {p}] (the dimension "
                             f"2(n - m) of the phase space of {mech.name!r})")
    return int(count)


def interval_count(duration: float, interval: float) -> int:
    """The renormalisation intervals of a run: the fewest equal intervals no longer than
    ``interval`` [s] in ``duration`` [s] (at least one)."""
    return max(1, math.ceil(duration / float(interval) - 1e-9))


def check_length(windows: int, discard: int, run: str, remedy: str) -> None:
    """A :class:`~jaxclear.ParameterError` when ``windows - discard`` counted intervals are fewer
    than :data:`MIN_INTERVALS`; ``run`` says how the intervals came about and ``remedy`` what to
    raise, in the caller's names (arguments, or the command line's flags)."""
    if windows - discard < MIN_INTERVALS:
        raise ParameterError(f"the run is too short for a converged estimate: {run} leaves {windows - discard} "
                             f"counted renormalisation interval(s), outside the allowed range [{MIN_INTERVALS}, inf); "
                             f"{remedy}")


def _max_growth(value):
    """``max_growth`` checked; ``None`` (:func:`~jaxclear.chaos.benettin.default_max_growth`) stays."""
    if value is None:
        return None
    if is_concrete(value) and not (math.isfinite(float(value)) and float(value) > 0):
        raise ParameterError(f"max_growth = {float(value):g} (the log growth allowed between two renormalisations) "
                             "is outside the allowed range (0, inf)")
    return jnp.asarray(float(value) if is_concrete(value) else value)


def _default_interval(mech: Mechanism) -> float:
    found = crank_driver(mech)
    if found is None or float(found[1].speed) == 0.0:
        raise ParameterError(f"interval: mechanism {mech.name!r} has no turning crank, so there is no default "
                             "renormalisation interval (one revolution); give interval [s] > 0")
    return float(crank_period(mech))


@jit
def _compiled(mech, s, y0, transient, interval, scale, windows, discard, samples, count, max_growth, keep):
    return benettin(mech, s, y0, transient=transient, interval=interval, windows=windows, discard=discard,
                    samples=samples, count=count, scale=scale, max_growth=max_growth, keep=keep)


#: :class:`LyapunovResult`'s pytree structure (every field an array), which the store of traced
#: programs needs without tracing.
_RESULT = jax.tree_util.tree_structure(LyapunovResult(**{f.name: 0 for f in dataclasses.fields(LyapunovResult)}))


def lyapunov(mech: Mechanism, settings: Settings | None = None, interval: float | None = None, *,
             transient: float = 0.0, discard: int = 0, count: int | None = None, samples: int = 8,
             time_scale: float | None = None, y0: State | None = None, tol: float | None = None,
             max_growth: float | None = None, keep: bool = True, s: Settings | None = None) -> LyapunovResult:
    r"""The Lyapunov spectrum of ``mech`` over the run of ``settings`` (Benettin's method on the
    tangent dynamics, :mod:`.benettin`), over the tangent space of the constraint manifold
    (:mod:`.manifold`).

    Args:
        mech: the mechanism.
        settings: the settings, whole (required: they hold the run's span): the run is
            ``[t_start, t_end]``; ``rtol``, ``atol``, ``solver``, ``max_steps`` (per interval)
            and the rest apply to the state and its tangents; nothing is replaced but ``throw``
            (the runs report their status; ``settings.throw`` says whether it raises).
        s: the old name of ``settings`` (deprecated: a ``DeprecationWarning``, one release).
        interval: the reporting interval [s] > 0 (default one crank revolution): the time after
            the transient is cut into the fewest equal intervals no longer than this; the running
            estimate, the batch means and the samples are per interval. The tangents are
            renormalised at the end of each and, within it, as often as ``max_growth`` asks.
        transient: time [s] integrated without tangents first (to reach the attractor).
        discard: intervals at the start that do not count (the basis aligns with the most
            expanding directions).
        count: how many exponents (the largest ``count``; default all :math:`2(n - m)`).
        samples: output samples per interval (the trajectory, :func:`trajectory`).
        time_scale: the metric's weight on the velocities [s] (default :math:`1/|\omega|` of
            the crank, else 1 s); the exponents do not depend on it.
        y0: start state (default: assembled at ``s.t_start``).
        tol: the convergence asked for [1/s]: the running estimate's spread over the last half
            of the counted intervals must not exceed it (else :class:`LyapunovError`).
        max_growth: the largest spread of the log growths :math:`\ln|R_{ii}|` (and 0) between
            two renormalisations [-] (default :math:`\ln(0.01/\mathrm{rtol})`, 9.2 at the
            default rtol; :mod:`.benettin`): a renormalisation step that spread them more is
            retried shorter. With all exponents (``count`` = :math:`2(n - m)`) a larger bound
            loses the smallest ones (a fixed interval of one revolution gave an undamped Hertz
            contact a spectrum summing to +899 1/s instead of 0); the largest exponent does not
            depend on it.
        keep: keep the trajectory's samples in the result.

    Returns:
        :class:`~jaxclear.chaos.LyapunovResult`. With ``s.throw`` (default) and concrete
        inputs, a failed run, an overflow (status ``tangent_overflow``) or a missed ``tol`` raise
        :class:`LyapunovError` (a parameter outside its range :class:`~jaxclear.ParameterError`);
        with ``s.throw=False`` the first two are the result's ``status``, a
        :class:`~jaxclear.RESULTS` code.
    """
    s = _renamed("lyapunov", settings, s, required=True)
    _check_interval(interval)
    count = check_count(mech, count)
    interval = _default_interval(mech) if interval is None else interval
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ParameterError(f"samples = {samples!r} per interval is outside the allowed range [1, inf)")
    if isinstance(discard, bool) or not isinstance(discard, (int, np.integer)) or discard < 0:
        raise ParameterError(f"discard = {discard!r} intervals is outside the allowed range [0, inf)")
    if tol is not None and not (math.isfinite(tol) and tol > 0):
        raise ParameterError(f"tol = {tol!r} 1/s (the requested convergence) is outside the allowed range (0, inf)")
    duration = float(s.t_end) - s.t_start - float(transient)
    if not float(transient) >= 0 or duration <= 0:
        raise ParameterError(f"transient = {float(transient):g} s is outside the allowed range [0, t_end - t_start = "
                             f"{float(s.t_end) - s.t_start:g} s)")
    windows = interval_count(duration, interval)
    check_length(windows, discard, f"{windows} renormalisation interval(s) of {duration / windows:g} s after the "
                 f"transient, {discard} discarded,", f"raise t_end (now {float(s.t_end):g} s), or shorten interval "
                 f"(now {float(interval):g} s) or transient")
    scale = manifold.time_scale(mech) if time_scale is None else jnp.asarray(float(time_scale))
    s_run = dataclasses.replace(s, throw=False)
    # through the store of traced programs: a new process neither traces nor (with JAX's cache)
    # compiles the run again
    result = _compiled.stored("lyapunov", lambda: _RESULT, mech, s_run, y0, jnp.asarray(float(transient)),
                              jnp.asarray(duration / windows), scale, int(windows), int(discard), int(samples), count,
                              _max_growth(max_growth), bool(keep))
    if s.throw:
        _raise_for_status(result, s, tol, mech)
    return result


def _renamed(driver: str, settings: Settings | None, s: Settings | None, required: bool) -> Settings:
    """The settings given as ``settings`` or by their old name ``s`` (a ``DeprecationWarning``;
    both: a :class:`~jaxclear.ParameterError`); None: ``Settings``' defaults where they are not
    ``required`` (a run's span)."""
    if s is not None:
        if settings is not None:
            raise ParameterError(f"{driver}: both settings= and s= (its old name) given; give settings= only")
        deprecated(f"{driver}(s=...)", "settings=...", stacklevel=3)
        settings = s
    return check_settings(driver, settings, required) or default_settings()


def check_convergence(result: LyapunovResult, tol: float | None) -> None:
    """:class:`LyapunovError` for a concrete result whose spread exceeds ``tol`` (its status is
    checked first by :func:`~jaxclear.integrate.raise_for_status`)."""
    if tol is not None:
        spread = float(jnp.max(result.spread))
        if not spread <= tol:
            raise LyapunovError(
                f"jaxclear: lyapunov: the estimate did not converge to tol = {tol:g} 1/s: its running estimate still "
                f"moves by {spread:.3g} 1/s over the last half of {result.running.shape[0]} intervals "
                f"(exponents {np.array2string(np.asarray(result.exponents), precision=4)}); run longer (t_end)")


def _raise_for_status(result: LyapunovResult, s: Settings, tol: float | None = None,
                      mech: Mechanism | None = None) -> None:
    """The one :func:`~jaxclear.integrate.raise_for_status` (the status, a
    :class:`~jaxclear.RESULTS` code; :class:`LyapunovError` for a failed run or an overflow),
    then :func:`check_convergence`."""
    _raise_run_status(result, s, f" (lyapunov, renormalisation interval {float(result.interval):g} s)", mech=mech,
                     error=LyapunovError)
    check_convergence(result, tol)


def __getattr__(name: str):
    """``raise_for_status`` of this module, deprecated: :func:`jaxclear.integrate.raise_for_status`
    (any result with a ``status``) and :func:`check_convergence`."""
    if name == "raise_for_status":
        import warnings

        warnings.warn("jaxclear.chaos.lyapunov.raise_for_status is deprecated: use "
                      "jaxclear.integrate.raise_for_status(result, s, error=LyapunovError) and "
                      "check_convergence(result, tol); it will be removed in the next release",
                      DeprecationWarning, stacklevel=2)
        return _raise_for_status
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def trajectory(mech: Mechanism, s: Settings, result: LyapunovResult) -> Solution:
    """The run of a :func:`lyapunov` result (``keep=True``) as a :class:`~jaxclear.Solution` on
    its output grid (``samples`` per interval after the transient): accelerations, reactions and
    contact outputs recomputed from the stored states, so that any named channel
    (:func:`jaxclear.channel`) applies. Traceable."""
    sol = stored_solution(mech, s, result.ts, result.packed, result.num_steps)
    return eqx.tree_at(lambda x: x.status, sol, jnp.asarray(result.run_status, jnp.int32))


# ---- many operating points --------------------------------------------------------------


class LyapunovMap(eqx.Module):
    """:func:`lyapunov_map`'s result, one row per operating point.

    Attributes:
        values: (B, P) the parameters' values (``names`` order).
        exponents: (B, count) [1/s]; spread, stderr: (B, count) [1/s] (see
            :class:`~jaxclear.chaos.LyapunovResult`).
        status, run_status: (B,) :class:`~jaxclear.RESULTS` codes (see
            :class:`~jaxclear.chaos.LyapunovResult`).
        sections: (B, K, C) the channels at every whole revolution after the transient (a
            Poincare section per channel; ``K`` = revolutions).
        running: (B, R, count) running estimates after each counted interval.
    """

    values: jax.Array
    exponents: jax.Array
    spread: jax.Array
    stderr: jax.Array
    status: jax.Array
    run_status: jax.Array
    sections: jax.Array
    running: jax.Array


def _member(mech, s, names, row, revolutions, transient_revolutions, per_revolution, samples, count, channels,
            discard):
    m = params.replace_many(mech, {n: row[i] for i, n in enumerate(names)})
    period = crank_period(m)
    r = benettin(m, s, None, transient=transient_revolutions * period, interval=period / per_revolution,
                 windows=revolutions * per_revolution, discard=discard, samples=samples, count=count,
                 scale=manifold.time_scale(m), keep=bool(channels))
    # one NaN column without channels (sliced off outside): lax.map's batching cannot reshape an empty output
    sections = jnp.full((revolutions, 1), jnp.nan, r.running.dtype)
    if channels:
        # one sample per revolution: the last sample of every per_revolution-th interval
        every = per_revolution * samples
        sub = eqx.tree_at(lambda x: (x.ts, x.packed), r, (r.ts[every - 1::every], r.packed[every - 1::every]))
        sol = trajectory(m, s, sub)
        sections = jnp.stack([channel(m, sol, c) for c in channels], axis=-1)
    return (r.exponents, r.spread, r.stderr, r.status, r.run_status, sections, r.running)


#: The outputs of a member, in :class:`LyapunovMap`'s order after ``values``.
MAP_KEYS = ("exponents", "spread", "stderr", "status", "run_status", "sections", "running")
#: The state files of :func:`lyapunov_map` in its output folder: the finished map.
MAP_FILE = "lyapunov_map.npz"
MAP_FORMAT = 1
MAP_RESTART = "restart=True"


def _lanes(rows, mech, s, names, revolutions, transient_revolutions, per_revolution, samples, count, channels, discard,
           batch_size):
    """The members of ``rows`` (B, P), by the lane runner's rule (:func:`~jaxclear.sweep.lanes.over_lanes`;
    ``batch_size``: side by side in batches of that many)."""
    f = lambda row: _member(mech, s, names, row, revolutions, transient_revolutions, per_revolution,  # noqa: E731
                            samples, count, channels, discard)
    return dict(zip(MAP_KEYS, over_lanes(f, rows, batch_size=batch_size)))


@eqx.filter_jit
def _compiled_map(rows, mech, s, mesh, *statics):
    """The members of a chunk ``rows`` split over ``mesh``'s devices (:func:`~jaxclear.sweep.lanes.on_devices`)."""
    return on_devices(lambda r, m, ss: _lanes(r, m, ss, *statics), mesh, rows, mech, s)


def lyapunov_map(mech: Mechanism, settings: Settings | None, names: Sequence[str], values, *, revolutions: int,
                 transient_revolutions: float = 0.0, per_revolution: int = 1, samples: int = 8, count: int = 1,
                 channels: Sequence[str] = (), discard: int = 0, batch_size: int | None = None,
                 chunk: int | None = None, out=None, restart: bool = False, devices: int | None = None,
                 progress: bool = False, s: Settings | None = None) -> LyapunovMap:
    """The Lyapunov exponents of many operating points: ``mech`` with the parameters ``names``
    (:mod:`jaxclear.params`) set to each row of ``values`` (B, P), by the lane runner of the sweeps
    (:mod:`jaxclear.sweep.lanes`): one compiled program per chunk shape, its rows split over the
    devices, chunk after chunk, resumable.

    Every run: ``transient_revolutions`` crank revolutions without tangents, then
    ``revolutions`` revolutions with ``count`` tangents in ``per_revolution`` reporting intervals
    a revolution (each renormalised at its end and, within it, as often as the default
    ``max_growth`` of :func:`lyapunov` asks), ``samples`` output samples per interval; ``channels`` (named channels,
    :func:`jaxclear.channel`) are sampled once per revolution (a Poincare section each, for a
    bifurcation diagram). ``settings`` (:class:`~jaxclear.Settings`, whole; None: its defaults)
    give the solver, tolerances, step limit and the rest; the map owns the span (its ``t_end``
    is not used: each row runs its revolutions of its own crank speed from ``t_start``) and
    ``throw`` (False).
    ``s``: the old name of ``settings`` (deprecated: a ``DeprecationWarning``, one release).
    Nothing raises for a failed member: its ``status`` says what happened.

    How the rows run (the lane runner's, as a sweep's):

    * ``batch_size``: None (default), the lane runner's rule: one row after another on a CPU
      with single-kernel loops (each takes its own steps), side by side (``jax.vmap``) on an
      accelerator; an integer, side by side in batches of that many rows, one batch after
      another.
    * ``chunk``: rows per compiled call (rounded up to a multiple of the devices; the last chunk
      padded by repeating its last row, so every chunk is one compilation); None: all rows at
      once, or, with ``out``, :data:`~jaxclear.sweep.devices.DEFAULT_RUNS_PER_DEVICE` per device.
      The rows' results do not depend on it where the rows run one after another.
    * ``devices``: the first ``devices`` of ``jax.devices()`` (default all), each chunk's rows
      split over them (``jax.shard_map``, as a sweep's; a CPU host has one per core after
      :func:`jaxclear.request_host_devices`).
    * ``out``: an output folder, locked while the map runs (a second process is refused with
      :class:`~jaxclear.OutputLockedError`), written as it goes through the one checkpoint
      protocol: every finished chunk ``OUT/chunks/chunk_NNNNNN.npz`` (its header the map's key:
      the mechanism, settings, names, values and the arguments above but ``progress``), the whole
      map ``OUT/lyapunov_map.npz`` at the end. The same call after a kill computes only the
      chunks not on disk and returns the map an uninterrupted call returns; a folder holding
      another map is refused (a :class:`~jaxclear.ParameterError` naming what changed) unless
      ``restart=True``, which discards it.
    * ``progress``: a tqdm bar over the chunks.
    """
    s = _renamed("lyapunov_map", settings, s, required=False)
    names = tuple(str(n) for n in names)
    values = jnp.atleast_2d(jnp.asarray(values, float))
    if values.shape[1] != len(names):
        raise ParameterError(f"values has {values.shape[1]} columns for {len(names)} names {list(names)}")
    for n in names:
        params.get(mech, n)  # a named ParameterError for an unknown name
    if crank_driver(mech) is None:
        raise ParameterError(f"lyapunov_map runs whole crank revolutions: mechanism {mech.name!r} has no AngleDriver")
    for key, v, low in (("revolutions", revolutions, 1), ("per_revolution", per_revolution, 1),
                        ("samples", samples, 1), ("discard", discard, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
            raise ParameterError(f"{key} = {v!r} is outside the allowed range [{low}, inf)")
    check_length(revolutions * per_revolution, discard, f"revolutions x per_revolution = {revolutions} x "
                 f"{per_revolution} intervals, {discard} discarded,", "raise revolutions or per_revolution")
    if not transient_revolutions >= 0:
        raise ParameterError(f"transient_revolutions = {transient_revolutions!r} is outside the allowed range [0, inf)")
    for key, v in (("batch_size", batch_size), ("chunk", chunk), ("devices", devices)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1):
            raise ParameterError(f"{key} = {v!r} is outside the allowed range [1, inf) (or None: all rows at once)")
    count = check_count(mech, count)
    channels = tuple(str(c) for c in channels)
    for c in channels:
        from ..analysis.channels import unit
        unit(mech, c)  # a named ParameterError for a channel that does not exist
    s = dataclasses.replace(s, throw=False)
    statics = (names, int(revolutions), float(transient_revolutions), int(per_revolution), int(samples), count,
               channels, int(discard), None if batch_size is None else int(batch_size))
    if not is_concrete(values):  # inside a traced program: one batch, no chunks, devices or files
        res = _lanes(values, mech, s, *statics)
    else:
        res = _run_map(mech, s, np.asarray(values), statics, chunk, out, restart, devices, progress)
    res = {k: jnp.asarray(v) for k, v in res.items()}
    return LyapunovMap(values, *(res[k] for k in MAP_KEYS[:-2]), res["sections"][..., :len(channels)], res["running"])


def _run_map(mech, s, values: np.ndarray, statics: tuple, chunk, out, restart: bool, devices, progress: bool) -> dict:
    """The map's rows through the lane runner (:func:`~jaxclear.sweep.lanes.run_lanes`), in the
    locked folder ``out`` written as it goes (None: nothing written)."""
    mesh = make_mesh(devices)
    if chunk is None and out is not None:
        chunk = DEFAULT_RUNS_PER_DEVICE * mesh.devices.size
    chunk = round_chunk(len(values) if chunk is None else chunk, mesh.devices.size)
    compiled = lambda rows, m, ss: _compiled_map(rows, m, ss, mesh, *statics)  # noqa: E731
    if out is None:
        return run_lanes(compiled, values, mech, s, chunk=chunk, mesh=mesh, progress=progress, desc="lyapunov_map")
    names, revolutions, transient, per_revolution, samples, count, channels, discard, batch_size = statics
    config = {"mechanism": mech.name, "names": list(names), "rows": len(values), "revolutions": revolutions,
              "transient_revolutions": transient, "per_revolution": per_revolution, "samples": samples,
              "count": count, "channels": list(channels), "discard": discard, "batch_size": batch_size,
              "chunk": chunk, "devices": int(mesh.devices.size)}
    work = Work(out, "lyapunov_map", work_key(mech, s, values, config), config, version=MAP_FORMAT,
                restart=MAP_RESTART)
    with work.lock():
        if restart and os.path.exists(work.path(MAP_FILE)):
            os.remove(work.path(MAP_FILE))  # the map of before, discarded (its chunks with it, run_lanes)
        finished = work.read_npz(MAP_FILE, restart=restart)
        if finished is not None:
            return {k: finished[k] for k in MAP_KEYS}
        res = run_lanes(compiled, values, mech, s, chunk=chunk, mesh=mesh, work=work, restart=restart,
                        progress=progress, desc="lyapunov_map")
        work.write_npz(MAP_FILE, {"values": values, **res}, finished=True)
    return res
