r"""A planar mechanism as data: bodies, ideal joints, drivers, force elements (clearance joints)
and loads; index bookkeeping, validation, and the kinematics of body points.

Reference: Nikravesh, "Computer-Aided Analysis of Mechanical Systems", Prentice-Hall 1988
(generalized Cartesian coordinates). ``q`` stacks ``[x_i, y_i, phi_i]`` of every body, shape
``(3 * n_bodies,)``; a body-fixed point :math:`s'_P` [m] sits at :math:`r_i + A(\phi_i) s'_P`.

Structure (names, which bodies a joint connects, which law) is static; every number (masses,
inertias, point coordinates, speeds, radii, law parameters) is an array leaf that can be
differentiated, vmapped or swept.
"""

from __future__ import annotations

from collections import Counter
from typing import ClassVar, Sequence

import equinox as eqx
import jax.numpy as jnp

from .._errors import RESULTS, MechanismError, failed_check, first_failure
from .._types import Array, ArrayLike, Float, Vec2
from .._parameters import Parameter
from .bodies import GROUND, Body, point_parameters, vec2
from .connectors import AbstractConnector
from .geometry import cross2, perp, rotate
from .joints import AbstractConstraint


class Mechanism(eqx.Module):
    """A planar mechanism: bodies, ideal joints, drivers, force elements and loads.

    Attributes:
        bodies: the moving bodies, in coordinate order.
        joints: ideal joints (:class:`~jaxclear.Revolute`, :class:`~jaxclear.Translational`,
            :class:`~jaxclear.Fixed`, or any :class:`~jaxclear.model.joints.AbstractConstraint`).
        drivers: :class:`~jaxclear.AngleDriver` / :class:`~jaxclear.FunctionDriver`.
        clearance_joints: force elements between two bodies
            (:class:`~jaxclear.elements.base.AbstractForceElement`, e.g.
            :class:`~jaxclear.ClearanceJoint`), each owning its slice of the state.
        loads: :class:`~jaxclear.PointForce` / :class:`~jaxclear.Torque`.
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

    #: named parameters of the frame (``point_x:ground.POINT``, ``point_y:ground.POINT``)
    PARAMETERS: ClassVar[dict[str, Parameter]] = point_parameters("ground_points")

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
        self.gravity = vec2("gravity", gravity)
        self.ground_points = {k: vec2(f"ground point {k!r}", v) for k, v in (ground_points or {}).items()}
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
    def constraints(self) -> tuple[AbstractConstraint, ...]:
        """Joints then drivers: the rows of :math:`\\Phi`, in order."""
        return (*self.joints, *self.drivers)

    @property
    def n_constraints(self) -> int:
        return sum(c.n_equations for c in self.constraints)

    @property
    def held_at_start(self) -> tuple:
        """What the start's assembly holds besides the joints and drivers: every force element
        (at its initial offset) and every load that has equations of its own (``n_equations``:
        a flexible link's spring-damping elements at rest, so a link starts undeformed)."""
        return (*self.clearance_joints, *(ld for ld in self.loads if getattr(ld, "n_equations", 0)))

    @property
    def elements(self) -> tuple:
        """The force elements (same as ``clearance_joints``)."""
        return self.clearance_joints

    def check(self) -> RESULTS:
        """Traceable range check of every number of the mechanism (bodies, then force
        elements, each through its own ``check()``): the first failing
        :class:`~jaxclear.RESULTS` ``invalid_*`` entry, or ``successful``. :func:`~jaxclear.simulate`
        evaluates it at run time, so it holds under ``jit`` and ``vmap`` where the constructors'
        checks see only tracers."""
        return first_failure(*(b.check() for b in self.bodies), *(e.check() for e in self.elements),
                             *(rule for load in self.loads for rule in load.checks()))

    def failed_check(self) -> str | None:
        """Eagerly, on concrete numbers: the first of :meth:`check`'s checks that fails, in one
        line naming the body or force element, the number, its value and the rule it broke
        (``"clearance joint rod-slider (clearance_joints[0]): clearance c = R_B - R_J = -0.0001 m
        is outside the allowed range (0, inf) m"``; a law's check: its status message); ``None``
        when every check passes."""
        for body in self.bodies:
            message = failed_check(body.checks())
            if message is not None:
                return f"body {body.name!r}: {message}"
        for k, element in enumerate(self.elements):
            message = failed_check(element.checks())
            if message is not None:
                return f"{element.label} (clearance_joints[{k}]): {message}"
        for k, load in enumerate(self.loads):
            message = failed_check(load.checks())
            if message is not None:
                return f"{load.label} (loads[{k}]): {message}"
        return None

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
        _validate_structure(self.bodies, self.joints, self.drivers, self.clearance_joints, self.loads,
                            self.ground_points, self.roles)

    # ---- coordinates ----------------------------------------------------------------
    def pose(self, q, name: str):
        """``(r, phi)`` of a body in configuration ``q`` (ground: zeros)."""
        i = self.body_index(name)
        if i < 0:
            return jnp.zeros(2, q.dtype), jnp.zeros((), q.dtype)
        return q[3 * i : 3 * i + 2], q[3 * i + 2]

    def angle(self, q, name: str):
        """Orientation :math:`\\phi` [rad] of a body (ground: 0)."""
        return self.pose(q, name)[1]

    def twist(self, qdot, name: str):
        """``(rdot, phidot)`` of a body (ground: zeros)."""
        return self.pose(qdot, name)

    def guess(self):
        """Stacked initial guesses ``(q, qdot)`` from the bodies."""
        q = jnp.concatenate([b.position for b in self.bodies])
        qd = jnp.concatenate([b.velocity for b in self.bodies])
        return q, qd

    def started(self, *, angle0=None, q=None, qdot=None, elements=None, within=None) -> "Mechanism":
        """This mechanism started from another state: the one way a run starts from a shifted
        crank, a state's guesses and its force elements' starts (the fit's windows, the design's
        ensembles). Traceable (``jit``, ``vmap``, ``grad`` through every number given).

        Args:
            angle0: the crank's (:func:`~jaxclear.model.crank_driver`) angle at ``t = 0`` [rad];
                None: as it is. A run started ``dt`` [s] later along the same motion at a
                constant speed: ``angle0 = crank.angle0 + crank.speed * dt``.
            q, qdot: ``(3 n_bodies,)`` the bodies' position [m, rad] and velocity [m/s, rad/s]
                guesses (the start's assembly begins from them, e.g. a state's ``q``, ``qdot``);
                None: as they are.
            elements: the force elements, one per clearance joint in order (e.g. each
                ``element.with_start(offset, velocity)`` of its :meth:`start_state` layout),
                replacing them; None: as they are.
            within: ``(n_equations,)`` fractions of the clearance by which every force element's
                start is moved (its ``started_within``: the design's start offsets); None: not
                moved. Applied after ``elements``.
        """
        m = self
        if angle0 is not None:
            from .drivers import crank_driver

            found = crank_driver(m)
            if found is None:
                raise MechanismError(f"mechanism {m.name!r} has no crank (an AngleDriver): no angle0 to start from")
            i = found[0]
            m = eqx.tree_at(lambda mm: mm.drivers[i].angle0, m, angle0)
        n_b = len(m.bodies)
        if q is not None:
            m = eqx.tree_at(lambda mm: [b.position for b in mm.bodies], m, [q[3 * b: 3 * b + 3] for b in range(n_b)])
        if qdot is not None:
            m = eqx.tree_at(lambda mm: [b.velocity for b in mm.bodies], m,
                            [qdot[3 * b: 3 * b + 3] for b in range(n_b)])
        if elements is not None and len(elements):
            if len(elements) != len(m.clearance_joints):
                raise MechanismError(f"started: {len(elements)} force element(s) for the {len(m.clearance_joints)} "
                                     f"of mechanism {m.name!r}")
            m = eqx.tree_at(lambda mm: list(mm.clearance_joints), m, list(elements))
        if within is not None and m.clearance_joints:
            m = eqx.tree_at(lambda mm: list(mm.clearance_joints), m,
                            [e.started_within(within) for e in m.clearance_joints])
        return m

    def mass_matrix_diagonal(self) -> Float[Array, " n"]:
        """Diagonal of :math:`M = \\mathrm{diag}(m_i, m_i, J_i)`."""
        return jnp.concatenate([jnp.stack([b.mass, b.mass, b.inertia]) for b in self.bodies])

    def ideal(self) -> "Mechanism":
        """The same mechanism with every force element replaced by its ideal joint
        (``element.ideal_joint()``: a :class:`Revolute` for the journal joints, a
        :class:`Translational` for the translational clearance joint; appended after the other
        joints), named ``NAME-ideal``: the reference whose response the clearance perturbs."""
        if not self.clearance_joints:
            return self
        pins = [c.ideal_joint() for c in self.clearance_joints]
        return Mechanism(
            bodies=self.bodies, joints=(*self.joints, *pins), drivers=self.drivers, clearance_joints=(),
            loads=self.loads, gravity=self.gravity, ground_points=self.ground_points, name=self.name + "-ideal",
            roles=dict(self.roles),
        )

    # ---- kinematics of body points (methods so that joints need not import this module) ----
    def point_position(self, q, body: str, point: str):
        return point_position(self, q, body, point)

    def point_velocity(self, q, qdot, body: str, point: str):
        return point_velocity(self, q, qdot, body, point)

    def point_acceleration(self, q, qdot, qddot, body: str, point: str):
        return point_acceleration(self, q, qdot, qddot, body, point)

    def point_load(self, q, body: str, at, force):
        return point_load(self, q, body, at, force)


#: Most bodies of a mechanism (3000 coordinates: far beyond a planar linkage; the dynamics solve a
#: dense system of that size at every step).
MAX_BODIES = 1000
#: Most joints, drivers, clearance joints or loads of a mechanism (each list): every joint and
#: driver adds at least one equation, and there are at most 3 per body.
MAX_PARTS = 3 * MAX_BODIES


def check_sizes(counts: dict[str, int], where: str = "") -> None:
    """Raise :class:`MechanismError` if a part list is longer than allowed (``counts``: part ->
    count, e.g. ``{"bodies": 20000}``; ``where`` prefixes the message). Checked before anything
    of that size is built or validated."""
    for part, count in counts.items():
        high = MAX_BODIES if part == "bodies" else MAX_PARTS
        if count > high:
            constant = "MAX_BODIES" if part == "bodies" else "MAX_PARTS"
            raise MechanismError(f"{where}{part}: {count} items, outside the allowed range [0, {high}] "
                                 f"(jaxclear.model.mechanism.{constant}); a planar mechanism this large is beyond "
                                 "what jaxclear integrates")


def _validate_structure(bodies, joints, drivers, elements, loads, ground_points, roles):
    """Names, references and counts of a mechanism's parts (the constructor's checks), in time
    linear in their number: the bodies' names and points are looked up in dicts built once."""
    check_sizes({"bodies": len(bodies), "joints": len(joints), "drivers": len(drivers),
                 "clearance joints": len(elements), "loads": len(loads)})
    if not bodies:
        raise MechanismError("a mechanism needs at least one body")
    names = [b.name for b in bodies]
    twice = sorted(n for n, k in Counter(names).items() if k > 1)
    if twice:
        raise MechanismError(f"body names must be unique, got {twice[0]!r} twice in "
                             f"{names if len(names) <= 20 else str(names[:20])[:-1] + ', ...]'}")
    twice = sorted(n for n, k in Counter(c.name for c in elements).items() if k > 1)
    if twice:
        raise MechanismError(f"clearance joint names must be unique (outputs and parameters address a joint by "
                             f"its name), got {twice[0]!r} twice in {[c.name for c in elements]}")
    named = [ld.name for ld in loads if isinstance(ld, AbstractConnector)]
    twice = sorted(n for n, k in Counter(named).items() if k > 1)
    if twice:
        raise MechanismError(f"force element names (springs, dampers, bushings among the loads) must be unique "
                             f"(parameters and outputs address one by its name), got {twice[0]!r} twice in {named}")
    points = {b.name: b.points for b in bodies}
    points[GROUND] = ground_points

    def known_body(name: str):
        if name not in points:
            shown = names if len(names) <= 20 else names[:20] + ["..."]
            raise MechanismError(f"unknown body {name!r}; bodies are {shown} and {GROUND!r}")

    for item in (*joints, *drivers, *elements, *loads):
        item_bodies = item.bodies()
        for b in item_bodies:
            known_body(b)
        for b, p in item.points():
            known_body(b)
            if p not in points[b]:
                raise MechanismError(f"unknown point {p!r} on body {b!r}; its points are {sorted(points[b])}")
        if len(item_bodies) == 2 and item_bodies[0] == item_bodies[1]:
            raise MechanismError(f"{item.label} connects body {item_bodies[0]!r} to itself")
    for _, body in roles:
        known_body(body)
    n_constraints = sum(c.n_equations for c in (*joints, *drivers))
    if n_constraints > 3 * len(bodies):
        raise MechanismError(
            f"{n_constraints} constraint equations (joints + drivers) for only "
            f"{3 * len(bodies)} coordinates: the mechanism is over-constrained; remove "
            "redundant joints or drivers (allowed: at most one equation per coordinate, "
            "independent)"
        )


# --------------------------------------------------------------------------------------
# Kinematics of body points (the one place these formulas live)
# --------------------------------------------------------------------------------------


def point_position(mech: Mechanism, q, body: str, point: str) -> Vec2:
    """Global position [m] of a named body point: :math:`r + A(\\phi) s'`."""
    r, phi = mech.pose(q, body)
    s = mech.point(body, point)
    if body == GROUND:
        return s
    return r + rotate(phi, s)


def point_velocity(mech: Mechanism, q, qdot, body: str, point: str) -> Vec2:
    """Global velocity [m/s] of a named body point: :math:`\\dot r + \\dot\\phi\\,\\mathrm{perp}(A s')`."""
    if body == GROUND:
        return jnp.zeros(2, q.dtype)
    _, phi = mech.pose(q, body)
    rd, phid = mech.twist(qdot, body)
    return rd + phid * perp(rotate(phi, mech.point(body, point)))


def point_acceleration(mech: Mechanism, q, qdot, qddot, body: str, point: str) -> Vec2:
    r"""Global acceleration [m/s^2] of a named body point (rigid-body kinematics):
    :math:`\ddot r + \ddot\phi\,\mathrm{perp}(A s') - \dot\phi^2 A s'`."""
    if body == GROUND:
        return jnp.zeros(2, q.dtype)
    _, phi = mech.pose(q, body)
    _, phid = mech.twist(qdot, body)
    rdd, phidd = mech.pose(qddot, body)
    arm = rotate(phi, mech.point(body, point))
    return rdd + phidd * perp(arm) - phid**2 * arm


def point_load(mech: Mechanism, q, body: str, at, force) -> Float[Array, " n"]:
    """Generalized force (n,) of a global ``force`` [N] applied at global point ``at`` [m]:
    ``[f_x, f_y, (at - r) x f]`` in the rows of ``body`` (nothing for the ground)."""
    n = mech.n_coordinates
    i = mech.body_index(body)
    if i < 0:
        return jnp.zeros(n, q.dtype)
    r, _ = mech.pose(q, body)
    gen = jnp.stack([force[0], force[1], cross2(at - r, force)])
    return jnp.zeros(n, q.dtype).at[3 * i : 3 * i + 3].add(gen)
