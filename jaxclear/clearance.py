r"""Revolute joints with radial clearance, as force elements (Flores, Ambrósio, Claro,
Lankarani, "Kinematics and Dynamics of Multibody Systems with Imperfect Joints", Springer
2008, ch. 4; spec section 2).

A bearing (hole, radius :math:`R_B`) on body *i* and a journal (pin, radius :math:`R_J`) on
body *j*; radial clearance :math:`c = R_B - R_J > 0`.

* eccentricity :math:`\mathbf e = P_j - P_i`, :math:`e = |\mathbf e|`, penetration
  :math:`\delta = e - c`, normal :math:`n = \mathbf e/e`, tangent :math:`t = \mathrm{perp}(n)`;
* contact points :math:`Q_k = P_k + R_k n`; :math:`\dot\delta = (v_{Q_j} - v_{Q_i})\cdot n`
  (equal to :math:`\dot e`), slip :math:`v_T = (v_{Q_j} - v_{Q_i})\cdot t`;
* force on the journal at :math:`Q_j`: :math:`f = -F_N n + F_T t`; on the bearing at
  :math:`Q_i`: :math:`-f`.

Sign note: spec section 2 writes the bearing force as :math:`F_N n + F_T t` with
:math:`F_T = -\mu c_d F_N \mathrm{sign}(v_T)`; with :math:`v_T` the slip of the *journal*
relative to the bearing that friction term would do positive work. The friction force opposes
the journal's slip on the journal and drags the bearing along; the energy test checks that
friction only dissipates.

The impact speed :math:`\dot\delta^{(-)}` of every joint is history, carried in
:class:`ContactMemory` and updated after every accepted step by :func:`update_memory`
(see :mod:`jaxclear.solve`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .contact.friction import Friction
from .contact.laws import ContactLaw
from .errors import ParameterError, check_range
from .mechanism import Mechanism, perp, point_load, point_position, point_velocity

Scalar = Float[Array, ""]
Vec2 = Float[Array, "2"]


class ClearanceJoint(eqx.Module):
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
    law: ContactLaw
    friction: Friction
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
        friction: Friction | None = None,
        impact_velocity_floor: ArrayLike = 1e-4,
        initial_offset: ArrayLike = (0.0, 0.0),
        initial_velocity: ArrayLike = (0.0, 0.0),
        name: str = "clearance",
    ):
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
            if hasattr(law, "check_geometry"):
                law.check_geometry(float(rb), float(rj))
        offset = jnp.asarray(initial_offset, dtype=float).reshape(2)
        if not isinstance(offset, jax.core.Tracer) and float(jnp.linalg.norm(offset)) >= float(rb - rj):
            raise ParameterError(
                f"initial_offset |e| = {float(jnp.linalg.norm(offset)):g} m must be smaller than the "
                f"clearance {float(rb - rj):g} m (the journal must start inside its bearing)"
            )
        self.bearing_body, self.bearing_point = bearing_body, bearing_point
        self.journal_body, self.journal_point = journal_body, journal_point
        self.bearing_radius, self.journal_radius = rb, rj
        self.length = jnp.asarray(length, dtype=float)
        self.law = ContactLaw() if law is None else law
        self.friction = Friction() if friction is None else friction
        self.impact_velocity_floor = jnp.asarray(impact_velocity_floor, dtype=float)
        self.initial_offset = offset
        self.initial_velocity = jnp.asarray(initial_velocity, dtype=float).reshape(2)
        self.name = name

    @property
    def clearance(self):
        """Radial clearance :math:`c = R_B - R_J` [m]."""
        return self.bearing_radius - self.journal_radius

    # --- used by the initial-condition solve: hold the journal at its initial offset ---
    n_equations = 2

    def equations(self, mech: Mechanism, q, t):
        """:math:`P_j - P_i - e_0 = 0` (2,), the joint treated as ideal at a fixed offset."""
        return (
            point_position(mech, q, self.journal_body, self.journal_point)
            - point_position(mech, q, self.bearing_body, self.bearing_point)
            - self.initial_offset
        )


class ContactKinematics(eqx.Module):
    """Geometry and velocities of one clearance joint in one configuration (all global, SI)."""

    ecc: Vec2  # eccentricity vector e = P_j - P_i [m]
    e: Scalar  # |e| [m]
    normal: Vec2  # n = e/|e| (arbitrary but finite at e = 0)
    tangent: Vec2  # t = perp(n)
    delta: Scalar  # e - c [m]
    deltadot: Scalar  # penetration rate [m/s]
    slip: Scalar  # tangential slip v_T [m/s]
    bearing_centre: Vec2
    journal_centre: Vec2
    bearing_velocity: Vec2
    journal_velocity: Vec2
    bearing_angle: Scalar
    journal_angle: Scalar
    bearing_omega: Scalar
    journal_omega: Scalar
    radius_bearing: Scalar
    radius_journal: Scalar
    length: Scalar


def safe_normal(ecc):
    """``(|e|, e/|e|)`` with finite values and gradients at ``e = 0`` (normal ``[1, 0]`` there)."""
    e2 = ecc[0] ** 2 + ecc[1] ** 2
    nonzero = e2 > 1e-300
    safe = jnp.where(nonzero, ecc, jnp.array([1.0, 0.0], ecc.dtype))
    norm = jnp.sqrt(safe[0] ** 2 + safe[1] ** 2)
    return jnp.where(nonzero, norm, 0.0), safe / norm


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
    """Journal state relative to its bearing of every clearance joint, stacked
    ``[e_x, e_y, v_x, v_y]`` per joint (``(4k,)``; [m, m, m/s, m/s]): the eccentricity and the
    velocity of the journal centre relative to the bearing centre. Poincare sections and the
    fit's window states use it."""
    rows = [
        jnp.concatenate([kin.ecc, kin.journal_velocity - kin.bearing_velocity])
        for kin in (kinematics(mech, joint, q, qdot) for joint in mech.clearance_joints)
    ]
    return jnp.concatenate(rows) if rows else jnp.zeros((0,), q.dtype)


