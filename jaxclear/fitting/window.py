r"""The model of one fit window and the record cut into windows.

Window ``k`` (length ``T_w`` [s], starting at ``t_k`` on the record's simulation clock) is
simulated from ``t = 0`` with the crank's start angle ``angle0 + omega t_k`` (``angle0`` and
``omega`` the crank driver's, fitted where they are free) and, for ``k > 0`` (every window,
the first included, with ``start_state="free"``), a free start state of every force element
(:mod:`.window_start`: contact-free for a record that begins at start-up; anywhere, in contact
too, with the ongoing contact's approach speed, for a record that begins mid-run). The
element's memory otherwise starts from its
:meth:`~jaxclear.elements.AbstractForceElement.state_init`.

The residual of channel ``j`` (weight ``w_j``) at the window's ``n_pad`` samples (mask ``m_i``:
1 fitted, 0 not) is

* signal: ``r_ji = sqrt(w_j) m_i (y_ji - d_ji) / s_j``, ``s_j`` the RMS of the column over the
  fitted windows;
* running integral (coarse stages): ``r_ji = sqrt(w_j) m_i sum_{l<=i} m_l (y_jl - d_jl) dt_l /
  v_j``, ``v_j`` the RMS of the integrated column over window 0,

with ``y_j`` the channel seen through its sensor, ``gain * filter(channel) + bias`` at the
times ``t - delay`` (:class:`~jaxclear.analysis.sensor.Accelerometer`), and ``d_j`` the record's column; the
channels' residuals are stacked (channel-major, ``(C n_pad,)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import params
from ..elements import ongoing_contact, start_states
from .._errors import ParameterError
from ..model import Mechanism
from ..analysis.channels import channel
from ..analysis.sensor import Accelerometer
from ..integrate import Settings, initial_state, jit, simulate
from ..sweep.lanes import ahead
from .parameters import SENSOR_PARAMETERS, from_z
from .records import quiet_cut
from .window_start import element_starts


class WindowInput(eqx.Module):
    """Arrays describing one window (all leaves, so windows share one compiled function)."""

    t_start: jax.Array  # start of the window on the record's simulation clock [s], ()
    guess_q: jax.Array  # position guess of the bodies at the window start, (3 n_b,)
    guess_qd: jax.Array  # velocity guess, (3 n_b,)
    t_rel: jax.Array  # record sample times relative to the window start [s], (n_pad,)
    data: jax.Array  # measured values, (C, n_pad)
    mask: jax.Array  # 1 for fitted samples, 0 else, (n_pad,)
    scale: jax.Array  # normalisation of each channel's residual (RMS of its data), (C,)
    dts: jax.Array  # sample intervals [s], (n_pad,), for the integrated residual
    integrate: jax.Array  # 1: residual of the integrated signal (velocity), 0: of the signal itself
    vscale: jax.Array  # normalisation of each channel's integrated residual, (C,)


class WindowModel(eqx.Module):
    """Mechanism + sensors + settings of the windows; ``free`` names the parameters in
    ``theta_z``; ``channels`` the fitted channels (:mod:`jaxclear.analysis.channels` names), one
    sensor and one weight each. ``sensor_gain``/``sensor_bias`` act on the first channel's sensor."""

    mech: Mechanism
    sensors: tuple
    weights: jax.Array
    settings: Settings
    bias_scale: jax.Array
    velocity_scale: jax.Array
    free: tuple = eqx.field(static=True)
    channels: tuple = eqx.field(static=True)
    driver: int | None = eqx.field(static=True)
    h: float = eqx.field(static=True)
    anywhere: bool = eqx.field(static=True, default=False)  # window starts in the anywhere layout (.window_start)

    @property
    def sensor(self) -> Accelerometer:
        """The first channel's sensor."""
        return self.sensors[0]

    def values(self, theta_z):
        """``name: value`` (SI) of the unconstrained ``theta_z`` ``(P,)``."""
        return {n: from_z(n, theta_z[i], self.bias_scale, self.mech) for i, n in enumerate(self.free)}

    def mechanism(self, theta_z, state_z, win: WindowInput):
        """The mechanism of the window (free values, crank angle, guesses and element start
        states), its values, and the approach speeds of contacts under way at its start (the
        anywhere layout; else None)."""
        values = self.values(theta_z)
        mech = params.replace_many(self.mech, {n: v for n, v in values.items() if n not in SENSOR_PARAMETERS})
        angle0 = None
        if self.driver is not None:  # the crank where the record is at the window's start (fitted angle0, speed too)
            crank = mech.drivers[self.driver]
            angle0 = crank.angle0 + crank.speed * win.t_start
        mech = mech.started(angle0=angle0, q=win.guess_q, qdot=win.guess_qd)
        elements, speeds = element_starts(mech, state_z, self.velocity_scale, self.anywhere)
        return mech.started(elements=elements), values, speeds

    def start(self, mech: Mechanism, speeds):
        """The run's start: assembled (None) or, with contacts under way, the assembled state
        whose memories hold their approach speeds (the onset placed one window before)."""
        if speeds is None:
            return None
        y0 = initial_state(mech, self.settings)
        onset = -self.settings.t_end
        return eqx.tree_at(lambda y: y.elements, y0, tuple(
            ongoing_contact(state, v, onset) for state, v in zip(y0.elements, speeds)))

    def signal(self, theta_z, state_z, win: WindowInput):
        """Sensor outputs ``(C, n_pad)`` at the window's samples and ``(q_end, qdot_end,
        start_states_end, status, onsets)`` of the simulation (``onsets``: the contact onsets
        of every force element within the window, ``()``, from their memories' counters)."""
        mech, values, speeds = self.mechanism(theta_z, state_z, win)
        sol = simulate(mech, self.settings, self.start(mech, speeds))
        ys = []
        for j, (name, sensor) in enumerate(zip(self.channels, self.sensors)):
            gain = values.get("sensor_gain", sensor.gain) if j == 0 else sensor.gain
            bias = values.get("sensor_bias", sensor.bias) if j == 0 else sensor.bias
            delay = values.get("sensor_delay", sensor.delay) if j == 0 else sensor.delay
            y = gain * sensor.filter(self.h, channel(mech, sol, name)) + bias
            ys.append(jnp.interp(win.t_rel - delay, sol.ts, y))
        q1, qd1 = sol.q[-1], sol.qdot[-1]
        impacts = sol.memory.impacts
        onsets = jnp.sum(impacts[-1] - impacts[0]).astype(q1.dtype)
        return jnp.stack(ys), (q1, qd1, start_states(mech, q1, qd1), sol.status, onsets)

    def residual(self, theta_z, state_z, win: WindowInput):
        """Residual ``(C n_pad,)`` of the window (module docstring), the signals, and the end."""
        y, extra = self.signal(theta_z, state_z, win)
        err = win.mask * (y - win.data)
        r_velocity = win.mask * jnp.cumsum(err * win.dts, axis=-1) / win.vscale[:, None]
        r = jnp.where(win.integrate > 0, r_velocity, err / win.scale[:, None])
        return jnp.reshape(jnp.sqrt(self.weights)[:, None] * r, (-1,)), (y, extra)


