r"""Contact parameters from the statistics of an acceleration record:
``jaxclear.fit_statistics(data, mech, ...)`` (:func:`fit_statistics`; theory:
docs/theory/statistics_fit.md).

When the trajectory cannot be followed
--------------------------------------
A record longer than the motion's predictability (the Flores benchmark at 5000 rpm: largest
Lyapunov exponent 444 1/s, :math:`1/\lambda_1 = 2.25` ms, a revolution 12 ms) that
begins mid-run has no trajectory a fit can follow: :func:`jaxclear.fit` with
``start_state="free"`` fits windows of about 3 ms (1.3 e-folding times) whose start states are
unknowns too, and on such records its estimates were not reliable (``benchmarks/README.md``).
What the parameters do fix is the *distribution* of the motion: how hard the impacts are, how
the journal rings in the bearing, how the power spreads over frequency. So this fit compares
statistics per crank revolution (:mod:`.statistics`: quantiles of the absolute acceleration,
log band powers of its spectrum) of the record with those of the model, by Wood's synthetic
likelihood, on a grid of parameter values, with no derivative of the chaotic runs.

The hand-over: the trajectory fit needs a record whose start state is known (start-up) or can be
found, and windows no longer than a few :math:`1/\lambda_1`; the statistics fit needs at least
:data:`MIN_RECORD_REVOLUTIONS` whole revolutions of a motion that has forgotten its start (the
record may begin anywhere after the start-up), and its precision grows as
:math:`\sqrt{n_r}` with the record's revolutions :math:`n_r`.

The model at a grid point
-------------------------
:mod:`.statistics_model`: ``replicates`` runs from start-up (offsets a few tens of nanometres
apart), each ``transient_revolutions`` left out and then ``blocks`` revolutions kept, so
:math:`n_m` = ``revolutions`` (rounded up to whole runs) revolutions per grid point, through the
accelerometer's low-pass (``sensor``: cut-off and order; its bias drops out with each
revolution's mean, its delay does not matter); then, in NumPy, white Gaussian noise of standard
deviation :math:`s` on the sensor's input scale and the gain :math:`g`. The noise draws are the
same at every grid point (common random numbers, so that the likelihood surface is not rough
from the noise). The gain shifts every statistic by :math:`w\log g` (:mod:`.statistics`), so a
free ``sensor_gain`` costs no simulation; the noise level is summed out over its own grid
(``noise_std=None``) or fixed.

The posterior
-------------
:math:`p(\theta, g, s \mid \text{record}) \propto L(\theta, g, s)\,\pi(\theta)\,\pi(g)\,\pi(s)` on
the grid, :math:`L` the synthetic likelihood. Priors: flat in the grid coordinate (log stiffness,
restitution, log gain, log noise), or ``priors`` (:mod:`.priors`: densities of the values,
``{"stiffness": "lognormal:6.6e10:3"}``) for the free parameters. Marginals, estimates (the
posterior mean), standard deviations and equal-tailed 90 % intervals are computed from the grid
with each node's cell (:mod:`.statistics_result`), which also says whether they are a result.
"""

from __future__ import annotations

import math
import time

import numpy as np
from tqdm.auto import tqdm

from .. import params
from .._errors import ParameterError
from ..analysis.sensor import Accelerometer, uniform_spacing
from ..integrate import Settings, default_settings, option_values
from ..model import Mechanism, crank_driver, crank_period
from .parameters import DEFAULT_FREE, SENSOR_PARAMETERS, check_name, current_value
from .priors import parse_prior
from .records import read_record, slider_role
from .statistics import (STATISTICS, block_statistics, check_kinds, precision_factor, revolution_blocks,
                         statistic_names, statistic_weights, whole_revolutions)
from .statistics_model import default_chunk, given_settings, make_plan, replicate_offsets, run_rows
from .statistics_result import (StatisticsFitResult, cell_edges, from_coordinate, log_jacobian, marginal_summary,
                                to_coordinate, verdict)
