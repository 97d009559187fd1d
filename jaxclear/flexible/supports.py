r"""What holds and loads a lone beam: supports (constraint equations :math:`\Phi(e, t) = 0` on its
coordinates, fixed or moving with time) and point loads.

Extension point: :class:`AbstractSupport` (``n_equations``, ``equations(beam, e, t)``); the
Jacobian :math:`D = \partial\Phi/\partial e` and the acceleration terms come from automatic
differentiation (:mod:`jaxclear.flexible.motion`), as for the mechanism's joints
(:mod:`jaxclear.model.constraints`). A position or angle that moves is a
:class:`AbstractMotion` of time (:class:`SpinUp`, :class:`CirclePath`) or a constant.

* :class:`PinSupport` (2 eq.): the point at arc length :math:`s` stays at :math:`p(t)`:
  :math:`r(s) - p(t) = 0` (an ideal revolute joint to the ground or to a driven crank pin).
* :class:`ClampSupport` (3 eq.): also the slope keeps the direction :math:`\theta(t)`:
  :math:`n(\theta)\cdot r'(s) = 0`, :math:`n = (-\sin\theta, \cos\theta)`; the slope's length
  stays free, so the beam may stretch at the clamp (the cable element's clamp in Exudyn:
  :math:`r'_y` fixed for :math:`\theta = 0`).
* :class:`LineSupport` (1 eq.): the point stays on the line through :math:`p` at angle
  :math:`\alpha`: :math:`n(\alpha)\cdot(r(s) - p) = 0` (a massless slider).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._errors import MechanismError, check_finite, check_range, check_vec2
from .._types import Array, Float, Scalar, Vec2
from .beam import AncfBeam


class AbstractMotion(eqx.Module):
    """A prescribed scalar or 2-vector of time (an angle [rad], a position [m])."""

    @abc.abstractmethod
    def __call__(self, t: Scalar) -> Array:
        """The value at time ``t`` [s]."""


class SpinUp(AbstractMotion):
    r"""The spin-up angle of Kane, Ryan and Banerjee (1987) [rad]: the angular velocity rises
    smoothly from 0 to :math:`\Omega_s` over :math:`T_s`,

    .. math::
        \theta(t) = \frac{\Omega_s}{T_s}\Big[\frac{t^2}{2} + \Big(\frac{T_s}{2\pi}\Big)^2
        \Big(\cos\frac{2\pi t}{T_s} - 1\Big)\Big]\ (t < T_s), \qquad
        \theta(t) = \Omega_s\,(t - T_s/2)\ (t \ge T_s),

    so :math:`\dot\theta = (\Omega_s/T_s)[t - (T_s/2\pi)\sin(2\pi t/T_s)]` and :math:`\ddot\theta`
    is continuous. ``omega`` :math:`\Omega_s` [rad/s], ``duration`` :math:`T_s` [s] > 0."""

    omega: Scalar
    duration: Scalar

    def __init__(self, omega, duration):
        check_range("SpinUp omega", omega, unit="rad/s")
        check_range("SpinUp duration", duration, low=0.0, low_open=True, unit="s")
        self.omega, self.duration = jnp.asarray(omega, float), jnp.asarray(duration, float)

    def __call__(self, t):
        ts, w = self.duration, self.omega
        tc = jnp.minimum(t, ts)
        ramp = w / ts * (tc**2 / 2 + (ts / (2 * jnp.pi)) ** 2 * (jnp.cos(2 * jnp.pi * tc / ts) - 1))
        return jnp.where(t < ts, ramp, w * (t - ts / 2))


class CirclePath(AbstractMotion):
    """A point turning on a circle at constant speed: ``centre + radius (cos(phi0 + omega t),
    sin(phi0 + omega t))`` [m] (the pin of a crank driven at ``omega`` [rad/s])."""

    centre: Vec2
    radius: Scalar
    omega: Scalar
    phase: Scalar

    def __init__(self, centre, radius, omega, phase=0.0):
        check_range("CirclePath radius", radius, low=0.0, low_open=True, unit="m")
        check_finite("CirclePath omega", omega)
        self.centre = check_vec2("CirclePath centre", centre)
        self.radius, self.omega, self.phase = (jnp.asarray(x, float) for x in (radius, omega, phase))

    def __call__(self, t):
        a = self.phase + self.omega * t
        return self.centre + self.radius * jnp.stack([jnp.cos(a), jnp.sin(a)])


def _at(value, t):
    """A constant, or an :class:`AbstractMotion` evaluated at ``t``."""
    return value(t) if isinstance(value, AbstractMotion) else value


def _normal(angle) -> Vec2:
    return jnp.stack([-jnp.sin(angle), jnp.cos(angle)])


class AbstractSupport(eqx.Module):
    """Constraint equations on a beam's coordinates; subclasses set ``n_equations`` and
    implement :meth:`equations`. ``point``: the name of a beam point (checked by the beam)."""

    point: eqx.AbstractVar[str]
    n_equations: ClassVar[int]

    @abc.abstractmethod
    def equations(self, beam: AncfBeam, e: Float[Array, " n"], t: Scalar) -> Float[Array, " k"]:
        """:math:`\\Phi` rows, ``(n_equations,)``."""

    @property
    def label(self) -> str:
        return f"{type(self).__name__}({self.point})"


class PinSupport(AbstractSupport):
    """Ideal pin (2 eq.): beam point ``point`` stays at ``at`` [m] (a 2-vector or an
    :class:`AbstractMotion`)."""

    point: str = eqx.field(static=True)
    at: Vec2 | AbstractMotion
    n_equations: ClassVar[int] = 2

    def __init__(self, point: str, at=(0.0, 0.0)):
        self.point = point
        self.at = at if isinstance(at, AbstractMotion) else check_vec2(f"PinSupport({point}) at", at)

    def equations(self, beam, e, t):
        return beam.position(e, beam.point(self.point)) - _at(self.at, t)


class ClampSupport(AbstractSupport):
    """Clamp (3 eq.): beam point ``point`` stays at ``at`` [m] and its slope along the direction
    ``angle`` [rad] (a number or an :class:`AbstractMotion`, e.g. :class:`SpinUp`)."""

    point: str = eqx.field(static=True)
    at: Vec2 | AbstractMotion
    angle: Scalar | AbstractMotion
    n_equations: ClassVar[int] = 3

    def __init__(self, point: str, at=(0.0, 0.0), angle=0.0):
        self.point = point
        self.at = at if isinstance(at, AbstractMotion) else check_vec2(f"ClampSupport({point}) at", at)
        self.angle = angle if isinstance(angle, AbstractMotion) else jnp.asarray(
            check_finite(f"ClampSupport({point}) angle", angle), float)

    def equations(self, beam, e, t):
        s = beam.point(self.point)
        pin = beam.position(e, s) - _at(self.at, t)
        return jnp.concatenate([pin, jnp.sum(_normal(_at(self.angle, t)) * beam.slope(e, s))[None]])


class LineSupport(AbstractSupport):
    """Point on a line (1 eq.): beam point ``point`` stays on the line through ``through`` [m]
    at ``angle`` [rad] to the x axis (a massless slider on a guide)."""

    point: str = eqx.field(static=True)
    through: Vec2
    angle: Scalar
    n_equations: ClassVar[int] = 1

    def __init__(self, point: str, through=(0.0, 0.0), angle=0.0):
        self.point = point
        self.through = check_vec2(f"LineSupport({point}) through", through)
        self.angle = jnp.asarray(check_finite(f"LineSupport({point}) angle", angle), float)

    def equations(self, beam, e, t):
        gap = beam.position(e, beam.point(self.point)) - self.through
        return jnp.sum(_normal(self.angle) * gap)[None]


class BeamLoad(eqx.Module):
    """A constant global force ``force`` [N] at the beam point ``point`` (follows the point, keeps
    its direction)."""

    point: str = eqx.field(static=True)
    force: Vec2

    def __init__(self, point: str, force):
        self.point = point
        self.force = check_vec2(f"BeamLoad({point}) force", force)

    def generalized_force(self, beam: AncfBeam) -> Float[Array, " n"]:
        """:math:`S(s)^T f` (n,): constant, since :math:`r(s)` is linear in the coordinates."""
        return beam.point_force(beam.point(self.point), self.force)


def check_supports(beam: AncfBeam, supports, loads=()) -> None:
    """Eager: every support and load names a point of the beam (:class:`MechanismError` naming
    it), and there are fewer equations than coordinates."""
    for item in (*supports, *loads):
        beam.point(item.point)
    m = sum(c.n_equations for c in supports)
    if m >= beam.n_coordinates:
        raise MechanismError(f"{m} support equations for the {beam.n_coordinates} coordinates of beam "
                             f"{beam.name!r}: allowed at most {beam.n_coordinates - 1}")
