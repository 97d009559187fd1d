r"""Revolute joints with radial clearance, as force elements (Flores, Ambrósio, Claro,
Lankarani, "Kinematics and Dynamics of Multibody Systems with Imperfect Joints", Springer
2008, ch. 4).

A bearing (hole, radius :math:`R_B`) on body *i* and a journal (pin, radius :math:`R_J`) on
body *j*; radial clearance :math:`c = R_B - R_J > 0`.

* eccentricity :math:`\mathbf e = P_j - P_i`, :math:`e = |\mathbf e|`, penetration
  :math:`\delta = e - c`, normal :math:`n = \mathbf e/e`, tangent :math:`t = \mathrm{perp}(n)`;
* contact points :math:`Q_k = P_k + R_k n`; :math:`\dot\delta = (v_{Q_j} - v_{Q_i})\cdot n`
  (equal to :math:`\dot e`), slip :math:`v_T = (v_{Q_j} - v_{Q_i})\cdot t`;
* force on the journal at :math:`Q_j`: :math:`f = -F_N n + F_T t`; on the bearing at
  :math:`Q_i`: :math:`-f`.

Sign convention: :math:`v_T` is the slip of the *journal* relative to the bearing, so the
friction force opposes it on the journal and drags the bearing along (written on the bearing
as :math:`F_N n + F_T t`, as some texts do, with :math:`F_T = -\mu c_d F_N \mathrm{sign}(v_T)`
it would do positive work); the energy tests check that friction only dissipates.

The impact speed :math:`\dot\delta^{(-)}` of the joint is history: the joint's state is a
:class:`~jaxclear.elements.memory.ContactMemory`, updated after every accepted step by
:meth:`ClearanceJoint.after_step` with the rule of :mod:`jaxclear.elements.memory`. A friction
law with internal states (the bristle laws of :mod:`jaxclear.contact.bristle`) adds them to the
joint's state (:class:`JournalState`); they are continuous states integrated with their rate
while in contact, frozen out of contact, and relaxed (zero) at each contact onset.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import RESULTS, ParameterError, Rule, check_range
from .._parameters import POSITIVE, Parameter
from .._types import Array, ArrayLike, Float, Scalar, Vec2
from ..contact.base import AbstractFriction, AbstractNormalLaw, ContactKinematics, element_friction
from ..contact.bristle import FrozenBristles
from ..contact.friction import Friction
from ..contact.hertz import ContactLaw
from ..model.geometry import perp, safe_normal
from ..model.joints import Revolute
from ..model.mechanism import Mechanism, point_load, point_position, point_velocity
from .base import AbstractForceElement, ContactOutput
from .memory import (N_FIELDS, ContactMemory, kink_fraction, onset_fraction, onset_update, penetration_accelerations,
                     with_peak_force)


class JournalState(eqx.Module):
    """State of a journal joint whose friction law has internal states (Dahl, LuGre): the
    impact memory and the bristle states ``(m,)`` [m]; the slice is the memory's six fields
    followed by the bristle states."""

    memory: ContactMemory
    friction: Float[Array, " m"]

    def summary(self) -> ContactMemory:
        """The impact memory (what ``Solution.memory`` stacks)."""
        return self.memory


class AbstractJournalJoint(AbstractForceElement):
    """A journal (pin, radius :math:`R_J`, on the journal body) inside a bearing (radius
    :math:`R_B`, on the bearing body), with one contact and one impact memory: what the
    revolute clearance joint, the lubricated joint and the pin-in-slot joint share (state,
    memory rule, assembly at an initial offset, ideal replacement). Subclasses give the
    kinematics of the contact (:meth:`kinematics`) and its forces (:meth:`contact`)."""

    bearing_body: eqx.AbstractVar[str]
    bearing_point: eqx.AbstractVar[str]
    journal_body: eqx.AbstractVar[str]
    journal_point: eqx.AbstractVar[str]
    bearing_radius: eqx.AbstractVar[Scalar]
    journal_radius: eqx.AbstractVar[Scalar]
    length: eqx.AbstractVar[Scalar]
    law: eqx.AbstractVar[AbstractNormalLaw]
    friction: eqx.AbstractVar[AbstractFriction]
    impact_velocity_floor: eqx.AbstractVar[Scalar]
    initial_offset: eqx.AbstractVar[Vec2]
    initial_velocity: eqx.AbstractVar[Vec2]

    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "clearance": Parameter("journal_radius", "m", **POSITIVE, doc="radial clearance R_B - R_J",
                               read=lambda j: j.clearance, write=lambda j, c: j.bearing_radius - c,
                               limit=lambda j: (float(j.bearing_radius), "the bearing radius")),
        **AbstractForceElement.PARAMETERS,
        "length": Parameter("length", "m", **POSITIVE, doc="axial length of the joint (a lubricated joint's film width)"),
    }

    def parameters(self) -> dict[str, Parameter]:
        """Those of :meth:`AbstractForceElement.parameters`; a stiffness left to the law (its leaf
        ``None``) is read derived from the materials and the radii (``law.stiffness_value``)."""
        table = super().parameters()
        if "stiffness" in table and table["stiffness"].derived:
            table["stiffness"] = table["stiffness"]._replace(
                read=lambda j: j.law.stiffness_value(j.bearing_radius, j.journal_radius))
        return table

    def describe(self) -> str:
        return (f"{self.label}: bearing {self.bearing_body}.{self.bearing_point}, journal {self.journal_body}."
                f"{self.journal_point}, R_B = {float(self.bearing_radius) * 1e3:.4g} mm, c = "
                f"{float(self.clearance) * 1e6:.4g} um, {self.laws_text()}")

    def started_within(self, fraction) -> "AbstractJournalJoint":
        """Its journal started ``fraction`` (2,) of the clearance further from its initial offset."""
        return eqx.tree_at(lambda j: j.initial_offset, self, self.initial_offset + fraction * self.clearance)

    @abc.abstractmethod
    def kinematics(self, mech: Mechanism, q, qdot) -> ContactKinematics:
        """The contact's kinematics (the penetration the law decides contact on)."""

    @abc.abstractmethod
    def contact(self, mech: Mechanism, q, qdot, impact_velocity) -> tuple[Float[Array, " n"], ContactOutput]:
        """Generalized force (n,) of the element and its :class:`ContactOutput`."""

    @property
    def clearance(self):
        """Radial clearance :math:`c = R_B - R_J` [m]."""
        return self.bearing_radius - self.journal_radius

    # ---- structure ------------------------------------------------------------------
    def bodies(self):
        return (self.bearing_body, self.journal_body)

    def points(self):
        return ((self.bearing_body, self.bearing_point), (self.journal_body, self.journal_point))

    @property
    def label(self):
        return f"clearance joint {self.name}"

    # ---- validity (shared by every journal joint) ---------------------------------------
    #: A penetration deeper than this fraction of the journal radius is reported as
    #: ``penetration_too_deep``. Hertz-type laws assume a contact zone small against the radii
    #: (Johnson, "Contact Mechanics", CUP 1985, ch. 4-5); for two cylinders the half-width
    #: a ~ sqrt(delta R) reaches ~0.3 R at delta = R/10, far outside that assumption, while
    #: steel contacts in real bearings penetrate microns (R/1000 or less).
    MAX_PENETRATION_FRACTION: ClassVar[float] = 0.1

    def checks(self) -> tuple:
        """Radii > 0 with R_J < R_B (clearance in (0, R_B): ``invalid_clearance``); length and
        impact_velocity_floor > 0 (``invalid_parameter``); then the normal law's and the
        friction law's own checks."""
        element_friction(self.friction, type(self).__name__, self.friction)  # a law set after __init__
        positive = dict(low=0.0, low_open=True)
        return (
            Rule("bearing_radius R_B", self.bearing_radius, RESULTS.invalid_clearance, unit="m", **positive),
            Rule("journal_radius R_J", self.journal_radius, RESULTS.invalid_clearance, unit="m", **positive),
            Rule("clearance c = R_B - R_J", self.clearance, RESULTS.invalid_clearance, unit="m", **positive),
            Rule("length", self.length, RESULTS.invalid_parameter, unit="m", **positive),
            Rule("impact_velocity_floor", self.impact_velocity_floor, RESULTS.invalid_parameter, unit="m/s",
                 **positive),
            self.law,  # the laws' own checks (first_failure calls check(); failed_check reads their checks())
            self.friction,
        )

    def penetration_limit(self):
        """:attr:`MAX_PENETRATION_FRACTION` times the journal radius [m]."""
        return self.MAX_PENETRATION_FRACTION * self.journal_radius

    def relative_state(self, mech: Mechanism, q, qdot):
        """``[e_x, e_y, v_x, v_y]``: eccentricity [m] and journal-centre velocity relative to the
        bearing centre [m/s] (4,)."""
        kin = self.kinematics(mech, q, qdot)
        return jnp.concatenate([kin.ecc, kin.journal_velocity - kin.bearing_velocity])

    def start_state(self, mech: Mechanism, q, qdot):
        """:meth:`relative_state`: the eccentricity and its rate are what the assembly holds."""
        return self.relative_state(mech, q, qdot)

    def start_scale(self):
        """The radial clearance ``c`` [m] along both axes (the clearance circle)."""
        return jnp.stack([self.clearance, self.clearance])

    def clearance_region(self, n: int = 361):
        r"""The clearance circle :math:`|\mathbf e| = c` (n, 2) [m]."""
        theta = jnp.linspace(0.0, 2.0 * jnp.pi, n)
        return self.clearance * jnp.stack([jnp.cos(theta), jnp.sin(theta)], axis=-1)

    def ideal_joint(self) -> Revolute:
        """The ideal revolute joint this element replaces: journal and bearing centres coincide."""
        return Revolute(self.journal_body, self.journal_point, self.bearing_body, self.bearing_point)

    # ---- state: one ContactMemory (and the friction law's bristle states, if any) -------
    @property
    def state_size(self) -> int:
        """:data:`~jaxclear.elements.memory.N_FIELDS` plus the friction law's internal states."""
        return N_FIELDS + self.friction.state_size

    def state_init(self, dtype=float):
        memory = ContactMemory.initial((), dtype)
        return memory if self.friction.state_size == 0 else JournalState(memory, self.friction.state_init(dtype))

    def state_to_vector(self, state):
        return jnp.concatenate([jnp.reshape(x, (-1,)) for x in jax.tree_util.tree_leaves(state)])

    def state_from_vector(self, v):
        memory = ContactMemory(*(v[i] for i in range(N_FIELDS)))
        return memory if self.friction.state_size == 0 else JournalState(memory, v[N_FIELDS:self.state_size])

    def split_state(self, state) -> tuple[ContactMemory, Float[Array, " m"]]:
        """``(memory, friction states)``; a bare memory (outputs recomputed from
        ``Solution.memory``) gets relaxed bristles."""
        if isinstance(state, JournalState):
            return state.memory, state.friction
        return state, self.friction.state_init(state.impact_velocity.dtype)

    # ---- physics ----------------------------------------------------------------------
    def forces(self, mech: Mechanism, t, q, qdot, state):
        """Generalized contact force (n,), state rate (the memory's work rate is the power; the
        bristle states move at the friction law's rate) and the joint's :class:`ContactOutput`."""
        if self.friction.state_size == 0:
            gen, out = self.contact(mech, q, qdot, state.impact_velocity)
            return gen, state.rate(out.power), out
        memory, bristles = self.split_state(state)
        frozen = eqx.tree_at(lambda j: j.friction, self, FrozenBristles(self.friction, bristles))
        gen, out = frozen.contact(mech, q, qdot, memory.impact_velocity)
        slip = self.kinematics(mech, q, qdot).slip
        _, rate = self.friction.force_and_rate(bristles, slip, out.normal_force)
        # out of contact the bristles carry no load and stay as they are (after_step relaxes
        # them at the next onset): their rate there would be stiff and unseen by the error norm
        rate = jnp.where(out.normal_force > 0.0, rate, 0.0)
        return gen, JournalState(memory.rate(out.power), rate), out

    def after_step(self, mech: Mechanism, t0, q0, qd0, t1, q1, qd1, state, qdd=None):
        """The impact-memory rule over the accepted step ``[t0, t1]``
        (:func:`~jaxclear.elements.memory.onset_update`), then the running peak force at the
        step's end."""
        memory, bristles = self.split_state(state)
        kin0, kin1 = self.kinematics(mech, q0, qd0), self.kinematics(mech, q1, qd1)
        p0, p1 = self.law.penetration(kin0), self.law.penetration(kin1)
        accel = penetration_accelerations(lambda q, qd: self.kinematics(mech, q, qd).deltadot, q0, qd0, q1, qd1, qdd)
        new, crossed = onset_update(memory, t0, t1, p0, p1, kin0.deltadot, kin1.deltadot, accel)
        _, out = self.contact(mech, q1, qd1, new.impact_velocity)
        new = with_peak_force(new, out.normal_force)
        if self.friction.state_size == 0:
            return new, crossed
        return JournalState(new, jnp.where(crossed, 0.0, bristles)), crossed  # relaxed at each onset

    def onset(self, mech: Mechanism, t0, q0, qd0, t1, q1, qd1, state: ContactMemory):
        """Fraction of ``[t0, t1]`` at the first contact switch to split at (:func:`~jaxclear.elements.memory.onset_fraction`)."""
        kin0, kin1 = self.kinematics(mech, q0, qd0), self.kinematics(mech, q1, qd1)
        p0, p1 = self.law.penetration(kin0), self.law.penetration(kin1)
        return onset_fraction(p0, p1, kin0.deltadot, kin1.deltadot, t1 - t0)

    def kinks(self, mech: Mechanism, t0, q0, qd0, qdd0, t1, q1, qd1, state):
        """Fraction of ``[t0, t1]`` at the first kink of the friction law while in contact
        (:func:`~jaxclear.elements.memory.kink_fraction`)."""
        kinks = lambda q, qd: self.friction.kinks(self.kinematics(mech, q, qd).slip)  # noqa: E731
        g0, rate0 = jax.jvp(kinks, (q0, qd0), (qd0, qdd0))
        kin0, kin1 = self.kinematics(mech, q0, qd0), self.kinematics(mech, q1, qd1)
        active = (self.law.penetration(kin0) > 0.0) & (self.law.penetration(kin1) > 0.0)
        return kink_fraction(g0, kinks(q1, qd1), rate0, t1 - t0, active)

    # ---- initial assembly: hold the journal at its initial offset ---------------------
    n_equations: ClassVar[int] = 2

    def equations(self, mech: Mechanism, q, t):
        """:math:`P_j - P_i - e_0 = 0` (2,), the joint treated as ideal at a fixed offset."""
        return (
            point_position(mech, q, self.journal_body, self.journal_point)
            - point_position(mech, q, self.bearing_body, self.bearing_point)
            - self.initial_offset
        )

    def assembly_velocity(self):
        """Relative velocity of the journal centre at the start [m/s] (2,)."""
        return self.initial_velocity



