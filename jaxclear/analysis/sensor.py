r"""What a measured acceleration record is compared with: the accelerometer model, and putting
the simulation on the record's clock (records read by :func:`jaxclear.io.read_measurements`;
used by :mod:`jaxclear.fitting`).

Accelerometer model
-------------------
A real accelerometer with its conditioning amplifier does not report the rigid-body
acceleration :math:`a(t)` of the slider: the impact spikes of a clearance joint (tens of
microseconds) are smoothed by its bandwidth, and the output has a gain and an offset. The
model is

.. math::
    \ddot y + \sqrt2\,\omega_c \dot y + \omega_c^2 y = \omega_c^2 a(t), \qquad
    a_\text{sensor}(t) = g\, y(t) + b,

a 2nd-order Butterworth low-pass with cut-off :math:`f_c = \omega_c / 2\pi` [Hz] (unit DC gain),
gain ``g`` [-] and bias ``b`` [m/s^2]; ``order=1`` takes the first-order low-pass
:math:`\dot y = \omega_c (a - y)` instead (an RC stage: many charge amplifiers and DAQ
anti-alias filters). ``cutoff_hz=None`` means an ideal (infinitely fast) sensor:
:math:`a_\text{sensor} = g a + b`. A ``delay`` :math:`\tau` [s] (a recorder's clock offset or
a filter's group delay not modelled) shifts the output: the sample at record time :math:`t` is
the model's output at :math:`t - \tau`.

The filter is applied to the simulated acceleration in continuous time, not to the record's
samples: the simulation writes :math:`a` on a grid ``oversample`` times finer than the record,
the linear ODE above is advanced exactly between grid points for an input that is linear
between them (first-order hold: :math:`x_{k+1} = \Phi x_k + (\Gamma_0 - \Gamma_1) u_k +
\Gamma_1 u_{k+1}`, with :math:`\Phi, \Gamma_0, \Gamma_1` from one matrix exponential), and
the output is interpolated linearly to the record's sample times. Sampling the spikes at the
record rate first would alias them. The filter starts at rest on the first input value
(:math:`y = a(t_0)`, :math:`\dot y = 0`), i.e. the sensor settled before the record begins;
for :math:`f_c` = 20 kHz that start transient decays in about 30 microseconds.

Everything here is linear in the input and written in ``jax.numpy``/``lax.scan``, so gradients
flow through it (gain and bias are array leaves and may be fitted; the cut-off is structure).

Clock alignment
---------------
:func:`record_times` maps the record's times to simulation time: ``align="time"`` takes the
first sample as :math:`t = 0` of the simulation (plus ``time_offset``); ``align="crank"`` uses
the ``crank_angle_rad`` column and the crank speed, :math:`t = (\varphi - \varphi_0)/\omega`,
which removes a clock offset or drift of the recorder.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError, check_range


class Accelerometer(eqx.Module):
    """The sensor model of the module docstring.

    Attributes:
        cutoff_hz: -3 dB cut-off frequency of the 2nd-order Butterworth low-pass [Hz] (> 0),
            or ``None`` for no filter (static: it sets the structure of the filter).
        gain: output gain g [-] (array leaf).
        bias: output offset b [m/s^2] (array leaf).
        order: 1 or 2, the low-pass's order (static; default 2, the Butterworth).
        delay: the output's delay tau [s] (array leaf; applied where the output is sampled at
            the record's times, :mod:`jaxclear.fitting.window`).
        oversample: the simulation grid is this many times finer than the record (static,
            >= 1); the default 4 resolves the filter (and a 50-microsecond impact at a
            200 kHz record) with a first-order-hold error far below 20 dB noise.
    """

    cutoff_hz: float | None = eqx.field(static=True)
    gain: jax.Array
    bias: jax.Array
    oversample: int = eqx.field(static=True)
    order: int = eqx.field(static=True)
    delay: jax.Array

    def __init__(self, cutoff_hz: float | None = None, gain=1.0, bias=0.0, oversample: int = 4, order: int = 2,
                 delay=0.0):
        if cutoff_hz is not None:
            check_range("sensor cutoff_hz", cutoff_hz, low=0.0, low_open=True, unit="Hz")
            cutoff_hz = float(cutoff_hz)
        check_range("sensor gain", gain)
        check_range("sensor bias", bias, unit="m/s^2")
        if int(oversample) != oversample or oversample < 1:
            raise ParameterError(f"sensor oversample = {oversample!r} must be an integer >= 1")
        self.cutoff_hz = cutoff_hz
        self.gain = jnp.asarray(gain, dtype=float)
        self.bias = jnp.asarray(bias, dtype=float)
        self.oversample = int(oversample)
        if order not in (1, 2):
            raise ParameterError(f"sensor order = {order!r} must be 1 (first-order low-pass) or 2 (Butterworth)")
        self.order = int(order)
        check_range("sensor delay", delay, unit="s")
        self.delay = jnp.asarray(delay, dtype=float)

    def describe(self) -> str:
        kind = "2nd-order Butterworth" if self.order == 2 else "1st-order"
        f = "no low-pass" if self.cutoff_hz is None else f"{kind} low-pass {self.cutoff_hz:g} Hz"
        delay = f", delay {float(self.delay):g} s" if float(self.delay) != 0.0 else ""
        return f"{f}, gain {float(self.gain):g}, bias {float(self.bias):g} m/s^2{delay}"

    def filter(self, dt: float, u):
        """Low-pass ``u`` sampled every ``dt`` seconds [m/s^2] (exact for piecewise-linear input).
        Without a cut-off, returns ``u``. Gain and bias are not applied here."""
        if self.cutoff_hz is None:
            return u
        phi, g0, g1 = _foh_matrices(self.cutoff_hz, float(dt), self.order)
        phi, g0, g1 = (jnp.asarray(m, dtype=u.dtype) for m in (phi, g0, g1))
        x0 = jnp.stack([u[0], jnp.zeros((), u.dtype)][: self.order])

        def step(x, uu):
            u0, u1 = uu
            x = phi @ x + (g0 - g1) * u0 + g1 * u1
            return x, x[0]

        _, y = jax.lax.scan(step, x0, (u[:-1], u[1:]))
        return jnp.concatenate([u[:1], y])

    def __call__(self, dt: float, u):
        """Sensor output for the true acceleration ``u`` on a uniform grid of spacing ``dt``."""
        return self.gain * self.filter(dt, u) + self.bias


def _foh_matrices(cutoff_hz: float, dt: float, order: int = 2):
    """(Phi, Gamma0, Gamma1) of the low-pass of ``order`` (2: Butterworth, 1: first-order) for
    step ``dt`` (first-order hold)."""
    wc = 2.0 * math.pi * cutoff_hz
    if order == 2:
        a = np.array([[0.0, 1.0], [-wc * wc, -math.sqrt(2.0) * wc]])
        b = np.array([0.0, wc * wc])
    else:
        a, b = np.array([[-wc]]), np.array([wc])
    n = order
    m = np.zeros((n + 2, n + 2))
    m[:n, :n] = a
    m[:n, n] = b
    m[n, n + 1] = 1.0
    import scipy.linalg  # here, not at module level: it adds ~0.2 s to every `import jaxclear`

    e = scipy.linalg.expm(m * dt)
    return e[:n, :n], e[:n, n], e[:n, n + 1] / dt


# --------------------------------------------------------------------------------------
# Clocks and grids
# --------------------------------------------------------------------------------------


def record_times(meas, align: str = "time", speed: float | None = None, angle0: float = 0.0,
                 time_offset: float = 0.0) -> np.ndarray:
    """Simulation times [s] of the record's samples.

    Args:
        meas: :class:`jaxclear.io.Measurements`.
        align: ``"time"``: ``t = time_s - time_s[0] + time_offset`` (the first sample is the
            simulation's start, the default of ``jaxclear fit``); ``"crank"``: ``t = (crank_angle_rad
            - angle0) / speed`` (needs that column and a constant crank speed [rad/s]).
        speed: crank speed [rad/s] for ``align="crank"``.
        angle0: crank angle at the simulation's start [rad].
        time_offset: added to the times [s] (``align="time"`` only).
    """
    if align == "time":
        return np.asarray(meas.time_s, dtype=float) - float(meas.time_s[0]) + float(time_offset)
    if align == "crank":
        where = f"{meas.path}: " if getattr(meas, "path", "") else ""
        if meas.crank_angle_rad is None:
            raise ParameterError(f"{where}align='crank' needs the column 'crank_angle_rad', which the record lacks")
        if speed is None or not speed > 0:
            raise ParameterError(f"align='crank' needs a positive crank speed [rad/s], got {speed!r}")
        t = (np.asarray(meas.crank_angle_rad, dtype=float) - angle0) / speed
        bad = np.nonzero(np.diff(t) <= 0.0)[0]
        if bad.size:
            raise ParameterError(
                f"{where}column 'crank_angle_rad' is not strictly increasing at data row {int(bad[0]) + 2} "
                "(needed to align by crank angle; the angle must be unwrapped)"
            )
        return t
    raise ParameterError(f"align = {align!r}; valid: 'time', 'crank'")


def uniform_spacing(t) -> float:
    """Median sample spacing [s] of an increasing time vector."""
    d = np.diff(np.asarray(t, dtype=float))
    if d.size == 0:
        raise ParameterError("a record needs at least 2 samples to have a sample spacing")
    return float(np.median(d))


__all__ = ["Accelerometer", "record_times", "uniform_spacing"]
