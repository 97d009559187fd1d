"""The driver: :func:`fit` builds the problem, runs the plan with checkpoints, estimates the
uncertainty at the optimum and returns a :class:`FitResult` (method: :mod:`jaxclear.fitting`)."""

from __future__ import annotations

import math
from functools import partial
import time
import warnings
from typing import Callable, Sequence

import numpy as np
import optax
from tqdm.auto import tqdm

from .._interrupt import stop_at_safe_points
from .._numbers import as_typed
from .._errors import CheckpointError, ParameterError
from .._checkpoint import locked
from ..integrate import on_trace
from ..model import Mechanism
from ..analysis.sensor import Accelerometer
from .parameters import DEFAULT_FREE, law_name, values_of
from .plan import DEFAULT_HORIZONS
from ..integrate import Settings
from .problem import FitProblem, build_problem, given_settings, settings_record
from .result import FitResult
from .profile import check_profile, run_profiles, summarize
from .scan import AUTO, auto_reason, auto_scan, check_scan, few_onsets, folder as scan_folder, run_scan, summarize_scan
from .run import evaluate_all, final_jacobian, fitted_mask, fresh_state, run_plan, window_losses, window_onsets
from .solver import make_optimizer
from .state import Checkpoint, FitState
from .uncertainty import AUTOCORRELATION_WARNING, Uncertainty, estimate_uncertainty
from .window import evaluate_window_ahead


#: What a fit says when its programs are not compiled yet (:func:`~jaxclear.integrate.on_trace`).
COMPILING = ("compiling the model (tens of seconds, once per structure of mechanism and record in a process; "
             "less where the persistent compilation cache holds it)")


