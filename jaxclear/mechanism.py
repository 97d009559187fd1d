r"""Planar mechanisms as data (Nikravesh, "Computer-Aided Analysis of Mechanical Systems",
Prentice-Hall 1988, generalized Cartesian coordinates).

Body ``i`` has coordinates :math:`q_i = [x_i, y_i, \phi_i]` (centroid position [m] and
orientation [rad]); ``q`` stacks all bodies, shape ``(3 * n_bodies,)``. The ground is not a
body: it is named ``"ground"`` and has index ``-1``. A body-fixed point :math:`s'_P` [m] sits
at :math:`r_i + A(\phi_i) s'_P`.

Structure (names, which bodies a joint connects, which law) is static; every number
(masses, inertias, point coordinates, speeds, radii, law parameters) is an array leaf that
can be differentiated, vmapped or swept.
"""

from __future__ import annotations

from typing import Callable, Sequence

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .errors import MechanismError, check_finite, check_range

GROUND = "ground"

Vec2 = Float[Array, "2"]
Scalar = Float[Array, ""]


def _vec2(name: str, value) -> Array:
    arr = jnp.asarray(value, dtype=float)
    if arr.shape != (2,):
        raise MechanismError(f"{name} must be a 2-vector [x, y] in metres, got shape {arr.shape}")
    check_finite(name, arr)
    return arr


# --------------------------------------------------------------------------------------
# Bodies
# --------------------------------------------------------------------------------------


class Body(eqx.Module):
    """A rigid body.

    Attributes:
        name: unique name (static).
        mass: m [kg] > 0.
        inertia: J [kg m^2] > 0 about the centroid.
        points: named body-fixed points [m], relative to the centroid.
        position: initial guess of [x, y, phi] [m, m, rad] for the position solve.
        velocity: initial guess of [xdot, ydot, phidot]; corrected to satisfy the constraints.
    """

    name: str = eqx.field(static=True)
    mass: Scalar
    inertia: Scalar
    points: dict[str, Vec2]
    position: Float[Array, "3"]
    velocity: Float[Array, "3"]

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
        self.points = {k: _vec2(f"point {k!r} of body {name!r}", v) for k, v in (points or {}).items()}
        self.position = jnp.asarray(position, dtype=float).reshape(3)
        self.velocity = jnp.asarray(velocity, dtype=float).reshape(3)
        check_finite(f"position guess of body {name!r}", self.position)
        check_finite(f"velocity guess of body {name!r}", self.velocity)


# --------------------------------------------------------------------------------------
# Ideal joints and drivers (their equations live in jaxclear.constraints)
# --------------------------------------------------------------------------------------


class Revolute(eqx.Module):
    """Ideal pin: point ``point_i`` of ``body_i`` coincides with ``point_j`` of ``body_j`` (2 eq.)."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)

    n_equations = 2


class Translational(eqx.Module):
    r"""Prismatic joint (2 eq.): the relative angle :math:`\phi_j - \phi_i` stays ``angle`` and
    point ``point_j`` of ``body_j`` stays on the line through ``point_i`` of ``body_i`` along the
    body-fixed unit direction ``axis`` of ``body_i``."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)
    axis: Vec2
    angle: Scalar

    n_equations = 2

    def __init__(self, body_i, point_i, body_j, point_j, axis=(1.0, 0.0), angle=0.0):
        self.body_i, self.point_i, self.body_j, self.point_j = body_i, point_i, body_j, point_j
        ax = _vec2("translational axis", axis)
        norm = float(jnp.linalg.norm(ax))
        if norm == 0.0:
            raise MechanismError("translational axis must be a non-zero vector")
        self.axis = ax / norm
        self.angle = jnp.asarray(angle, dtype=float)


class Fixed(eqx.Module):
    """Weld (3 eq.): points coincide and the relative angle stays ``angle`` [rad]."""

    body_i: str = eqx.field(static=True)
    point_i: str = eqx.field(static=True)
    body_j: str = eqx.field(static=True)
    point_j: str = eqx.field(static=True)
    angle: Scalar

    n_equations = 3

    def __init__(self, body_i, point_i, body_j, point_j, angle=0.0):
        self.body_i, self.point_i, self.body_j, self.point_j = body_i, point_i, body_j, point_j
        self.angle = jnp.asarray(angle, dtype=float)


