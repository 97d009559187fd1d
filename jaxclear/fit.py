r"""Identification of contact parameters from a measured slider acceleration
(``jaxclear.fit`` and ``jaxclear fit DATA.csv``). The module is callable:
``jaxclear.fit(data, mech, ...)`` is :func:`fit`.

The problem
-----------
A record (spec section 8) holds the slider acceleration of a mechanism whose clearance joint
rattles. The model is :func:`jaxclear.simulate` of a preset with some parameters free
(default ``stiffness`` and ``restitution``), seen through the accelerometer model of
:mod:`jaxclear.sensor` (low-pass, gain, bias). The record is *chaotic*: at 5000 rpm two
trajectories of the Flores benchmark that differ by 1e-9 in restitution separate visibly after
a few milliseconds, so a least-squares loss on a long record is a landscape of narrow local
minima in which no optimiser finds the truth, and its gradient is dominated by the timing of
late impacts that no parameter controls smoothly.

The loss (the choice, and why)
------------------------------
What *is* deterministic is the start: the preset starts from a known state (crank angle 0,
journal centred, velocities from the ideal kinematics) at the first sample, and the first
impacts follow from it and from the parameters alone. So the loss is a least-squares misfit of
the sensor signal on **short windows**:

* **window 0** starts from that known state and has no extra unknowns. Its length is
  ``window`` seconds (default a quarter of a crank revolution: 3 ms and about 7 impacts at
  5000 rpm, 75 ms and about 9 impacts at 200 rpm).
* **windows 1..W-1** (``windows=W``, optional) follow it back to back; each starts from a
  journal state that is *not* known: the journal's offset in the bearing (2) and its velocity
  relative to the bearing (4 numbers per clearance joint) are extra unknowns of the fit
  (multiple shooting without continuity constraints: every window re-anchors the chaotic
  trajectory on the data). The rest of the start state follows from the constraints and the
  driver. Window ``k`` is simulated from ``t = 0`` with the crank's start angle advanced by
  ``omega k T_w`` (so the mechanism's only time dependence must be its :class:`AngleDriver`),
  and the first ``2 / f_c`` seconds of its samples are left out, because the sensor filter's
  history before the window is unknown.
* **continuation in the horizon**: a 3x error in stiffness moves the later impacts of even a
  3 ms window by more than their width, and the loss of the whole window is then non-convex.
  So every window is first fitted on the first quarter of its samples, then the first half,
  then all of them (``horizons``), each stage starting from the previous estimate; a partial
  horizon ends at the quietest record sample within the next 10 % of the window, so that it
  does not cut an impact in half. On the benchmark record the loss restricted to the first
  0.75 ms is unimodal over stiffness [1/3, 3] x true and restitution [0.5, 0.99].
* **continuation in the signal** (``coarse="velocity"``, default): impacts are spikes a few
  samples wide; when the model's spike sits beside the measured one, the squared difference
  does not tell which way to move (at 200 rpm the restitution landscape of the acceleration
  loss has a local minimum 0.1 from the truth even over two impacts). The integral of the
  acceleration (the slider's velocity change) turns each spike into a step, whose misfit
  grows smoothly with the timing error. So the first stage of every window fits the running
  integral of the residual, and the later stages the acceleration itself (which carries the
  stiffness, through the spike shapes). Without this stage the Flores 2011 rig fit from 3x
  stiffness and restitution 0.6 ends at (0.6 x stiffness, 0.32); with it at the truth.
* The residual is ``(model - measured) / rms(measured)`` at the record's samples, so the
  reported ``loss`` (its mean square over the fitted samples) is the normalised misfit: about
  ``10**(-SNR/10)`` (0.01 at 20 dB) for an exact model, larger with a model error.

Per-revolution statistics (peak or RMS acceleration per revolution) were rejected as the
default: they are robust to chaos but mix stiffness and restitution into a few numbers, are
biased by the sensor bandwidth, and have no simple noise model for the uncertainty.

The optimiser
-------------
The fit minimises ``0.5 |r(z)|^2`` over unconstrained coordinates ``z`` (the transforms of
:mod:`jaxclear.params`: ``log`` stiffness, clearance, friction, masses; ``logit``
restitution; plus ``sensor_gain`` (log) and ``sensor_bias`` (scaled by the data RMS)).
The residual Jacobian ``dr/dz`` is computed in **forward mode** (``jax.jacfwd`` through
diffrax with ``adjoint="forward"``): there are a handful of columns and hundreds of rows, so
forward mode costs about one simulation per column while reverse mode would cost one
backward pass per row.

The default optimiser is :func:`levenberg_marquardt`, a Levenberg-Marquardt step (Gauss-Newton
with Marquardt's diagonal damping and Nielsen's damping update) written as an optax
``GradientTransformationExtraArgs``: it receives the gradient ``J^T r`` like any optax
transformation and, as extra arguments, the Jacobian, the residual and a ``value_fn`` to
accept or reject its step. On the benchmark it converges in about 15 iterations in all.
Any first-order optax optimiser may be passed instead (``optimizer=optax.adam(0.02)`` or
``"adam:0.05"``): it is given the same gradient ``J^T r`` and ignores the extra arguments. It
is not a good choice here: on the acceptance problem adam (learning rate 0.05) had not reached
the truth after 300 iterations (stiffness still 45 % off; ``benchmarks/bench_fit.py --adam``),
where Levenberg-Marquardt needs 14. The Gauss-Newton matrix is what makes the fit converge, so
it is the default rather than an optional polish. L-BFGS from optax is not supported (its
line search needs a traceable ``value_fn``; each value here is a simulation driven from Python).

Stopping: per stage, at most ``max_iter`` iterations (intermediate horizons ``max_iter // 2``);
a stage ends when an accepted step lowers the loss by less than ``ftol`` (relative; 1e-3 for
intermediate horizons), when the largest step in ``z`` is below ``xtol``, or when
Levenberg-Marquardt cannot find a decreasing step (damping above 1e10).

Several starts: ``starts=N`` fits the first (shortest) horizon of window 0 from ``N`` starts
(the given one and ``N - 1`` others spread deterministically by +-log 3 in the log
parameters and +-1 in logit restitution around it) and continues from the best.

Uncertainty
-----------
At the optimum, with all windows and all samples, ``sigma^2 = |r|^2 / (N - P)`` (residual in
m/s^2, ``N`` samples, ``P`` unknowns including the window states) and
``Cov(z) = sigma^2 (J^T J)^{-1}`` (Gauss-Newton approximation of the Fisher information for
white Gaussian noise); the standard deviation of each parameter follows by the delta method,
``std(theta) = |d theta / d z| std(z)``. This is honest only if the residual is white noise:
``fit.json`` reports the lag-1 autocorrelation of the residuals (about 0 for white noise;
near 1 when the model cannot reproduce the data, e.g. a different contact law), and the fit
warns when it exceeds 0.3, because then the std understates the error.

Resuming
--------
With ``out`` given, the state of the fit (stage, iteration, unknowns, optimiser state,
history) is written to ``out/fit_checkpoint.json`` after every iteration, keyed by a
fingerprint of the data and of every setting. A fit started again with the same inputs resumes
where it stopped; other inputs start afresh.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import sys
import time
import types
import warnings
from dataclasses import dataclass, field
from typing import Callable, NamedTuple, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from . import io, params
from .elements import kinematics
from ._errors import JaxclearError, ParameterError
from .model import AngleDriver, FunctionDriver, Mechanism
from .analysis.sensor import Accelerometer, record_times, uniform_spacing
from .integrate import Settings, jit, settings as make_settings, simulate
from .model import crank_period

#: Free parameters by default.
DEFAULT_FREE = ("stiffness", "restitution")
#: Parameters of the sensor that may be fitted besides the mechanism's (see :mod:`jaxclear.params`).
SENSOR_PARAMETERS = {
    "sensor_gain": ("-", 0.0, None, "log", "accelerometer gain"),
    "sensor_bias": ("m/s^2", None, None, "scaled", "accelerometer bias"),
}
#: Default horizons of the continuation, as fractions of the window.
DEFAULT_HORIZONS = (0.25, 0.5, 1.0)
#: Offset of a window's start state as a fraction of the clearance: the map keeps it inside.
_OFFSET_RADIUS = 1.0
CHECKPOINT_NAME = "fit_checkpoint.json"
AUTOCORRELATION_WARNING = 0.3


# --------------------------------------------------------------------------------------
# Parameter names and transforms
# --------------------------------------------------------------------------------------


def _check_name(mech: Mechanism, name: str):
    """Raise a ParameterError naming ``name`` unless it is a parameter of ``mech`` or of the sensor."""
    if name in SENSOR_PARAMETERS:
        return
    try:
        params._accessor(mech, name)
    except JaxclearError as err:
        raise ParameterError(
            f"free parameter {name!r} does not exist: {err}; fit parameters are the names of "
            f"jaxclear.params ({', '.join(params.parameter_names())}) and {', '.join(SENSOR_PARAMETERS)}"
        ) from None


def _transform(name: str) -> str:
    if name in SENSOR_PARAMETERS:
        return SENSOR_PARAMETERS[name][3]
    return params.info(name).transform


def _current_value(mech: Mechanism, sensor: Accelerometer, name: str) -> float:
    if name == "sensor_gain":
        return float(sensor.gain)
    if name == "sensor_bias":
        return float(sensor.bias)
    try:
        value = params.get(mech, name)
    except AttributeError:  # params.get assumes stiffness_for() on every law with a 'stiffness' leaf
        value = params._accessor(mech, name)[1](mech)
    if value is None:  # laws whose stiffness is derived lazily (cylindrical: modulus; hybrid: K_f)
        base, k, _ = params._split(name)
        law = mech.clearance_joints[k].law
        if hasattr(law, "modulus_value"):
            value = law.modulus_value()
        elif getattr(law, "stiffness_field", "") == "foundation_modulus":
            from .contact.hybrid import foundation_modulus

            value = foundation_modulus(law.journal_material)
        if value is None:
            raise ParameterError(f"parameter {name!r} has no value in the mechanism; give a start value for it")
    return float(value)


def _check_start(mech: Mechanism, name: str, value: float):
    """Range check of a start value, including the fit transform's open bounds."""
    if name in SENSOR_PARAMETERS:
        unit, low, high, transform, _ = SENSOR_PARAMETERS[name]
        if not math.isfinite(value):
            raise ParameterError(f"start value of {name!r} must be finite, got {value!r}")
        if low is not None and not value > low:
            raise ParameterError(f"start value {name} = {value:g} is outside its bounds ({low:g}, inf)")
        return
    try:
        params.validate(mech, name, value)
    except ParameterError as err:
        raise ParameterError(f"start value of {name!r} is outside its bounds: {err}") from None
    t = params.info(name).transform
    if t == "log" and not value > 0:
        raise ParameterError(
            f"start value {name} = {value:g} is on the bound 0 of (0, inf); the fit's log parameterization "
            "needs a positive value"
        )
    if t == "logit" and not 0 < value < 1:
        raise ParameterError(
            f"start value {name} = {value:g} is outside (0, 1), the open interval the fit's logit "
            "parameterization covers"
        )


