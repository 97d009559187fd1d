"""The fit problem: the checked inputs, the record on the simulation clock cut into windows, the
window model, the start values and the plan, built once before any compilation."""

from __future__ import annotations

import json
import dataclasses
from dataclasses import dataclass
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import FitDataError, ParameterError
from ..model import FunctionDriver, Mechanism, crank_driver, crank_period
from ..analysis.channels import unit as named_unit
from ..analysis.sensor import Accelerometer, record_times, uniform_spacing
from ..integrate import ExactOnsets, SampleBlock, Sensitivity, Settings
from ..integrate import default_settings, option_values, settings_or_default
from .parameters import check_free, fixed_values, start_values, z_vector
from .plan import check_plan, plan_stages, spread_starts
from .records import read_record
from .state import checkpoint_key
from .targets import DEFAULT_COLUMN, resolve_targets
from .window import WindowInput, WindowModel, WindowSet, cut_windows
from .window_start import crank_guesses, state_size, state_to_z

#: How a fit treats the state at the record's start (``start_state``): ``"known"``, the
#: mechanism's own start (a record that begins at start-up; windows after the first get
#: contact-free free starts); ``"free"``, unknown (a record that begins mid-run: every window's
#: start is found by the way in and fitted, in contact or not; :mod:`.window_start`, :mod:`.way_in`).
START_STATES = ("known", "free")
#: Solver steps of one window's run (values and sensitivities) at most: a known start, and a
#: free one. A free start's trial step can put the journal deep into its bearing, where a
#: violent impact makes a run take 10-50 times its usual 1,000-10,000 steps; such a trial is
#: worth no more than a rejected step (its run fails, the step is refused).
MAX_STEPS = 200_000
FREE_START_MAX_STEPS = 20_000
#: Parameters of a force element's start state: a fit window sets them itself (a free one would
#: be ignored).
START_PARAMETERS = ("offset_x", "offset_y", "velocity_x", "velocity_y")
#: Crank parameters whose fit moves every window's crank angle (``angle0 + speed t_k``).
CRANK_PARAMETERS = ("angle0", "speed", "speed_rpm")

#: How the fit's model treats contact onsets (:class:`~jaxclear.Settings` ``onsets``): exactly
#: (:class:`~jaxclear.ExactOnsets`), as every other run does. It was off while the forward-mode derivative of
#: the approach speed at an onset was noise on the short steps that end just past an onset (the
#: rig record's Jacobian 10 to 600 times too large, its fit stalled at -10 % stiffness; fixed in
#: :func:`jaxclear.elements.memory.contact_switches`, see "Impact memory" in the documentation).
FIT_ONSETS = ExactOnsets()
#: How the fit's model writes its dense output samples (:class:`~jaxclear.Settings` ``output``).
FIT_OUTPUT = SampleBlock()


#: The model's tolerances where a fit is given no settings: its Jacobians are forward-mode
#: derivatives of the runs, which need tighter tolerances than the values (the default 1e-6 of a
#: plain run leaves their non-smooth part at 1.7e-3: :func:`derivative_tolerance`).
RTOL, ATOL = 1e-8, 1e-11
#: The same where every window's start is free (``start_state="free"``): its records are long and in
#: contact most of the time, and its fit's cost is the runs'. At 1e-7 the acceptance records' estimates
#: and std equal those at 1e-8 to the digits reported (stiffness +0.39 %, restitution 0.827 +- 0.021 on
#: record 1) in 58 % of the time (185 s against 322 s on 2 cores; ``benchmarks/bench_lab_fit.py --rtol``).
FREE_START_RTOL, FREE_START_ATOL = 1e-7, 1e-10