class AngleDriver(eqx.Module):
    r"""Constant-speed rotation (1 eq.): :math:`\phi_{body} - \phi_{ref} - (\phi_0 + \omega t) = 0`.

    Attributes:
        body: driven body; ``relative_to``: reference body (default ground).
        speed: :math:`\\omega` [rad/s]; ``angle0``: :math:`\\phi_0` [rad].
    """

    body: str = eqx.field(static=True)
    speed: Scalar
    angle0: Scalar
    relative_to: str = eqx.field(static=True)

    n_equations = 1

    def __init__(self, body, speed, angle0=0.0, relative_to=GROUND):
        check_finite("driver speed", speed)
        self.body = body
        self.speed = jnp.asarray(speed, dtype=float)
        self.angle0 = jnp.asarray(angle0, dtype=float)
        self.relative_to = relative_to


class FunctionDriver(eqx.Module):
    """User-prescribed coordinate (1 eq.): ``q[body, coordinate] - function(t) = 0``.

    ``coordinate`` is ``"x"``, ``"y"`` or ``"phi"``; ``function`` maps time [s] to the
    coordinate [m or rad] and must be a JAX-traceable function (it is differentiated twice).
    """

    body: str = eqx.field(static=True)
    coordinate: str = eqx.field(static=True)
    function: Callable = eqx.field(static=True)

    n_equations = 1

    def __init__(self, body, coordinate, function):
        if coordinate not in ("x", "y", "phi"):
            raise MechanismError(f"driver coordinate must be 'x', 'y' or 'phi', got {coordinate!r}")
        self.body, self.coordinate, self.function = body, coordinate, function


# --------------------------------------------------------------------------------------
# Applied loads
# --------------------------------------------------------------------------------------


class PointForce(eqx.Module):
    """A force [N] in global axes at a body point: constant ``force`` plus an optional
    ``function(t, q, qdot) -> (2,)`` (static, JAX-traceable)."""

    body: str = eqx.field(static=True)
    point: str = eqx.field(static=True)
    force: Vec2
    function: Callable | None = eqx.field(static=True, default=None)

    def __init__(self, body, point, force=(0.0, 0.0), function=None):
        self.body, self.point, self.function = body, point, function
        self.force = _vec2("point force", force)


class Torque(eqx.Module):
    """A torque [N m] on a body: constant ``torque`` plus optional ``function(t, q, qdot)``."""

    body: str = eqx.field(static=True)
    torque: Scalar
    function: Callable | None = eqx.field(static=True, default=None)

    def __init__(self, body, torque=0.0, function=None):
        check_finite("torque", torque)
        self.body, self.function = body, function
        self.torque = jnp.asarray(torque, dtype=float)


# --------------------------------------------------------------------------------------
# The mechanism
# --------------------------------------------------------------------------------------