def to_z(name: str, value, scale: float = 1.0):
    """Unconstrained coordinate of a parameter value (``scale`` for ``sensor_bias``)."""
    t = _transform(name)
    if t == "scaled":
        return jnp.asarray(value, dtype=float) / scale
    if name in SENSOR_PARAMETERS:
        return jnp.log(jnp.asarray(value, dtype=float))
    return params.to_unconstrained(name, value)


def from_z(name: str, z, scale: float = 1.0):
    """Inverse of :func:`to_z`."""
    t = _transform(name)
    if t == "scaled":
        return z * scale
    if name in SENSOR_PARAMETERS:
        return jnp.exp(z)
    return params.from_unconstrained(name, z)


def _dvalue_dz(name: str, z: float, scale: float) -> float:
    return float(jax.grad(lambda zz: from_z(name, zz, scale))(jnp.asarray(z, dtype=float)))


# --------------------------------------------------------------------------------------
# Synthetic records (tests, notebook, benchmark)
# --------------------------------------------------------------------------------------


def sensor_signal(mech: Mechanism, t_end: float, sample_rate_hz: float, sensor: Accelerometer | None = None,
                  rtol: float = 1e-10, atol: float = 1e-13, max_steps: int = 400_000):
    """Noise-free sensor output of the slider acceleration: ``(t, acc, crank_angle)`` at
    ``sample_rate_hz`` on ``[0, t_end]``, simulated ``sensor.oversample`` times finer and filtered
    (:class:`jaxclear.analysis.sensor.Accelerometer`)."""
    sensor = Accelerometer() if sensor is None else sensor
    slider = _slider(mech)
    n = int(round(t_end * sample_rate_hz))
    h = 1.0 / (sample_rate_hz * sensor.oversample)
    s = make_settings(n * sensor.oversample * h, n_out=n * sensor.oversample + 1, rtol=rtol, atol=atol,
                      max_steps=max_steps)
    sol = simulate(mech, s)
    acc = sensor(h, sol.coordinate(mech, slider, "x", derivative=2))
    crank = mech.role("crank")
    angle = sol.coordinate(mech, crank, "phi") if crank is not None else None
    k = slice(None, None, sensor.oversample)
    t = np.asarray(sol.ts)[k]
    return t, np.asarray(acc)[k], (None if angle is None else np.asarray(angle)[k])


def synthetic_record(mech: Mechanism, t_end: float, sample_rate_hz: float, sensor: Accelerometer | None = None,
                     snr_db: float | None = 20.0, seed: int = 0, path=None, rtol: float = 1e-10,
                     atol: float = 1e-13, metadata: dict | None = None) -> io.Measurements:
    """A record made by jaxclear: the sensor signal of :func:`sensor_signal` plus white Gaussian
    noise at ``snr_db`` (``10 log10(mean(signal^2) / sigma^2)``; None for none), with the true
    crank angle column. Written as a spec-section-8 CSV (with ``#`` metadata lines naming the true
    parameters) when ``path`` is given."""
    t, acc, angle = sensor_signal(mech, t_end, sample_rate_hz, sensor, rtol=rtol, atol=atol)
    sigma = 0.0
    if snr_db is not None:
        sigma = float(np.sqrt(np.mean(acc**2) / 10 ** (snr_db / 10)))
        acc = acc + np.random.default_rng(seed).normal(0.0, sigma, acc.shape)
    meta = {"source": f"jaxclear.fit.synthetic_record, mechanism {mech.name}", "snr_db": snr_db,
            "noise_sigma_m_s2": sigma, "sensor": (sensor or Accelerometer()).describe(), "seed": seed}
    if mech.clearance_joints:
        for name in ("stiffness", "restitution", "clearance", "friction"):
            try:
                meta[f"true_{name}"] = _current_value(mech, Accelerometer(), name)
            except (ParameterError, AttributeError):
                pass
    meta.update(metadata or {})
    meas = io.Measurements(time_s=t, slider_acc_m_s2=acc, crank_angle_rad=angle, metadata=meta,
                           path=os.fspath(path) if path is not None else "")
    if path is not None:
        write_measurements(path, meas)
    return meas


def write_measurements(path, meas: io.Measurements) -> str:
    """Write a record in the format of spec section 8 (``# key: value`` lines, header, rows)."""
    cols = {name: getattr(meas, name) for name in meas.columns}
    with open(os.fspath(path), "w", encoding="utf-8") as f:
        for key, value in meas.metadata.items():
            f.write(f"# {key}: {value}\n")
        f.write(",".join(cols) + "\n")
        np.savetxt(f, np.column_stack(list(cols.values())), delimiter=",", fmt="%.12g")
    return os.fspath(path)


