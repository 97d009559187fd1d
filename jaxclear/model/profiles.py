r"""Time profiles: scalar functions of time :math:`v(t)` with their exact integral and derivative,
for drivers whose speed varies (:class:`~jaxclear.model.drivers.ProfileDriver`: :math:`v` is the
angular speed, its integral the angle, its derivative the angular acceleration) and for loads
that vary in time (:class:`~jaxclear.PointForce`, :class:`~jaxclear.Torque`: :math:`v` is a
dimensionless factor on the load). Every profile is closed-form and traceable (parameters are
arrays: ``jit``, ``vmap`` and ``grad`` apply); mechanism files name them by ``kind``.

=============  =======================================================================  ==============
kind           :math:`v(t)`                                                              parameters
=============  =======================================================================  ==============
``constant``   :math:`v_0`                                                               ``value``
``ramp``       :math:`v_0\,s(t/T)`, :math:`s(\tau) = 3\tau^2 - 2\tau^3` for              ``value``,
               :math:`0 \le \tau \le 1` (0 before, 1 after)                              ``ramp_time``
``harmonic``   :math:`v_0 + a\sin(2\pi f t + \psi)`                                      ``value``,
                                                                                         ``amplitude``,
                                                                                         ``frequency``,
                                                                                         ``phase``
``table``      the monotone piecewise-cubic (PCHIP) interpolant of :math:`(t_k, v_k)`,   ``time``,
               :math:`v_0` held before the first and :math:`v_n` after the last point   ``values``
=============  =======================================================================  ==============

The ramp is the cubic smooth step: speed, its slope and the angle are continuous, the slope
:math:`6v_0\tau(1-\tau)/T` is 0 at both ends, so a driven crank starts from rest without a jump
in acceleration. Its integral is :math:`v_0T(\tau^3 - \tau^4/2)` (:math:`v_0T/2` at the end of
the ramp, then :math:`v_0(t - T/2)`). The harmonic profile's integral is
:math:`v_0t - a(\cos(2\pi ft + \psi) - \cos\psi)/(2\pi f)`.

The table's interpolant is Fritsch and Carlson's monotone cubic (F.N. Fritsch, R.E. Carlson,
"Monotone piecewise cubic interpolation", SIAM J. Numer. Anal. 17 (1980) 238-246) as SciPy's
``PchipInterpolator`` builds it: C1 (speed and acceleration continuous), no overshoot between
the points of a monotone speed ramp (a cubic spline would overshoot). SciPy computes the
coefficients once, when the table is read; the evaluation here is a few lines of JAX, because
SciPy's piecewise polynomials cannot be traced by JAX (and ``interpax`` is not a dependency).
The integral is the exact antiderivative of the same cubics.
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError, check_finite, check_range
from .._types import Array, Float, Scalar

#: profile kinds of mechanism files -> class (filled below)
PROFILE_KINDS: dict[str, type] = {}


class AbstractProfile(eqx.Module):
    """A scalar function of time with its exact integral and time derivative."""

    kind: str = eqx.field(static=True)

    @abc.abstractmethod
    def value(self, t: Scalar) -> Scalar:
        """:math:`v(t)`."""

    @abc.abstractmethod
    def integral(self, t: Scalar) -> Scalar:
        r""":math:`\int_0^t v\,dt'`."""

    @abc.abstractmethod
    def derivative(self, t: Scalar) -> Scalar:
        """:math:`dv/dt`."""

    def end_time(self) -> float:
        """A time span that shows the profile whole [s] (drawings; ``jaxclear check``)."""
        return 1.0


class ConstantProfile(AbstractProfile):
    """:math:`v = v_0` (``value``)."""

    value0: Scalar

    def __init__(self, value=1.0):
        check_finite("value", value)
        self.kind, self.value0 = "constant", jnp.asarray(value, dtype=float)

    def value(self, t):
        return self.value0 + 0.0 * t

    def integral(self, t):
        return self.value0 * t

    def derivative(self, t):
        return 0.0 * t


class RampProfile(AbstractProfile):
    """The cubic smooth step from 0 to ``value`` over ``ramp_time`` [s] > 0 (module docstring)."""

    value0: Scalar
    ramp_time: Scalar

    def __init__(self, value=1.0, ramp_time=0.01):
        check_finite("value", value)
        check_range("ramp_time", ramp_time, low=0.0, low_open=True, unit="s")
        self.kind = "ramp"
        self.value0, self.ramp_time = jnp.asarray(value, dtype=float), jnp.asarray(ramp_time, dtype=float)

    def _tau(self, t):
        # jnp.where rather than clip: clip's derivative is 1/2 where t meets a bound exactly
        x = t / self.ramp_time
        return jnp.where(x < 0.0, 0.0, jnp.where(x > 1.0, 1.0, x))

    def value(self, t):
        tau = self._tau(t)
        return self.value0 * tau * tau * (3.0 - 2.0 * tau)

    def integral(self, t):
        tau = self._tau(t)
        inside = self.value0 * self.ramp_time * (tau**3 - 0.5 * tau**4)
        return jnp.where(t > self.ramp_time, self.value0 * (t - 0.5 * self.ramp_time), inside)

    def derivative(self, t):
        tau = self._tau(t)
        return 6.0 * self.value0 * tau * (1.0 - tau) / self.ramp_time

    def end_time(self):
        return 2.0 * float(self.ramp_time)


class HarmonicProfile(AbstractProfile):
    """:math:`v_0 + a\\sin(2\\pi f t + \\psi)`: ``value`` :math:`v_0`, ``amplitude`` :math:`a`,
    ``frequency`` :math:`f` [Hz] > 0, ``phase`` :math:`\\psi` [rad]."""

    value0: Scalar
    amplitude: Scalar
    frequency: Scalar
    phase: Scalar

    def __init__(self, value=1.0, amplitude=0.1, frequency=1.0, phase=0.0):
        for name, v in (("value", value), ("amplitude", amplitude), ("phase", phase)):
            check_finite(name, v)
        check_range("frequency", frequency, low=0.0, low_open=True, unit="Hz")
        self.kind = "harmonic"
        self.value0, self.amplitude = jnp.asarray(value, dtype=float), jnp.asarray(amplitude, dtype=float)
        self.frequency, self.phase = jnp.asarray(frequency, dtype=float), jnp.asarray(phase, dtype=float)

    def value(self, t):
        return self.value0 + self.amplitude * jnp.sin(2.0 * math.pi * self.frequency * t + self.phase)

    def integral(self, t):
        w = 2.0 * math.pi * self.frequency
        return self.value0 * t - self.amplitude * (jnp.cos(w * t + self.phase) - jnp.cos(self.phase)) / w

    def derivative(self, t):
        w = 2.0 * math.pi * self.frequency
        return self.amplitude * w * jnp.cos(w * t + self.phase)

    def end_time(self):
        return 3.0 / float(self.frequency)


class TableProfile(AbstractProfile):
    """The PCHIP interpolant of a table (module docstring): ``time`` [s], strictly increasing,
    from 0, at least 2 points; ``values`` of the same length, finite."""

    time: Float[Array, " n"]
    coefficients: Float[Array, "4 m"]  # the cubic of each interval in powers of t - t_k
    integrals: Float[Array, "5 m"]  # its antiderivative, 0 at t = 0
    values: Float[Array, " n"]

    def __init__(self, time, values):
        from scipy.interpolate import PchipInterpolator

        t, v = np.asarray(time, dtype=float).ravel(), np.asarray(values, dtype=float).ravel()
        if t.size < 2 or t.size != v.size:
            raise ParameterError(f"table: time and values must have the same length >= 2, got {t.size} and {v.size}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ParameterError("table: time and values must be finite numbers")
        if t[0] != 0.0 or not np.all(np.diff(t) > 0.0):
            raise ParameterError(f"table: time must start at 0 s and increase strictly, got {t[:4].tolist()}...")
        pchip = PchipInterpolator(t, v)
        self.kind, self.time, self.values = "table", jnp.asarray(t), jnp.asarray(v)
        self.coefficients, self.integrals = jnp.asarray(pchip.c), jnp.asarray(pchip.antiderivative().c)

    def _piece(self, t):
        return table_piece(self.time, t)

    def value(self, t):
        _, k, x = self._piece(t)
        return cubic(self.coefficients[:, k], x)

    def integral(self, t):
        tc, k, x = self._piece(t)
        c = self.integrals[:, k]
        inside = (((c[0] * x + c[1]) * x + c[2]) * x + c[3]) * x + c[4]
        return inside + self.values[-1] * jnp.maximum(t - self.time[-1], 0.0)  # held value after the table

    def derivative(self, t):
        _, k, x = self._piece(t)
        inside = cubic_slope(self.coefficients[:, k], x)
        return jnp.where((t < self.time[0]) | (t > self.time[-1]), 0.0, inside)

    def end_time(self):
        return float(self.time[-1])


def table_piece(knots: Float[Array, " n"], x: Scalar):
    """``(xc, k, xc - knots[k])``: ``x`` held to ``[knots[0], knots[-1]]`` and the interval ``k``
    of a piecewise cubic on strictly increasing ``knots`` (the PCHIP tables here and of
    :class:`~jaxclear.model.curves.TableCurve`)."""
    xc = jnp.where(x < knots[0], knots[0], jnp.where(x > knots[-1], knots[-1], x))  # not clip (1/2)
    k = jnp.clip(jnp.searchsorted(knots, xc, side="right") - 1, 0, knots.shape[0] - 2)
    return xc, k, xc - knots[k]


def cubic(c: Float[Array, " 4"], x: Scalar) -> Scalar:
    """:math:`c_0x^3 + c_1x^2 + c_2x + c_3` (one interval of SciPy's piecewise-polynomial layout)."""
    return ((c[0] * x + c[1]) * x + c[2]) * x + c[3]


def cubic_slope(c: Float[Array, " 4"], x: Scalar) -> Scalar:
    """The derivative of :func:`cubic`: :math:`3c_0x^2 + 2c_1x + c_2`."""
    return (3.0 * c[0] * x + 2.0 * c[1]) * x + c[2]


PROFILE_KINDS.update(constant=ConstantProfile, ramp=RampProfile, harmonic=HarmonicProfile, table=TableProfile)
