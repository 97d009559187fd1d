r"""Rigid bodies with named body-fixed points (Nikravesh, "Computer-Aided Analysis of Mechanical
Systems", Prentice-Hall 1988, generalized Cartesian coordinates).

Body ``i`` has coordinates :math:`q_i = [x_i, y_i, \phi_i]` (centroid position [m] and
orientation [rad]). The ground is not a body: it is named ``"ground"`` and has index ``-1``.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._errors import RESULTS, MechanismError, Rule, check_finite, check_range, check_vec2, first_failure
from .._parameters import FREE, POSITIVE, Parameter
from .._types import Array, ArrayLike, Float, Scalar, Vec2

GROUND = "ground"
"""The name of the frame: ``body_a``/``body_b`` of a joint fixed to it, ``ground.POINT`` of its points
(``Mechanism.ground_points``)."""


def vec2(name: str, value) -> Array:
    """``value`` as a finite float 2-vector; :class:`MechanismError` naming ``name`` otherwise."""
    return check_vec2(name, value, MechanismError)


def _centroid_moved(axis: int):
    """``write`` of ``centroid_x``/``centroid_y``: every point of the body moved by minus the
    shift along its ``axis`` (the centroid moves by the shift relative to the points)."""
    def write(body, value):
        shift = jnp.zeros(2, dtype=float).at[axis].set(value)
        return {p: jnp.asarray(v, dtype=float) - shift for p, v in body.points.items()}

    return write


def point_parameters(field: str) -> dict[str, Parameter]:
    """``point_x``, ``point_y``: the components of the named points in the dict leaf ``field``
    (``NAME:OWNER.POINT``)."""
    return {f"point_{c}": Parameter(field, "m", **FREE, component=k, keyed=True,
                                    doc=f"{c} of a body-fixed point (point_{c}:BODY.POINT)")
            for k, c in enumerate("xy")}


class Body(eqx.Module):
    """A rigid body.

    Attributes:
        name: unique name (static).
        mass: m [kg] > 0.
        inertia: J [kg m^2] > 0 about the centroid.
        points: named body-fixed points [m], relative to the centroid.
        position: initial guess of (x [m], y [m], phi [rad]) for the position solve.
        velocity: initial guess of (xdot, ydot, phidot); corrected to satisfy the constraints.
    """

    name: str = eqx.field(static=True)
    mass: Scalar
    inertia: Scalar
    points: dict[str, Vec2]
    position: Float[Array, "3"]
    velocity: Float[Array, "3"]

    #: named parameters (:mod:`jaxclear.params`, ``NAME:BODY``; points ``NAME:BODY.POINT``).
    #: ``centroid_x``/``centroid_y`` are derived names: the value, read as 0, is the centroid's
    #: shift relative to the points as given, made by moving every point the other way.
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "mass": Parameter("mass", "kg", **POSITIVE, doc="body mass (mass:BODY)"),
        "inertia": Parameter("inertia", "kg m^2", **POSITIVE, doc="body inertia (inertia:BODY)"),
        **{f"centroid_{c}": Parameter("points", "m", **FREE, read=lambda body: jnp.zeros((), dtype=float),
                                      write=_centroid_moved(k),
                                      doc=f"shift of a body's centroid along its {c} axis, its points moving the "
                                          f"other way (centroid_{c}:BODY)")
           for k, c in enumerate("xy")},
        **point_parameters("points"),
    }

    def __init__(
        self,
        name: str,
        mass: ArrayLike,
        inertia: ArrayLike,
        points: dict[str, ArrayLike] | None = None,
        position: ArrayLike = (0.0, 0.0, 0.0),
        velocity: ArrayLike = (0.0, 0.0, 0.0),
    ):
        if name == GROUND:
            raise MechanismError(f"{GROUND!r} is reserved for the fixed frame; choose another body name")
        check_range(f"mass of body {name!r}", mass, low=0.0, low_open=True, unit="kg")
        check_range(f"inertia of body {name!r}", inertia, low=0.0, low_open=True, unit="kg m^2")
        self.name = name
        self.mass = jnp.asarray(mass, dtype=float)
        self.inertia = jnp.asarray(inertia, dtype=float)
        self.points = {k: vec2(f"point {k!r} of body {name!r}", v) for k, v in (points or {}).items()}
        self.position = jnp.asarray(position, dtype=float).reshape(3)
        self.velocity = jnp.asarray(velocity, dtype=float).reshape(3)
        check_finite(f"position guess of body {name!r}", self.position)
        check_finite(f"velocity guess of body {name!r}", self.velocity)

    def check(self) -> RESULTS:
        """Traceable range check (run time): ``invalid_mass`` unless mass and inertia are
        finite and > 0."""
        return first_failure(*self.checks())

    def checks(self) -> tuple:
        """Mass [kg] and inertia [kg m^2] finite and > 0 (:class:`~jaxclear._errors.Rule` s,
        ``invalid_mass``)."""
        return (Rule("mass", self.mass, RESULTS.invalid_mass, low=0.0, low_open=True, unit="kg"),
                Rule("inertia", self.inertia, RESULTS.invalid_mass, low=0.0, low_open=True, unit="kg m^2"))