# --------------------------------------------------------------------------------------
# The optax Levenberg-Marquardt transformation
# --------------------------------------------------------------------------------------


class LMState(NamedTuple):
    """State of :func:`levenberg_marquardt`: the damping ``mu`` and the factor ``nu`` by which it
    grows after a rejected step (Nielsen)."""

    damping: jax.Array
    nu: jax.Array


class LevenbergMarquardt(optax.GradientTransformationExtraArgs):
    """The optax transformation returned by :func:`levenberg_marquardt` (a marker subclass)."""


def levenberg_marquardt(damping: float = 1e-3, max_tries: int = 12, max_damping: float = 1e10,
                        extrapolate: int = 3, max_step: float = 1.5) -> LevenbergMarquardt:
    r"""Levenberg-Marquardt as an optax transformation.

    ``update(grad, state, params, *, jacobian, residual, value_fn)`` returns the step
    :math:`-(J^TJ + \mu\,\mathrm{diag}(J^TJ))^{-1} J^T r` for the smallest damping ``mu`` (tried
    from the state's, growing by ``nu``, ``nu`` doubling) whose trial point lowers
    ``value_fn(params + step)`` (``0.5 |r|^2``); the damping then shrinks by Nielsen's factor
    ``max(1/3, 1 - (2 rho - 1)^3)`` (``rho``: actual over predicted decrease). An accepted step is
    then doubled up to ``extrapolate`` times while the value keeps decreasing: in the curved
    valleys of impact-timing misfits the Gauss-Newton step is much shorter than the way to the
    minimum (on the benchmark this halves the iterations from a 3x stiffness error). No step
    (extended or not) exceeds ``max_step`` in any coordinate (a trust region in the transformed
    parameters: 1.5 is a factor 4.5 in a log parameter), so a parameter the data do not yet
    constrain cannot run off. If no step within
    ``max_tries`` (or below ``max_damping``) decreases the value, the update is zero and the
    damping is left above ``max_damping``, which the fit reads as convergence/stall.
    The step is computed in NumPy and ``value_fn`` is called from Python: do not ``jit`` it.
    """

    def init(params_):
        return LMState(jnp.asarray(damping, dtype=float), jnp.asarray(2.0))

    def update(updates, state, params_=None, *, jacobian=None, residual=None, value_fn=None, **_):
        if jacobian is None or residual is None or value_fn is None or params_ is None:
            raise ValueError("levenberg_marquardt needs params and the extra arguments jacobian, residual, value_fn")
        J = np.asarray(jacobian, dtype=float)
        r = np.asarray(residual, dtype=float)
        z = np.asarray(params_, dtype=float)
        jtj = J.T @ J
        g = J.T @ r
        value0 = 0.5 * float(r @ r)
        diag = np.maximum(np.diag(jtj), 1e-12 * max(float(np.max(np.diag(jtj))), 1e-300))
        mu, nu = float(state.damping), float(state.nu)
        for _ in range(max_tries):
            if mu > max_damping:
                break
            try:
                step = -np.linalg.solve(jtj + mu * np.diag(diag), g)
            except np.linalg.LinAlgError:
                mu, nu = mu * nu, 2.0 * nu
                continue
            if not np.all(np.isfinite(step)):
                mu, nu = mu * nu, 2.0 * nu
                continue
            largest = float(np.max(np.abs(step))) if step.size else 0.0
            if largest > max_step:
                step = step * (max_step / largest)
            value = float(value_fn(jnp.asarray(z + step)))
            predicted = -(g @ step + 0.5 * step @ jtj @ step)
            if math.isfinite(value) and value < value0 and predicted > 0:
                rho = (value0 - value) / predicted
                mu = mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                # along a curved valley the Gauss-Newton step is short: extend it while that helps
                best = step
                for _ in range(extrapolate):
                    trial = 2.0 * best
                    if float(np.max(np.abs(trial))) > max_step:
                        break
                    v = float(value_fn(jnp.asarray(z + trial)))
                    if not (math.isfinite(v) and v < value):
                        break
                    best, value = trial, v
                if best is not step:
                    value_fn(jnp.asarray(z + best))  # leave the accepted point last (evaluation cache)
                return jnp.asarray(best), LMState(jnp.asarray(max(mu, 1e-12)), jnp.asarray(2.0))
            mu, nu = mu * nu, 2.0 * nu
        return jnp.zeros_like(jnp.asarray(z)), LMState(jnp.asarray(max(mu, 2 * max_damping)), jnp.asarray(nu))

    return LevenbergMarquardt(init, update)


# --------------------------------------------------------------------------------------
# The model of one window
# --------------------------------------------------------------------------------------


def _slider(mech: Mechanism) -> str:
    slider = mech.role("slider")
    if slider is None:
        raise ParameterError(
            f"mechanism {mech.name!r} has no 'slider' role: the measured signal (slider_acc_m_s2) has "
            "nothing to compare with"
        )
    return slider


def _angle_driver(mech: Mechanism) -> int | None:
    for i, d in enumerate(mech.drivers):
        if isinstance(d, AngleDriver):
            return i
    return None


class WindowInput(eqx.Module):
    """Arrays describing one window (all leaves, so windows share one compiled function)."""

    angle0: jax.Array  # crank start angle of the window [rad]
    guess_q: jax.Array  # position guess of the bodies at the window start
    guess_qd: jax.Array
    t_rel: jax.Array  # record sample times relative to the window start (n_pad,)
    data: jax.Array  # measured values (n_pad,)
    mask: jax.Array  # 1 for fitted samples, 0 else (n_pad,)
    scale: jax.Array  # normalisation of the residual (RMS of the data)
    dts: jax.Array  # sample intervals (n_pad,), for the integrated residual
    integrate: jax.Array  # 1: residual of the integrated signal (velocity), 0: of the acceleration
    vscale: jax.Array  # normalisation of the integrated residual [m/s]


class WindowModel(eqx.Module):
    """Mechanism + sensor + settings of the windows; ``free`` names the parameters in ``theta_z``."""

    mech: Mechanism
    sensor: Accelerometer
    settings: Settings
    bias_scale: jax.Array
    velocity_scale: jax.Array
    free: tuple = eqx.field(static=True)
    slider: str = eqx.field(static=True)
    driver: int | None = eqx.field(static=True)
    h: float = eqx.field(static=True)

    def values(self, theta_z):
        return {n: from_z(n, theta_z[i], self.bias_scale) for i, n in enumerate(self.free)}

    def mechanism(self, theta_z, state_z, win: WindowInput):
        values = self.values(theta_z)
        mech = params.replace_many(self.mech, {n: v for n, v in values.items() if n not in SENSOR_PARAMETERS})
        if self.driver is not None:
            mech = eqx.tree_at(lambda m: m.drivers[self.driver].angle0, mech, win.angle0)
        n_b = len(mech.bodies)
        mech = eqx.tree_at(lambda m: [b.position for b in m.bodies], mech,
                           [win.guess_q[3 * i: 3 * i + 3] for i in range(n_b)])
        mech = eqx.tree_at(lambda m: [b.velocity for b in m.bodies], mech,
                           [win.guess_qd[3 * i: 3 * i + 3] for i in range(n_b)])
        offsets, velocities = [], []
        for k, joint in enumerate(mech.clearance_joints):
            u = state_z[4 * k: 4 * k + 2]
            c = joint.clearance
            offsets.append(c * _OFFSET_RADIUS * u / jnp.sqrt(1.0 + u @ u))
            velocities.append(self.velocity_scale * c * state_z[4 * k + 2: 4 * k + 4])
        if mech.clearance_joints:
            mech = eqx.tree_at(lambda m: [j.initial_offset for j in m.clearance_joints], mech, offsets)
            mech = eqx.tree_at(lambda m: [j.initial_velocity for j in m.clearance_joints], mech, velocities)
        return mech, values

    def signal(self, theta_z, state_z, win: WindowInput):
        """Sensor output at the window's samples, the end state, and the solver status."""
        mech, values = self.mechanism(theta_z, state_z, win)
        sol = simulate(mech, self.settings)
        acc = sol.coordinate(mech, self.slider, "x", derivative=2)
        gain = values.get("sensor_gain", self.sensor.gain)
        bias = values.get("sensor_bias", self.sensor.bias)
        y = gain * self.sensor.filter(self.h, acc) + bias
        y = jnp.interp(win.t_rel, sol.ts, y)
        q1, qd1 = sol.q[-1], sol.qdot[-1]
        end = []
        for joint in mech.clearance_joints:
            kin = kinematics(mech, joint, q1, qd1)
            end.append(jnp.concatenate([kin.ecc, kin.journal_velocity - kin.bearing_velocity]))
        end = jnp.concatenate(end) if end else jnp.zeros((0,), q1.dtype)
        return y, (q1, qd1, end, sol.status)