from .statistics_surrogate import NOISE_NODES, NOISE_RANGE, Surrogate, evaluate, node_moments

#: Fewest whole revolutions a record must hold.
MIN_RECORD_REVOLUTIONS = 2
#: Model revolutions per grid point by default (after the transient).
DEFAULT_REVOLUTIONS = 200
#: Start-up revolutions of every model run left out by default.
DEFAULT_TRANSIENT = 3
#: Most revolutions kept from one run (longer is split into replicates).
MAX_BLOCKS_PER_RUN = 20
#: Default grids (nodes, geometric for a log coordinate, even in logit for restitution):
#: stiffness a factor 4 either side of the mechanism's, 9 nodes; restitution 0.3 to 0.98, 10
#: nodes; sensor_gain a factor 1.3 either side of the sensor's, 241 points (a gain costs no
#: simulation); another positive parameter a factor 3 either side, 9 nodes.
DEFAULT_GRIDS = {"stiffness": (4.0, 9), "restitution": ((0.3, 0.98), 10), "sensor_gain": (1.3, 241)}
#: Refinement of the mechanism parameters' grids by default (points per node spacing).
DEFAULT_REFINE = 4
#: Grid points evaluated together (bounds the memory of the interpolated covariances).
EVAL_CHUNK = 2048
#: Largest relative difference between the record's crank speed (its crank_angle_rad column)
#: and the mechanism's.
SPEED_TOLERANCE = 1e-3
#: Largest departure of a sample spacing from the median spacing, relative.
SPACING_TOLERANCE = 1e-6


def coordinate(name: str, mech: Mechanism | None = None) -> str:
    """``name``'s grid coordinate: ``"log"``, ``"logit"`` or ``"none"`` (the value), the transform
    of :mod:`jaxclear.params` (``sensor_gain``: log); with ``mech``, also of the names its own
    classes declare."""
    if name in SENSOR_PARAMETERS:
        return "log" if SENSOR_PARAMETERS[name][3] == "log" else "none"
    t = params.info(name.split("@")[0], mech).transform
    return t if t in ("log", "logit") else "none"


def grid_values(mech: Mechanism, sensor: Accelerometer, name: str, spec=None) -> np.ndarray:
    """The grid of ``name``: ``spec`` a sequence of values (strictly increasing, in the
    parameter's range), a string ``"LOW:HIGH:N"`` (``N`` nodes, geometric for a log coordinate,
    else even), or ``None`` for the default (:data:`DEFAULT_GRIDS`)."""
    kind = coordinate(name, mech)
    log = kind == "log"
    if spec is None:
        v = current_value(mech, sensor, name)
        if name == "restitution":
            (lo, hi), n = DEFAULT_GRIDS[name]
        elif log:
            f, n = DEFAULT_GRIDS.get(name, (3.0, 9))
            lo, hi = v / f, v * f
        else:
            raise ParameterError(f"grid[{name!r}]: no default grid for a parameter of any sign: give its values "
                                 f"or 'LOW:HIGH:N'")
        spec = f"{lo!r}:{hi!r}:{n}"
    if isinstance(spec, str):
        parts = spec.split(":")
        try:
            lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
            if len(parts) != 3:
                raise ValueError
        except (ValueError, IndexError):
            raise ParameterError(f"grid[{name!r}] = {spec!r}: write LOW:HIGH:N (N nodes)") from None
        if n < 2 or not lo < hi or (log and lo <= 0):
            raise ParameterError(f"grid[{name!r}] = {spec!r}: needs N >= 2 and LOW < HIGH"
                                 f"{' and LOW > 0 (a log-spaced grid)' if log else ''}")
        if kind == "logit" and not 0 < lo < hi < 1:
            raise ParameterError(f"grid[{name!r}] = {spec!r}: needs 0 < LOW < HIGH < 1 (a logit-spaced grid)")
        spec = from_coordinate(np.linspace(*to_coordinate([lo, hi], kind), n), kind)
    v = np.atleast_1d(np.asarray(spec, dtype=float))
    if v.ndim != 1 or v.size < 2 or not np.all(np.isfinite(v)) or np.any(np.diff(v) <= 0):
        raise ParameterError(f"grid[{name!r}]: expected at least 2 finite, strictly increasing values, got {spec!r}")
    if name == "sensor_gain":
        if v[0] <= 0:
            raise ParameterError(f"grid['sensor_gain']: {v[0]:g} outside the allowed range (0, inf)")
    else:
        params.validate(mech, name, v)
    return v


