r"""Pin-in-slot joints with clearance: a journal (pin) of radius :math:`R_J` moving in a slot of
width :math:`2R_B` whose straight part has length :math:`\ell` between two semicircular ends
(a stadium), as a force element.

Reference: Škrinjar, Slavič, Boltežar, "A validated model for a pin-slot clearance joint",
Nonlinear Dyn. 88 (2017) 131-143; contact laws as for the revolute clearance joint (Flores,
Ambrósio, Claro, Lankarani, "Kinematics and Dynamics of Multibody Systems with Imperfect
Joints", Springer 2008, ch. 4).

Geometry (SI): the slot body *i* carries the slot centre :math:`P_i` and the body-fixed unit
axis :math:`a` (global :math:`u = A(\phi_i)a`); the slot's centre segment is
:math:`P_i + s\,u`, :math:`|s| \le \ell/2`. With :math:`\mathbf r = P_j - P_i`, the nearest
point of the segment to the pin centre is :math:`P_i + s^* u`,
:math:`s^* = \mathrm{clip}(\mathbf r\cdot u, -\ell/2, \ell/2)`, and the contact is that of a
revolute clearance joint whose bearing centre is that point: eccentricity
:math:`\mathbf e = P_j - P_i - s^* u` (the distance to the stadium boundary is
:math:`R_B - |\mathbf e|`), penetration :math:`\delta = |\mathbf e| - c`, normal
:math:`n = \mathbf e/|\mathbf e|`, the bearing's contact point :math:`P_i + s^* u + R_B n` moving
with the slot body. On the straight faces the normal is perpendicular to the slot and the contact
is the pin against a flat face; the law still sees the radii :math:`R_B, R_J` (exact at the
semicircular ends). With :math:`\ell = 0` every expression reduces to the revolute clearance
joint's.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._errors import RESULTS, ParameterError, Rule, check_range, is_concrete
from .._types import ArrayLike, Scalar, Vec2
from ..contact.base import AbstractFriction, AbstractNormalLaw, ContactKinematics, element_friction
from ..contact.friction import Friction
from ..contact.hertz import ContactLaw
from ..model.bodies import vec2
from ..model.geometry import perp, rotate, safe_normal
from ..model.joints import PointOnLine
from ..model.mechanism import Mechanism, point_position, point_velocity
from .revolute_clearance import AbstractJournalJoint, check_journal_geometry, contact_forces


#: The ideal joints a pin-in-slot joint can stand for (``ideal``; class docstring).
IDEALS = ("revolute", "line")


def nearest_on_segment(r: Vec2, u: Vec2, slot_length) -> Scalar:
    r""":math:`s^* = \mathrm{clip}(\mathbf r\cdot u, -\ell/2, \ell/2)` [m]."""
    half = 0.5 * slot_length
    return jnp.clip(r[0] * u[0] + r[1] * u[1], -half, half)


class PinSlotJoint(AbstractJournalJoint):
    """A pin in a stadium-shaped slot with clearance (module docstring for the model).

    Attributes (besides those of :class:`~jaxclear.ClearanceJoint`, with the bearing being the
    slot: ``bearing_radius`` = half the slot width, ``bearing_point`` = the slot centre):
        slot_length: length :math:`\\ell` [m] >= 0 of the straight part (0: a round hole).
        axis: slot direction, body-fixed in the slot body (unit, (2,)).
        initial_offset: pin centre relative to the slot centre at the start [m] (inside the
            stadium shrunk by the clearance).
        ideal: the ideal joint that replaces it in :meth:`~jaxclear.Mechanism.ideal` (static):
            ``"revolute"`` (default: the slot's length is play, like the clearance; the pin at
            the slot centre) or ``"line"`` (:class:`~jaxclear.PointOnLine`: the slot is a guide
            the pin travels along; the ends are not modelled).
    """

    bearing_body: str = eqx.field(static=True)
    bearing_point: str = eqx.field(static=True)
    journal_body: str = eqx.field(static=True)
    journal_point: str = eqx.field(static=True)
    bearing_radius: Scalar
    journal_radius: Scalar
    slot_length: Scalar
    axis: Vec2
    length: Scalar
    law: AbstractNormalLaw
    friction: AbstractFriction
    impact_velocity_floor: Scalar
    initial_offset: Vec2
    initial_velocity: Vec2
    ideal: str = eqx.field(static=True)
    name: str = eqx.field(static=True)

    def describe(self) -> str:
        return f"{super().describe()}, slot length {float(self.slot_length) * 1e3:.4g} mm"

    def __init__(
        self,
        bearing_body: str,
        bearing_point: str,
        journal_body: str,
        journal_point: str,
        bearing_radius: ArrayLike = 0.010,
        journal_radius: ArrayLike = 0.0095,
        slot_length: ArrayLike = 0.0,
        axis: ArrayLike = (1.0, 0.0),
        length: ArrayLike = 0.010,
        law=None,
        friction: AbstractFriction | None = None,
        impact_velocity_floor: ArrayLike = 1e-4,
        initial_offset: ArrayLike = (0.0, 0.0),
        initial_velocity: ArrayLike = (0.0, 0.0),
        ideal: str = "revolute",
        name: str = "pin-slot",
    ):
        if ideal not in IDEALS:
            raise ParameterError(f"ideal = {ideal!r}; valid: 'revolute' (pin at the slot centre), 'line' (pin on the "
                                 "slot's line)")
        check_range("slot_length", slot_length, low=0.0, unit="m")
        rb, rj, _ = check_journal_geometry(bearing_radius, journal_radius, length, impact_velocity_floor, law,
                                           (0.0, 0.0))
        ax = vec2("axis", axis)
        if is_concrete(ax):
            norm = float(jnp.linalg.norm(ax))
            if norm == 0.0:
                raise ParameterError("axis of the pin-in-slot joint must be a non-zero vector")
            ax = ax / norm
        offset = jnp.asarray(initial_offset, dtype=float).reshape(2)
        if all(is_concrete(v) for v in (rb, rj, slot_length, offset, ax)):
            s = nearest_on_segment(offset, ax, float(slot_length))
            e = float(jnp.linalg.norm(offset - s * ax))
            if e >= float(rb - rj):
                raise ParameterError(
                    f"initial_offset puts the pin {e:g} m from the slot's centre segment, not less than the "
                    f"clearance {float(rb - rj):g} m (the pin must start inside its slot)"
                )
        self.bearing_body, self.bearing_point = bearing_body, bearing_point
        self.journal_body, self.journal_point = journal_body, journal_point
        self.bearing_radius, self.journal_radius = rb, rj
        self.slot_length = jnp.asarray(slot_length, dtype=float)
        self.axis = ax
        self.length = jnp.asarray(length, dtype=float)
        self.law = ContactLaw() if law is None else law
        self.friction = element_friction(friction, "PinSlotJoint", Friction())
        self.impact_velocity_floor = jnp.asarray(impact_velocity_floor, dtype=float)
        self.initial_offset = offset
        self.initial_velocity = jnp.asarray(initial_velocity, dtype=float).reshape(2)
        self.ideal = ideal
        self.name = name

    def checks(self) -> tuple:
        """The journal joint's checks (radii, clearance, length, floor, laws), then
        slot_length >= 0 and a non-zero finite axis (``invalid_parameter``)."""
        return (
            *super().checks(),
            Rule("slot_length", self.slot_length, RESULTS.invalid_parameter, low=0.0, unit="m"),
            Rule("|axis|^2", jnp.sum(self.axis * self.axis), RESULTS.invalid_parameter, low=0.0, low_open=True),
        )

    def clearance_region(self, n: int = 361):
        r"""The stadium the pin centre may roam without contact, around the slot centre with the
        slot axis at the slot body's reference orientation (n, 2) [m]: half-length
        :math:`\ell/2`, radius :math:`c`."""
        theta = jnp.linspace(-0.5 * jnp.pi, 1.5 * jnp.pi, n - 1)
        u, m = self.axis, perp(self.axis)
        side = jnp.where(jnp.arange(n - 1) < n // 2, 0.5, -0.5) * self.slot_length  # right half, then left
        ring = (side + self.clearance * jnp.cos(theta))[:, None] * u + (self.clearance * jnp.sin(theta))[:, None] * m
        return jnp.concatenate([ring, ring[:1]])

    def relative_state(self, mech: Mechanism, q, qdot):
        """``[r_x, r_y, v_x, v_y]``: pin centre relative to the slot centre and its velocity relative
        to the slot centre point [m, m/s]."""
        r = point_position(mech, q, self.journal_body, self.journal_point) - point_position(
            mech, q, self.bearing_body, self.bearing_point)
        v = point_velocity(mech, q, qdot, self.journal_body, self.journal_point) - point_velocity(
            mech, q, qdot, self.bearing_body, self.bearing_point)
        return jnp.concatenate([r, v])

    def ideal_joint(self):
        """The ideal joint chosen by ``ideal``: a :class:`~jaxclear.Revolute` at the slot centre or a
        :class:`~jaxclear.PointOnLine` (pin on the slot's line, no end stops)."""
        if self.ideal == "line":
            return PointOnLine(self.bearing_body, self.bearing_point, self.journal_body, self.journal_point,
                               axis=self.axis)
        return super().ideal_joint()

    def kinematics(self, mech: Mechanism, q, qdot) -> ContactKinematics:
        """The contact with the nearest point of the stadium (module docstring); the bearing
        centre is the nearest point of the slot's centre segment and moves with the slot body."""
        p_i = point_position(mech, q, self.bearing_body, self.bearing_point)
        p_j = point_position(mech, q, self.journal_body, self.journal_point)
        v_i = point_velocity(mech, q, qdot, self.bearing_body, self.bearing_point)
        v_j = point_velocity(mech, q, qdot, self.journal_body, self.journal_point)
        _, phi_i = mech.pose(q, self.bearing_body)
        _, phi_j = mech.pose(q, self.journal_body)
        _, w_i = mech.twist(qdot, self.bearing_body)
        _, w_j = mech.twist(qdot, self.journal_body)
        u = rotate(phi_i, self.axis)
        along = nearest_on_segment(p_j - p_i, u, self.slot_length) * u
        centre = p_i + along
        v_centre = v_i + w_i * perp(along)
        ecc = p_j - centre
        e, n = safe_normal(ecc)
        t = perp(n)
        vq_i = v_centre + w_i * perp(self.bearing_radius * n)
        vq_j = v_j + w_j * perp(self.journal_radius * n)
        rel = vq_j - vq_i
        return ContactKinematics(
            ecc=ecc, e=e, normal=n, tangent=t, delta=e - self.clearance,
            deltadot=rel[0] * n[0] + rel[1] * n[1], slip=rel[0] * t[0] + rel[1] * t[1],
            bearing_centre=centre, journal_centre=p_j, bearing_velocity=v_centre, journal_velocity=v_j,
            bearing_angle=phi_i, journal_angle=phi_j, bearing_omega=w_i, journal_omega=w_j,
            radius_bearing=self.bearing_radius, radius_journal=self.journal_radius, length=self.length,
        )

    #: the stadium's feature nearest to the pin (0 a flank, the straight part; 1 an end, a
    #: semicircle), the pin's penetration into it (negative: the gap) and the pin centre's
    #: coordinate along the slot from the slot centre
    OUTPUTS = {"feature": "-", "feature_penetration": "m", "slot_coordinate": "m"}

    def outputs(self, mech: Mechanism, t, q, qdot, state, continuous_after):
        r"""The active feature (0 flank, 1 end: the pin centre beyond the straight part's end,
        :math:`|s| > \ell/2`), its penetration [m] (:math:`e - c` to the nearest point, what
        the law sees; ``Solution.ecc`` is the pin centre from the slot centre, so
        :math:`|ecc| - c` is not a penetration here) and the slot coordinate :math:`s` [m]."""
        kin = self.kinematics(mech, q, qdot)
        centre = point_position(mech, q, self.bearing_body, self.bearing_point)
        _, phi_i = mech.pose(q, self.bearing_body)
        u = rotate(phi_i, self.axis)
        r = kin.journal_centre - centre
        along = r[0] * u[0] + r[1] * u[1]
        end = jnp.abs(along) > 0.5 * self.slot_length
        return {"feature": end.astype(jnp.int32), "feature_penetration": self.law.penetration(kin),
                "slot_coordinate": along}

    def contact(self, mech: Mechanism, q, qdot, impact_velocity):
        r"""Dry contact with the stadium (:func:`~jaxclear.elements.revolute_clearance.contact_forces`);
        the output's ``ecc`` is the pin centre relative to the slot centre (``kin.ecc`` plus the
        nearest point's offset along the slot; the same for :math:`\ell = 0`)."""
        kin = self.kinematics(mech, q, qdot)
        gen, out = contact_forces(mech, self, kin, q, qdot, impact_velocity)
        centre = point_position(mech, q, self.bearing_body, self.bearing_point)
        return gen, eqx.tree_at(lambda o: o.ecc, out, kin.journal_centre - centre)