def _evaluate(model: WindowModel, theta_z, state_z, win: WindowInput):
    def f(theta_z, state_z):
        y, extra = model.signal(theta_z, state_z, win)
        err = win.mask * (y - win.data)
        r_velocity = win.mask * jnp.cumsum(err * win.dts) / win.vscale
        r = jnp.where(win.integrate > 0, r_velocity, err / win.scale)
        return r, (r, y, extra)

    (jt, js), (r, y, extra) = jax.jacfwd(f, argnums=(0, 1), has_aux=True)(theta_z, state_z)
    return r, jt, js, y, extra


_evaluate_jit = jit(_evaluate)


def _state_to_z(state: np.ndarray, clearance: Sequence[float], velocity_scale: float) -> np.ndarray:
    """Inverse of the window-state map of :meth:`WindowModel.mechanism` (offset clipped inside)."""
    out = []
    for k, c in enumerate(clearance):
        w = np.asarray(state[4 * k: 4 * k + 2]) / (c * _OFFSET_RADIUS)
        n = float(np.linalg.norm(w))
        if n >= 0.999:
            w = w * 0.999 / n
            n = 0.999
        out.append(w / math.sqrt(1.0 - n * n))
        out.append(np.asarray(state[4 * k + 2: 4 * k + 4]) / (velocity_scale * c))
    return np.concatenate(out) if out else np.zeros(0)


# --------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------


@dataclass
class FitResult:
    """What :func:`fit` found.

    Attributes:
        estimates, std, start: parameter name -> value (SI; std by the delta method, see the
            module docstring), and the start of the best run.
        loss: mean square of the normalised residual over the fitted samples (module docstring).
        iterations: optimiser iterations over all stages and starts.
        wall_time_s: wall time of the fit [s] (including compilation; summed over resumed runs).
        correlation: correlation matrix of the free parameters (list of lists, ``free`` order).
        noise_sigma_m_s2: residual standard deviation sigma [m/s^2]; residual_rms_m_s2: RMS.
        residual_autocorrelation: lag-1 autocorrelation of the residuals (about 0 when white).
        converged: whether the last stage stopped on a tolerance (not on ``max_iter``).
        history: one record per iteration (stage, loss, values).
        t, measured, fitted, initial: the fitted samples for the plot (times in simulation time,
            ``initial`` = the model at the start values), per window stacked; ``window_starts`` [s].
        free, fixed, settings, warnings: inputs and remarks, written to ``fit.json``.
    """

    estimates: dict
    std: dict
    loss: float
    iterations: int
    wall_time_s: float
    start: dict = field(default_factory=dict)
    correlation: list = field(default_factory=list)
    noise_sigma_m_s2: float = float("nan")
    residual_rms_m_s2: float = float("nan")
    residual_autocorrelation: float = float("nan")
    n_samples: int = 0
    n_unknowns: int = 0
    converged: bool = False
    stop_reason: str = ""
    history: list = field(default_factory=list)
    t: np.ndarray | None = None
    measured: np.ndarray | None = None
    fitted: np.ndarray | None = None
    initial: np.ndarray | None = None
    window_starts: list = field(default_factory=list)
    window_length_s: float = 0.0
    free: tuple = ()
    fixed: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    window_states: list = field(default_factory=list)
    window_losses: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """The content of ``fit.json``."""
        return {
            "estimates": self.estimates,
            "std": self.std,
            "loss": self.loss,
            "iterations": self.iterations,
            "wall_time_s": self.wall_time_s,
            "start": self.start,
            "fixed": self.fixed,
            "correlation": {"names": list(self.free), "matrix": self.correlation},
            "noise_sigma_m_s2": self.noise_sigma_m_s2,
            "residual_rms_m_s2": self.residual_rms_m_s2,
            "residual_lag1_autocorrelation": self.residual_autocorrelation,
            "n_samples": self.n_samples,
            "n_unknowns": self.n_unknowns,
            "converged": self.converged,
            "stop_reason": self.stop_reason,
            "window_starts_s": self.window_starts,
            "window_length_s": self.window_length_s,
            "window_losses": self.window_losses,
            "window_states": self.window_states,
            "settings": self.settings,
            "warnings": self.warnings,
            "loss_definition": "mean over the fitted samples of ((model - measured) / rms(measured))^2",
            "std_definition": "Gauss-Newton: sigma^2 (J^T J)^-1 in the transformed parameters, delta method back",
        }

    def write_json(self, path) -> str:
        return io.write_json(path, self.to_dict())

    def plot(self, path=None):
        """The fit plot (:func:`jaxclear.plot.plot_fit`)."""
        from .plot import plot_fit

        return plot_fit(path, self)


# --------------------------------------------------------------------------------------
# The fit
# --------------------------------------------------------------------------------------


class _Stage(NamedTuple):
    name: str
    windows: tuple  # window indices evaluated
    horizon: float  # fraction of the window
    theta: bool  # theta free
    states: tuple  # windows whose start state is free
    start: int  # index of the start (multi-start stages), -1 else
    final: bool
    integrate: bool = False  # residual of the integrated signal (coarse stage)


def _fingerprint(*items) -> str:
    h = hashlib.sha256()
    for item in items:
        if isinstance(item, np.ndarray):
            h.update(np.ascontiguousarray(item, dtype=float).tobytes())
        else:
            h.update(repr(item).encode())
    return h.hexdigest()[:20]


def _spread_starts(z0: np.ndarray, free: Sequence[str], n: int) -> list[np.ndarray]:
    """``n`` starts: ``z0`` and ``n - 1`` points around it (deterministic, alternating signs on a
    Halton-like sequence): +-log 3 for log parameters, +-1 for logit ones, +-0.1 data-RMS bias."""
    span = np.array([{"log": math.log(3.0), "logit": 1.0, "scaled": 0.1}.get(_transform(f), 0.1 * max(abs(z), 1.0))
                     for f, z in zip(free, z0)])
    out = [np.array(z0, dtype=float)]
    primes = [2, 3, 5, 7, 11, 13, 17, 19]
    for i in range(1, n):
        point = []
        for d in range(len(free)):
            p, f, x, k = primes[d % len(primes)], 1.0, 0.0, i
            while k:
                f /= p
                x += f * (k % p)
                k //= p
            point.append(2.0 * x - 1.0 if i > 1 else (1.0 if d % 2 == 0 else -1.0))
        out.append(z0 + span * np.array(point))
    return out