def _check_free(mech: Mechanism, free) -> tuple[tuple, bool]:
    """``(mechanism names, gain free)``; a ParameterError for a name that is not a parameter or
    that the statistics cannot see."""
    free = (free,) if isinstance(free, str) else tuple(free)
    if not free or len(set(free)) != len(free):
        raise ParameterError(f"free = {list(free)!r}: give at least one name, none twice")
    for name in free:
        check_name(mech, name)
        if name in SENSOR_PARAMETERS and name != "sensor_gain":
            raise ParameterError(f"free parameter {name!r} cannot be fitted from per-revolution statistics (each "
                                 "revolution's mean is removed, and a delay moves no statistic): allowed are the "
                                 "mechanism's parameters and sensor_gain")
    mech_names = tuple(n for n in free if n != "sensor_gain")
    if not mech_names:
        raise ParameterError("free = ['sensor_gain'] alone: a statistics fit needs a mechanism parameter too")
    return mech_names, "sensor_gain" in free


def _record(data, mech: Mechanism, column: str):
    """``(samples (N,), dt [s], phase [rad], path)`` of the record; the crank column, where there
    is one, gives the phase and is checked against the mechanism's speed."""
    rec = read_record(data, (column,))
    t, y = rec.time_s, rec.columns[column]
    dt = uniform_spacing(t)
    dev = np.max(np.abs(np.diff(t) - dt)) / dt if t.size > 1 else 0.0
    if dev > SPACING_TOLERANCE:
        raise ParameterError(f"{rec.path or 'the record'}: sample spacing varies by {dev:.2g} of its median "
                             f"{dt:.6g} s, outside the allowed range [0, {SPACING_TOLERANCE:g}]: per-revolution "
                             "statistics need a uniformly sampled record (resample it)")
    speed, angle0 = float(params.get(mech, "speed")), float(params.get(mech, "angle0"))
    phase = 0.0
    if rec.crank_angle_rad is not None:
        slope = np.polyfit(t - t[0], rec.crank_angle_rad, 1)[0]
        if abs(slope / speed - 1.0) > SPEED_TOLERANCE:
            raise ParameterError(f"the record's crank turns at {slope:.6g} rad/s, the mechanism's speed is {speed:.6g} "
                                 f"rad/s: they differ by more than {SPEED_TOLERANCE:g} (set the mechanism's 'speed')")
        phase = float(rec.crank_angle_rad[0]) - angle0
    return np.asarray(y, dtype=float), dt, phase, rec.path


def _log_prior(name: str, values: np.ndarray, spec, kind: str) -> np.ndarray:
    """Log prior density in the grid coordinate at ``values``: ``log p(value) + log |d value / d u|``."""
    prior = parse_prior(spec, where=f"priors[{name!r}]")
    return np.asarray([float(prior.logpdf(v)) for v in values]) + log_jacobian(values, kind)


def _log_cells(u) -> np.ndarray:
    """Log of each grid point's cell width in its coordinate ``u`` (0 for a single point)."""
    u = np.asarray(u, dtype=float)
    return np.zeros(1) if u.size == 1 else np.log(np.diff(cell_edges(u)))