def evaluate_window(model: WindowModel, theta_z, state_z, win: WindowInput):
    """Residual ``r`` ``(C n_pad,)``, its Jacobians ``dr/dtheta_z`` ``(C n_pad, P)`` and
    ``dr/dstate_z`` ``(C n_pad, S)`` in forward mode (``jax.jacfwd``: few columns, many rows),
    the signals ``y`` ``(C, n_pad)`` and the end ``(q, qdot, start states, status, onsets)``. ``r`` is NaN
    where the simulation failed (status not 0) or a value is not finite."""

    def f(theta_z, state_z):
        r, (y, extra) = model.residual(theta_z, state_z, win)
        return r, (r, y, extra)

    (jt, js), (r, y, extra) = jax.jacfwd(f, argnums=(0, 1), has_aux=True)(theta_z, state_z)
    ok = (extra[3] == 0) & jnp.all(jnp.isfinite(r)) & jnp.all(jnp.isfinite(jt)) & jnp.all(
        jnp.isfinite(js))
    r = jnp.where(ok, r, jnp.nan)
    return r, jnp.where(ok, jt, 0.0), jnp.where(ok, js, 0.0), y, extra


_evaluate_window = jit(evaluate_window)
#: The structure of :func:`evaluate_window`'s output: ``r``, the two Jacobians, ``y`` and the end
#: ``(q, qdot, start states, status, onsets)``, arrays all (the store of traced programs rebuilds it).
_EVALUATE_STRUCTURE = jax.tree_util.tree_structure((0, 0, 0, 0, (0, 0, 0, 0, 0)))
#: The window's program's name in the store (:func:`evaluate_window_ahead` traces what
#: :func:`evaluate_window_jit` runs).
_WINDOW = "fit-window"


def evaluate_window_jit(model: WindowModel, theta_z, state_z, win: WindowInput):
    """:func:`evaluate_window` compiled (outside the solver's step: start states, uncertainty,
    plot), through the store of traced programs (:meth:`jaxclear.integrate.jit.stored`): a new
    process of the same structure loads the program instead of tracing it."""
    return _evaluate_window.stored(_WINDOW, lambda: _EVALUATE_STRUCTURE, model, theta_z, state_z, win)


def evaluate_window_ahead(model: WindowModel, theta_z, state_z, win: WindowInput):
    """The window's program (:func:`evaluate_window_jit`) traced (or loaded from the store) here,
    then compiled and run once at these values on a thread of its own
    (:func:`jaxclear.sweep.lanes.ahead`): the fit starts it before its way in, whose programs are
    then traced and compiled beside it. Returns the future, or None (no thread to spare)."""
    args = (model, jnp.asarray(theta_z), jnp.asarray(state_z), win)
    _evaluate_window.prepare(_WINDOW, *args)
    return ahead(evaluate_window_jit, *args)