def check_journal_geometry(bearing_radius, journal_radius, length, impact_velocity_floor, law, initial_offset):
    """Validate the geometry of a journal in a bearing (concrete values only; tracers pass):
    radii positive with :math:`R_J < R_B`, length and floor positive, the law able to serve the
    radii, the initial offset inside the clearance. Returns ``(R_B, R_J, offset)`` as arrays."""
    check_range("bearing_radius", bearing_radius, low=0.0, low_open=True, unit="m")
    check_range("journal_radius", journal_radius, low=0.0, low_open=True, unit="m")
    check_range("length (joint width)", length, low=0.0, low_open=True, unit="m")
    check_range("impact_velocity_floor", impact_velocity_floor, low=0.0, low_open=True, unit="m/s")
    rb, rj = jnp.asarray(bearing_radius, dtype=float), jnp.asarray(journal_radius, dtype=float)
    if not isinstance(rb, jax.core.Tracer) and not isinstance(rj, jax.core.Tracer):
        if float(rj) >= float(rb):
            raise ParameterError(
                f"journal_radius = {float(rj):g} m must be smaller than bearing_radius = "
                f"{float(rb):g} m (clearance c = R_B - R_J must be > 0; got {float(rb - rj):g} m)"
            )
        if law is not None:
            law.check_geometry(float(rb), float(rj))
    offset = jnp.asarray(initial_offset, dtype=float).reshape(2)
    if not isinstance(offset, jax.core.Tracer) and float(jnp.linalg.norm(offset)) >= float(rb - rj):
        raise ParameterError(
            f"initial_offset |e| = {float(jnp.linalg.norm(offset)):g} m must be smaller than the "
            f"clearance {float(rb - rj):g} m (the journal must start inside its bearing)"
        )
    return rb, rj, offset


