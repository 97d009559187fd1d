r"""Drivers: prescribed motion as constraint equations (Nikravesh 1988, sec. 3.5), and the one
lookup of a mechanism's crank (:func:`crank_driver`) and its one period (:func:`crank_period`).

Extension point: :class:`AbstractDriver` (a subclass of
:class:`~jaxclear.model.joints.AbstractConstraint` acting on one body).
"""

from __future__ import annotations

from typing import Callable, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import MechanismError, ParameterError, check_finite, is_concrete
from .._parameters import FREE, Parameter
from .._types import Scalar
from .._units import rad_s_to_rpm, rpm_to_rad_s
from .bodies import GROUND
from .joints import AbstractConstraint
from .profiles import AbstractProfile


COORDINATES = {"x": 0, "y": 1, "phi": 2}


class AbstractDriver(AbstractConstraint):
    """A driver prescribes the motion of ``body`` (one equation per prescribed coordinate)."""

    body: eqx.AbstractVar[str]


class AngleDriver(AbstractDriver):
    r"""Constant-speed rotation (1 eq.): :math:`\phi_{body} - \phi_{ref} - (\phi_0 + \omega t) = 0`.

    Attributes:
        body: driven body; ``relative_to``: reference body (default ground).
        speed: :math:`\omega` [rad/s]; ``angle0``: :math:`\phi_0` [rad].
    """

    body: str = eqx.field(static=True)
    speed: Scalar
    angle0: Scalar
    relative_to: str = eqx.field(static=True)

    n_equations: ClassVar[int] = 1
    #: named parameters of the crank (the first AngleDriver, :func:`crank_driver`; no suffix)
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "speed": Parameter("speed", "rad/s", **FREE, doc="crank speed"),
        "speed_rpm": Parameter("speed", "rpm", **FREE, doc="crank speed", read=lambda d: rad_s_to_rpm(d.speed),
                               write=lambda d, value: rpm_to_rad_s(value)),
        "angle0": Parameter("angle0", "rad", **FREE, doc="crank angle at t = 0"),
    }

    def __init__(self, body, speed, angle0=0.0, relative_to=GROUND):
        check_finite("driver speed", speed)
        self.body = body
        self.speed = jnp.asarray(speed, dtype=float)
        self.angle0 = jnp.asarray(angle0, dtype=float)
        self.relative_to = relative_to

    def bodies(self):
        return (self.body, self.relative_to)

    def equations(self, mech, q, t):
        rel = mech.angle(q, self.body) - mech.angle(q, self.relative_to)
        return (rel - self.angle0 - self.speed * t)[None]


class ProfileDriver(AbstractDriver):
    r"""Rotation at a speed that varies in time (1 eq.):
    :math:`\phi_{body} - \phi_{ref} - (\phi_0 + \int_0^t\omega\,dt') = 0` with the angular
    speed :math:`\omega(t)` [rad/s] of a time profile (:mod:`jaxclear.model.profiles`: constant,
    smooth ramp-up, harmonic fluctuation, PCHIP table), integrated in closed form.

    Attributes:
        body: driven body; ``relative_to``: reference body (default ground).
        profile: the speed profile :math:`\omega(t)` [rad/s]; ``angle0``: :math:`\phi_0` [rad].
    """

    body: str = eqx.field(static=True)
    profile: AbstractProfile
    angle0: Scalar
    relative_to: str = eqx.field(static=True)

    n_equations: ClassVar[int] = 1

    def __init__(self, body, profile, angle0=0.0, relative_to=GROUND):
        if not isinstance(profile, AbstractProfile):
            raise ParameterError(f"ProfileDriver needs a time profile (jaxclear.model.profiles), got "
                                 f"{type(profile).__name__}")
        check_finite("angle0", angle0)
        self.body, self.profile, self.relative_to = body, profile, relative_to
        self.angle0 = jnp.asarray(angle0, dtype=float)

    def bodies(self):
        return (self.body, self.relative_to)

    def angle(self, t):
        """Prescribed angle [rad] at ``t``; ``speed(t)`` [rad/s] and ``acceleration(t)`` [rad/s^2]
        below are its exact derivatives."""
        return self.angle0 + self.profile.integral(t)

    def speed(self, t):
        return self.profile.value(t)

    def acceleration(self, t):
        return self.profile.derivative(t)

    def equations(self, mech, q, t):
        rel = mech.angle(q, self.body) - mech.angle(q, self.relative_to)
        return (rel - self.angle(t))[None]