def fit(
    data,
    mech: Mechanism,
    free: Sequence[str] = DEFAULT_FREE,
    start: dict | None = None,
    *,
    channels=None,
    sensor: Accelerometer | None = None,
    window: float | None = None,
    windows: int = 1,
    start_state: str = "known",
    horizons: Sequence[float] = DEFAULT_HORIZONS,
    coarse: str | None = "velocity",
    starts: int | None = None,
    optimizer: optax.GradientTransformation | str | None = None,
    max_iter: int = 30,
    ftol: float = 1e-6,
    xtol: float = 1e-5,
    rtol: float | None = None,
    atol: float | None = None,
    max_steps: int | None = None,
    settings: Settings | None = None,
    align: str = "time",
    time_offset: float = 0.0,
    out=None,
    resume: bool = True,
    progress: bool = True,
    callback: Callable | None = None,
    profile: Sequence[str] | str | bool | None = None,
    noise_sigma: float | None = None,
    scan: str | dict | None = AUTO,
) -> FitResult:
    """Fit the ``free`` parameters of ``mech`` to measured channels, by default the slider
    acceleration (method: :mod:`jaxclear.fitting`).

    Args:
        data: a :class:`jaxclear.io.Measurements`, a pandas DataFrame or dict of columns
            (``time_s`` and the fitted columns), or the path of a record CSV.
        mech: the mechanism with every known value set (the free ones are replaced).
        free: names of the fitted parameters (:mod:`jaxclear.params` names, ``sensor_gain``,
            ``sensor_bias`` (of the first channel's sensor)); default stiffness and restitution.
        start: ``name: value`` start values (SI; default: the mechanism's / sensor's values).
        channels: record column -> channel spec (a :mod:`jaxclear.analysis.channels` name, a
            :class:`~jaxclear.fitting.FitChannel` or a table ``{"channel", "weight", "cutoff_hz",
            "gain", "bias"}``; :mod:`jaxclear.fitting.targets`), several at once with weights and
            sensors of their own. Default None: ``{"slider_acc_m_s2": "body:SLIDER:x:acc"}``
            (``SLIDER``: the ``slider`` role) through ``sensor``.
        sensor: the sensor model of every channel without one of its own (default: no filter,
            gain 1, bias 0, oversample 4; the oversampling is common to all channels).
        window: window length [s], holding at least 4 samples (default a quarter crank revolution,
            shortened to the record's span over ``windows`` when the record is shorter).
        windows: number of back-to-back windows; windows after the first have the journal
            state at their start as extra unknowns.
        start_state: ``"known"`` (default): the record begins where the mechanism starts (crank
            at its ``angle0``, journal at its initial offset, ideal velocities). ``"free"``: the
            record begins mid-run (a laboratory record): the force elements' state at every
            window's start, the first included, is unknown (in contact or not, with the ongoing
            contact's approach speed); it is found by scoring candidate starts on the window's
            first part (:mod:`jaxclear.fitting.way_in`) and then fitted with the parameters.
            The crank's angle at the record's first sample is the mechanism's ``angle0`` (set it
            from the encoder: ``jc.params.replace(mech, "angle0", angle)``, or free ``angle0``
            and ``speed`` to fit them). With ``starts = N > 1`` the way in runs once (at the
            start values) and the joint stages N times, from N starts of the parameters; the
            best is the result, and the verdict fails a fit whose equally good starts disagree.
        horizons: fractions of the window fitted in turn (continuation), ending at 1.
        coarse: ``"velocity"`` (default): the first stage (and the first stage of every window's
            state) fits the integrated signal; None: acceleration only.
        starts: number of starts for the first stage. None (default): one start and, where the
            fit stops on ``max_iter`` or leaves a residual that is not white (lag-1
            autocorrelation above 0.3), the whole fit again from :data:`AUTO_STARTS` starts
            (Levenberg-Marquardt only; ``FitResult.settings["auto_starts"]`` says why). Both
            checkpoint into ``out``: a fit killed in the single start, at the switch or in the
            refit resumes where it stopped (``settings["resumed"]``); no checkpointed iteration
            is fitted again.
        optimizer: None / ``"levenberg-marquardt"`` (default: :class:`optimistix.LevenbergMarquardt`),
            ``"adam"``, ``"adam:LR"``, an optax transformation or an optimistix solver
            (:func:`jaxclear.fitting.make_optimizer`).
        max_iter, ftol, xtol: stopping rules per stage (:mod:`jaxclear.fitting.solver`).
        settings: how the model is integrated (:class:`~jaxclear.Settings`: solver,
            tolerances, step limit, derivatives...). None (default): ``Settings``' defaults with
            the fit's tolerances ``rtol`` 1e-8, ``atol`` 1e-11
            (:data:`~jaxclear.fitting.problem.RTOL`: the Jacobians are forward-mode derivatives
            of the runs). The fit replaces what it owns (:func:`~jaxclear.fitting.problem.model_settings`):
            each window's ``t_end`` and ``n_out``, ``t_start`` 0, ``throw`` False (a failed trial
            run is a refused step), ``progress`` False, and, where ``settings`` leaves them at
            ``Settings``' defaults, its documented choices: the step limit
            :data:`~jaxclear.fitting.problem.MAX_STEPS` (200,000;
            :data:`~jaxclear.fitting.problem.FREE_START_MAX_STEPS` with ``start_state="free"``),
            block output sampling (:data:`~jaxclear.fitting.problem.FIT_OUTPUT`) and the
            derivatives ``Sensitivity(derivative_tolerance(rtol))``
            (:func:`~jaxclear.fitting.problem.derivative_tolerance`: the sensitivity solve at the
            model's own tolerance where ``rtol`` <= 1e-7, a tenth of it above). Derivatives set
            otherwise than ``Sensitivity()`` (``jc.Sensitivity(0.5)``, ``jc.ThroughLoop()``) are
            used as given.
        rtol, atol, max_steps: deprecated (a ``DeprecationWarning``, one release):
            ``settings=jc.settings(1.0, rtol=1e-8, atol=1e-11)``; given with ``settings``, a
            :class:`~jaxclear.ParameterError`.
        align, time_offset: how record times map to simulation time
            (:func:`jaxclear.analysis.sensor.record_times`).
        out: folder for the checkpoint (``fit_checkpoint.json``); None: no checkpoint.
        resume: continue from a matching checkpoint in ``out``.
        progress: show a tqdm progress bar.
        callback: called as ``callback(record)`` after every iteration (record: dict with
            ``stage``, ``iteration``, ``loss``, ``values``).
        profile: free parameter name(s), or True for all, whose profile likelihood is walked
            after the fit (:mod:`jaxclear.fitting.profile`: each held at up to 20 values while
            every other unknown is fitted again): their 90 % interval is
            ``FitResult.profiles[name]["interval"]`` and their ``std`` the interval's longer half
            over 1.645 (the Gauss-Newton std beside it), infinite where the record does not bound
            them; a profile that finds a better fit than the estimate begins the fit again from
            it and is walked anew (once: ``profile.RESTARTS``), and one that still finds one
            fails the fit. Costs up to
            20 warm-started final stages per name (usually 4-8). Not part of the checkpoint's key: the same
            call with ``out`` and a profile added to a finished fit runs only the profile.
        noise_sigma: the sensor's noise standard deviation [record units, m/s^2], measured
            on a record of the machine at rest; None (default): unknown. Given, the verdict
            tests the residual against it (:mod:`jaxclear.fitting.verdict`: a residual std
            more than 3 chi-square std above it fails the fit: the model does not follow the
            record to its noise). One fitted column only. Not part of the checkpoint's key.
        scan: a free parameter of the mechanism (or ``{name: [values]}``) scanned after the
            fit (:mod:`jaxclear.fitting.scan`): the record is fitted again with it held at each
            value (default: two, either side of the estimate), the window starts searched anew
            at each; where the best of them fits better than the estimate, every unknown is
            fitted again from it and that result is taken. Its profile likelihood is then
            walked (as with ``profile``). For records that begin mid-run, where a window's
            start found in another basin bends a weakly determined parameter (a restitution
            seen through few impacts). Costs one whole fit per value, each checkpointed in
            ``out/scan-NAME-VALUE``; not part of the checkpoint's key. ``"auto"`` (default):
            the restitution is scanned where every window's start is free and the fitted
            motion holds fewer than ``scan.FEW_ONSETS`` (4) contact onsets
            (:func:`~jaxclear.fitting.scan.auto_reason`), nothing elsewhere; None: no scan.

    Raises:
        ParameterError: unknown free parameter, start value outside its bounds, record shorter
            than the windows, mechanism without a slider or a crank driver where one is needed.
        FitDataError (a ParameterError): the record holds non-finite or absurd samples or no
            signal, or the loss at the start values is not finite (the model cannot be simulated
            there) or exactly zero (nothing to fit); the message names the record.
        OutputLockedError: another process holds ``out``.
        CheckpointError: the checkpoint in ``out`` cannot be read.
        KeyboardInterrupt: Ctrl-C (SIGINT) during the fit, raised after the iteration under way
            has finished and been checkpointed (a second Ctrl-C raises at once); the same call
            resumes from the checkpoint.
    """
    t_wall = time.perf_counter()
    integration, steps = given_settings("fit", settings, rtol, atol, max_steps,
                                         anywhere=start_state == "free")
    opt = make_optimizer(optimizer, ftol, xtol)
    settings = dict(max_iter=max_iter, ftol=ftol, xtol=xtol, **settings_record(integration, steps), align=align,
                    time_offset=time_offset, optimizer=opt.name)
    auto = starts is None
    problem = build_problem(data, mech, free, start, sensor, window, windows, horizons, coarse, 1 if auto else starts,
                            settings, channels, start_state, integration)
    names = check_profile(profile, problem.free)
    extra = {"noise_sigma_given_m_s2": check_noise(noise_sigma, problem)} if noise_sigma is not None else {}
    if isinstance(scan, str) and scan == AUTO:
        scanned, when = auto_scan(problem.free, problem.anywhere), partial(auto_reason, problem)
    else:
        scanned, when = check_scan(scan, problem.free, mech), lambda st: "asked"

    def fit_at(value: float, others: dict, out_at) -> FitResult:  # the record again, scanned[0] held at value
        held = build_problem(data, mech, problem.free, {**others, scanned[0]: value}, sensor, window, windows,
                             horizons, coarse, 1 if starts is None else starts, dict(settings), channels, start_state,
                             integration).holding(scanned[0])
        with locked(out_at, "fit"), warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # a held fit's warnings are not the result's
            return _fit_locked(held, opt, out_at, resume, progress, callback, time.perf_counter(), extra=extra)

    scanned = (*scanned, fit_at, when) if scanned else ()
    auto = auto and not problem.anywhere
    with locked(out, "fit"):
        if not (auto and opt.least_squares):
            return _fit_locked(problem, opt, out, resume, progress, callback, t_wall, profile=names, scan=scanned,
                               extra=extra)
        several = problem.with_starts(AUTO_STARTS)
        if resume and _checkpoint(several, out).load() is not None:  # killed in the refit (or at the switch to it)
            return _fit_locked(several, opt, out, resume, progress, callback, t_wall, profile=names, scan=scanned,
                               extra=extra)
        with warnings.catch_warnings(record=True) as first_warnings:
            warnings.simplefilter("always")
            first = _fit_locked(problem, opt, out, resume, progress, callback, t_wall, profile=names, scan=scanned,
                                unless=_not_converged, extra=extra)
        why = _not_converged(first)
        if not why:
            for w in first_warnings:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            return first
        if progress:
            tqdm.write(f"jaxclear fit: one start {why}; fitting again from {AUTO_STARTS} starts")
        return _fit_locked(several, opt, out, False, progress, callback, time.perf_counter(), after=first, profile=names,
                           scan=scanned, extra=extra)