def default_fit_settings(anywhere: bool = False) -> Settings:
    """The settings of a fit given none: ``Settings``' defaults with :data:`RTOL`, :data:`ATOL`
    (:data:`FREE_START_RTOL`, :data:`FREE_START_ATOL` with ``anywhere``: every window's start free;
    the rest of the fit's own choices: :func:`model_settings`)."""
    rtol, atol = (FREE_START_RTOL, FREE_START_ATOL) if anywhere else (RTOL, ATOL)
    return dataclasses.replace(default_settings(), rtol=rtol, atol=atol)


def given_settings(driver: str, settings: Settings | None, rtol=None, atol=None, max_steps=None,
                   stacklevel: int = 4, anywhere: bool = False) -> tuple[Settings, int | None]:
    """``(settings, max_steps or None)`` of a fit or posterior: ``settings``, else
    :func:`default_fit_settings` (of ``anywhere``) with the deprecated ``rtol``, ``atol``, ``max_steps`` keywords
    (a ``DeprecationWarning``; with ``settings`` too, a :class:`~jaxclear.ParameterError`). The
    second is the step limit given (the keyword, or the settings' where it is not ``Settings``'
    default), None where the fit chooses (:func:`model_settings`)."""
    s = settings_or_default(driver, settings, default_fit_settings(anywhere), stacklevel, rtol=rtol, atol=atol,
                            max_steps=max_steps)
    if settings is None:
        return s, max_steps
    return s, (s.max_steps if s.max_steps != default_settings().max_steps else None)


def model_settings(base: Settings, anywhere: bool, max_steps: int | None = None) -> Settings:
    """The window model's settings (its ``t_end`` and ``n_out`` are each window's): ``base``,
    what the fit owns replaced: ``t_start`` 0 (a window's own clock), ``throw`` False (a failed
    trial run is a refused step), ``progress`` False, and, where ``base`` leaves them at
    ``Settings``' defaults, the fit's documented choices: the step limit ``max_steps`` (given) or
    :data:`MAX_STEPS` (:data:`FREE_START_MAX_STEPS` for free starts), the output
    :data:`FIT_OUTPUT`, the onsets :data:`FIT_ONSETS` and the derivatives
    ``Sensitivity(derivative_tolerance(rtol))`` (the fit's second policy for the sensitivity
    tolerance: it applies only where the derivatives were not set; any other ``derivatives``
    is used as given)."""
    default = default_settings()
    changes = dict(t_start=0.0, throw=False, progress=False)
    if max_steps is not None:
        changes["max_steps"] = max_steps
    elif base.max_steps == default.max_steps:
        changes["max_steps"] = FREE_START_MAX_STEPS if anywhere else MAX_STEPS
    if base.output == default.output:
        changes["output"] = FIT_OUTPUT
    if base.onsets == default.onsets:
        changes["onsets"] = FIT_ONSETS
    if base.derivatives == default.derivatives:
        changes["derivatives"] = Sensitivity(derivative_tolerance(base.rtol))
    return dataclasses.replace(base, **changes)


def settings_record(s: Settings, max_steps: int | None) -> dict:
    """What a fit records of its settings (its result's ``settings``, its checkpoint's key):
    ``rtol``, ``atol``, ``max_steps`` (the given one, or None), and under ``integration`` the
    fields that differ from :func:`default_fit_settings` (none for a fit given no settings: the
    keys of before)."""
    mine, default = option_values(s), option_values(default_fit_settings())
    changed = {k: v for k, v in mine.items() if k not in ("rtol", "atol", "max_steps") and v != default[k]}
    baumgarte = [float(s.baumgarte.alpha), float(s.baumgarte.beta)]
    if baumgarte != [5.0, 5.0]:
        changed["baumgarte"] = baumgarte
    return dict(rtol=float(s.rtol), atol=float(s.atol), max_steps=max_steps, **({"integration": changed} if changed else {}))