class FunctionDriver(AbstractDriver):
    """User-prescribed coordinate (1 eq.): ``q[body, coordinate] - function(t) = 0``.

    ``coordinate`` is ``"x"``, ``"y"`` or ``"phi"``; ``function`` maps time [s] to the
    coordinate [m or rad] and must be a JAX-traceable function (it is differentiated twice).
    """

    body: str = eqx.field(static=True)
    coordinate: str = eqx.field(static=True)
    function: Callable = eqx.field(static=True)

    n_equations: ClassVar[int] = 1

    def __init__(self, body, coordinate, function):
        if coordinate not in COORDINATES:
            raise MechanismError(f"driver coordinate must be one of {list(COORDINATES)}, got {coordinate!r}")
        self.body, self.coordinate, self.function = body, coordinate, function

    def bodies(self):
        return (self.body,)

    def equations(self, mech, q, t):
        i = mech.body_index(self.body)
        return (q[3 * i + COORDINATES[self.coordinate]] - self.function(t))[None]


def crank_driver(mech) -> tuple[int, AngleDriver] | None:
    """The mechanism's crank: ``(index in mech.drivers, driver)`` of its first
    :class:`AngleDriver`, or ``None``. The one lookup that 'revolutions', 'speed' and the crank
    angle of outputs go through."""
    for i, d in enumerate(mech.drivers):
        if isinstance(d, AngleDriver):
            return i, d
    return None


def crank_period(mech, revolutions=1.0) -> jax.Array:
    r"""The one crank period: the duration [s] of ``revolutions`` turns of the crank
    (:func:`crank_driver`) at its constant speed :math:`\omega` [rad/s],

    .. math:: T = N_{rev}\, 2\pi / |\omega|

    written as the jnp expression ``revolutions * 2.0 * jnp.pi / jnp.abs(speed)`` on the driver's
    ``speed`` leaf, so it traces: inside ``jit``, ``vmap`` and ``grad`` a swept or differentiated
    speed flows through it (:math:`dT/d\omega = -N_{rev}\, 2\pi\,\mathrm{sign}(\omega)/\omega^2`).
    On the host ``float()`` of it is ``revolutions * 2 pi / |omega|`` in float64.

    Args:
        mech: the mechanism (its first :class:`AngleDriver` is the crank).
        revolutions: crank revolutions :math:`N_{rev}` [-], a number or an array that
            broadcasts against the speed (default 1: one period).

    Returns:
        :math:`T` [s], a float64 array of the broadcast shape of ``revolutions`` and the speed
        (0-d for one mechanism and a number of revolutions).

    Raises:
        ParameterError: the mechanism has no crank driver (no :class:`AngleDriver`; a
            :class:`ProfileDriver` has no constant period), or its speed is concrete (not
            traced) and 0 rad/s somewhere: the period is undefined (give ``t_end`` [s] instead
            of revolutions).
    """
    found = crank_driver(mech)
    if found is None:
        raise ParameterError(f"mechanism {mech.name!r} has no crank driver (AngleDriver), so it has "
                             "no crank period: give t_end [s] instead of revolutions")
    speed = found[1].speed
    if is_concrete(speed) and bool(np.any(np.asarray(speed) == 0.0)):
        raise ParameterError(f"mechanism {mech.name!r}: the crank driver's speed is 0 rad/s, so the "
                             "crank period (and revolutions) is undefined: give t_end [s] instead")
    return revolutions * 2.0 * jnp.pi / jnp.abs(speed)
