r"""The model of one fit window and the record cut into windows.

Window ``k`` (length ``T_w`` [s]) is simulated from ``t = 0`` with the crank's start angle
advanced by ``omega k T_w`` and, for ``k > 0``, a free journal state at its start: per
clearance joint 4 unconstrained numbers ``s = (u, w)`` map to the journal offset
``e0 = c u / sqrt(1 + |u|^2)`` [m] (``c``: radial clearance; always inside the bearing) and the
relative velocity ``v0 = v_s c w`` [m/s] (``v_s``: crank speed [rad/s], or ``1 / T_w``).

The residual at the window's ``n_pad`` samples (mask ``m_i``: 1 fitted, 0 not) is

* acceleration: ``r_i = m_i (y_i - d_i) / s_a``, ``s_a`` the RMS of the record [m/s^2];
* velocity (coarse stages): ``r_i = m_i sum_{j<=i} m_j (y_j - d_j) dt_j / s_v``, the running
  integral of the misfit, ``s_v`` [m/s] the RMS of the integrated record,

with ``y`` the sensor model ``gain * filter(acc) + bias`` and ``d`` the data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import params
from ..elements import journal_state
from .._errors import ParameterError
from ..model import Mechanism
from ..analysis.sensor import Accelerometer
from ..integrate import Settings, jit, simulate
from .parameters import SENSOR_PARAMETERS, from_z
from .records import quiet_cut

#: Offset of a window's start state as a fraction of the clearance: the map keeps it inside.
OFFSET_RADIUS = 1.0


class WindowInput(eqx.Module):
    """Arrays describing one window (all leaves, so windows share one compiled function)."""

    angle0: jax.Array  # crank start angle of the window [rad], ()
    guess_q: jax.Array  # position guess of the bodies at the window start, (3 n_b,)
    guess_qd: jax.Array  # velocity guess, (3 n_b,)
    t_rel: jax.Array  # record sample times relative to the window start [s], (n_pad,)
    data: jax.Array  # measured values [m/s^2], (n_pad,)
    mask: jax.Array  # 1 for fitted samples, 0 else, (n_pad,)
    scale: jax.Array  # normalisation of the residual (RMS of the data) [m/s^2], ()
    dts: jax.Array  # sample intervals [s], (n_pad,), for the integrated residual
    integrate: jax.Array  # 1: residual of the integrated signal (velocity), 0: of the acceleration
    vscale: jax.Array  # normalisation of the integrated residual [m/s], ()


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
        """``name: value`` (SI) of the unconstrained ``theta_z`` ``(P,)``."""
        return {n: from_z(n, theta_z[i], self.bias_scale) for i, n in enumerate(self.free)}

    def mechanism(self, theta_z, state_z, win: WindowInput):
        """The mechanism of the window: free values, crank angle, guesses and journal start state."""
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
            offsets.append(c * OFFSET_RADIUS * u / jnp.sqrt(1.0 + u @ u))
            velocities.append(self.velocity_scale * c * state_z[4 * k + 2: 4 * k + 4])
        if mech.clearance_joints:
            mech = eqx.tree_at(lambda m: [j.initial_offset for j in m.clearance_joints], mech, offsets)
            mech = eqx.tree_at(lambda m: [j.initial_velocity for j in m.clearance_joints], mech, velocities)
        return mech, values

    def signal(self, theta_z, state_z, win: WindowInput):
        """Sensor output ``(n_pad,)`` [m/s^2] at the window's samples and ``(q_end, qdot_end,
        journal_state_end, status)`` of the simulation."""
        mech, values = self.mechanism(theta_z, state_z, win)
        sol = simulate(mech, self.settings)
        acc = sol.coordinate(mech, self.slider, "x", derivative=2)
        gain = values.get("sensor_gain", self.sensor.gain)
        bias = values.get("sensor_bias", self.sensor.bias)
        y = gain * self.sensor.filter(self.h, acc) + bias
        y = jnp.interp(win.t_rel, sol.ts, y)
        q1, qd1 = sol.q[-1], sol.qdot[-1]
        return y, (q1, qd1, journal_state(mech, q1, qd1), sol.status)

    def residual(self, theta_z, state_z, win: WindowInput):
        """Residual ``(n_pad,)`` of the window (module docstring), the signal, and the end."""
        y, extra = self.signal(theta_z, state_z, win)
        err = win.mask * (y - win.data)
        r_velocity = win.mask * jnp.cumsum(err * win.dts) / win.vscale
        r = jnp.where(win.integrate > 0, r_velocity, err / win.scale)
        return r, (y, extra)


def evaluate_window(model: WindowModel, theta_z, state_z, win: WindowInput):
    """Residual ``r`` ``(n_pad,)``, its Jacobians ``dr/dtheta_z`` ``(n_pad, P)`` and
    ``dr/dstate_z`` ``(n_pad, 4 n_c)`` in forward mode (``jax.jacfwd``: few columns, many rows),
    the signal ``y`` ``(n_pad,)`` and the end ``(q, qdot, journal_state, status)``. ``r`` is NaN
    where the simulation failed (status not 0) or a value is not finite."""

    def f(theta_z, state_z):
        r, (y, extra) = model.residual(theta_z, state_z, win)
        return r, (r, y, extra)

    (jt, js), (r, y, extra) = jax.jacfwd(f, argnums=(0, 1), has_aux=True)(theta_z, state_z)
    ok = (extra[3] == 0) & jnp.all(jnp.isfinite(r)) & jnp.all(jnp.isfinite(jt)) & jnp.all(
        jnp.isfinite(js))
    r = jnp.where(ok, r, jnp.nan)
    return r, jnp.where(ok, jt, 0.0), jnp.where(ok, js, 0.0), y, extra


#: :func:`evaluate_window` compiled (outside the solver's step: start states, uncertainty, plot).
evaluate_window_jit = jit(evaluate_window)


def state_to_z(state: np.ndarray, clearance: Sequence[float], velocity_scale: float) -> np.ndarray:
    """Inverse of the window-state map of :meth:`WindowModel.mechanism`: journal state
    ``[e_x, e_y, v_x, v_y]`` per joint ``(4 n_c,)`` [m, m/s] to ``s`` ``(4 n_c,)`` (offset
    clipped to 0.999 of the clearance)."""
    out = []
    for k, c in enumerate(clearance):
        w = np.asarray(state[4 * k: 4 * k + 2]) / (c * OFFSET_RADIUS)
        n = float(np.linalg.norm(w))
        if n >= 0.999:
            w = w * 0.999 / n
            n = 0.999
        out.append(w / math.sqrt(1.0 - n * n))
        out.append(np.asarray(state[4 * k + 2: 4 * k + 4]) / (velocity_scale * c))
    return np.concatenate(out) if out else np.zeros(0)


@dataclass(frozen=True)
class WindowSet:
    """The record on the simulation clock cut into ``W`` windows of ``n_pad`` samples (padded).

    Attributes: ``t_rel``, ``data``, ``valid`` (1: sample may be fitted; 0: padding or the
    filter's settling time ``2 / f_c`` at the start of windows ``k > 0``), ``dts`` all ``(W,
    n_pad)``; ``counts`` samples per window; ``starts`` window start times [s]; ``length`` ``T_w``
    [s]; ``dt`` sample spacing [s]; ``scale`` RMS of the data [m/s^2]; ``vscale`` RMS of the
    integrated data of window 0 [m/s]; ``cuts`` ``(window, horizon) -> end time`` [s]."""

    t_rel: np.ndarray
    data: np.ndarray
    valid: np.ndarray
    dts: np.ndarray
    counts: tuple
    starts: tuple
    length: float
    dt: float
    scale: float
    vscale: float
    cuts: dict

    @property
    def n_pad(self) -> int:
        return self.t_rel.shape[1]

    def mask(self, k: int, horizon: float) -> np.ndarray:
        """``(n_pad,)`` fitted samples of window ``k`` within ``horizon`` (fraction of the window)."""
        end = self.cuts.get((k, horizon), horizon * self.length)
        return self.valid[k] * (self.t_rel[k] <= end + 1e-9 * self.dt)

    def window_input(self, k: int, horizon: float, integrate: bool, angle0: float, guess) -> WindowInput:
        """The :class:`WindowInput` of window ``k`` (``guess``: ``(q, qdot)`` at its start)."""
        return WindowInput(jnp.asarray(angle0), jnp.asarray(guess[0]), jnp.asarray(guess[1]),
                           jnp.asarray(self.t_rel[k]), jnp.asarray(self.data[k]),
                           jnp.asarray(self.mask(k, horizon)), jnp.asarray(self.scale), jnp.asarray(self.dts[k]),
                           jnp.asarray(1.0 if integrate else 0.0), jnp.asarray(self.vscale))


def cut_windows(t_rec, y_rec, dt: float, windows: int, window: float, settle: float, horizons: Sequence[float],
                where: str) -> WindowSet:
    """Cut the record (``t_rec`` on the simulation clock [s], ``y_rec`` [m/s^2]) into ``windows``
    back-to-back windows of ``window`` seconds (``dt``: the uniform sample spacing [s]); a partial horizon ends at the quietest sample
    within the next 10 % of the window (:func:`quiet_cut`)."""
    starts = tuple(k * window for k in range(windows))
    idx = [np.nonzero((t_rec >= t0 - 1e-12 * window) & (t_rec <= t0 + window + 1e-9 * dt))[0] for t0 in starts]
    n_pad = max(len(i) for i in idx)
    scale = float(np.sqrt(np.mean(np.concatenate([y_rec[i] for i in idx]) ** 2)))
    if not scale > 0:
        raise ParameterError(f"{where}: the measured acceleration is zero over the fitted window(s)")
    t_rel, data, valid = np.zeros((windows, n_pad)), np.zeros((windows, n_pad)), np.zeros((windows, n_pad))
    dts = np.full((windows, n_pad), dt)
    for k, i in enumerate(idx):
        t_rel[k, : len(i)] = t_rec[i] - starts[k]
        data[k, : len(i)] = y_rec[i]
        valid[k, : len(i)] = 1.0 if k == 0 else (t_rel[k, : len(i)] >= settle)
        dts[k, 1: len(i)] = np.diff(t_rel[k, : len(i)])
    n0 = len(idx[0])
    vscale = float(np.sqrt(np.mean(np.cumsum(data[0, :n0] * dts[0, :n0]) ** 2)))
    vscale = vscale if vscale > 0 else scale * window
    cuts = {(k, hz): quiet_cut(t_rel[k, : len(i)], data[k, : len(i)], hz * window, 0.1 * window)
            if hz < 1.0 else window for k, i in enumerate(idx) for hz in horizons}
    return WindowSet(t_rel, data, valid, dts, tuple(len(i) for i in idx), starts, float(window), dt, scale, vscale,
                     cuts)
