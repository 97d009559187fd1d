"""The fit problem: the checked inputs, the record on the simulation clock cut into windows, the
window model, the start values and the plan, built once before any compilation."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import FitDataError, ParameterError
from ..model import FunctionDriver, Mechanism, crank_driver, crank_period
from ..analysis.sensor import Accelerometer, record_times, uniform_spacing
from ..integrate import settings as make_settings
from .parameters import check_free, fixed_values, start_values, z_vector
from .plan import Stage, check_plan, plan_stages, spread_starts
from .records import read_record, slider_role
from .state import checkpoint_key
from .window import WindowInput, WindowModel, WindowSet, cut_windows, state_to_z


@dataclass(frozen=True)
class FitProblem:
    """Everything fixed during a fit (see :func:`build_problem`)."""

    meas: object
    t_rec: np.ndarray
    y_rec: np.ndarray
    mech: Mechanism
    sensor: Accelerometer
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
    clearances: list
    velocity_scale: float
    angle0: float
    speed: float
    settings: dict

    @property
    def windows(self) -> int:
        return len(self.win.starts)

    def window_input(self, k: int, horizon: float, integrate: bool, guesses) -> WindowInput:
        """Window ``k``'s input; its crank starts at ``angle0 + omega t_k`` [rad]."""
        return self.win.window_input(k, horizon, integrate, self.angle0 + self.speed * self.win.starts[k], guesses[k])

    def checkpoint_config(self) -> dict:
        s = dict(self.settings)
        return dict(free=self.free, start=self.values0, window=self.win.length, windows=self.windows,
                    horizons=self.horizons, starts=s["starts"], coarse=s["coarse"], max_iter=s["max_iter"],
                    ftol=s["ftol"], xtol=s["xtol"], rtol=s["rtol"], atol=s["atol"], align=s["align"],
                    time_offset=s["time_offset"], sensor=self.sensor.describe(), oversample=self.sensor.oversample,
                    optimizer=s["optimizer"], mechanism=str(jax.tree_util.tree_structure(self.mech)))

    def checkpoint_key(self) -> str:
        leaves = [np.ravel(np.asarray(x, dtype=float)) for x in jax.tree_util.tree_leaves((self.mech, self.sensor))]
        return checkpoint_key(self.t_rec, self.y_rec, np.concatenate(leaves), self.checkpoint_config())


def _check_mechanism(mech: Mechanism, windows: int):
    slider_role(mech)
    if not mech.clearance_joints:
        raise ParameterError(f"mechanism {mech.name!r} has no clearance joint: nothing to identify")
    if windows > 1:
        if crank_driver(mech) is None or any(isinstance(d, FunctionDriver) for d in mech.drivers) or any(
                getattr(ld, "function", None) is not None for ld in mech.loads):
            raise ParameterError(
                "windows > 1 needs a mechanism whose only time dependence is an AngleDriver (the windows are "
                "simulated from t = 0 with the crank angle advanced)"
            )


def _window_length(mech, window, windows: int, span: float, dt: float, h: float, n_samples: int, t_rec, where):
    """The window length [s], a whole number of fine steps ``h``; checks the record covers it."""
    if window is None:
        window = 0.25 * crank_period(mech) if crank_driver(mech) is not None else span / windows
    if not window > 0:
        raise ParameterError(f"window = {window!r} s must be > 0")
    window = int(round(window / h)) * h
    needed = windows * window
    if span + 0.5 * dt < needed or np.count_nonzero((t_rec >= 0) & (t_rec <= window)) < 4:
        raise ParameterError(
            f"{where}: the record covers {max(span, 0.0):.6g} s of simulation time ({n_samples} samples) but "
            f"{windows} window(s) of {window:.6g} s need {needed:.6g} s (record shorter than the fit windows); give a "
            "shorter window (window=..., --window S) or fewer windows"
        )
    return window


#: Largest |acceleration| [m/s^2] a fit accepts: the least-squares loss sums squares of
#: residuals, which must stay far below the float64 maximum (1.8e308) for a million samples.
MAX_ABS_DATA = 1e100