class ClearanceJoint(AbstractJournalJoint):
    """A revolute joint with radial clearance, modelled as a contact force element.

    Attributes:
        bearing_body, bearing_point: body and named point of the bearing (hole) centre (static).
        journal_body, journal_point: body and named point of the journal (pin) centre (static).
        bearing_radius: :math:`R_B` [m] > 0.
        journal_radius: :math:`R_J` [m], :math:`0 < R_J < R_B`.
        length: axial length L of the joint [m] > 0 (used by the cylindrical and hybrid laws).
        law: the normal contact law (default Lankarani-Nikravesh, steel, :math:`c_r = 0.9`).
        friction: the tangential law (default Ambrósio with :math:`\\mu = 0`).
        impact_velocity_floor: lower bound [m/s] > 0 of the impact speed used by the law, so
            that grazing contact cannot divide by zero. Trade-off: a contact that begins with
            an approach speed near the floor (grazing, re-entry into continuous contact) gets
            a damping coefficient ~ chi K delta^n / floor, which is physically an overdamped
            contact and numerically stiff for explicit solvers (many small steps). Raise the
            floor (e.g. 1e-3 m/s) for faster runs dominated by continuous contact, or use
            an implicit solver (``Settings(solver="kvaerno5")``).
        initial_offset: eccentricity vector [m] at the start (default centred).
        initial_velocity: velocity [m/s] of the journal centre relative to the bearing centre at
            the start (default 0: the journal moves with its bearing, the ideal kinematics).
        name: label (static).
    """

    bearing_body: str = eqx.field(static=True)
    bearing_point: str = eqx.field(static=True)
    journal_body: str = eqx.field(static=True)
    journal_point: str = eqx.field(static=True)
    bearing_radius: Scalar
    journal_radius: Scalar
    length: Scalar
    law: AbstractNormalLaw
    friction: AbstractFriction
    impact_velocity_floor: Scalar
    initial_offset: Vec2
    initial_velocity: Vec2
    name: str = eqx.field(static=True)

    def __init__(
        self,
        bearing_body: str,
        bearing_point: str,
        journal_body: str,
        journal_point: str,
        bearing_radius: ArrayLike = 0.010,
        journal_radius: ArrayLike = 0.0095,
        length: ArrayLike = 0.010,
        law=None,
        friction: AbstractFriction | None = None,
        impact_velocity_floor: ArrayLike = 1e-4,
        initial_offset: ArrayLike = (0.0, 0.0),
        initial_velocity: ArrayLike = (0.0, 0.0),
        name: str = "clearance",
    ):
        rb, rj, offset = check_journal_geometry(bearing_radius, journal_radius, length, impact_velocity_floor, law,
                                                initial_offset)
        self.bearing_body, self.bearing_point = bearing_body, bearing_point
        self.journal_body, self.journal_point = journal_body, journal_point
        self.bearing_radius, self.journal_radius = rb, rj
        self.length = jnp.asarray(length, dtype=float)
        self.law = ContactLaw() if law is None else law
        self.friction = element_friction(friction, "ClearanceJoint", Friction())
        self.impact_velocity_floor = jnp.asarray(impact_velocity_floor, dtype=float)
        self.initial_offset = offset
        self.initial_velocity = jnp.asarray(initial_velocity, dtype=float).reshape(2)
        self.name = name

    # ---- the two hooks of AbstractJournalJoint -----------------------------------------
    def kinematics(self, mech: Mechanism, q, qdot) -> ContactKinematics:
        """Eccentricity, penetration, its rate and the slip (:func:`kinematics`)."""
        return kinematics(mech, self, q, qdot)

    def contact(self, mech: Mechanism, q, qdot, impact_velocity):
        """Generalized contact force (n,) and :class:`ContactOutput` (:func:`joint_forces`)."""
        return joint_forces(mech, self, q, qdot, impact_velocity)