class Mechanism(eqx.Module):
    """A planar mechanism: bodies, ideal joints, drivers, clearance joints and loads.

    Attributes:
        bodies: the moving bodies, in coordinate order.
        joints: ideal joints (:class:`Revolute`, :class:`Translational`, :class:`Fixed`).
        drivers: :class:`AngleDriver` / :class:`FunctionDriver`.
        clearance_joints: :class:`jaxclear.clearance.ClearanceJoint` force elements.
        loads: :class:`PointForce` / :class:`Torque`.
        gravity: acceleration of gravity [m/s^2], global (2,).
        ground_points: named points of the fixed frame [m].
        name: label (static).
        roles: optional map of role -> body name (static), e.g. ``{"crank": "crank",
            "slider": "slider"}``, used by outputs, plots and the command line.
    """

    bodies: tuple[Body, ...]
    joints: tuple
    drivers: tuple
    clearance_joints: tuple
    loads: tuple
    gravity: Vec2
    ground_points: dict[str, Vec2]
    name: str = eqx.field(static=True)
    roles: tuple[tuple[str, str], ...] = eqx.field(static=True)

    def __init__(
        self,
        bodies: Sequence[Body],
        joints: Sequence = (),
        drivers: Sequence = (),
        clearance_joints: Sequence = (),
        loads: Sequence = (),
        gravity: ArrayLike = (0.0, -9.81),
        ground_points: dict[str, ArrayLike] | None = None,
        name: str = "mechanism",
        roles: dict[str, str] | None = None,
    ):
        self.bodies = tuple(bodies)
        self.joints = tuple(joints)
        self.drivers = tuple(drivers)
        self.clearance_joints = tuple(clearance_joints)
        self.loads = tuple(loads)
        self.gravity = _vec2("gravity", gravity)
        self.ground_points = {k: _vec2(f"ground point {k!r}", v) for k, v in (ground_points or {}).items()}
        self.name = name
        self.roles = tuple(sorted((roles or {}).items()))
        self._validate_structure()

    def role(self, role: str) -> str | None:
        """Body playing ``role`` (``"crank"``, ``"slider"``...), or None."""
        return dict(self.roles).get(role)

    # ---- bookkeeping ----------------------------------------------------------------
    @property
    def body_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bodies)

    @property
    def n_bodies(self) -> int:
        return len(self.bodies)

    @property
    def n_coordinates(self) -> int:
        return 3 * len(self.bodies)

    @property
    def n_constraints(self) -> int:
        return sum(j.n_equations for j in self.joints) + sum(d.n_equations for d in self.drivers)

    def body_index(self, name: str) -> int:
        """Index of a body, ``-1`` for the ground; :class:`MechanismError` for unknown names."""
        if name == GROUND:
            return -1
        names = self.body_names
        if name not in names:
            raise MechanismError(f"unknown body {name!r}; bodies are {list(names)} and {GROUND!r}")
        return names.index(name)

    def body(self, name: str) -> Body:
        return self.bodies[self.body_index(name)]

    def point(self, body: str, point: str) -> Vec2:
        """Body-fixed coordinates [m] of a named point (ground points are global)."""
        table = self.ground_points if body == GROUND else self.body(body).points
        if point not in table:
            raise MechanismError(f"unknown point {point!r} on body {body!r}; its points are {sorted(table)}")
        return table[point]

    def _validate_structure(self):
        names = self.body_names
        if len(set(names)) != len(names):
            raise MechanismError(f"body names must be unique, got {list(names)}")
        if not names:
            raise MechanismError("a mechanism needs at least one body")
        for j in self.joints:
            self.point(j.body_i, j.point_i)
            self.point(j.body_j, j.point_j)
            if j.body_i == j.body_j:
                raise MechanismError(f"{type(j).__name__} joint connects body {j.body_i!r} to itself")
        for d in self.drivers:
            self.body_index(d.body)
            if isinstance(d, AngleDriver):
                self.body_index(d.relative_to)
        for c in self.clearance_joints:
            self.point(c.bearing_body, c.bearing_point)
            self.point(c.journal_body, c.journal_point)
            if c.bearing_body == c.journal_body:
                raise MechanismError(f"clearance joint {c.name!r} connects body {c.bearing_body!r} to itself")
        for f in self.loads:
            self.body_index(f.body)
            if isinstance(f, PointForce):
                self.point(f.body, f.point)
        for _, body in self.roles:
            self.body_index(body)
        if self.n_constraints > self.n_coordinates:
            raise MechanismError(
                f"{self.n_constraints} constraint equations (joints + drivers) for only "
                f"{self.n_coordinates} coordinates: the mechanism is over-constrained; remove "
                "redundant joints or drivers (allowed: at most one equation per coordinate, "
                "independent)"
            )

    # ---- coordinates ----------------------------------------------------------------
    def pose(self, q, name: str):
        """``(r, phi)`` of a body in configuration ``q`` (ground: zeros)."""
        i = self.body_index(name)
        if i < 0:
            return jnp.zeros(2, q.dtype), jnp.zeros((), q.dtype)
        return q[3 * i : 3 * i + 2], q[3 * i + 2]

    def twist(self, qdot, name: str):
        """``(rdot, phidot)`` of a body (ground: zeros)."""
        return self.pose(qdot, name)

    def guess(self):
        """Stacked initial guesses ``(q, qdot)`` from the bodies."""
        q = jnp.concatenate([b.position for b in self.bodies])
        qd = jnp.concatenate([b.velocity for b in self.bodies])
        return q, qd

    def ideal(self) -> "Mechanism":
        """The same mechanism with every clearance joint replaced by an ideal :class:`Revolute`
        between its bearing and journal points (appended after the other joints), named
        ``NAME-ideal``: the reference whose response the clearance perturbs."""
        if not self.clearance_joints:
            return self
        pins = [Revolute(c.journal_body, c.journal_point, c.bearing_body, c.bearing_point) for c in self.clearance_joints]
        return Mechanism(
            bodies=self.bodies, joints=(*self.joints, *pins), drivers=self.drivers, clearance_joints=(),
            loads=self.loads, gravity=self.gravity, ground_points=self.ground_points, name=self.name + "-ideal",
            roles=dict(self.roles),
        )

    def mass_matrix_diagonal(self) -> Float[Array, " n"]:
        """Diagonal of :math:`M = \\mathrm{diag}(m_i, m_i, J_i)`."""
        return jnp.concatenate([jnp.stack([b.mass, b.mass, b.inertia]) for b in self.bodies])