def _check_data(y_rec, where: str):
    """:class:`~jaxclear.FitDataError` for data a least-squares fit cannot treat honestly: non-finite values,
    magnitudes beyond :data:`MAX_ABS_DATA`, or a record without any signal (all zero)."""
    bad = ~np.isfinite(y_rec)
    if bad.any():
        raise FitDataError(f"{where}: slider_acc_m_s2 holds {int(bad.sum())} non-finite value(s) "
                             f"(first at sample {int(np.argmax(bad))}); remove or interpolate them")
    peak = float(np.max(np.abs(y_rec))) if y_rec.size else 0.0
    if peak > MAX_ABS_DATA:
        raise FitDataError(f"{where}: |slider_acc_m_s2| reaches {peak:g} m/s^2, beyond the allowed "
                             f"{MAX_ABS_DATA:g} m/s^2 (check the units or the scale of the record)")
    if peak == 0.0:
        raise FitDataError(f"{where}: slider_acc_m_s2 is zero everywhere: there is nothing to fit")


def build_problem(data, mech: Mechanism, free: Sequence[str], start: dict | None, sensor: Accelerometer | None,
                  window, windows: int, horizons, coarse, starts: int, settings: dict) -> FitProblem:
    """Check the inputs (ParameterError before any compilation) and build the :class:`FitProblem`.
    ``settings``: max_iter, ftol, xtol, rtol, atol, max_steps, align, time_offset, optimizer."""
    meas = read_record(data)
    sensor = Accelerometer() if sensor is None else sensor
    start = dict(start or {})
    free = check_free(mech, free, start)
    _check_mechanism(mech, windows)
    horizons = check_plan(windows, horizons, starts, coarse)
    crank = crank_driver(mech)
    speed = float(crank[1].speed) if crank is not None else 0.0
    angle0 = float(crank[1].angle0) if crank is not None else 0.0
    t_rec = record_times(meas, settings["align"], speed=speed if crank else None, angle0=angle0,
                         time_offset=settings["time_offset"])
    y_rec = np.asarray(meas.slider_acc_m_s2, dtype=float)
    dt = uniform_spacing(t_rec)
    h = dt / sensor.oversample
    where = meas.path or "the record"
    _check_data(y_rec, where)
    window = _window_length(mech, window, windows, float(t_rec[-1]), dt, h, len(t_rec), t_rec, where)
    settle = 2.0 / sensor.cutoff_hz if sensor.cutoff_hz is not None else 0.0
    win = cut_windows(t_rec, y_rec, dt, windows, window, settle, horizons, where)
    values0 = start_values(mech, sensor, free, start)
    z0 = z_vector(free, values0, win.scale)
    velocity_scale = abs(speed) if speed else 1.0 / window
    n_fine = int(round(window / h))
    s = make_settings(n_fine * h, n_out=n_fine + 1, rtol=settings["rtol"], atol=settings["atol"], adjoint="forward",
                      throw=False, max_steps=settings["max_steps"])
    model = WindowModel(mech=mech, sensor=sensor, settings=s, bias_scale=jnp.asarray(win.scale),
                        velocity_scale=jnp.asarray(velocity_scale), free=free, slider=slider_role(mech),
                        driver=crank[0] if crank is not None else None, h=h)
    clearances = [float(j.clearance) for j in mech.clearance_joints]
    state0 = state_to_z(np.concatenate([np.concatenate([np.asarray(j.initial_offset), np.asarray(j.initial_velocity)])
                                        for j in mech.clearance_joints]), clearances, velocity_scale)
    guess0 = tuple(np.asarray(a) for a in mech.guess())
    stages: list[Stage] = plan_stages(windows, horizons, starts, coarse)
    settings = dict(settings, starts=starts, coarse=coarse, dt=dt)
    return FitProblem(meas, t_rec, y_rec, mech, sensor, free, values0, fixed_values(mech, sensor, free), z0,
                      spread_starts(z0, free, starts), model, win, stages, horizons, state0, guess0, clearances,
                      velocity_scale, angle0, speed, json.loads(json.dumps(settings, default=str)))