class ContactMemory(eqx.Module):
    """History carried in the state, one entry per clearance joint (shape ``(n_joints,)``).

    Attributes:
        impact_velocity: :math:`\\dot\\delta^{(-)}` [m/s], approach speed at the onset of the
            current contact (out of contact it tracks the current :math:`\\dot\\delta`).
        contact_start: time of the last contact onset [s] (``-inf`` before the first).
        impacts: number of contact onsets so far.
        work: work done on the mechanism by the contact forces since the start [J]
            (its decrease over a closed contact is the energy the contact dissipated).
        peak_force: largest normal force [N] at any accepted step's end so far (steps are
            short during contact, so this resolves peaks that an output grid misses).
        peak_penetration: largest penetration [m] at any accepted step's end so far.
    """

    impact_velocity: Float[Array, " k"]
    contact_start: Float[Array, " k"]
    impacts: Float[Array, " k"]
    work: Float[Array, " k"]
    peak_force: Float[Array, " k"]
    peak_penetration: Float[Array, " k"]

    @staticmethod
    def initial(n_joints: int, dtype=float):
        z = jnp.zeros((n_joints,), dtype)
        # finite sentinels (not -inf): dense interpolation of the state may difference two samples
        return ContactMemory(z, jnp.full((n_joints,), -1e9, dtype), z, z, z, jnp.full((n_joints,), -1.0, dtype))

    def zeros_like(self):
        z = jnp.zeros_like(self.impacts)
        return ContactMemory(z, z, z, z, z, z)


class ContactOutput(eqx.Module):
    """Contact quantities of one joint at one instant (SI)."""

    ecc: Vec2
    penetration: Scalar
    normal_force: Scalar
    friction_force: Scalar
    power: Scalar  # power of the contact forces on the mechanism [W]


def joint_forces(mech: Mechanism, joint: ClearanceJoint, q, qdot, impact_velocity):
    """Generalized contact force (n,) of one joint and its :class:`ContactOutput`."""
    kin = kinematics(mech, joint, q, qdot)
    speed0 = jnp.maximum(impact_velocity, joint.impact_velocity_floor)
    if hasattr(joint.law, "contact_force"):  # laws that set their own direction (profiles)
        f_n, n = joint.law.contact_force(kin, speed0)
    else:
        f_n, n = joint.law.normal_force(kin, speed0), kin.normal
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


