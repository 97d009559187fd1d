r"""Translational (prismatic) joints with clearance: a rectangular slider block inside a guide
whose two parallel surfaces leave a gap, as a force element with four corner contacts.

Reference: Flores, Ambrósio, Claro, Lankarani, "Translational joints with clearance in rigid
multibody systems", J. Comput. Nonlinear Dyn. 3 (2008) 011007.

Geometry (SI): the guide body *i* carries the guide line through point :math:`G` along the
body-fixed unit axis :math:`a` (global :math:`u = A(\phi_i)a`, normal :math:`m = \mathrm{perp}(u)`);
its two surfaces lie at :math:`\pm W/2` from the line (``guide_width`` :math:`W`). The slider body
*j* is a block of length :math:`\ell` (``slider_length``) and height :math:`b` (``slider_height``)
centred on its point :math:`S`, aligned with the guide when :math:`\phi_j - \phi_i` equals
``angle``; clearance per side :math:`c = (W - b)/2 > 0`. Corner :math:`k` with signs
:math:`(\sigma_k, \tau_k) \in \{\pm1\}^2` sits at
:math:`C_k = S + \sigma_k(\ell/2)u_j + \tau_k(b/2)\mathrm{perp}(u_j)`,
:math:`u_j = A(\phi_j - \text{angle})a`, and faces the surface on its own side :math:`\tau_k`:

* penetration :math:`\delta_k = \tau_k (C_k - G)\cdot m - W/2` (positive beyond the surface),
  its rate :math:`\dot\delta_k = \tau_k (v_{C_k} - v^{i}_{C_k})\cdot m` and the slip
  :math:`v_{T,k} = (v_{C_k} - v^{i}_{C_k})\cdot u`, with :math:`v^{i}_{C_k}` the velocity of the
  guide body's material point at :math:`C_k`;
* normal force :math:`F_{N,k}` from the joint's normal law (each corner with its own impact
  memory, :mod:`jaxclear.elements.memory`), friction :math:`F_{T,k}` from its friction law (a
  law with bristle states, Dahl or LuGre, gets its own states per corner, carried as the journal
  joints carry theirs: integrated while the corner is in contact, frozen out of contact, relaxed
  to zero at the corner's contact onset);
  force on the slider at :math:`C_k`: :math:`-F_{N,k}\tau_k m + F_{T,k} u`, minus it on the guide.

Each corner is a point contact against a flat surface: the law is meant to be a point law (the
dissipative-Hertz family, Kelvin-Voigt) with its stiffness given; the kinematics handed to it
carry ``radius_journal = corner_radius`` and a flat counterpart (``radius_bearing`` = 1 km).
The guide is taken long enough for the slider never to leave it. Free flight, one corner, face
contact (two corners on one surface) and jamming (two diagonal corners on opposite surfaces) are
all covered by the four independent corner contacts.

Outputs (:class:`~jaxclear.elements.base.ContactOutput`): ``ecc`` = ``[y, (l/2) theta]``, the
lateral offset of :math:`S` from the guide line and the tilt :math:`\theta` times the half
length (both in metres, both zero for the ideal joint); ``penetration`` = the deepest corner's;
``normal_force`` and ``friction_force`` = sums over the corners. Per-corner forces:
:meth:`TranslationalClearanceJoint.corner_forces`; per-corner memories: the state's ``corners``.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, ParameterError, Rule, check_range, is_concrete
from .._parameters import POSITIVE, Parameter
from .._types import Array, ArrayLike, Float, Scalar, Vec2
from ..contact.base import AbstractFriction, AbstractNormalLaw, ContactKinematics, element_friction
from ..contact.friction import Friction
from ..contact.hertz import ContactLaw
from ..model.bodies import vec2
from ..model.geometry import perp, rotate
from ..model.joints import Translational
from ..model.mechanism import Mechanism, point_load, point_position, point_velocity
from .base import AbstractForceElement, ContactOutput, contact_mode
from .memory import (N_FIELDS, ContactMemory, kink_fraction, onset_fraction, onset_update, penetration_accelerations,
                     with_peak_force)

#: Corner signs (sigma along the slider, tau across it): rear-lower, front-lower, rear-upper, front-upper.
SIGMA = np.array([-1.0, 1.0, -1.0, 1.0])
#: the corners' names, in that order (output channels)
CORNERS = ("rear_lower", "front_lower", "rear_upper", "front_upper")
TAU = np.array([-1.0, -1.0, 1.0, 1.0])
FLAT_RADIUS = 1e3  # m, the radius a law sees for the guide surface


class CornerMemory(eqx.Module):
    """State of a translational clearance joint: one :class:`ContactMemory` per corner, fields
    shaped ``(..., 4)`` (corner order of :data:`SIGMA`/:data:`TAU`), and, for a friction law
    with internal states (Dahl, LuGre), each corner's bristle states ``friction`` ``(..., 4, m)``
    [m] (``None`` otherwise). The slice is the memory's six fields (field-major, 6 x 4) followed
    by the bristle states (corner-major, 4 x m)."""

    corners: ContactMemory
    friction: Float[Array, "4 m"] | None = None

    def summary(self) -> ContactMemory:
        """The joint as one contact: latest onset (and its corner's impact speed), impacts and
        work summed over the corners, largest corner peak force and penetration."""
        m = self.corners
        last = jnp.argmax(m.contact_start, axis=-1)[..., None]
        return ContactMemory(
            impact_velocity=jnp.take_along_axis(m.impact_velocity, last, axis=-1)[..., 0],
            contact_start=jnp.max(m.contact_start, axis=-1),
            impacts=jnp.sum(m.impacts, axis=-1),
            work=jnp.sum(m.work, axis=-1),
            peak_force=jnp.max(m.peak_force, axis=-1),
            peak_penetration=jnp.max(m.peak_penetration, axis=-1),
        )


class TranslationalClearanceJoint(AbstractForceElement):
    """A slider block in a guide with clearance (module docstring for the model).

    Attributes:
        guide_body, guide_point: body and named point on the guide's centre line (static).
        slider_body, slider_point: body and named point at the slider block's centre (static).
        axis: guide direction, body-fixed in the guide body (unit, (2,)).
        angle: relative angle :math:`\\phi_j - \\phi_i` [rad] at which the block is aligned.
        slider_length: block length :math:`\\ell` [m] > 0.
        slider_height: block height :math:`b` [m] > 0.
        guide_width: distance :math:`W` [m] between the guide surfaces, > ``slider_height``.
        corner_radius: radius [m] > 0 the law sees for a corner.
        law: normal law of every corner (default Lankarani-Nikravesh, :math:`K = 4.8\\times10^9`
            N/m^1.5, the Hertz sphere-on-plane stiffness of a 1 mm steel corner, :math:`c_r = 0.9`).
        friction: tangential law of every corner (default none).
        impact_velocity_floor: lower bound [m/s] of the impact speed the law divides by.
        initial_offset: ``[y, theta]`` lateral offset [m] and tilt [rad] at the start.
        initial_velocity: their rates [m/s, rad/s] at the start.
        name: label (static).
    """

    guide_body: str = eqx.field(static=True)
    guide_point: str = eqx.field(static=True)
    slider_body: str = eqx.field(static=True)
    slider_point: str = eqx.field(static=True)
    axis: Vec2
    angle: Scalar
    slider_length: Scalar
    slider_height: Scalar
    guide_width: Scalar
    corner_radius: Scalar
    law: AbstractNormalLaw
    friction: AbstractFriction
    impact_velocity_floor: Scalar
    initial_offset: Vec2
    initial_velocity: Vec2
    name: str = eqx.field(static=True)

    def __init__(
        self,
        guide_body: str,
        guide_point: str,
        slider_body: str,
        slider_point: str,
        slider_length: ArrayLike = 0.05,
        slider_height: ArrayLike = 0.03,
        guide_width: ArrayLike = 0.0302,
        axis: ArrayLike = (1.0, 0.0),
        angle: ArrayLike = 0.0,
        corner_radius: ArrayLike = 1e-3,
        law: AbstractNormalLaw | None = None,
        friction: AbstractFriction | None = None,
        impact_velocity_floor: ArrayLike = 1e-4,
        initial_offset: ArrayLike = (0.0, 0.0),
        initial_velocity: ArrayLike = (0.0, 0.0),
        name: str = "guide",
    ):
        check_range("slider_length", slider_length, low=0.0, low_open=True, unit="m")
        check_range("slider_height", slider_height, low=0.0, low_open=True, unit="m")
        check_range("guide_width", guide_width, low=0.0, low_open=True, unit="m")
        check_range("corner_radius", corner_radius, low=0.0, low_open=True, unit="m")
        check_range("impact_velocity_floor", impact_velocity_floor, low=0.0, low_open=True, unit="m/s")
        law = ContactLaw(stiffness=4.8e9) if law is None else law
        leaf = getattr(law, law.stiffness_parameter, 0.0)
        if leaf is None:
            raise ParameterError(
                f"the translational clearance joint needs a law with an explicit {law.stiffness_parameter} "
                "(a corner against a flat surface has no journal-bearing stiffness to derive); allowed: > 0"
            )
        ax = vec2("axis", axis)
        if is_concrete(ax):
            norm = float(jnp.linalg.norm(ax))
            if norm == 0.0:
                raise ParameterError("axis of the translational clearance joint must be a non-zero vector")
            ax = ax / norm
        offset = jnp.asarray(initial_offset, dtype=float).reshape(2)
        if all(is_concrete(v) for v in (slider_length, slider_height, guide_width, offset)):
            a, b, w = float(slider_length), float(slider_height), float(guide_width)
            if b >= w:
                raise ParameterError(
                    f"the slider does not fit its guide: slider_height = {b:g} m must be smaller than "
                    f"guide_width = {w:g} m (clearance per side (W - b)/2 must be > 0)"
                )
            y, th = float(offset[0]), float(offset[1])
            depth = np.max(TAU * (y + SIGMA * a / 2 * np.sin(th) + TAU * b / 2 * np.cos(th)) - w / 2)
            if depth >= 0.0:
                raise ParameterError(
                    f"initial_offset (y = {y:g} m, theta = {th:g} rad) puts a corner {depth:g} m into the guide "
                    f"surface; the slider must start inside its guide (clearance {(w - b) / 2:g} m per side)"
                )
        self.guide_body, self.guide_point = guide_body, guide_point
        self.slider_body, self.slider_point = slider_body, slider_point
        self.axis = ax
        self.angle = jnp.asarray(angle, dtype=float)
        self.slider_length = jnp.asarray(slider_length, dtype=float)
        self.slider_height = jnp.asarray(slider_height, dtype=float)
        self.guide_width = jnp.asarray(guide_width, dtype=float)
        self.corner_radius = jnp.asarray(corner_radius, dtype=float)
        self.law = law
        self.friction = element_friction(friction, "TranslationalClearanceJoint", Friction())
        self.impact_velocity_floor = jnp.asarray(impact_velocity_floor, dtype=float)
        self.initial_offset = offset
        self.initial_velocity = jnp.asarray(initial_velocity, dtype=float).reshape(2)
        self.name = name

    @property
    def clearance(self):
        """Clearance per side :math:`c = (W - b)/2` [m]."""
        return 0.5 * (self.guide_width - self.slider_height)

    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "clearance": Parameter("guide_width", "m", **POSITIVE, doc="radial clearance R_B - R_J",
                               read=lambda j: j.clearance, write=lambda j, c: j.slider_height + 2.0 * c),
        **AbstractForceElement.PARAMETERS,
    }

    def parameters(self) -> dict[str, Parameter]:
        """Those of :meth:`AbstractForceElement.parameters`; the stiffness always explicit (the
        joint needs the law's stiffness leaf set)."""
        table = super().parameters()
        if "stiffness" in table:
            table["stiffness"] = table["stiffness"]._replace(derived=False)
        return table

    def describe(self) -> str:
        return (f"{self.label}: guide {self.guide_body}.{self.guide_point}, slider {self.slider_body}."
                f"{self.slider_point}, block {float(self.slider_length) * 1e3:.4g} x "
                f"{float(self.slider_height) * 1e3:.4g} mm, guide width {float(self.guide_width) * 1e3:.4g} mm, "
                f"c = {float(self.clearance) * 1e6:.4g} um per side, {self.laws_text()}")

    # ---- structure ------------------------------------------------------------------
    def bodies(self):
        return (self.guide_body, self.slider_body)

    def points(self):
        return ((self.guide_body, self.guide_point), (self.slider_body, self.slider_point))

    @property
    def label(self):
        return f"translational clearance joint {self.name}"

    orbit_labels: ClassVar[tuple[str, str]] = ("lateral offset y", "tilt x half length")

    # ---- validity (run time) -----------------------------------------------------------
    #: A corner penetration deeper than this fraction of the corner radius is reported as
    #: ``penetration_too_deep``: the corner is a Hertz sphere on a plane, whose contact radius
    #: :math:`a = \sqrt{\delta r}` reaches ~0.3 r at :math:`\delta = r/10`, far outside the
    #: small-contact assumption (Johnson, "Contact Mechanics", CUP 1985, ch. 4), the same bound
    #: as the journal joints' (a tenth of the journal radius).
    MAX_PENETRATION_FRACTION: ClassVar[float] = 0.1

    def checks(self) -> tuple:
        """Block length, height and guide width > 0 with the block fitting its guide (clearance
        per side :math:`(W - b)/2 > 0`) -> ``invalid_clearance``; corner radius and
        impact_velocity_floor > 0, a non-zero finite axis and a finite angle ->
        ``invalid_parameter``; then the corner law's and the friction law's own checks."""
        element_friction(self.friction, type(self).__name__, self.friction)  # a law set after __init__
        positive = dict(low=0.0, low_open=True)
        fits, other = RESULTS.invalid_clearance, RESULTS.invalid_parameter
        return (
            Rule("slider_length", self.slider_length, fits, unit="m", **positive),
            Rule("slider_height b", self.slider_height, fits, unit="m", **positive),
            Rule("guide_width W", self.guide_width, fits, unit="m", **positive),
            Rule("clearance per side (W - b)/2 (the block must fit its guide)", self.clearance, fits, unit="m",
                 **positive),
            Rule("corner_radius", self.corner_radius, other, unit="m", **positive),
            Rule("impact_velocity_floor", self.impact_velocity_floor, other, unit="m/s", **positive),
            Rule("|axis|^2", jnp.sum(self.axis * self.axis), other, **positive),
            Rule("angle", self.angle, other, unit="rad"),
            self.law,  # the laws' own checks (first_failure calls check(); failed_check reads their checks())
            self.friction,
        )

    def penetration_limit(self):
        """:attr:`MAX_PENETRATION_FRACTION` times the corner radius [m]."""
        return self.MAX_PENETRATION_FRACTION * self.corner_radius

    def clearance_region(self, n: int = 361):
        r"""Offsets ``[y, (l/2) theta]`` with no corner in contact, to first order in the tilt:
        the square :math:`|y| + |(l/2)\theta| \le c` (n, 2) [m]."""
        s = jnp.linspace(0.0, 4.0, n)
        x = jnp.interp(s, jnp.arange(5.0), jnp.array([1.0, 0.0, -1.0, 0.0, 1.0]))
        y = jnp.interp(s, jnp.arange(5.0), jnp.array([0.0, 1.0, 0.0, -1.0, 0.0]))
        return self.clearance * jnp.stack([x, y], axis=-1)

    def start_scale(self):
        """``[c / sqrt 2, sqrt 2 c / l]`` [m, rad]: the ellipse with these half-axes lies inside the
        contact-free square ``|y| + (l/2)|theta| <= c`` of :meth:`clearance_region`."""
        c = self.clearance
        return jnp.stack([c / jnp.sqrt(2.0), jnp.sqrt(2.0) * c / self.slider_length])

    def ideal_joint(self) -> Translational:
        """The ideal translational joint: slider centre on the guide line, block aligned."""
        return Translational(self.guide_body, self.guide_point, self.slider_body, self.slider_point,
                             axis=self.axis, angle=self.angle)

    # ---- state: four corner memories (and each corner's bristle states, if any) ---------
    @property
    def state_size(self) -> int:
        """Four :class:`ContactMemory` (4 x :data:`~jaxclear.elements.memory.N_FIELDS`) plus the
        friction law's internal states for each corner."""
        return 4 * (N_FIELDS + self.friction.state_size)

    def _bristles_init(self, dtype):
        m = self.friction.state_size
        return None if m == 0 else jnp.stack([self.friction.state_init(dtype)] * 4)

    def state_init(self, dtype=float) -> CornerMemory:
        return CornerMemory(ContactMemory.initial((4,), dtype), self._bristles_init(dtype))

    def state_to_vector(self, state: CornerMemory):
        return jnp.concatenate([jnp.reshape(x, (-1,)) for x in jax.tree_util.tree_leaves(state)])

    def state_from_vector(self, v) -> CornerMemory:
        rows = jnp.reshape(v[:4 * N_FIELDS], (N_FIELDS, 4))
        memory = ContactMemory(*(rows[i] for i in range(N_FIELDS)))
        m = self.friction.state_size
        return CornerMemory(memory, None if m == 0 else jnp.reshape(v[4 * N_FIELDS:self.state_size], (4, m)))

    def corner_bristles(self, state: CornerMemory | None, dtype=float):
        """The corners' bristle states ``(4, m)`` of ``state`` (relaxed ones for ``None`` or a
        state without them); ``None`` for a memoryless friction law."""
        if self.friction.state_size == 0:
            return None
        if state is None or state.friction is None:
            return self._bristles_init(dtype)
        return state.friction

    # ---- kinematics -----------------------------------------------------------------
    def _frame(self, mech: Mechanism, q, qdot):
        g = point_position(mech, q, self.guide_body, self.guide_point)
        s = point_position(mech, q, self.slider_body, self.slider_point)
        vg = point_velocity(mech, q, qdot, self.guide_body, self.guide_point)
        vs = point_velocity(mech, q, qdot, self.slider_body, self.slider_point)
        phi_i, phi_j = mech.angle(q, self.guide_body), mech.angle(q, self.slider_body)
        _, w_i = mech.twist(qdot, self.guide_body)
        _, w_j = mech.twist(qdot, self.slider_body)
        return g, s, vg, vs, phi_i, phi_j, w_i, w_j

    def corner_kinematics(self, mech: Mechanism, q, qdot) -> ContactKinematics:
        """The four corners' contacts as one :class:`ContactKinematics` with fields shaped (4,)
        (vectors (4, 2)): ``normal`` = :math:`\\tau_k m`, ``tangent`` = :math:`u`,
        ``journal_centre`` = the corner :math:`C_k`."""
        g, s, vg, vs, phi_i, phi_j, w_i, w_j = self._frame(mech, q, qdot)
        u = rotate(phi_i, self.axis)
        m = perp(u)
        uj = rotate(phi_j - self.angle, self.axis)
        sig, tau = jnp.asarray(SIGMA, q.dtype)[:, None], jnp.asarray(TAU, q.dtype)[:, None]
        arm = sig * (0.5 * self.slider_length) * uj + tau * (0.5 * self.slider_height) * perp(uj)  # (4, 2)
        corners = s + arm
        v_c = vs + w_j * jnp.stack([-arm[:, 1], arm[:, 0]], axis=-1)
        rel_g = corners - g
        v_gm = vg + w_i * jnp.stack([-rel_g[:, 1], rel_g[:, 0]], axis=-1)  # guide material point
        rel_v = v_c - v_gm
        normal = tau * m
        delta = jnp.sum(rel_g * normal, axis=-1) - 0.5 * self.guide_width
        ones = jnp.ones(4, q.dtype)
        return ContactKinematics(
            ecc=rel_g, e=jnp.sum(rel_g * normal, axis=-1), normal=normal, tangent=jnp.broadcast_to(u, (4, 2)),
            delta=delta, deltadot=jnp.sum(rel_v * normal, axis=-1), slip=jnp.sum(rel_v * u, axis=-1),
            bearing_centre=jnp.broadcast_to(g, (4, 2)), journal_centre=corners,
            bearing_velocity=v_gm, journal_velocity=v_c, bearing_angle=phi_i * ones, journal_angle=phi_j * ones,
            bearing_omega=w_i * ones, journal_omega=w_j * ones, radius_bearing=FLAT_RADIUS * ones,
            radius_journal=self.corner_radius * ones, length=self.slider_length * ones,
        )

    def offset(self, mech: Mechanism, q) -> Vec2:
        """``[y, theta]``: lateral offset [m] of the slider centre and tilt [rad] of the block."""
        g = point_position(mech, q, self.guide_body, self.guide_point)
        s = point_position(mech, q, self.slider_body, self.slider_point)
        m = perp(rotate(mech.angle(q, self.guide_body), self.axis))
        tilt = mech.angle(q, self.slider_body) - mech.angle(q, self.guide_body) - self.angle
        return jnp.stack([jnp.sum((s - g) * m), tilt])

    def relative_state(self, mech: Mechanism, q, qdot):
        """``[x, y, v_x, v_y]`` of the slider centre relative to the guide point, in the guide's
        axes (x along the guide) [m, m/s]."""
        g, s, vg, vs, phi_i, _, w_i, _ = self._frame(mech, q, qdot)
        u = rotate(phi_i, self.axis)
        m = perp(u)
        rel = s - g
        v = vs - vg - w_i * perp(rel)
        return jnp.stack([jnp.sum(rel * u), jnp.sum(rel * m), jnp.sum(v * u), jnp.sum(v * m)])

    # ---- forces ---------------------------------------------------------------------
    def corner_forces(self, mech: Mechanism, q, qdot, impact_velocity, bristles=None):
        """Normal and friction forces [N] of the four corners (each (4,)) and their kinematics,
        for the corners' impact speeds ``impact_velocity`` (4,) [m/s] and, for a friction law
        with internal states, the corners' bristle states ``bristles`` (4, m) (``None``:
        relaxed)."""
        f_n, f_t, _, kin = self._corner_contacts(mech, q, qdot, impact_velocity, bristles)
        return f_n, f_t, kin

    def _corner_contacts(self, mech: Mechanism, q, qdot, impact_velocity, bristles):
        """``(F_N (4,), F_T (4,), bristle rates (4, m) or None, kinematics)``; the rates are zero
        for a corner out of contact (its bristles carry no load and stay as they are)."""
        kin = self.corner_kinematics(mech, q, qdot)
        speed0 = jnp.maximum(impact_velocity, self.impact_velocity_floor)
        f_n = jax.vmap(lambda k, s: self.law.contact_force(k, s)[0])(kin, speed0)
        if self.friction.state_size == 0:
            return f_n, jax.vmap(self.friction)(kin.slip, f_n), None, kin
        if bristles is None:
            bristles = self.corner_bristles(None, q.dtype)
        f_t, rate = jax.vmap(self.friction.force_and_rate)(bristles, kin.slip, f_n)
        return f_n, f_t, jnp.where(f_n[:, None] > 0.0, rate, 0.0), kin

    def contact(self, mech: Mechanism, q, qdot, impact_velocity, bristles=None):
        """Generalized force (n,), per-corner power (4,) [W], the joint's :class:`ContactOutput`
        and the corners' normal forces (4,) [N] (``bristles`` as in :meth:`corner_forces`)."""
        gen, powers, out, f_n, _ = self._contact(mech, q, qdot, impact_velocity, bristles)
        return gen, powers, out, f_n

    def _contact(self, mech: Mechanism, q, qdot, impact_velocity, bristles):
        """:meth:`contact` and the corners' bristle rates (or ``None``)."""
        f_n, f_t, rate, kin = self._corner_contacts(mech, q, qdot, impact_velocity, bristles)
        gens = []
        for k in range(4):
            f = -f_n[k] * kin.normal[k] + f_t[k] * kin.tangent[k]
            gens.append(point_load(mech, q, self.slider_body, kin.journal_centre[k], f)
                        + point_load(mech, q, self.guide_body, kin.journal_centre[k], -f))
        gens = jnp.stack(gens)
        powers = gens @ qdot
        off = self.offset(mech, q)
        out = ContactOutput(
            ecc=jnp.stack([off[0], 0.5 * self.slider_length * off[1]]),
            penetration=jnp.max(jax.vmap(self.law.penetration)(kin)),
            normal_force=jnp.sum(f_n),
            friction_force=jnp.sum(f_t),
            power=jnp.sum(powers),
        )
        return jnp.sum(gens, axis=0), powers, out, f_n, rate

    #: per corner (:data:`CORNERS`, the order of :data:`SIGMA`/:data:`TAU`): normal and friction
    #: force, penetration (negative: the gap) and contact mode (0 free, 1 impact, 2 continuous)
    OUTPUTS = {f"{c}_{what}": unit for c in CORNERS for what, unit in (("normal_force", "N"), ("friction_force", "N"), ("penetration", "m"),
                                  ("mode", "-"))}

    def outputs(self, mech: Mechanism, t, q, qdot, state: CornerMemory, continuous_after):
        """Each corner's normal and friction force [N], penetration [m] and contact mode (from
        its own memory; ``Solution`` sees the joint as one contact: summed forces, the deepest
        corner, the offset and tilt as ``ecc``)."""
        bristles = self.corner_bristles(state, q.dtype)
        f_n, f_t, _, kin = self._corner_contacts(mech, q, qdot, state.corners.impact_velocity, bristles)
        pen = jax.vmap(self.law.penetration)(kin)
        mode = contact_mode(t, pen, state.corners.contact_start, continuous_after)
        out = {}
        for k, c in enumerate(CORNERS):
            out |= {f"{c}_normal_force": f_n[k], f"{c}_friction_force": f_t[k], f"{c}_penetration": pen[k],
                    f"{c}_mode": mode[k]}
        return out

    def forces(self, mech: Mechanism, t, q, qdot, state: CornerMemory):
        """Generalized force (n,), state rate (each corner's work rate is its power; the bristle
        states move at the friction law's rate while their corner is in contact) and the joint's
        :class:`ContactOutput`."""
        bristles = self.corner_bristles(state, q.dtype)
        gen, powers, out, _, rate = self._contact(mech, q, qdot, state.corners.impact_velocity, bristles)
        return gen, CornerMemory(state.corners.rate(powers), rate), out

    def after_step(self, mech: Mechanism, t0, q0, qd0, t1, q1, qd1, state: CornerMemory, qdd=None):
        """The impact-memory rule for every corner over ``[t0, t1]``, then each corner's
        running peak force; a corner's bristle states relax to zero at its onset."""
        k0, k1 = self.corner_kinematics(mech, q0, qd0), self.corner_kinematics(mech, q1, qd1)
        pen = jax.vmap(self.law.penetration)
        accel = penetration_accelerations(lambda q, qd: self.corner_kinematics(mech, q, qd).deltadot,
                                          q0, qd0, q1, qd1, qdd)
        new, crossed = onset_update(state.corners, t0, t1, pen(k0), pen(k1), k0.deltadot, k1.deltadot, accel)
        bristles = self.corner_bristles(state, q1.dtype)
        f_n, _, _ = self.corner_forces(mech, q1, qd1, new.impact_velocity, bristles)
        if bristles is not None:
            bristles = jnp.where(crossed[:, None], 0.0, bristles)
        return CornerMemory(with_peak_force(new, f_n), bristles), jnp.any(crossed)

    def onset(self, mech: Mechanism, t0, q0, qd0, t1, q1, qd1, state: CornerMemory):
        """Fraction of ``[t0, t1]`` at the earliest corner switch to split at (``onset_fraction`` per corner)."""
        k0, k1 = self.corner_kinematics(mech, q0, qd0), self.corner_kinematics(mech, q1, qd1)
        pen = jax.vmap(self.law.penetration)
        s, crossed = onset_fraction(pen(k0), pen(k1), k0.deltadot, k1.deltadot, t1 - t0)
        return jnp.min(s), jnp.any(crossed)

    def kinks(self, mech: Mechanism, t0, q0, qd0, qdd0, t1, q1, qd1, state: CornerMemory):
        """Fraction of ``[t0, t1]`` at the first friction kink among the corners in contact."""
        kinks = lambda q, qd: jax.vmap(self.friction.kinks)(self.corner_kinematics(mech, q, qd).slip)  # noqa: E731
        g0, rate0 = jax.jvp(kinks, (q0, qd0), (qd0, qdd0))
        k0, k1 = self.corner_kinematics(mech, q0, qd0), self.corner_kinematics(mech, q1, qd1)
        pen = jax.vmap(self.law.penetration)
        return kink_fraction(g0, kinks(q1, qd1), rate0, t1 - t0, (pen(k0) > 0.0) & (pen(k1) > 0.0))

    # ---- initial assembly: hold the block at its initial offset and tilt ----------------
    n_equations: ClassVar[int] = 2

    def equations(self, mech: Mechanism, q, t):
        """``[y, theta] - initial_offset`` (2,)."""
        return self.offset(mech, q) - self.initial_offset

    def assembly_velocity(self):
        return self.initial_velocity
