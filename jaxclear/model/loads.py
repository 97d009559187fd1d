"""Applied loads: forces and torques given as functions of time and state, and gravity.

Extension point: :class:`AbstractLoad` (a generalized force on the coordinates).
"""

from __future__ import annotations

import abc
from typing import Callable, ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._errors import ParameterError, check_finite
from .._parameters import FREE, Parameter
from .._types import Array, Float, Scalar, Vec2
from .bodies import vec2
from .profiles import AbstractProfile


class AbstractLoad(eqx.Module):
    """An applied load on one or more bodies: its generalized force on all coordinates (the
    force elements between two bodies: :class:`~jaxclear.model.connectors.AbstractConnector`)."""

    @abc.abstractmethod
    def generalized_force(self, mech, t: Scalar, q, qdot) -> Float[Array, " n"]:
        """Generalized force (n,) [N, N, N m per body]."""

    @abc.abstractmethod
    def bodies(self) -> tuple[str, ...]:
        """The bodies it acts on (``"ground"`` allowed)."""

    def points(self) -> tuple[tuple[str, str], ...]:
        return ()

    def checks(self) -> tuple:
        """Its range rules (:class:`~jaxclear._errors.Rule`), evaluated at run time by
        :meth:`Mechanism.check <jaxclear.Mechanism.check>`. Default: none."""
        return ()

    @property
    def label(self) -> str:
        return f"{type(self).__name__}({', '.join(self.bodies())})"


def _factor(profile, t):
    """The load's time factor: 1, or the time profile's value at ``t``."""
    return 1.0 if profile is None else profile.value(t)


def _check_profile(profile):
    if profile is not None and not isinstance(profile, AbstractProfile):
        raise ParameterError(f"a load's profile must be a time profile (jaxclear.model.profiles), got "
                             f"{type(profile).__name__}")


class PointForce(AbstractLoad):
    """A force [N] in global axes at a body point: ``force`` times the time factor ``profile(t)``
    (a :mod:`~jaxclear.model.profiles` profile; none: 1), plus an optional
    ``function(t, q, qdot) -> (2,)`` (static, JAX-traceable; Python only)."""

    body: str = eqx.field(static=True)
    point: str = eqx.field(static=True)
    force: Vec2
    function: Callable | None = eqx.field(static=True, default=None)
    profile: AbstractProfile | None = None

    #: named parameters (``NAME:K``, ``K`` its index in ``mech.loads``): the constant part
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "load_x": Parameter("force", "N", **FREE, component=0,
                            doc="x of the force of a point load (load_x:K, K its index in mech.loads)"),
        "load_y": Parameter("force", "N", **FREE, component=1, doc="y of the force of a point load (load_y:K)"),
    }

    def __init__(self, body, point, force=(0.0, 0.0), function=None, profile=None):
        _check_profile(profile)
        self.body, self.point, self.function, self.profile = body, point, function, profile
        self.force = vec2("point force", force)

    def bodies(self):
        return (self.body,)

    def points(self):
        return ((self.body, self.point),)

    def generalized_force(self, mech, t, q, qdot):
        f = self.force * _factor(self.profile, t)
        f = f if self.function is None else f + self.function(t, q, qdot)
        return mech.point_load(q, self.body, mech.point_position(q, self.body, self.point), f)


class Torque(AbstractLoad):
    """A torque [N m] on a body: ``torque`` times the time factor ``profile(t)`` (none: 1), plus
    an optional ``function(t, q, qdot)`` (Python only)."""

    body: str = eqx.field(static=True)
    torque: Scalar
    function: Callable | None = eqx.field(static=True, default=None)
    profile: AbstractProfile | None = None

    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "torque": Parameter("torque", "N m", **FREE,
                            doc="torque of a torque load (torque:K, K its index in mech.loads)"),
    }

    def __init__(self, body, torque=0.0, function=None, profile=None):
        check_finite("torque", torque)
        _check_profile(profile)
        self.body, self.function, self.profile = body, function, profile
        self.torque = jnp.asarray(torque, dtype=float)

    def bodies(self):
        return (self.body,)

    def generalized_force(self, mech, t, q, qdot):
        tau = self.torque * _factor(self.profile, t)
        tau = tau if self.function is None else tau + self.function(t, q, qdot)
        i = mech.body_index(self.body)
        return jnp.zeros(mech.n_coordinates, q.dtype).at[3 * i + 2].add(tau)


def gravity_force(mech, dtype) -> Float[Array, " n"]:
    r"""Generalized gravity force :math:`[m_i g_x, m_i g_y, 0]` per body (n,) [N]."""
    m = mech.mass_matrix_diagonal()
    return (jnp.tile(jnp.concatenate([mech.gravity, jnp.zeros(1)]), mech.n_bodies) * m).astype(dtype)