def fit(
    data,
    mech: Mechanism,
    free: Sequence[str] = DEFAULT_FREE,
    start: dict | None = None,
    *,
    sensor: Accelerometer | None = None,
    window: float | None = None,
    windows: int = 1,
    horizons: Sequence[float] = DEFAULT_HORIZONS,
    coarse: str | None = "velocity",
    starts: int = 1,
    optimizer: optax.GradientTransformation | str | None = None,
    max_iter: int = 30,
    ftol: float = 1e-6,
    xtol: float = 1e-5,
    rtol: float = 1e-8,
    atol: float = 1e-11,
    max_steps: int = 200_000,
    align: str = "time",
    time_offset: float = 0.0,
    out=None,
    resume: bool = True,
    progress: bool = True,
    callback: Callable | None = None,
) -> FitResult:
    """Fit the ``free`` parameters of ``mech`` to a measured slider acceleration (module docstring).

    Args:
        data: a :class:`jaxclear.io.Measurements` or the path of a spec-section-8 CSV.
        mech: the mechanism with every known value set (the free ones are replaced).
        free: names of the fitted parameters (:mod:`jaxclear.params` names, ``sensor_gain``,
            ``sensor_bias``); default stiffness and restitution.
        start: ``name: value`` start values (default: the mechanism's / sensor's values).
        sensor: the accelerometer model (default: no filter, gain 1, bias 0, oversample 4).
        window: window length [s] (default a quarter crank revolution, at most the record).
        windows: number of back-to-back windows; windows after the first have the journal
            state at their start as extra unknowns.
        horizons: fractions of the window fitted in turn (continuation), ending at 1.
        coarse: ``"velocity"`` (default): the first stage (and the first stage of every window's
            state) fits the integrated signal (module docstring); None: acceleration only.
        starts: number of starts for the first stage (see module docstring).
        optimizer: an optax transformation or a name for :func:`make_optimizer`; default
            :func:`levenberg_marquardt`.
        max_iter, ftol, xtol: stopping rules (module docstring).
        rtol, atol, max_steps: integration settings of the model (forward-mode Jacobians).
        align, time_offset: how record times map to simulation time
            (:func:`jaxclear.analysis.sensor.record_times`).
        out: folder for the checkpoint (``fit_checkpoint.json``); None: no checkpoint.
        resume: continue from a matching checkpoint in ``out``.
        progress: show a tqdm progress bar.
        callback: called as ``callback(record)`` after every iteration (record: dict).

    Raises:
        ParameterError: unknown free parameter, start value outside its bounds, record shorter
            than the windows, mechanism without a slider or a crank driver where one is needed.
    """
    t_wall = time.perf_counter()
    meas = io.read_measurements(data) if isinstance(data, (str, os.PathLike)) else data
    _check_record(meas)
    sensor = Accelerometer() if sensor is None else sensor
    free = tuple(free)
    if not free:
        raise ParameterError("no free parameter: give at least one name (e.g. stiffness)")
    if len(set(free)) != len(free):
        raise ParameterError(f"free parameters listed twice: {list(free)}")
    for name in free:
        _check_name(mech, name)
    start = dict(start or {})
    for name in start:
        if name not in free:
            raise ParameterError(f"start value given for {name!r}, which is not a free parameter (free: {list(free)})")
    slider = _slider(mech)
    if not mech.clearance_joints:
        raise ParameterError(f"mechanism {mech.name!r} has no clearance joint: nothing to identify")
    if windows < 1 or int(windows) != windows:
        raise ParameterError(f"windows = {windows!r} must be an integer >= 1")
    horizons = tuple(float(h) for h in horizons)
    if not horizons or any(not 0 < h <= 1 for h in horizons) or horizons[-1] != 1.0 or list(horizons) != sorted(horizons):
        raise ParameterError(f"horizons = {horizons} must increase within (0, 1] and end at 1")
    if starts < 1:
        raise ParameterError(f"starts = {starts!r} must be >= 1")
    driver = _angle_driver(mech)
    if windows > 1:
        if driver is None or any(isinstance(d, FunctionDriver) for d in mech.drivers) or any(
                getattr(ld, "function", None) is not None for ld in mech.loads):
            raise ParameterError(
                "windows > 1 needs a mechanism whose only time dependence is an AngleDriver (the windows are "
                "simulated from t = 0 with the crank angle advanced)"
            )

    # ---- record on the simulation clock --------------------------------------------------
    speed = float(mech.drivers[driver].speed) if driver is not None else None
    angle0 = float(mech.drivers[driver].angle0) if driver is not None else 0.0
    t_rec = record_times(meas, align, speed=speed, angle0=angle0, time_offset=time_offset)
    y_rec = np.asarray(meas.slider_acc_m_s2, dtype=float)
    dt = uniform_spacing(t_rec)
    h = dt / sensor.oversample
    where = meas.path or "the record"
    span = float(t_rec[-1])
    if window is None:
        window = 0.25 * crank_period(mech) if driver is not None else span / windows
    if not window > 0:
        raise ParameterError(f"window = {window!r} s must be > 0")
    n_fine = int(round(window / h))
    window = n_fine * h
    needed = windows * window
    if span + 0.5 * dt < needed or np.count_nonzero((t_rec >= 0) & (t_rec <= window)) < 4:
        raise ParameterError(
            f"{where}: the record covers {max(span, 0.0):.6g} s of simulation time ({len(t_rec)} samples) but "
            f"{windows} window(s) of {window:.6g} s need {needed:.6g} s (record shorter than the fit windows); give a "
            "shorter window (window=..., --window S) or fewer windows"
        )
    starts_t = [k * window for k in range(windows)]
    idx = [np.nonzero((t_rec >= t0 - 1e-12 * window) & (t_rec <= t0 + window + 1e-9 * dt))[0] for t0 in starts_t]
    n_pad = max(len(i) for i in idx)
    scale = float(np.sqrt(np.mean(np.concatenate([y_rec[i] for i in idx]) ** 2)))
    if not scale > 0:
        raise ParameterError(f"{where}: the measured acceleration is zero over the fitted window(s)")
    settle = 2.0 / sensor.cutoff_hz if sensor.cutoff_hz is not None else 0.0
    if coarse not in ("velocity", None):
        raise ParameterError(f"coarse = {coarse!r}; valid: 'velocity', None")

    base_t_rel = np.zeros((windows, n_pad))
    base_data = np.zeros((windows, n_pad))
    valid = np.zeros((windows, n_pad))
    for k, i in enumerate(idx):
        base_t_rel[k, : len(i)] = t_rec[i] - starts_t[k]
        base_data[k, : len(i)] = y_rec[i]
        ok = np.ones(len(i))
        if k > 0:
            ok[(t_rec[i] - starts_t[k]) < settle] = 0.0
        valid[k, : len(i)] = ok
    base_dts = np.full((windows, n_pad), dt)
    for k, i in enumerate(idx):
        base_dts[k, 1: len(i)] = np.diff(base_t_rel[k, : len(i)])
    vscale = float(np.sqrt(np.mean(np.cumsum(base_data[0, : len(idx[0])] * base_dts[0, : len(idx[0])]) ** 2)))
    vscale = vscale if vscale > 0 else scale * window

    # ---- values ----------------------------------------------------------------------------
    values0 = {}
    for name in free:
        v = float(start[name]) if name in start else _current_value(mech, sensor, name)
        _check_start(mech, name, v)
        values0[name] = v
    fixed = {}
    for name in ("stiffness", "restitution", "clearance", "friction", "speed_rpm"):
        if name not in free:
            try:
                fixed[name] = _current_value(mech, sensor, name)
            except ParameterError:
                pass
    if "sensor_gain" not in free:
        fixed["sensor_gain"] = float(sensor.gain)
    if "sensor_bias" not in free:
        fixed["sensor_bias"] = float(sensor.bias)
    z0 = np.array([float(to_z(n, values0[n], scale)) for n in free])
    p = len(free)
    n_state = 4 * len(mech.clearance_joints)
    velocity_scale = abs(speed) if speed else 1.0 / window
    s = make_settings(n_fine * h, n_out=n_fine + 1, rtol=rtol, atol=atol, adjoint="forward", throw=False,
                      max_steps=max_steps)
    model = WindowModel(mech=mech, sensor=sensor, settings=s, bias_scale=jnp.asarray(scale),
                        velocity_scale=jnp.asarray(velocity_scale), free=free, slider=slider, driver=driver, h=h)
    clearances = [float(j.clearance) for j in mech.clearance_joints]
    state0 = _state_to_z(np.concatenate([np.concatenate([np.asarray(j.initial_offset), np.asarray(j.initial_velocity)])
                                         for j in mech.clearance_joints]), clearances, velocity_scale)
    guess_q0, guess_qd0 = (np.asarray(a) for a in mech.guess())

    optimizer, optimizer_name = make_optimizer(optimizer)
    is_lm = isinstance(optimizer, LevenbergMarquardt)
    opt = optax.with_extra_args_support(optimizer)

    # ---- stages ------------------------------------------------------------------------------
    z_starts = _spread_starts(z0, free, starts)
    stages: list[_Stage] = []
    velocity = coarse == "velocity"
    kind = "velocity" if velocity else "acceleration"
    for j in range(starts):
        stages.append(_Stage(f"start {j + 1}/{starts}, window 1, {kind}, horizon {horizons[0]:g}", (0,), horizons[0],
                             True, (), j, not velocity and len(horizons) == 1 and windows == 1, velocity))
    for hz in horizons if velocity else horizons[1:]:
        stages.append(_Stage(f"window 1, acceleration, horizon {hz:g}", (0,), hz, True, (), -1,
                             windows == 1 and hz == 1.0))
    for k in range(1, windows):
        if velocity:
            stages.append(_Stage(f"window {k + 1} start state, velocity, horizon {horizons[0]:g}", (k,), horizons[0],
                                 False, (k,), -1, False, True))
        for hz in horizons:
            stages.append(_Stage(f"window {k + 1} start state, acceleration, horizon {hz:g}", (k,), hz, False, (k,),
                                 -1, False))
    if windows > 1:
        stages.append(_Stage(f"all {windows} windows", tuple(range(windows)), 1.0, True, tuple(range(1, windows)), -1, True))

    config = dict(free=free, start=values0, window=window, windows=windows, horizons=horizons, starts=starts, coarse=coarse,
                  max_iter=max_iter, ftol=ftol, xtol=xtol, rtol=rtol, atol=atol, align=align,
                  time_offset=time_offset, sensor=sensor.describe(), oversample=sensor.oversample,
                  optimizer=optimizer_name, mechanism=str(jax.tree_util.tree_structure(mech)))
    leaves = [np.ravel(np.asarray(x, dtype=float)) for x in jax.tree_util.tree_leaves((mech, sensor))]
    key = _fingerprint(t_rec, y_rec, np.concatenate(leaves), json.dumps(config, default=str, sort_keys=True))
    ckpt_path = os.path.join(os.fspath(out), CHECKPOINT_NAME) if out is not None else None

    # ---- mutable fit state -------------------------------------------------------------------
    st = dict(stage=0, iteration=0, total=0, z=None, opt_leaves=None, theta=z0.tolist(),
              states=[state0.tolist() for _ in range(windows)], guesses=None, start_losses={},
              start_thetas={}, start_reasons={}, history=[], wall=0.0, stop_reason="")
    resumed = False
    if ckpt_path and resume and os.path.isfile(ckpt_path):
        try:
            with open(ckpt_path, encoding="utf-8") as f:
                saved = json.load(f)
            if saved.get("key") == key:
                st.update(saved["state"])
                resumed = True
        except (OSError, ValueError, KeyError):
            resumed = False
    if st["guesses"] is None:
        st["guesses"] = [[guess_q0.tolist(), guess_qd0.tolist()] for _ in range(windows)]
    wall_before = float(st["wall"])

    def save():
        if ckpt_path is None:
            return
        os.makedirs(os.fspath(out), exist_ok=True)
        st["wall"] = wall_before + time.perf_counter() - t_wall
        tmp = ckpt_path + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"key": key, "config": json.loads(json.dumps(config, default=str)), "state": st}, f)
        os.replace(tmp, ckpt_path)

    cuts = {(k, hz): _quiet_cut(base_t_rel[k, : len(i)], base_data[k, : len(i)], hz * window, 0.1 * window)
            if hz < 1.0 else window for k, i in enumerate(idx) for hz in horizons}

    def win_input(k: int, horizon: float, integrate: bool = False) -> WindowInput:
        mask = valid[k] * (base_t_rel[k] <= cuts.get((k, horizon), horizon * window) + 1e-9 * dt)
        gq, gqd = st["guesses"][k]
        a0 = angle0 + (speed or 0.0) * starts_t[k]
        return WindowInput(jnp.asarray(a0), jnp.asarray(gq), jnp.asarray(gqd), jnp.asarray(base_t_rel[k]),
                           jnp.asarray(base_data[k]), jnp.asarray(mask), jnp.asarray(scale), jnp.asarray(base_dts[k]),
                           jnp.asarray(1.0 if integrate else 0.0), jnp.asarray(vscale))

    def evaluate(theta, states, stage: _Stage):
        """Residual (stacked over the stage's windows) and Jacobian over the stage's unknowns."""
        rs, cols_theta, cols_state, ends, ys, ok = [], [], {}, {}, {}, True
        for k in stage.windows:
            r, jt, js, y, (q1, qd1, end, status) = _evaluate_jit(
                model, jnp.asarray(theta), jnp.asarray(states[k]), win_input(k, stage.horizon, stage.integrate))
            r, jt, js = np.asarray(r), np.asarray(jt), np.asarray(js)
            ok &= int(status) == 0 and bool(np.all(np.isfinite(r))) and bool(np.all(np.isfinite(jt)))
            rs.append(r)
            cols_theta.append(jt)
            cols_state[k] = js
            ends[k] = (np.asarray(q1), np.asarray(qd1), np.asarray(end))
            ys[k] = np.asarray(y)
        r = np.concatenate(rs)
        blocks = []
        if stage.theta:
            blocks.append(np.concatenate(cols_theta, axis=0))
        for k in stage.states:
            col = np.zeros((r.shape[0], n_state))
            row = list(stage.windows).index(k) * n_pad
            col[row: row + n_pad] = cols_state[k]
            blocks.append(col)
        jac = np.concatenate(blocks, axis=1) if blocks else np.zeros((r.shape[0], 0))
        if not ok:
            r = np.full_like(r, np.nan)
        return r, jac, ends, ys

    def split(stage: _Stage, x: np.ndarray):
        theta = np.array(st["theta"], dtype=float)
        states = [np.array(v, dtype=float) for v in st["states"]]
        i = 0
        if stage.theta:
            theta = x[:p]
            i = p
        for k in stage.states:
            states[k] = x[i: i + n_state]
            i += n_state
        return theta, states

    def join(stage: _Stage, theta, states) -> np.ndarray:
        parts = [np.asarray(theta)] if stage.theta else []
        parts += [np.asarray(states[k]) for k in stage.states]
        return np.concatenate(parts) if parts else np.zeros(0)

    total_iters = sum((max_iter if s_.final else max(5, max_iter // 2)) for s_ in stages)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=total_iters, initial=min(st["total"], total_iters), desc="fit", unit="it", leave=True)
    try:
        while st["stage"] < len(stages):
            stage = stages[st["stage"]]
            if stage.start >= 0 and st["iteration"] == 0 and st["z"] is None:
                st["theta"] = z_starts[stage.start].tolist()
            if stage.start < 0 and st["iteration"] == 0 and st["z"] is None and stages[st["stage"] - 1].start >= 0:
                best = min(st["start_losses"], key=lambda j: st["start_losses"][j])
                st["theta"] = st["start_thetas"][best]
            if not stage.theta and stage.states and st["iteration"] == 0 and st["z"] is None:
                # initialise this window's state from the end of the previous window's simulation
                k = stage.states[0]
                _, _, ends, _ = evaluate(np.array(st["theta"]), [np.array(v) for v in st["states"]],
                                         _Stage("", (k - 1,), 1.0, False, (), -1, False))
                q1, qd1, end = ends[k - 1]
                st["guesses"][k] = [q1.tolist(), qd1.tolist()]
                st["states"][k] = _state_to_z(end, clearances, velocity_scale).tolist()
            x = np.array(st["z"], dtype=float) if st["z"] is not None else join(
                stage, st["theta"], [np.array(v) for v in st["states"]])
            opt_state = opt.init(jnp.asarray(x))
            if st["opt_leaves"] is not None:
                treedef = jax.tree_util.tree_structure(opt_state)
                opt_state = jax.tree_util.tree_unflatten(treedef, [jnp.asarray(v) for v in st["opt_leaves"]])
            limit = max_iter if stage.final else max(5, max_iter // 2)
            tol_f = ftol if stage.final else max(ftol, 1e-3)
            cache = {}

            def value_and_jac(xx):
                keyx = np.asarray(xx, dtype=float).tobytes()
                if keyx not in cache:
                    cache.clear()
                    theta, states = split(stage, np.asarray(xx, dtype=float))
                    cache[keyx] = evaluate(theta, states, stage)
                return cache[keyx]

            def value_fn(xx):
                r = value_and_jac(xx)[0]
                return 0.5 * float(r @ r) if np.all(np.isfinite(r)) else float("inf")

            r, jac, _, _ = value_and_jac(x)
            if not np.all(np.isfinite(r)):
                raise ParameterError(
                    f"the model cannot be simulated at the values {dict(zip(free, _values(free, split(stage, x)[0], scale)))} "
                    "(solver failure or non-finite state); choose other start values"
                )
            loss = float(r @ r)
            reason = ""
            while True:
                if st["iteration"] >= limit:
                    reason = "max_iter"
                    break
                grad = jac.T @ r
                updates, new_state = opt.update(jnp.asarray(grad), opt_state, jnp.asarray(x), jacobian=jac, residual=r,
                                                value_fn=value_fn)
                step = np.asarray(updates, dtype=float)
                x_new = x + step
                st["iteration"] += 1
                st["total"] += 1
                stalled = isinstance(new_state, LMState) and float(new_state.damping) > 1e10
                if stalled or not np.any(step):
                    opt_state = new_state
                    reason = "no decreasing step (converged within the solver's noise)"
                    break
                r_new, jac_new, _, _ = value_and_jac(x_new)
                loss_new = float(r_new @ r_new) if np.all(np.isfinite(r_new)) else float("inf")
                if not math.isfinite(loss_new):  # first-order optimisers: halve the step until finite
                    for _ in range(8):
                        step = 0.5 * step
                        x_new = x + step
                        r_new, jac_new, _, _ = value_and_jac(x_new)
                        if np.all(np.isfinite(r_new)):
                            loss_new = float(r_new @ r_new)
                            break
                    else:
                        reason = "the model failed along the step"
                        break
                rel = (loss - loss_new) / max(loss, 1e-300)
                x, r, jac, loss, opt_state = x_new, r_new, jac_new, loss_new, new_state
                theta_now, _ = split(stage, x)
                n_fit = max(float(np.sum(np.concatenate([win_input(k, stage.horizon).mask for k in stage.windows]))), 1.0)
                record = {"stage": stage.name, "iteration": st["total"], "loss": loss / n_fit,
                          "values": dict(zip(free, _values(free, theta_now, scale)))}
                st["history"].append(record)
                st["z"] = x.tolist()
                st["opt_leaves"] = [np.asarray(v).tolist() for v in jax.tree_util.tree_leaves(opt_state)]
                theta_now, states_now = split(stage, x)
                st["theta"] = np.asarray(theta_now).tolist()
                st["states"] = [np.asarray(v).tolist() for v in states_now]
                save()
                if bar is not None:
                    bar.update(1)
                    bar.set_description(stage.name)
                    bar.set_postfix({"loss": f"{loss / n_fit:.4g}", **{n: f"{v:.4g}" for n, v in record["values"].items()}})
                if callback is not None:
                    callback(record)
                if is_lm and 0 <= rel < tol_f:
                    reason = f"relative loss decrease {rel:.2g} < ftol {tol_f:g}"
                    break
                if float(np.max(np.abs(step))) < xtol:
                    reason = f"step {float(np.max(np.abs(step))):.2g} < xtol {xtol:g}"
                    break
            if stage.start >= 0:
                st["start_losses"][str(stage.start)] = loss
                st["start_thetas"][str(stage.start)] = np.asarray(split(stage, x)[0]).tolist()
                st["start_reasons"][str(stage.start)] = reason
            theta_now, states_now = split(stage, x)
            st["theta"] = np.asarray(theta_now).tolist()
            st["states"] = [np.asarray(v).tolist() for v in states_now]
            if stage.final:
                st["stop_reason"] = reason
            st["stage"] += 1
            st["iteration"] = 0
            st["z"] = None
            st["opt_leaves"] = None
            save()
    finally:
        if bar is not None:
            bar.total = bar.n
            bar.refresh()
            bar.close()

    if stages[-1].start >= 0:  # a single horizon and window: the best start is the result
        best = min(st["start_losses"], key=lambda j: st["start_losses"][j])
        st["theta"] = st["start_thetas"][best]
        st["stop_reason"] = st["start_reasons"][best]
    stop_reason = st["stop_reason"]
    converged = stop_reason not in ("", "max_iter")

    # ---- uncertainty at the optimum, all windows, all samples ------------------------------------
    final = _Stage("final", tuple(range(windows)), 1.0, True, tuple(range(1, windows)), -1, True)
    theta = np.array(st["theta"], dtype=float)
    states = [np.array(v, dtype=float) for v in st["states"]]
    r, jac, _, ys = evaluate(theta, states, final)
    mask = np.concatenate([np.asarray(win_input(k, 1.0).mask) for k in range(windows)])
    n_fit = int(mask.sum())
    n_unknown = jac.shape[1]
    res = r * scale  # m/s^2 (zero where masked)
    sigma2 = float(res @ res) / max(n_fit - n_unknown, 1)
    jm = jac * scale
    warn = []
    try:
        cov = sigma2 * np.linalg.inv(jm.T @ jm)
    except np.linalg.LinAlgError:
        cov = np.full((n_unknown, n_unknown), np.nan)
        warn.append("J^T J is singular at the optimum: a free parameter is not identifiable from this record")
    std_z = np.sqrt(np.maximum(np.diag(cov)[:p], 0.0))
    est = dict(zip(free, _values(free, theta, scale)))
    std = {n: abs(_dvalue_dz(n, theta[i], scale)) * float(std_z[i]) for i, n in enumerate(free)}
    d = np.sqrt(np.maximum(np.diag(cov)[:p], 1e-300))
    corr = (cov[:p, :p] / np.outer(d, d)).tolist()
    res_fit = res[mask > 0]
    auto = float(np.corrcoef(res_fit[:-1], res_fit[1:])[0, 1]) if res_fit.size > 3 and np.std(res_fit) > 0 else float("nan")
    if math.isfinite(auto) and auto > AUTOCORRELATION_WARNING:
        warn.append(
            f"the residuals are not white (lag-1 autocorrelation {auto:.2f} > {AUTOCORRELATION_WARNING}): the model "
            "does not reproduce the data to the noise level (another contact law, a wrong known parameter or a "
            "wrong sensor model?), so the std understate the true error"
        )
    if not converged:
        warn.append(f"the last stage stopped on max_iter = {max_iter} before meeting ftol/xtol")
    for i, n in enumerate(free):
        if _transform(n) == "logit" and abs(float(theta[i])) > 9.0:
            warn.append(f"{n} = {est[n]:.6g} ran to the edge of its range: the model reaches no interior optimum "
                        "(wrong contact law or known parameter?)")
    window_losses = [float(np.mean(r[k * n_pad:(k + 1) * n_pad][np.asarray(win_input(k, 1.0).mask) > 0] ** 2))
                     for k in range(windows)]
    for w in warn:
        warnings.warn(w, stacklevel=2)
    # the model at the start values (window 0 only has a known start; others use the fitted states)
    y_init = []
    for k in range(windows):
        yk = np.asarray(_evaluate_jit(model, jnp.asarray(z_starts[0] if starts >= 1 else z0),
                                      jnp.asarray(states[k]), win_input(k, 1.0))[3])
        y_init.append(yk)
    t_all, m_all, f_all, i_all = [], [], [], []
    for k, i in enumerate(idx):
        n_k = len(i)
        keep = valid[k, :n_k] > 0
        t_all.append((base_t_rel[k, :n_k] + starts_t[k])[keep])
        m_all.append(base_data[k, :n_k][keep])
        f_all.append(ys[k][:n_k][keep])
        i_all.append(y_init[k][:n_k][keep])
    wall = wall_before + time.perf_counter() - t_wall
    result = FitResult(
        estimates=est,
        std=std,
        loss=float(np.mean(r[mask > 0] ** 2)),
        iterations=int(st["total"]),
        wall_time_s=wall,
        start=dict(zip(free, _values(free, z0, scale))),
        correlation=corr,
        noise_sigma_m_s2=math.sqrt(sigma2),
        residual_rms_m_s2=float(np.sqrt(np.mean(res_fit**2))),
        residual_autocorrelation=auto,
        n_samples=n_fit,
        n_unknowns=n_unknown,
        converged=converged,
        stop_reason=stop_reason,
        history=list(st["history"]),
        t=np.concatenate(t_all),
        measured=np.concatenate(m_all),
        fitted=np.concatenate(f_all),
        initial=np.concatenate(i_all),
        window_starts=[float(t) for t in starts_t],
        window_length_s=float(window),
        free=free,
        fixed=fixed,
        settings={"window_s": window, "windows": windows, "horizons": list(horizons), "coarse": coarse, "starts": starts,
                  "max_iter": max_iter, "ftol": ftol, "xtol": xtol, "rtol": rtol, "atol": atol, "align": align,
                  "sensor": sensor.describe(), "oversample": sensor.oversample, "record": meas.path,
                  "record_samples": len(t_rec), "sample_spacing_s": dt, "data_rms_m_s2": scale,
                  "mechanism": mech.name, "law": _law_name(mech), "resumed": resumed,
                  "optimizer": optimizer_name},
        warnings=warn,
        window_states=[list(map(float, v)) for v in states[1:]],
        window_losses=window_losses,
    )
    return result


def make_optimizer(spec=None):
    """``(optax transformation, name)`` from ``None`` / ``"levenberg-marquardt"`` (the default),
    ``"adam"`` or ``"adam:LR"`` (learning rate in the transformed parameters, default 0.02), or an
    optax transformation (named by its type; a checkpoint cannot tell two of them apart)."""
    if spec is None or spec in ("levenberg-marquardt", "lm"):
        return levenberg_marquardt(), "levenberg-marquardt"
    if isinstance(spec, str):
        name, _, lr = spec.partition(":")
        if name == "adam":
            try:
                rate = float(lr) if lr else 0.02
            except ValueError:
                raise ParameterError(f"optimizer {spec!r}: the learning rate after ':' must be a number") from None
            return optax.adam(rate), f"adam:{rate:g}"
        raise ParameterError(f"unknown optimizer {spec!r}; valid: 'levenberg-marquardt', 'adam', 'adam:LR'")
    return spec, f"custom:{type(spec).__name__}:{getattr(spec.update, '__qualname__', '')}"


def _check_record(meas):
    where = meas.path or "the record"
    t = np.asarray(meas.time_s, dtype=float)
    y = np.asarray(meas.slider_acc_m_s2, dtype=float)
    if t.ndim != 1 or y.shape != t.shape:
        raise ParameterError(f"{where}: time_s and slider_acc_m_s2 must be 1-D of equal length, got {t.shape}, {y.shape}")
    for name, arr in (("time_s", t), ("slider_acc_m_s2", y)):
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise ParameterError(f"{where}: column {name!r} has a non-finite value at sample {int(bad[0])} "
                                 f"(data row {int(bad[0]) + 1})")
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        raise ParameterError(f"{where}: column 'time_s' is not strictly increasing at sample {int(bad[0]) + 1} "
                             f"(data row {int(bad[0]) + 2})")


def _quiet_cut(t, y, t_cut: float, search: float) -> float:
    """Where to end a partial horizon: the quietest sample of the record in ``[t_cut, t_cut +
    search]``, quiet meaning the smallest mean absolute sample-to-sample change over +-5 samples
    (an impact in progress has a large one). A horizon that ends inside an impact compares half
    an impulse, which can drive a parameter the rest of the data would fix (restitution) to the
    edge of its range; ending in free flight avoids that."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    inside = np.nonzero((t >= t_cut) & (t <= t_cut + search))[0]
    if inside.size < 3:
        return t_cut
    change = np.abs(np.diff(y, prepend=y[0]))
    m = 5
    activity = np.convolve(change, np.ones(2 * m + 1) / (2 * m + 1), mode="same")
    return float(t[inside[np.argmin(activity[inside])]])


def _values(free, theta, scale):
    return [float(from_z(n, theta[i], scale)) for i, n in enumerate(free)]


def _law_name(mech: Mechanism) -> str:
    from .plot import law_label

    return law_label(mech.clearance_joints[0].law) if mech.clearance_joints else ""


# --------------------------------------------------------------------------------------
# Gradients of a scalar of a simulation
# --------------------------------------------------------------------------------------


def parameter_grad(loss: Callable, mech: Mechanism, names: Sequence[str], s: Settings, mode: str = "reverse"):
    """Value and gradient of ``loss(solution, mechanism)`` (a scalar) with respect to the named
    parameters (:mod:`jaxclear.params`), through diffrax.

    ``mode="reverse"``: ``jax.value_and_grad`` with ``s.adjoint`` (default ``"recursive"``:
    RecursiveCheckpointAdjoint, memory bounded by ``s.checkpoints``); ``mode="forward"``:
    ``jax.jacfwd`` with ``adjoint="forward"`` (cheaper for few parameters). Returns
    ``(value, {name: d loss / d name})``. Compiles on every call: for repeated use, build your
    own ``eqx.filter_jit`` of the same function.
    """
    names = tuple(names)
    for n in names:
        _check_name(mech, n)
    if mode not in ("reverse", "forward"):
        raise ParameterError(f"mode = {mode!r}; valid: 'reverse', 'forward'")
    if mode == "forward":
        s = dataclasses.replace(s, adjoint="forward")
    elif s.adjoint == "forward":
        s = dataclasses.replace(s, adjoint="recursive")
    x0 = jnp.asarray([params.get(mech, n) for n in names], dtype=float)

    def f(x):
        m = params.replace_many(mech, dict(zip(names, x)))
        value = loss(simulate(m, s), m)
        return value, value

    if mode == "reverse":
        g, value = jit(jax.grad(f, has_aux=True))(x0)
    else:
        g, value = jit(jax.jacfwd(f, has_aux=True))(x0)
    return float(value), {n: float(g[i]) for i, n in enumerate(names)}


__all__ = [
    "fit",
    "FitResult",
    "levenberg_marquardt",
    "LevenbergMarquardt",
    "LMState",
    "make_optimizer",
    "synthetic_record",
    "sensor_signal",
    "write_measurements",
    "parameter_grad",
    "DEFAULT_FREE",
    "SENSOR_PARAMETERS",
    "WindowModel",
    "WindowInput",
]


class _CallableModule(types.ModuleType):
    """``jaxclear.fit`` is this module and, called, the function :func:`fit`."""

    def __call__(self, *args, **kwargs):
        return fit(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