def derivative_tolerance(rtol: float) -> float:
    """The fit's :class:`~jaxclear.Sensitivity` ``tolerance`` for a model at ``rtol``: 1
    (the sensitivity solve at the model's own tolerance) where ``rtol`` is 1e-7 or tighter, else
    :class:`~jaxclear.Sensitivity`'s default (a tenth). The tenth keeps a misfit's derivatives smooth
    in the parameters at the default rtol 1e-6 (their non-smooth part at parameter values 1e-7
    apart: 1.7e-3 at rtol 1e-6, 2.0e-5 at 1e-7, 1.5e-6 at 1e-8; ``benchmarks/README.md``,
    "Derivatives through impacts"); the fit's model runs at 1e-8, where it is already smooth,
    and the tenth cost its Jacobians about 1.2x."""
    return 1.0 if rtol <= 1e-7 else Sensitivity().tolerance


@dataclass(frozen=True)
class FitProblem:
    """Everything fixed during a fit (see :func:`build_problem`)."""

    meas: object
    t_rec: np.ndarray
    y_rec: np.ndarray  # (C, N): the fitted columns
    mech: Mechanism
    sensor: Accelerometer
    targets: tuple  # ((column, FitChannel), ...)
    free: tuple
    values0: dict
    fixed: dict
    z0: np.ndarray
    z_starts: list
    model: WindowModel
    win: WindowSet
    stages: list
    horizons: tuple
    state0: np.ndarray
    guess0: tuple
    start_scales: list
    velocity_scale: float
    angle0: float
    speed: float
    settings: dict
    anywhere: bool = False  # start_state="free": every window's start in the anywhere layout
    window_guesses: tuple = ()  # per window (q, qdot) of the ideal assembly at its crank angle (anywhere)

    @property
    def windows(self) -> int:
        return len(self.win.starts)

    def with_starts(self, starts: int) -> "FitProblem":
        """This problem fitted from ``starts`` starts: its plan, its start points, its settings."""
        return dataclasses.replace(self, stages=plan_stages(self.windows, self.horizons, starts, self.settings["coarse"],
                                                            self.anywhere),
                                   z_starts=spread_starts(self.z0, self.free, starts, self.mech),
                                   settings={**self.settings, "starts": starts})

    def holding(self, name: str) -> "FitProblem":
        """This problem with the free parameter ``name`` held at its start value in every stage
        (a point of a scan, :mod:`.scan`): the unknowns and so every compiled program stay this
        problem's (the held column of each stage's Jacobian is zero,
        :func:`~jaxclear.fitting.run.stage_evaluation`), where a problem without ``name`` among
        its free parameters would compile its programs again (measured on acceptance record 2
        of the independent simulator: the first held fit's first way in 41 s against 15 s)."""
        i = self.free.index(name)
        stages = [s._replace(held=(i,)) if s.theta else s for s in self.stages]
        z_starts = [np.where(np.arange(len(z)) == i, self.z0[i], z) for z in self.z_starts]
        return dataclasses.replace(self, stages=stages, z_starts=z_starts, settings={**self.settings, "held": name})

    def window_input(self, k: int, horizon: float, integrate: bool, guesses) -> WindowInput:
        """Window ``k``'s input; its crank starts at ``angle0 + omega t_k`` [rad] (:class:`WindowModel`)."""
        return self.win.window_input(k, horizon, integrate, guesses[k])

    def checkpoint_config(self) -> dict:
        s = dict(self.settings)
        return dict(free=self.free, start=self.values0, window=self.win.length, windows=self.windows,
                    horizons=self.horizons, starts=s["starts"], coarse=s["coarse"], max_iter=s["max_iter"],
                    ftol=s["ftol"], xtol=s["xtol"], rtol=s["rtol"], atol=s["atol"], align=s["align"],
                    time_offset=s["time_offset"], sensor=self.sensor.describe(), oversample=self.sensor.oversample,
                    optimizer=s["optimizer"], mechanism=str(jax.tree_util.tree_structure(self.mech)),
                    **({} if self.default_target else {"channels": self.channel_config()}),
                    **({"start_state": "free"} if self.anywhere else {}),
                    **({"held": s["held"]} if s.get("held") else {}))

    @property
    def default_target(self) -> bool:
        """Whether the fit compares the slider acceleration column alone (the default target)."""
        return self.columns == (DEFAULT_COLUMN,) and self.targets[0][1].weight == 1.0 and \
            self.targets[0][1].sensor is self.sensor

    @property
    def columns(self) -> tuple:
        return tuple(c for c, _ in self.targets)

    def channel_config(self) -> dict:
        """column -> channel, weight, sensor (for the checkpoint and ``fit.json``)."""
        return {c: fc.describe() for c, fc in self.targets}

    def checkpoint_key(self) -> str:
        sensors = [fc.sensor for _, fc in self.targets]
        leaves = [np.ravel(np.asarray(x, dtype=float)) for x in jax.tree_util.tree_leaves(
            (self.mech, self.sensor) if self.default_target else (self.mech, self.sensor, sensors))]
        y = self.y_rec[0] if self.default_target else self.y_rec
        return checkpoint_key(self.t_rec, y, np.concatenate(leaves), self.checkpoint_config())


