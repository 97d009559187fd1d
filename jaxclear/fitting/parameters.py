"""Names, values and unconstrained coordinates of the fitted parameters.

The fit works in unconstrained coordinates ``z`` (the transforms of :mod:`jaxclear.params`):
``z = log(theta)`` for positive parameters (stiffness [N/m^n], clearance [m], friction [-],
masses [kg], ``sensor_gain`` [-]), ``z = logit(theta)`` for restitution [-] in (0, 1), and
``z = theta / s`` for ``sensor_bias`` [m/s^2] with ``s`` the RMS of the measured acceleration
over the fitted windows [m/s^2], ``z = tau / 10 us`` for ``sensor_delay`` [s].
"""

from __future__ import annotations

import math
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .. import params
from .._errors import JaxclearError, ParameterError
from ..model import Mechanism
from ..plot import law_label
from ..analysis.sensor import Accelerometer

#: Free parameters by default.
DEFAULT_FREE = ("stiffness", "restitution")
#: Parameters of the sensor that may be fitted besides the mechanism's: name -> (unit, lower
#: bound, upper bound, transform, description) (see :mod:`jaxclear.params`).
SENSOR_PARAMETERS = {
    "sensor_gain": ("-", 0.0, None, "log", "accelerometer gain"),
    "sensor_bias": ("m/s^2", None, None, "scaled", "accelerometer bias"),
    "sensor_delay": ("s", None, None, "delay", "delay of the record behind the model (clock offset)"),
}
#: Unit of ``sensor_delay``'s unconstrained coordinate [s]: half a sample at 50 kHz, so that a
#: step of 1 in ``z`` moves the model by about one sample of a laboratory record.
DELAY_UNIT = 1e-5
#: Known values reported in ``FitResult.fixed`` when they are not free.
REPORTED_FIXED = ("stiffness", "restitution", "clearance", "friction", "speed_rpm")


def check_name(mech: Mechanism, name: str):
    """Raise a ParameterError naming ``name`` unless it is a parameter of ``mech`` or of the sensor."""
    if name in SENSOR_PARAMETERS:
        return
    try:
        params.check_name(mech, name)
    except JaxclearError as err:
        raise ParameterError(f"free parameter {name!r} does not exist: {err}; besides the mechanism's names a fit "
                             f"frees the sensor's {', '.join(SENSOR_PARAMETERS)}") from None


def check_free(mech: Mechanism, free: Sequence[str], start: dict) -> tuple:
    """Validate the free names and the names of the start values; returns ``free`` as a tuple."""
    free = tuple(free)
    if not free:
        raise ParameterError("no free parameter: give at least one name (e.g. stiffness)")
    if len(set(free)) != len(free):
        raise ParameterError(f"free parameters listed twice: {list(free)}")
    for name in free:
        check_name(mech, name)
    for name in start:
        if name not in free:
            raise ParameterError(f"start value given for {name!r}, which is not a free parameter (free: {list(free)})")
    return free


def transform(name: str, mech: Mechanism | None = None) -> str:
    """The transform of ``name``: ``"log"``, ``"logit"``, ``"scaled"``, ``"delay"`` or ``"none"``;
    with ``mech``, also of the names its own classes declare (a force element of the user's:
    :func:`jaxclear.params.info`). Every function below takes ``mech`` for the same reason."""
    if name in SENSOR_PARAMETERS:
        return SENSOR_PARAMETERS[name][3]
    return params.info(name, mech).transform


def current_value(mech: Mechanism, sensor: Accelerometer, name: str) -> float:
    """The value of ``name`` in the mechanism or the sensor (SI units)."""
    if name == "sensor_gain":
        return float(sensor.gain)
    if name == "sensor_bias":
        return float(sensor.bias)
    if name == "sensor_delay":
        return float(sensor.delay)
    return float(params.get(mech, name))  # a derived stiffness (leaf None) reads its derived value


def check_start(mech: Mechanism, name: str, value: float):
    """Range check of a start value, including the fit transform's open bounds."""
    if name in SENSOR_PARAMETERS:
        low = SENSOR_PARAMETERS[name][1]
        if not math.isfinite(value):
            raise ParameterError(f"start value of {name!r} must be finite, got {value!r}")
        if low is not None and not value > low:
            raise ParameterError(f"start value {name} = {value:g} is outside its bounds ({low:g}, inf)")
        return
    try:
        params.validate(mech, name, value)
    except ParameterError as err:
        raise ParameterError(f"start value of {name!r} is outside its bounds: {err}") from None
    t = transform(name, mech)
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


def start_values(mech: Mechanism, sensor: Accelerometer, free: tuple, start: dict) -> dict:
    """``name: value`` at the start of the fit (given, else the mechanism's/sensor's), checked."""
    values = {}
    for name in free:
        value = float(start[name]) if name in start else current_value(mech, sensor, name)
        check_start(mech, name, value)
        values[name] = value
    return values


def fixed_values(mech: Mechanism, sensor: Accelerometer, free: tuple) -> dict:
    """The known (not fitted) values reported with the result."""
    fixed = {}
    for name in REPORTED_FIXED:
        if name not in free:
            try:
                fixed[name] = current_value(mech, sensor, name)
            except ParameterError:
                pass
    for name, value in (("sensor_gain", sensor.gain), ("sensor_bias", sensor.bias), ("sensor_delay", sensor.delay)):
        if name not in free:
            fixed[name] = float(value)
    return fixed


def to_z(name: str, value, scale: float = 1.0, mech: Mechanism | None = None):
    """Unconstrained coordinate of a parameter value (``scale``: the data RMS, for ``sensor_bias``)."""
    t = transform(name, mech)
    if t == "scaled":
        return jnp.asarray(value, dtype=float) / scale
    if t == "delay":
        return jnp.asarray(value, dtype=float) / DELAY_UNIT
    if name in SENSOR_PARAMETERS:
        return jnp.log(jnp.asarray(value, dtype=float))
    return params.to_unconstrained(name, value, mech)


def from_z(name: str, z, scale: float = 1.0, mech: Mechanism | None = None):
    """Inverse of :func:`to_z` (traceable)."""
    t = transform(name, mech)
    if t == "scaled":
        return z * scale
    if t == "delay":
        return z * DELAY_UNIT
    if name in SENSOR_PARAMETERS:
        return jnp.exp(z)
    return params.from_unconstrained(name, z, mech)


def dvalue_dz(name: str, z: float, scale: float, mech: Mechanism | None = None) -> float:
    """``d theta / d z`` at ``z`` (the delta method's factor)."""
    return float(jax.grad(lambda zz: from_z(name, zz, scale, mech))(jnp.asarray(z, dtype=float)))


def z_vector(free: Sequence[str], values: dict, scale: float, mech: Mechanism | None = None) -> np.ndarray:
    """``(P,)`` unconstrained coordinates of ``values`` in ``free`` order."""
    return np.array([float(to_z(n, values[n], scale, mech)) for n in free])


def values_of(free: Sequence[str], theta, scale: float, mech: Mechanism | None = None) -> list:
    """Parameter values (SI) of the unconstrained ``theta`` ``(P,)``, in ``free`` order."""
    return [float(from_z(n, theta[i], scale, mech)) for i, n in enumerate(free)]


def law_name(mech: Mechanism) -> str:
    """Label of the contact law of the first clearance joint ('' without one)."""
    return law_label(mech.clearance_joints[0].law) if mech.clearance_joints else ""
