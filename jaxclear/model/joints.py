r"""Ideal joints: holonomic constraint equations :math:`\Phi(q, t) = 0` between two bodies
(Nikravesh 1988, ch. 3). Each joint is a class with its equations; the Jacobians come from
automatic differentiation (:mod:`jaxclear.model.constraints`).

Extension point: :class:`AbstractConstraint` (equations of joints and drivers). A new joint is
one subclass with ``n_equations``, ``bodies`` and ``equations``.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._errors import MechanismError
from .._types import Array, Float, Scalar, Vec2
from .bodies import vec2
from .geometry import dot2, perp, rotate



class AbstractConstraint(eqx.Module):
    """Holonomic constraint equations of an ideal joint or a driver.

    Subclasses set ``n_equations`` (class variable) and implement :meth:`equations` and
    :meth:`bodies`; the mechanism validates the named bodies and points."""

    n_equations: ClassVar[int]

    @abc.abstractmethod
    def equations(self, mech, q: Float[Array, " n"], t: Scalar) -> Float[Array, " e"]:
        r""":math:`\Phi` rows of this joint, shape ``(n_equations,)``."""

    @abc.abstractmethod
    def bodies(self) -> tuple[str, ...]:
        """Names of the bodies it connects (``"ground"`` allowed)."""

    def points(self) -> tuple[tuple[str, str], ...]:
        """``(body, point)`` pairs it uses (checked to exist)."""
        return ()

    @property
    def label(self) -> str:
        """Human-readable label for messages: ``Kind(body-body)``."""
        return f"{type(self).__name__}({'-'.join(self.bodies())})"


class AbstractJoint(AbstractConstraint):
    """An ideal joint between point ``point_i`` of ``body_i`` and ``point_j`` of ``body_j``."""

    body_i: eqx.AbstractVar[str]
    point_i: eqx.AbstractVar[str]
    body_j: eqx.AbstractVar[str]
    point_j: eqx.AbstractVar[str]

    def bodies(self) -> tuple[str, ...]:
        return (self.body_i, self.body_j)

    def points(self) -> tuple[tuple[str, str], ...]:
        return ((self.body_i, self.point_i), (self.body_j, self.point_j))

    def _separation(self, mech, q) -> Float[Array, "2"]:
        return mech.point_position(q, self.body_i, self.point_i) - mech.point_position(q, self.body_j, self.point_j)


class Revolute(AbstractJoint):
    """Ideal pin (2 eq.): point ``point_i`` of ``body_i`` coincides with ``point_j`` of ``body_j``."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)

    n_equations: ClassVar[int] = 2

    def equations(self, mech, q, t):
        return self._separation(mech, q)


class Translational(AbstractJoint):
    r"""Prismatic joint (2 eq.): the relative angle :math:`\phi_j - \phi_i` stays ``angle`` [rad]
    and point ``point_j`` of ``body_j`` stays on the line through ``point_i`` of ``body_i``
    along the body-fixed unit direction ``axis`` of ``body_i``."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)
    axis: Vec2
    angle: Scalar

    n_equations: ClassVar[int] = 2

    def __init__(self, body_i, point_i, body_j, point_j, axis=(1.0, 0.0), angle=0.0):
        self.body_i, self.point_i, self.body_j, self.point_j = body_i, point_i, body_j, point_j
        ax = vec2("translational axis", axis)
        norm = float(jnp.linalg.norm(ax))
        if norm == 0.0:
            raise MechanismError("translational axis must be a non-zero vector")
        self.axis = ax / norm
        self.angle = jnp.asarray(angle, dtype=float)

    def equations(self, mech, q, t):
        normal = rotate(mech.angle(q, self.body_i), perp(self.axis))
        rel = mech.angle(q, self.body_j) - mech.angle(q, self.body_i) - self.angle
        return jnp.stack([rel, -dot2(normal, self._separation(mech, q))])


class PointOnLine(AbstractJoint):
    r"""Ideal pin in a slot (1 eq.): point ``point_j`` of ``body_j`` stays on the line through
    ``point_i`` of ``body_i`` along the body-fixed unit direction ``axis`` of ``body_i``
    (the ideal pin-in-slot joint; the slot's ends are not modelled)."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)
    axis: Vec2

    n_equations: ClassVar[int] = 1

    def __init__(self, body_i, point_i, body_j, point_j, axis=(1.0, 0.0)):
        self.body_i, self.point_i, self.body_j, self.point_j = body_i, point_i, body_j, point_j
        ax = vec2("slot axis", axis)
        norm = float(jnp.linalg.norm(ax))
        if norm == 0.0:
            raise MechanismError("slot axis must be a non-zero vector")
        self.axis = ax / norm

    def equations(self, mech, q, t):
        normal = rotate(mech.angle(q, self.body_i), perp(self.axis))
        return -dot2(normal, self._separation(mech, q))[None]


class Fixed(AbstractJoint):
    """Weld (3 eq.): points coincide and the relative angle stays ``angle`` [rad]."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)
    angle: Scalar

    n_equations: ClassVar[int] = 3

    def __init__(self, body_i, point_i, body_j, point_j, angle=0.0):
        self.body_i, self.point_i, self.body_j, self.point_j = body_i, point_i, body_j, point_j
        self.angle = jnp.asarray(angle, dtype=float)

    def equations(self, mech, q, t):
        rel = mech.angle(q, self.body_j) - mech.angle(q, self.body_i) - self.angle
        return jnp.concatenate([self._separation(mech, q), rel[None]])