@dataclass(frozen=True)
class WindowSet:
    """The record on the simulation clock cut into ``W`` windows of ``n_pad`` samples (padded),
    ``C`` channels.

    Attributes: ``t_rel``, ``valid`` (1: sample may be fitted; 0: padding or the filter's
    settling time ``2 / f_c`` at the start of windows ``k > 0``), ``dts`` all ``(W, n_pad)``;
    ``data`` ``(W, C, n_pad)``; ``counts`` samples per window; ``starts`` window start times
    [s]; ``length`` ``T_w`` [s]; ``dt`` sample spacing [s]; ``scales`` ``(C,)`` RMS of each
    column; ``vscales`` ``(C,)`` RMS of each integrated column over window 0; ``cuts``
    ``(window, horizon) -> end time`` [s]."""

    t_rel: np.ndarray
    data: np.ndarray
    valid: np.ndarray
    dts: np.ndarray
    counts: tuple
    starts: tuple
    length: float
    dt: float
    scales: np.ndarray
    vscales: np.ndarray
    cuts: dict

    @property
    def n_pad(self) -> int:
        return self.t_rel.shape[1]

    @property
    def n_channels(self) -> int:
        return self.data.shape[1]

    @property
    def scale(self) -> float:
        """RMS of the first column (the unit of ``sensor_bias`` and of the reported noise)."""
        return float(self.scales[0])

    def mask(self, k: int, horizon: float) -> np.ndarray:
        """``(n_pad,)`` fitted samples of window ``k`` within ``horizon`` (fraction of the window)."""
        end = self.cuts.get((k, horizon), horizon * self.length)
        return self.valid[k] * (self.t_rel[k] <= end + 1e-9 * self.dt)

    def residual_mask(self, k: int, horizon: float) -> np.ndarray:
        """``(C n_pad,)``: :meth:`mask` for every channel, in the residual's order."""
        return np.tile(self.mask(k, horizon), self.n_channels)

    def window_input(self, k: int, horizon: float, integrate: bool, guess) -> WindowInput:
        """The :class:`WindowInput` of window ``k`` (``guess``: ``(q, qdot)`` at its start)."""
        return WindowInput(jnp.asarray(self.starts[k]), jnp.asarray(guess[0]), jnp.asarray(guess[1]),
                           jnp.asarray(self.t_rel[k]), jnp.asarray(self.data[k]),
                           jnp.asarray(self.mask(k, horizon)), jnp.asarray(self.scales), jnp.asarray(self.dts[k]),
                           jnp.asarray(1.0 if integrate else 0.0), jnp.asarray(self.vscales))


def cut_windows(t_rec, y_rec, dt: float, windows: int, window: float, settle: float, horizons: Sequence[float],
                where: str, columns: Sequence[str] = ("slider_acc_m_s2",), settle_first: bool = False) -> WindowSet:
    """Cut the record (``t_rec`` ``(N,)`` on the simulation clock [s], ``y_rec`` ``(C, N)`` the
    fitted ``columns``) into ``windows`` back-to-back windows of ``window`` seconds (``dt``: the
    uniform sample spacing [s]); a partial horizon ends at the quietest sample of the first
    column within the next 10 % of the window (:func:`quiet_cut`). The first ``settle`` seconds
    of every window after the first (of the first too with ``settle_first``: a record that begins
    mid-run) are not fitted: the sensor filter's history before the window is unknown."""
    y_rec = np.atleast_2d(np.asarray(y_rec, dtype=float))
    n_c = y_rec.shape[0]
    starts = tuple(k * window for k in range(windows))
    idx = [np.nonzero((t_rec >= t0 - 1e-12 * window) & (t_rec <= t0 + window + 1e-9 * dt))[0] for t0 in starts]
    n_pad = max(len(i) for i in idx)
    fitted = np.concatenate(idx)
    scales = np.sqrt(np.mean(y_rec[:, fitted] ** 2, axis=1))
    for j, name in enumerate(columns):
        if not scales[j] > 0:
            raise ParameterError(f"{where}: the measured column {name!r} is zero over the fitted window(s)")
    t_rel, valid = np.zeros((windows, n_pad)), np.zeros((windows, n_pad))
    data = np.zeros((windows, n_c, n_pad))
    dts = np.full((windows, n_pad), dt)
    for k, i in enumerate(idx):
        t_rel[k, : len(i)] = t_rec[i] - starts[k]
        data[k, :, : len(i)] = y_rec[:, i]
        valid[k, : len(i)] = 1.0 if k == 0 and not settle_first else (t_rel[k, : len(i)] >= settle)
        dts[k, 1: len(i)] = np.diff(t_rel[k, : len(i)])
    n0 = len(idx[0])
    vscales = np.sqrt(np.mean(np.cumsum(data[0, :, :n0] * dts[0, :n0], axis=1) ** 2, axis=1))
    vscales = np.where(vscales > 0, vscales, scales * window)
    cuts = {(k, hz): quiet_cut(t_rel[k, : len(i)], data[k, 0, : len(i)], hz * window, 0.1 * window)
            if hz < 1.0 else window for k, i in enumerate(idx) for hz in horizons}
    return WindowSet(t_rel, data, valid, dts, tuple(len(i) for i in idx), starts, float(window), dt, scales, vscales,
                     cuts)