def fit_statistics(data, mech: Mechanism, free=DEFAULT_FREE, grid: dict | None = None,
                   revolutions: int = DEFAULT_REVOLUTIONS, transient_revolutions: int = DEFAULT_TRANSIENT,
                   statistics=STATISTICS, sensor: Accelerometer | None = None, noise_std: float | None = None,
                   priors: dict | None = None, refine: int = DEFAULT_REFINE, column: str = "slider_acc_m_s2",
                   rtol: float | None = None, atol: float | None = None, max_steps: int | None = None,
                   chunk: int | None = None, seed: int = 0, progress: bool = True,
                   settings: Settings | None = None) -> StatisticsFitResult:
    """Posterior of contact parameters on a grid from per-revolution statistics of an
    acceleration record, by Wood's synthetic likelihood (module docstring).

    Args:
        data: the record: a :class:`jaxclear.io.Measurements`, a DataFrame, a dict of columns or
            a CSV path, with ``time_s`` [s] (uniform) and ``column`` [m/s^2]; a ``crank_angle_rad``
            column [rad] gives the crank angle of the first sample (else the mechanism's ``angle0``).
        mech: the mechanism (one crank driver, a ``slider`` role, a clearance joint); its values
            of the parameters that are not free are taken as known.
        free: fitted names: mechanism parameters (:mod:`jaxclear.params`) and ``sensor_gain``.
        grid: name -> grid (:func:`grid_values`: values or ``"LOW:HIGH:N"``); default
            :data:`DEFAULT_GRIDS`. A mechanism parameter's grid holds the nodes that are simulated;
            ``sensor_gain``'s is where the posterior is evaluated.
        revolutions: model revolutions per grid point after the transient, ``n_m`` (more than
            the number of statistics plus 4; rounded up to whole runs of at most
            :data:`MAX_BLOCKS_PER_RUN`).
        transient_revolutions: start-up revolutions of every run left out (>= 1).
        statistics: kinds of :data:`~jaxclear.fitting.statistics.STATISTICS`.
        sensor: the accelerometer (:class:`jaxclear.Accelerometer`; its cut-off, order, gain and
            oversampling are used); default an ideal one.
        noise_std: the record's white-noise standard deviation [m/s^2], if known; ``None``
            profiles it out (:mod:`.statistics_surrogate`).
        priors: name -> prior of a free parameter (:mod:`jaxclear.fitting.priors` object or
            string); default flat in the grid coordinate.
        refine: the posterior is evaluated on a grid this many times finer than the nodes,
            the model's moments interpolated (:mod:`.statistics_surrogate`).
        column: the record's column compared with the slider's acceleration.
        rtol, atol, max_steps: deprecated (a ``DeprecationWarning``, one release):
            ``settings=jc.settings(1.0, rtol=...)``; with ``settings`` too, a
            :class:`~jaxclear.ParameterError`.
        chunk: runs per compiled call (default 4 on CPU, 32 on accelerators).
        seed: of the model's noise draws.
        progress: a tqdm bar over the runs.
        settings: how every run is integrated (:class:`jaxclear.Settings`: solver, tolerances,
            step limit, onsets...), used whole; the fit replaces only what it owns
            (:func:`~jaxclear.fitting.statistics_model.run_settings`): ``t_start`` 0 and
            ``t_end`` (start-up to the last revolution kept), ``n_out`` (``sensor.oversample``
            samples per record sample), ``throw`` False (a failed run is reported with its
            grid point) and ``progress`` False. Default None: ``Settings``' defaults (rtol
            1e-6, atol 1e-9, 400,000 steps).

    Returns:
        :class:`~jaxclear.fitting.statistics_result.StatisticsFitResult`.
    """
    wall0 = time.perf_counter()
    integration = given_settings(settings, rtol=rtol, atol=atol, max_steps=max_steps)
    mech_names, gain_free = _check_free(mech, free)
    kinds = check_kinds(statistics)
    sensor = Accelerometer() if sensor is None else sensor
    if crank_driver(mech) is None:
        raise ParameterError("fit_statistics needs a mechanism with a crank (an AngleDriver): statistics are per "
                             "crank revolution")
    slider_role(mech)
    grid = dict(grid or {})
    unknown = sorted(set(grid) - set(mech_names) - ({"sensor_gain"} if gain_free else set()))
    if unknown:
        raise ParameterError(f"grid given for {unknown}, which are not free (free: {list(free)})")
    priors = dict(priors or {})
    stray = sorted(set(priors) - set(mech_names) - ({"sensor_gain"} if gain_free else set()))
    if stray:
        raise ParameterError(f"priors given for {stray}, which are not free (free: {list(free)})")
    if int(transient_revolutions) != transient_revolutions or transient_revolutions < 1:
        raise ParameterError(f"transient_revolutions = {transient_revolutions!r} outside the allowed range [1, inf) "
                             "(an integer: the start-up revolutions of every run left out)")

    y, dt, phase, path = _record(data, mech, column)
    period = float(crank_period(mech))
    spr = period / dt
    nb = int(math.floor(spr))
    n_rec = whole_revolutions(y.size, spr)
    if n_rec < MIN_RECORD_REVOLUTIONS:
        raise ParameterError(f"the record holds {n_rec} whole crank revolution(s) ({y.size * dt:.4g} s at "
                             f"{period:.4g} s per revolution), outside the allowed range [{MIN_RECORD_REVOLUTIONS}, "
                             "inf) for per-revolution statistics: a longer record, or the trajectory fit jc.fit")
    fs = 1.0 / dt
    names = statistic_names(kinds, fs, nb)
    d = len(names)
    rec_blocks = revolution_blocks(y, spr, n_rec)
    observed_all = block_statistics(rec_blocks, fs, kinds)
    if not np.all(np.isfinite(observed_all)):
        raise ParameterError("the record has a revolution whose statistics are not finite (a constant stretch): "
                             f"{names}")
    observed = observed_all.mean(axis=0)
    rms = float(np.sqrt(np.mean((rec_blocks - rec_blocks.mean(axis=-1, keepdims=True)) ** 2)))
    weights = statistic_weights(kinds)

    if int(revolutions) != revolutions or revolutions < d + 5:
        raise ParameterError(f"revolutions = {revolutions!r} outside the allowed range [{d + 5}, inf) for {d} "
                             "statistics (the covariance of the model's statistics needs more revolutions than "
                             "statistics; its inverse is scaled by (n_m - d - 2) / (n_m - 1))")
    replicates = math.ceil(revolutions / MAX_BLOCKS_PER_RUN)
    blocks = math.ceil(revolutions / replicates)
    n_m = replicates * blocks

    values = {n: grid_values(mech, sensor, n, grid.get(n)) for n in mech_names}
    gains = (grid_values(mech, sensor, "sensor_gain", grid.get("sensor_gain")) if gain_free
             else np.array([float(sensor.gain)]))
    g_ref = float(sensor.gain)
    if noise_std is None:
        levels = np.geomspace(*NOISE_RANGE, NOISE_NODES) * rms / g_ref
    elif not (math.isfinite(noise_std) and noise_std >= 0):
        raise ParameterError(f"noise_std = {noise_std!r} m/s^2 outside the allowed range [0, inf)")
    else:
        levels = np.array([float(noise_std) / g_ref])
    if int(refine) != refine or refine < 1:
        raise ParameterError(f"refine = {refine!r} outside the allowed range [1, inf) (an integer)")

    # the model's runs: every grid node x replicates
    shape = tuple(len(values[n]) for n in mech_names)
    nodes = np.stack(np.meshgrid(*[values[n] for n in mech_names], indexing="ij"), axis=-1).reshape(-1, len(shape))
    offsets = replicate_offsets(mech, replicates)
    rows = np.concatenate([np.repeat(nodes, replicates, axis=0), np.tile(offsets, len(nodes))[:, None]], axis=1)
    plan = make_plan(mech, mech_names, dt, sensor.oversample, period, nb, blocks, transient_revolutions, phase)
    if progress:
        tqdm.write(f"jaxclear fit_statistics: {len(nodes)} grid nodes x {replicates} runs of "
                   f"{transient_revolutions + blocks} revolutions; compiling first (tens of seconds)")
    with tqdm(total=len(rows), desc="fit_statistics", unit="run", disable=not progress) as bar:
        signals, status = run_rows(mech, sensor, plan, rows, chunk or default_chunk(), bar, integration)
    status = status.reshape(len(nodes), replicates)
    failed = np.any(status != 0, axis=1)
    signals = signals.reshape(len(nodes), n_m, nb)
    signals[failed] = np.nan

    # the moments at the nodes, interpolated between them; the noise profiled (statistics_surrogate)
    if progress:
        tqdm.write(f"jaxclear fit_statistics: the statistics of {len(nodes)} nodes x {len(levels)} noise levels, "
                   f"then the likelihood at {int(np.prod([(n - 1) * refine + 1 for n in shape]))} grid points")
    eps = np.random.default_rng(seed).standard_normal((n_m, nb))
    mu, cov = node_moments(signals, eps, levels, fs, kinds)
    kinds_u = {n: coordinate(n, mech) for n in (*mech_names, "sensor_gain")}
    u_nodes = [to_coordinate(values[n], kinds_u[n]) for n in mech_names]
    surrogate = Surrogate([*u_nodes, np.log(levels)], mu.reshape(*shape, len(levels), d),
                          cov.reshape(*shape, len(levels), d, d))
    u_fine = [_refined(u, refine) for u in u_nodes]
    fine = {n: from_coordinate(u, kinds_u[n]) for n, u in zip(mech_names, u_fine)}
    fine_shape = tuple(len(u) for u in u_fine)
    points = np.stack(np.meshgrid(*u_fine, indexing="ij"), axis=-1).reshape(-1, len(shape))
    t = np.log(gains)
    log_gain_w = _log_cells(t) + (_log_prior("sensor_gain", gains, priors["sensor_gain"], "log")
                                  if "sensor_gain" in priors else 0.0)
    scale = precision_factor(n_m, d) / (1.0 / n_rec + 1.0 / n_m)
    parts = [evaluate(surrogate, points[i:i + EVAL_CHUNK], np.log(levels), observed, weights, t, log_gain_w, scale)
             for i in range(0, len(points), EVAL_CHUNK)]
    loglik = np.concatenate([p[0] for p in parts]).reshape(*fine_shape, len(gains))
    chi2 = np.concatenate([p[1] for p in parts]).reshape(*fine_shape, len(gains))
    noise_hat = np.exp(np.concatenate([p[2] for p in parts])).reshape(fine_shape) * g_ref

    # posterior on the refined grid: likelihood x prior x cell (flat priors in the grid coordinate)
    logw = loglik + log_gain_w
    for ax, n in enumerate(mech_names):
        w = _log_cells(u_fine[ax]) + (_log_prior(n, fine[n], priors[n], kinds_u[n]) if n in priors else 0.0)
        logw = logw + w.reshape([-1 if i == ax else 1 for i in range(logw.ndim)])
    top = np.max(logw)
    post = np.exp(logw - top) if np.isfinite(top) else np.zeros_like(logw)
    total = float(post.sum())
    post = post / total if total > 0 else post
    finite = total > 0

    free_names = (*mech_names, *(("sensor_gain",) if gain_free else ()))
    grid_out = {**fine, **({"sensor_gain": gains} if gain_free else {})}
    marginals, summaries = {}, {}
    for ax, n in enumerate(free_names):
        m = post.sum(axis=tuple(i for i in range(post.ndim) if i != ax))
        marginals[n] = m
        cells = 1 if n == "sensor_gain" else refine
        summaries[n] = marginal_summary(grid_out[n], m, kinds_u[n], cells) if finite else None
    free_post = post if gain_free else post.sum(axis=-1)
    best = np.unravel_index(int(np.argmax(post)), post.shape)
    best_free = best if gain_free else best[:-1]
    mu_best, _ = surrogate(np.concatenate([points[np.ravel_multi_index(best[:-1], fine_shape)],
                                           [np.log(noise_hat[best[:-1]] / g_ref)]])[None])
    sigma_hat = float(noise_hat[best[:-1]])

    nan = float("nan")
    result = StatisticsFitResult(
        free=free_names,
        estimates={n: summaries[n]["mean"] if finite else nan for n in free_names},
        map={n: float(grid_out[n][best_free[i]]) for i, n in enumerate(free_names)},
        std={n: summaries[n]["std"] if finite else nan for n in free_names},
        intervals={n: (summaries[n]["q05"], summaries[n]["q95"]) if finite else (nan, nan) for n in free_names},
        grid=grid_out, nodes={n: values[n] for n in mech_names}, posterior=free_post, log_likelihood=loglik,
        marginals=marginals,
        noise={"estimate": sigma_hat, "profiled": noise_std is None, "range": [float(levels[0] * g_ref),
                                                                               float(levels[-1] * g_ref)]},
        noise_profile=noise_hat, statistics=names, observed=observed,
        model_mean=mu_best[0] + weights * t[best[-1]], chi2=float(chi2[best]),
        record_revolutions=n_rec, model_revolutions=n_m,
        failed_points=[{**{n: float(nodes[p, i]) for i, n in enumerate(mech_names)},
                        "status": int(status[p][status[p] != 0][0])} for p in np.nonzero(failed)[0]],
        settings=dict(revolutions=n_m, replicates=replicates, transient_revolutions=int(transient_revolutions),
                      statistics=list(kinds), sensor=sensor.describe(), noise_std=noise_std, column=column,
                      record=path, sample_spacing_s=dt, crank_phase_rad=phase, record_rms=rms, refine=int(refine),
                      interpolation=surrogate.method, **_settings_record(integration), seed=seed,
                      priors={n: str(v) for n, v in priors.items()}, precision_factor=precision_factor(n_m, d)),
    )
    node_mass = _node_mass(post.sum(axis=-1), shape, refine) if finite else np.zeros(shape)
    result.failures, result.notes = verdict(result, summaries, failed.reshape(shape), node_mass, finite)
    result.wall_time_s = time.perf_counter() - wall0
    return result