def _hermite_crossing(p0, p1, r0, r1, h, crossed):
    """Root ``s`` in [0, 1] of the cubic Hermite interpolant of the penetration over a step
    (values ``p0, p1``, rates ``r0, r1``, step ``h``) and the interpolated rate there.

    ``h`` may be 0 (under ``vmap`` the members of a batch that have finished take empty steps
    while the others go on): a safe step keeps the masked branch finite, so reverse mode gets no
    NaN cotangents."""
    h = jnp.where(h > 0, h, 1.0)
    denom = jnp.where(crossed, p0 - p1, 1.0)
    s = jnp.clip(jnp.where(crossed, p0 / denom, 0.5), 0.0, 1.0)

    def value_and_slope(s):
        s2, s3 = s * s, s * s * s
        val = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * r0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * h * r1
        slope = (6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * h * r0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * h * r1
        return val, slope

    for _ in range(6):
        val, slope = value_and_slope(s)
        ok = jnp.abs(slope) > 1e-300
        s = jnp.clip(s - jnp.where(ok, val / jnp.where(ok, slope, 1.0), 0.0), 0.0, 1.0)
    _, slope = value_and_slope(s)
    return s, slope / h


def update_memory(mech: Mechanism, t0, q0, qd0, t1, q1, qd1, memory: ContactMemory):
    r"""The impact-memory rule, applied after every accepted step ``[t0, t1]`` (spec section 6).

    Per joint, with penetration :math:`\delta` and rate :math:`\dot\delta` at both ends:

    * :math:`\delta_1 \le 0` (free at the step's end): :math:`\dot\delta^{(-)} \leftarrow \dot\delta_1`;
    * :math:`\delta_0 \le 0 < \delta_1` (the step crossed into contact): :math:`\dot\delta^{(-)}
      \leftarrow \dot\delta(t_c)` at the crossing :math:`t_c` of the cubic Hermite interpolant of
      :math:`\delta` (exact to the step's third order), onset time :math:`t_c`, impacts + 1;
    * in contact at both ends: unchanged.

    The running peaks of normal force and penetration are updated at the step's end too.

    Returns the new memory and whether any joint crossed (the solver then re-evaluates its
    first stage, since the force law changed).
    """
    if not mech.clearance_joints:
        return memory, jnp.zeros((), bool)
    h = t1 - t0
    new_v, new_start, crossed_all, forces, pens = [], [], [], [], []
    for k, joint in enumerate(mech.clearance_joints):
        kin0 = kinematics(mech, joint, q0, qd0)
        kin1 = kinematics(mech, joint, q1, qd1)
        p0, p1 = joint.law.penetration(kin0), joint.law.penetration(kin1)
        crossed = (p0 <= 0.0) & (p1 > 0.0)
        s, rate_c = _hermite_crossing(p0, p1, kin0.deltadot, kin1.deltadot, h, crossed)
        v = jnp.where(p1 <= 0.0, kin1.deltadot, jnp.where(crossed, rate_c, memory.impact_velocity[k]))
        new_v.append(v)
        new_start.append(jnp.where(crossed, t0 + s * h, memory.contact_start[k]))
        crossed_all.append(crossed)
        _, out = joint_forces(mech, joint, q1, qd1, v)
        forces.append(out.normal_force)
        pens.append(p1)
    crossed_all = jnp.stack(crossed_all)
    new = ContactMemory(
        impact_velocity=jnp.stack(new_v),
        contact_start=jnp.stack(new_start),
        impacts=memory.impacts + crossed_all.astype(memory.impacts.dtype),
        work=memory.work,
        peak_force=jnp.maximum(memory.peak_force, jnp.stack(forces)),
        peak_penetration=jnp.maximum(memory.peak_penetration, jnp.stack(pens)),
    )
    return new, jnp.any(crossed_all)