#: Starts of the refit of a fit with ``starts=None`` (the default) whose single start stops on
#: ``max_iter`` or leaves a residual that is not white. An outside check fitted a slider-crank of
#: its own (c_r from 0.85, truth 0.6, 10 % noise): one start stopped at max_iter with c_r 0.6945
#: +- 0.0025 (38 std off), 4 starts recovered the truth (here one start fitted all 15 records of 6
#: such variants). Always starting 4 times would cost 1.7x the iterations of every fit (24
#: against 11 on 3 of those records), so it is done only where one start fails.
AUTO_STARTS = 4


def check_noise(noise_sigma, problem: FitProblem) -> float:
    """The given noise level as a float > 0 [record units]; a
    :class:`~jaxclear.ParameterError` for another value or a fit of several columns."""
    if isinstance(noise_sigma, bool) or not isinstance(noise_sigma, (int, float)) or not math.isfinite(noise_sigma) \
            or noise_sigma <= 0:
        raise ParameterError(f"noise_sigma = {noise_sigma!r} must be a finite number > 0 (the sensor's noise standard "
                             "deviation in the record's units, m/s^2), or None")
    if len(problem.columns) > 1:
        raise ParameterError(f"noise_sigma applies to a fit of one column; this fit compares {len(problem.columns)} "
                             f"({', '.join(problem.columns)})")
    return float(noise_sigma)