def _settings_record(s: Settings) -> dict:
    """What the result records of the runs' settings: ``rtol``, ``atol``, ``max_steps`` (the keys
    of before) and, under ``integration``, the other fields that differ from ``Settings``'
    defaults (none for a fit given no settings)."""
    mine, default = option_values(s), option_values(default_settings())
    changed = {k: v for k, v in mine.items() if k not in ("rtol", "atol", "max_steps") and v != default[k]}
    return dict(rtol=float(s.rtol), atol=float(s.atol), max_steps=s.max_steps, **({"integration": changed} if changed else {}))


def _refined(u, refine: int) -> np.ndarray:
    """``refine - 1`` evenly spaced points between consecutive nodes ``u``."""
    u = np.asarray(u, dtype=float)
    if refine == 1 or u.size == 1:
        return u
    parts = [np.linspace(a, b, refine + 1)[:-1] for a, b in zip(u[:-1], u[1:])]
    return np.concatenate([*parts, u[-1:]])


def _node_mass(post, shape, refine: int) -> np.ndarray:
    """The posterior mass of the refined grid gathered to the nearest node ``shape``."""
    out = post
    for ax, n in enumerate(shape):
        idx = np.rint(np.arange(out.shape[ax]) / refine).astype(int) if n > 1 else np.zeros(out.shape[ax], int)
        out = np.add.reduceat(np.moveaxis(out, ax, 0), np.searchsorted(idx, np.arange(n)), axis=0)
        out = np.moveaxis(out, 0, ax)
    return out