def kinematics(mech: Mechanism, joint: ClearanceJoint, q, qdot) -> ContactKinematics:
    """Eccentricity, penetration, its rate and the slip of one clearance joint."""
    p_i = point_position(mech, q, joint.bearing_body, joint.bearing_point)
    p_j = point_position(mech, q, joint.journal_body, joint.journal_point)
    v_i = point_velocity(mech, q, qdot, joint.bearing_body, joint.bearing_point)
    v_j = point_velocity(mech, q, qdot, joint.journal_body, joint.journal_point)
    _, phi_i = mech.pose(q, joint.bearing_body)
    _, phi_j = mech.pose(q, joint.journal_body)
    _, w_i = mech.twist(qdot, joint.bearing_body)
    _, w_j = mech.twist(qdot, joint.journal_body)
    ecc = p_j - p_i
    e, n = safe_normal(ecc)
    t = perp(n)
    # contact-point velocities: v_Q = v_P + omega perp(R n)
    vq_i = v_i + w_i * perp(joint.bearing_radius * n)
    vq_j = v_j + w_j * perp(joint.journal_radius * n)
    rel = vq_j - vq_i
    return ContactKinematics(
        ecc=ecc,
        e=e,
        normal=n,
        tangent=t,
        delta=e - joint.clearance,
        deltadot=rel[0] * n[0] + rel[1] * n[1],
        slip=rel[0] * t[0] + rel[1] * t[1],
        bearing_centre=p_i,
        journal_centre=p_j,
        bearing_velocity=v_i,
        journal_velocity=v_j,
        bearing_angle=phi_i,
        journal_angle=phi_j,
        bearing_omega=w_i,
        journal_omega=w_j,
        radius_bearing=joint.bearing_radius,
        radius_journal=joint.journal_radius,
        length=joint.length,
    )