def crank_driver(mech: "Mechanism") -> tuple[int, AngleDriver] | None:
    """The mechanism's crank: ``(index in mech.drivers, driver)`` of its first
    :class:`AngleDriver`, or ``None``. The one lookup that 'revolutions', 'speed' and the crank
    angle of outputs go through."""
    for i, d in enumerate(mech.drivers):
        if isinstance(d, AngleDriver):
            return i, d
    return None


# --------------------------------------------------------------------------------------
# Kinematics of body points (the one place these formulas live)
# --------------------------------------------------------------------------------------


def rotate(phi, v):
    """:math:`A(\\phi) v`, :math:`A(\\phi) = [[\\cos\\phi, -\\sin\\phi], [\\sin\\phi,
    \\cos\\phi]]`, for a 2-vector ``v``, written elementwise: XLA on CPU fuses it with its
    neighbours, while a 2x2 ``dot`` would be a kernel call of its own."""
    c, s = jnp.cos(phi), jnp.sin(phi)
    return jnp.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def perp(v):
    """Rotate a 2-vector by +90 degrees: ``[-v_y, v_x]``."""
    return jnp.stack([-v[1], v[0]])


def cross2(a, b):
    """Planar cross product :math:`a_x b_y - a_y b_x`."""
    return a[0] * b[1] - a[1] * b[0]


def point_position(mech: Mechanism, q, body: str, point: str):
    """Global position [m] of a named body point."""
    r, phi = mech.pose(q, body)
    s = mech.point(body, point)
    if body == GROUND:
        return s
    return r + rotate(phi, s)


def point_velocity(mech: Mechanism, q, qdot, body: str, point: str):
    """Global velocity [m/s] of a named body point: :math:`\\dot r + \\dot\\phi\\,\\mathrm{perp}(A s')`."""
    if body == GROUND:
        return jnp.zeros(2, q.dtype)
    _, phi = mech.pose(q, body)
    rd, phid = mech.twist(qdot, body)
    return rd + phid * perp(rotate(phi, mech.point(body, point)))


def point_load(mech: Mechanism, q, body: str, at, force):
    """Generalized force (n,) of a global ``force`` [N] applied at global point ``at`` [m]:
    ``[f_x, f_y, (at - r) x f]`` in the rows of ``body`` (nothing for the ground)."""
    n = mech.n_coordinates
    i = mech.body_index(body)
    if i < 0:
        return jnp.zeros(n, q.dtype)
    r, _ = mech.pose(q, body)
    gen = jnp.stack([force[0], force[1], cross2(at - r, force)])
    return jnp.zeros(n, q.dtype).at[3 * i : 3 * i + 3].add(gen)