def _check_mechanism(mech: Mechanism, windows: int):
    if not mech.clearance_joints:
        raise ParameterError(f"mechanism {mech.name!r} has no clearance joint: nothing to identify")
    if windows > 1:
        if crank_driver(mech) is None or any(isinstance(d, FunctionDriver) for d in mech.drivers) or any(
                getattr(ld, "function", None) is not None for ld in mech.loads):
            raise ParameterError(
                "windows > 1 needs a mechanism whose only time dependence is an AngleDriver (the windows are "
                "simulated from t = 0 with the crank angle advanced)"
            )


#: Fewest record samples a fit window holds (at t = 0 and up to the window's end).
MIN_WINDOW_SAMPLES = 4


def _window_length(mech, window, windows: int, span: float, dt: float, h: float, n_samples: int, t_rec, where):
    """The window length [s], a whole number of fine steps ``h``. A window given is checked: the
    record must cover ``windows`` of it and one must hold :data:`MIN_WINDOW_SAMPLES` samples. By
    default (``window`` None) a quarter crank revolution (without a crank: the record's span
    shared by the windows), shortened to what the record covers when it is shorter."""
    given = window is not None
    if not given:
        window = 0.25 * float(crank_period(mech)) if crank_driver(mech) is not None else span / windows
    if not window > 0:
        raise ParameterError(f"window = {window!r} s must be > 0")
    steps = int(round(window / h))
    if not given:  # a window that fits the record: whole fine steps, windows of them within its span
        steps = min(steps, int(np.floor(max(span, 0.0) / windows / h + 1e-9)))
    window = steps * h
    needed = windows * window
    if given and span + 0.5 * dt < needed:
        raise ParameterError(
            f"{where}: the record covers {max(span, 0.0):.6g} s of simulation time ({n_samples} samples) but "
            f"{windows} window(s) of {window:.6g} s need {needed:.6g} s (record shorter than the fit windows); give a "
            "shorter window (window=..., --window S) or fewer windows"
        )
    held = int(np.count_nonzero((t_rec >= 0) & (t_rec <= window + 0.5 * h)))
    if held < MIN_WINDOW_SAMPLES:
        shortest = (MIN_WINDOW_SAMPLES - 1) * dt
        if given:
            raise ParameterError(
                f"{where}: a window of {window:.6g} s holds {held} sample(s) of the record (one every {dt:.6g} s); "
                f"at least {MIN_WINDOW_SAMPLES} are needed: give a window of at least {shortest:.6g} s (window=..., "
                "--window S)")
        raise ParameterError(
            f"{where}: the record's {n_samples} samples over {max(span, 0.0):.6g} s of simulation time give "
            f"{windows} window(s) of {window:.6g} s holding {held} sample(s) each; at least {MIN_WINDOW_SAMPLES} are "
            f"needed: give a longer record (at least {windows * shortest:.6g} s) or fewer windows")
    return window