def journal_state(mech: Mechanism, q, qdot) -> Float[Array, " 4k"]:
    """Relative state of every force element, stacked ``[e_x, e_y, v_x, v_y]`` per element
    (``(4k,)``; [m, m, m/s, m/s]): for a journal joint the eccentricity and the velocity of the
    journal centre relative to the bearing centre
    (:meth:`~jaxclear.elements.base.AbstractForceElement.relative_state`). Poincare sections and
    the fit's window states use it."""
    rows = [element.relative_state(mech, q, qdot) for element in mech.clearance_joints]
    return jnp.concatenate(rows) if rows else jnp.zeros((0,), q.dtype)


def joint_forces(mech: Mechanism, joint: ClearanceJoint, q, qdot, impact_velocity):
    """Generalized contact force (n,) of one joint and its :class:`ContactOutput`."""
    return contact_forces(mech, joint, kinematics(mech, joint, q, qdot), q, qdot, impact_velocity)


def contact_forces(mech: Mechanism, joint: AbstractJournalJoint, kin: ContactKinematics, q, qdot, impact_velocity):
    """Generalized force (n,) of the dry contact of a journal joint with kinematics ``kin``
    (normal law, then friction law; the force on the journal at :math:`Q_j = P_j + R_J n`, minus
    it on the bearing at ``kin.bearing_centre`` :math:`+ R_B n`) and its :class:`ContactOutput`."""
    speed0 = jnp.maximum(impact_velocity, joint.impact_velocity_floor)
    f_n, n = joint.law.contact_force(kin, speed0)
    f_t = joint.friction(kin.slip, f_n)
    f_journal = -f_n * n + f_t * perp(n)
    q_i = kin.bearing_centre + joint.bearing_radius * n
    q_j = kin.journal_centre + joint.journal_radius * n
    gen = point_load(mech, q, joint.journal_body, q_j, f_journal) + point_load(
        mech, q, joint.bearing_body, q_i, -f_journal
    )
    out = ContactOutput(
        ecc=kin.ecc,
        penetration=joint.law.penetration(kin),
        normal_force=f_n,
        friction_force=f_t,
        power=jnp.sum(gen * qdot),
    )
    return gen, out