def _not_converged(res: FitResult) -> str:
    """Why one start's result needs more starts ('' if it does not): it stopped on max_iter or
    its residual is not white."""
    if res.stop_reason == "max_iter":
        return f"stopped on max_iter = {res.settings['max_iter']}"
    if res.residual_autocorrelation > AUTOCORRELATION_WARNING:
        return f"left a residual that is not white (lag-1 autocorrelation {res.residual_autocorrelation:.2f})"
    return ""


def _checkpoint(problem: FitProblem, out, clock=None) -> Checkpoint:
    return Checkpoint(out, problem.checkpoint_key(), problem.checkpoint_config(), clock=clock)


def _fit_locked(problem: FitProblem, opt, out, resume: bool, progress: bool, callback, t_wall: float,
                after: FitResult | None = None, profile: tuple = (), unless: Callable | None = None,
                extra: dict | None = None, scan: tuple = ()):
    """:func:`fit` inside the output folder's lock, its wall time counted from ``t_wall``
    (:func:`time.perf_counter`). ``after``: the single start that this automatic refit follows
    (a fresh refit: its state starts from that fit's wall time and reason, and is checkpointed at
    once, so that a kill from here on resumes the refit; the result is resumed if that fit was).
    ``profile``: the names whose profile likelihood is walked after the plan, unless
    ``unless(result)`` says the result will be fitted again (the single start of the automatic
    refit). ``scan``: ``(name, values, fit_at, when)`` of the scan of held values run after the
    plan where ``when(state)`` gives a reason (:func:`~jaxclear.fitting.scan.run_scan`; each held
    fit has its own safe points; the name's profile is then walked), under the same condition.
    ``extra``: settings for the result only (the given noise level), not the checkpoint's key."""
    ckpt = _checkpoint(problem, out, clock=lambda: wall_before + time.perf_counter() - t_wall)
    saved = ckpt.resume() if resume else None  # the protocol's rules: another fit's checkpoint is refused
    if saved is not None:
        _check_resumed(problem, saved, ckpt.path)
    if saved is not None and progress:
        what = f" the {problem.settings['starts']}-start refit" if saved.refit else ""
        tqdm.write(f"jaxclear fit: resuming{what} from {ckpt.path} after {saved.total} iteration(s)")
    st = saved if saved is not None else fresh_state(problem)
    if after is not None and saved is None:
        st = st.replace(refit=_not_converged(after), wall=after.wall_time_s)
    wall_before = st.wall
    if after is not None and saved is None:
        ckpt.save(st)
    bars = []  # the bar starts after the first iteration, which includes any compilation

    def report(record: dict, now: FitState):
        if progress and not bars:
            bars.append(tqdm(total=None, initial=record["iteration"] - 1, desc="fit", unit="it", leave=True))
        if bars:
            bars[0].total = record["iteration"] + iterations_left(problem, now)
            bars[0].update(1)
            bars[0].set_description(record["stage"] + (" (resumed)" if saved is not None else ""))
            bars[0].set_postfix({"loss": f"{record['loss']:.4g}", **{n: f"{v:.4g}" for n, v in record["values"].items()}})
        if callback is not None:
            callback(record)
        interrupt.check()  # a Ctrl-C stops here, the iteration checkpointed

    def compiling(name: str):  # a cache miss of the fit's programs (the data were checked before)
        if progress and not bars and not told:
            told.append(name)
            tqdm.write(f"jaxclear fit: {COMPILING}; the progress bar starts after the first iteration")

    told: list = []
    phases, clock = {}, [time.perf_counter()]

    def lap(phase: str) -> None:  # seconds of a phase in this process (compilation included)
        now = time.perf_counter()
        phases[phase] = round(now - clock[0], 3)
        clock[0] = now

    try:
        with stop_at_safe_points("the current iteration") as interrupt, on_trace(compiling):
            # the windows' program compiles on a thread of its own while the way in's are traced
            evaluate_window_ahead(problem.model, st.theta, st.states[0], problem.window_input(0, 1.0, False, st.guesses))
            st = run_plan(problem, opt, st, ckpt, report)
            after_plan = not (unless is not None and (profile or scan)
                              and unless(_result(problem, st, 0.0, False, quiet=True)))
        lap("plan")
        name, values, fit_at, when = scan if scan and after_plan else (None, None, None, None)
        why = when(st) if when is not None else ""
        if why:
            close_bars(bars)
            st = run_scan(problem, opt, st, ckpt, name, values,
                          lambda value, others: fit_at(value, others, scan_folder(out, name, value)),
                          lambda record, now: None, tqdm.write if progress else (lambda text: None), why)
            profile = profile if name in profile else (*profile, name)  # the scanned name's profile is walked
            lap("scan")
        with stop_at_safe_points("the current iteration") as interrupt, on_trace(compiling):
            if profile and after_plan:
                st = run_profiles(problem, opt, st, ckpt, profile, lambda record, now: interrupt.check(),
                                  tqdm.write if progress else (lambda text: None))
                lap("profile")
    finally:
        close_bars(bars)
    resumed = saved is not None or (after is not None and after.settings["resumed"])
    return _result(problem, st, wall_before + time.perf_counter() - t_wall, resumed, profile=profile,
                   extra={**(extra or {}), "phase_s": phases})