#: Largest |acceleration| [m/s^2] a fit accepts: the least-squares loss sums squares of
#: residuals, which must stay far below the float64 maximum (1.8e308) for a million samples.
MAX_ABS_DATA = 1e100


def _check_data(y_rec, where: str, column: str = DEFAULT_COLUMN, unit: str = "m/s^2"):
    """:class:`~jaxclear.FitDataError` for data a least-squares fit cannot treat honestly: non-finite values,
    magnitudes beyond :data:`MAX_ABS_DATA`, or a record without any signal (all zero)."""
    bad = ~np.isfinite(y_rec)
    if bad.any():
        raise FitDataError(f"{where}: {column} holds {int(bad.sum())} non-finite value(s) "
                           f"(first at sample {int(np.argmax(bad))}); remove or interpolate them")
    peak = float(np.max(np.abs(y_rec))) if y_rec.size else 0.0
    if peak > MAX_ABS_DATA:
        raise FitDataError(f"{where}: |{column}| reaches {peak:g} {unit}, beyond the allowed "
                           f"{MAX_ABS_DATA:g} {unit} (check the units or the scale of the record)")
    if peak == 0.0:
        raise FitDataError(f"{where}: {column} is zero everywhere: there is nothing to fit")


def build_problem(data, mech: Mechanism, free: Sequence[str], start: dict | None, sensor: Accelerometer | None,
                  window, windows: int, horizons, coarse, starts: int, settings: dict, channels=None,
                  start_state: str = "known", integration: Settings | None = None) -> FitProblem:
    """Check the inputs (ParameterError before any compilation) and build the :class:`FitProblem`.
    ``settings``: max_iter, ftol, xtol, rtol, atol, max_steps, align, time_offset, optimizer;
    ``integration``: the model's settings (:func:`model_settings`; default: ``Settings`` with
    the ``rtol`` and ``atol`` of ``settings``);
    ``channels``: record column -> channel spec (:mod:`.targets`; None: the slider acceleration);
    ``start_state``: one of :data:`START_STATES`."""
    if start_state not in START_STATES:
        raise ParameterError(f"start_state = {start_state!r}; valid: {', '.join(map(repr, START_STATES))} ('free': "
                             "a record that begins mid-run, the state at every window's start unknown)")
    anywhere = start_state == "free"
    sensor = Accelerometer() if sensor is None else sensor
    targets = resolve_targets(mech, channels, sensor)
    columns = tuple(c for c, _ in targets)
    meas = read_record(data, columns)
    start = dict(start or {})
    free = check_free(mech, free, start)
    _check_mechanism(mech, windows)
    starts_free = [n for n in free if n.split("@")[0] in START_PARAMETERS]
    if starts_free:
        raise ParameterError(
            f"free parameter(s) {starts_free} are the force element's start state, which every fit window sets itself "
            "(the mechanism's start for a record that begins at start-up); a record that begins mid-run: "
            "start_state='free' (--start-state free) fits the state at every window's start")
    crank_free = [n for n in free if n in CRANK_PARAMETERS]
    if crank_free and crank_driver(mech) is None:
        raise ParameterError(f"free parameter(s) {crank_free} need a crank (an AngleDriver); the mechanism has none")
    horizons = check_plan(windows, horizons, starts, coarse)
    crank = crank_driver(mech)
    speed = float(crank[1].speed) if crank is not None else 0.0
    angle0 = float(crank[1].angle0) if crank is not None else 0.0
    t_rec = record_times(meas, settings["align"], speed=speed if crank else None, angle0=angle0,
                         time_offset=settings["time_offset"])
    y_rec = np.stack([np.asarray(meas.columns[c], dtype=float) for c in columns])
    dt = uniform_spacing(t_rec)
    h = dt / sensor.oversample
    where = meas.path or "the record"
    for (column, fc), y in zip(targets, y_rec):
        _check_data(y, where, column, named_unit(mech, fc.channel))
    window = _window_length(mech, window, windows, float(t_rec[-1]), dt, h, len(t_rec), t_rec, where)
    cutoffs = [fc.sensor.cutoff_hz for _, fc in targets if fc.sensor.cutoff_hz is not None]
    settle = 2.0 / min(cutoffs) if cutoffs else 0.0
    win = cut_windows(t_rec, y_rec, dt, windows, window, settle, horizons, where, columns, settle_first=anywhere)
    values0 = start_values(mech, sensor, free, start)
    z0 = z_vector(free, values0, win.scale, mech)
    velocity_scale = abs(speed) if speed else 1.0 / window
    n_fine = int(round(window / h))
    base = integration if integration is not None else dataclasses.replace(
        default_settings(), rtol=settings["rtol"], atol=settings["atol"])
    s = dataclasses.replace(model_settings(base, anywhere, settings["max_steps"]),
                            t_end=jnp.asarray(n_fine * h, dtype=float), n_out=n_fine + 1)
    model = WindowModel(mech=mech, sensors=tuple(fc.sensor for _, fc in targets),
                        weights=jnp.asarray([fc.weight for _, fc in targets], dtype=float), settings=s,
                        bias_scale=jnp.asarray(win.scale), velocity_scale=jnp.asarray(velocity_scale), free=free,
                        channels=tuple(fc.channel for _, fc in targets),
                        driver=crank[0] if crank is not None else None, h=h, anywhere=anywhere)
    start_scales = [np.asarray(j.start_scale(), dtype=float) for j in mech.clearance_joints]
    guess0 = tuple(np.asarray(a) for a in mech.guess())
    window_guesses = ()
    if anywhere:  # found by the way in (.way_in); the guesses of the ideal assembly at each window's crank angle
        state0 = np.zeros(state_size(mech, True))
        window_guesses = tuple(crank_guesses(mech, crank[0], [angle0 + speed * t for t in win.starts])
                               if crank is not None else [guess0] * windows)
    else:
        state0 = state_to_z(np.concatenate([np.concatenate([np.asarray(j.initial_offset),
                                                            np.asarray(j.initial_velocity)])
                                            for j in mech.clearance_joints]), start_scales, velocity_scale)
    settings = dict(settings, coarse=coarse, dt=dt)
    problem = FitProblem(meas, t_rec, y_rec, mech, sensor, targets, free, values0, fixed_values(mech, sensor, free), z0,
                         [], model, win, [], horizons, state0, guess0, start_scales, velocity_scale, angle0, speed,
                         json.loads(json.dumps(settings, default=str)), anywhere, window_guesses).with_starts(starts)
    _check_stage_samples(problem, where)
    return problem


def _check_stage_samples(problem: FitProblem, where: str):
    """A :class:`~jaxclear.FitDataError` before any compilation for a stage that would fit no
    record sample (a partial horizon of a window that the record's samples do not reach, for
    example with ``align="crank"`` when the record's first sample maps to a late simulation
    time): it names the stage, the window's span and where the record's samples lie."""
    win = problem.win
    for stage in problem.stages:
        if sum(float(win.mask(k, stage.horizon).sum()) for k in stage.windows) > 0:
            continue
        k = stage.windows[0]
        end = win.cuts.get((k, stage.horizon), stage.horizon * win.length)
        raise FitDataError(
            f"{where}: stage {stage.name!r} fits no sample of the record: window {k + 1} spans simulation time "
            f"{win.starts[k]:.6g} to {win.starts[k] + end:.6g} s there, and the record's samples lie at "
            f"{problem.t_rec[0]:.6g} to {problem.t_rec[-1]:.6g} s (align={problem.settings['align']!r}); give a longer "
            "window or horizons (window=..., --window), align='time', or a record that covers the windows")