def close_bars(bars: list) -> None:
    """Close the progress bars (their total what they counted) and empty the list."""
    for bar in bars:
        bar.total = bar.n
        bar.refresh()
        bar.close()
    bars.clear()


def iterations_left(problem: FitProblem, st: FitState) -> int:
    """The most iterations the plan can still take after ``st``: what the current stage's limit
    leaves, plus the limits of the stages after it. With the iterations done, the progress bar's
    total: exact for the plan from the first iteration on (a resumed fit's finished stages
    count what they took), shrinking whenever a stage stops before its limit."""
    limit = problem.settings["max_iter"]
    stages = problem.stages[st.stage:]
    return max(sum(stage.max_iter(limit) for stage in stages) - st.iteration, 0)


def _check_resumed(problem: FitProblem, st: FitState, path: str) -> None:
    """A :class:`~jaxclear.CheckpointError` naming the checkpoint and the field when a state read
    back is not one this fit can continue from: counters that are not integers >= 0, a stage
    beyond the plan, or parameters, window states, guesses or unknowns of another shape or not
    finite (a damaged file: its key matched)."""

    def damaged(detail: str):
        raise CheckpointError(f"the fit checkpoint {path!r} is damaged ({detail}); delete it, or start over with "
                              "--restart (API: resume=False)")

    for name in ("stage", "iteration", "total", "evaluations"):
        v = getattr(st, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            damaged(f"{name} = {v!r} is not an integer >= 0")
    if st.stage > len(problem.stages):
        damaged(f"stage = {st.stage} is beyond this fit's {len(problem.stages)} stages")
    fresh = fresh_state(problem)
    for name in ("theta", "states", "guesses", "x"):
        value = getattr(st, name)
        if value is None and name == "x":
            continue
        try:
            got = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            damaged(f"{name} is not an array of numbers")
        want = np.asarray(getattr(fresh, name), dtype=float).shape if name != "x" else (got.size,)
        if got.shape != want:
            damaged(f"{name} has shape {got.shape}, this fit's is {want}")
        if not np.all(np.isfinite(got)):
            damaged(f"{name} holds a value that is not finite")


def _progress_bar(problem: FitProblem, done: int):
    """The iteration bar, started after the first iteration of this call (so its rate and ETA
    leave the compilation out): the ``done`` iterations so far count as its start."""
    total = sum(stage.max_iter(problem.settings["max_iter"]) for stage in problem.stages)
    return tqdm(total=total, initial=min(done, total), desc="fit", unit="it", leave=True)


def _plot_series(problem: FitProblem, evals, initial, j: int = 0) -> dict:
    """Fitted samples of every window of channel ``j`` for the plot: t (simulation time),
    measured, fitted, initial."""
    parts = {"t": [], "measured": [], "fitted": [], "initial": []}
    win = problem.win
    for k, n_k in enumerate(win.counts):
        keep = win.valid[k, :n_k] > 0
        parts["t"].append((win.t_rel[k, :n_k] + win.starts[k])[keep])
        parts["measured"].append(win.data[k, j, :n_k][keep])
        parts["fitted"].append(evals[k][3][j, :n_k][keep])
        parts["initial"].append(initial[k][3][j, :n_k][keep])
    return {name: np.concatenate(v) for name, v in parts.items()}


def _channel_series(problem: FitProblem, evals, initial) -> dict:
    """column -> ``{"measured", "fitted", "initial"}`` fitted samples (times: ``FitResult.t``)."""
    return {c: {k: v for k, v in _plot_series(problem, evals, initial, j).items() if k != "t"}
            for j, c in enumerate(problem.columns)}


def _result(problem: FitProblem, st: FitState, wall: float, resumed: bool, profile: tuple = (),
            quiet: bool = False, extra: dict | None = None) -> FitResult:
    """The :class:`FitResult` at the state's optimum (uncertainty on all windows, all samples;
    the std of the ``profile`` names from their profile likelihood); ``quiet``: no warnings."""
    theta, states = np.asarray(st.theta, dtype=float), np.asarray(st.states, dtype=float)
    evals = evaluate_all(problem, theta, states, st.guesses)
    r, jac = final_jacobian(problem, evals)
    mask = fitted_mask(problem)
    unc: Uncertainty = estimate_uncertainty(r, jac, mask, problem.win.scale, theta, problem.free, problem.mech)
    converged = st.stop_reason not in ("", "max_iter")
    warn = list(unc.warnings)
    if not converged:
        warn.append(f"the last stage stopped on max_iter = {problem.settings['max_iter']} before meeting ftol/xtol")
    if warn and (not converged or unc.autocorrelation > AUTOCORRELATION_WARNING):
        warn.append(f"the fit may sit in a local minimum: try more starts (--starts N, starts=N; this fit had "
                    f"{problem.settings['starts']}), other start values (--start NAME=VALUE, start=...) or a larger "
                    "max_iter")
    onsets = window_onsets(evals)
    few = few_onsets(problem.free, problem.anywhere, bool(st.scan), onsets)
    if few:
        warn.append(few)
    profiles = summarize(problem, st, profile, unc.std)
    std = {**unc.std, **{name: p["std"] for name, p in profiles.items()}}
    for w in warn if not quiet else ():
        warnings.warn(w, stacklevel=3)
    losses = window_losses(problem, evals)
    initial = evaluate_all(problem, problem.z_starts[0], states, st.guesses)
    s = problem.settings
    return FitResult(
        estimates=unc.estimates, std=std, profiles=profiles, loss=float(np.mean(r[mask > 0] ** 2)), iterations=int(st.total),
        evaluations=int(st.evaluations), wall_time_s=wall,
        start={name: as_typed(v) for name, v in zip(problem.free, values_of(problem.free, problem.z0, problem.win.scale, problem.mech))},
        correlation=unc.correlation, noise_sigma_m_s2=unc.sigma, residual_rms_m_s2=unc.rms,
        residual_autocorrelation=unc.autocorrelation, n_samples=unc.n_samples, n_unknowns=unc.n_unknowns,
        converged=converged, stop_reason=st.stop_reason, history=list(st.history),
        **_plot_series(problem, evals, initial), window_starts=[float(t) for t in problem.win.starts],
        window_length_s=as_typed(problem.win.length), free=problem.free, mech=problem.mech,
        fixed={name: as_typed(v) for name, v in problem.fixed.items()},
        settings={"window_s": as_typed(problem.win.length), "windows": problem.windows, "horizons": list(problem.horizons),
                  "coarse": s["coarse"], "starts": s["starts"], "max_iter": s["max_iter"], "ftol": s["ftol"],
                  "xtol": s["xtol"], "rtol": s["rtol"], "atol": s["atol"], "align": s["align"],
                  **({"integration": s["integration"]} if "integration" in s else {}),
                  "sensor": problem.sensor.describe(), "oversample": problem.sensor.oversample,
                  "record": problem.meas.path, "record_samples": len(problem.t_rec), "sample_spacing_s": s["dt"],
                  "data_rms_m_s2": problem.win.scale, "mechanism": problem.mech.name,
                  "law": law_name(problem.mech), "resumed": resumed, "optimizer": s["optimizer"],
                  "skipped_stages": list(st.skipped), "start_state": "free" if problem.anywhere else "known",
                  "way_in": [dict(w) for w in st.way_in],
                  **({"scan": summarize_scan(st, float(np.mean(r[mask > 0] ** 2)), unc.n_samples, unc.n_unknowns)}
                     if st.scan else {}),
                  "channels": problem.channel_config(), **(extra or {}),
                  **({"auto_starts": f"{s['starts']} starts: one start {st.refit}"} if st.refit else {})},
        series=_channel_series(problem, evals, initial),
        warnings=warn, window_states=[list(map(float, v)) for v in (states if problem.anywhere else states[1:])],
        window_losses=losses, window_onsets=onsets,
        window_samples=[int(problem.win.residual_mask(k, 1.0).sum()) for k in range(problem.windows)])

