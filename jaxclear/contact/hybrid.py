r"""The hybrid contact model of J. Ma, L. Qian, G. Chen, M. Li, "Dynamic analysis of mechanical
systems with planar revolute joints with clearance", Mech. Mach. Theory 94 (2015) 148-164 (the
hybrid Gauss-point model): Lankarani-Nikravesh framework,
elastic-foundation (Winkler) stiffness, Qin-Lu damping, the pin surface cut into elements with
Gauss-Legendre points, a penetration computed at every point and the force integrated over the
contact area.

Point :math:`k` (body-fixed angle :math:`\theta_k` on the journal) sits at
:math:`p_k = P_j + R_J(\theta_k)\,u(\theta_k + \phi_j)`; its penetration is
:math:`\delta_k = |p_k - P_i| - R_B(\alpha_k)` (``geometry="exact"``) or the small-gap
:math:`\delta_k = e\cos(\theta_k + \phi_j - \theta_n) - c` (``geometry="small-gap"``, the
profile of the closed-form check). The foundation pressure is
:math:`p_k = K_f\delta_k/h`, :math:`K_f = E(1-\nu)/((1+\nu)(1-2\nu))` for one compliant
layer of thickness :math:`h` (for two layers the overlaps add at equal pressure:
:math:`p = \delta/(h/K_{f,J} + h/K_{f,B})`). The elastic force on the journal is
:math:`F_{el} = -\sum_k w_k J_k p_k R_J L u_k`.

Damping (``damping="joint"``, default): :math:`F_N = |F_{el}|(1 + \hat\chi_{QinLu}(c_r)
\dot\delta/\dot\delta^{(-)})`. ``damping="point"``: every point is damped with its own
penetration rate :math:`\dot\delta_k` and the joint's impact speed :math:`\dot\delta^{(-)}`
(all points of one contact start with the same approach speed to first order), the
point forces clipped at zero before they are summed.

Placement of the points (both legitimate readings of the model):

* ``fixed``: ``n_elements`` equal elements over the whole journal circumference, body-fixed
  (what the hybrid paper describes); needs hundreds of points because the contact arc spans only a
  few degrees;
* ``arc``: the elements cover the current contact arc :math:`[\theta_n - \theta_c, \theta_n +
  \theta_c]` of the two circles (exact geometry:
  :math:`\cos\theta_c = (R_B^2 - R_J^2 - e^2)/(2eR_J)`; small-gap: :math:`\cos\theta_c = c/e`),
  where the integrand is smooth, so a few points are exact. Circular profiles only.

Profiles (:class:`FourierProfile`, e.g. :func:`oval`) give the radial deviation [m] of the
journal (body-fixed angle) and/or the bearing (angle in the bearing body): only the point
model can integrate such contacts. The force then acts along the resultant of the point
forces, which for a circle is :math:`-n`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from typing import ClassVar

from .._errors import RESULTS, ParameterError, Rule, check_range
from .._types import Array, ArrayLike, Float, Scalar
from .._parameters import Parameter
from .base import STEEL, AbstractNormalLaw, law_parameters, ContactKinematics, Material
from .hertz import chi_qin_lu


def foundation_modulus(material: Material):
    r"""Elastic-foundation (Winkler) modulus of a thin layer :math:`K_f = E(1-\nu)/((1+\nu)
    (1-2\nu))` [Pa] (Johnson, *Contact Mechanics*, 1985, sec. 5.9); 2.787e11 Pa for steel."""
    e, nu = material.young, material.poisson
    return e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu))


def small_gap_force(e, clearance, modulus, thickness, radius_journal, length):
    r"""Closed form of the foundation force on the small-gap profile
    :math:`\delta(\theta) = e\cos\theta - c`: :math:`F = (K_f R_J L/h)(e\theta_c - c\sin\theta_c)`,
    :math:`\theta_c = \arccos(c/e)` (grows like :math:`\delta^{1.5}`)."""
    inside = e > clearance
    ratio = jnp.where(inside, clearance / e, 0.5)
    theta_c = jnp.arccos(ratio)
    return jnp.where(inside, modulus * radius_journal * length / thickness * (e * theta_c - clearance * jnp.sin(theta_c)), 0.0)


#: Most Gauss points per element (Gauss-Legendre nodes come from an eigenvalue problem of this
#: size; 4 are exact for cubics, and a finer rule comes from more elements).
MAX_GAUSS_PER_ELEMENT = 64
#: Most Gauss points of one rule, elements x points per element (the default fixed placement has
#: 180 x 4 = 720; every point is evaluated at every step).
MAX_GAUSS_POINTS = 100_000


def check_gauss_points(n_elements, n_gauss, where: str = ""):
    """Raise :class:`ParameterError` unless ``n_elements`` and ``n_gauss`` are integers >= 1,
    ``n_gauss`` at most :data:`MAX_GAUSS_PER_ELEMENT` and their product at most
    :data:`MAX_GAUSS_POINTS` (checked before any array of that size is made); ``where``
    prefixes the message."""
    for name, value, high in (("n_elements", n_elements, MAX_GAUSS_POINTS), ("n_gauss", n_gauss, MAX_GAUSS_PER_ELEMENT)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer, float, np.floating)) or \
                int(value) != value or not 1 <= value <= high:
            raise ParameterError(f"{where}{name} = {value!r} is outside the allowed range: an integer in [1, {high}]")
    if n_elements * n_gauss > MAX_GAUSS_POINTS:
        raise ParameterError(f"{where}n_elements x n_gauss = {n_elements} x {n_gauss} = {n_elements * n_gauss} Gauss "
                             f"points, outside the allowed range [1, {MAX_GAUSS_POINTS}] "
                             "(jaxclear.contact.hybrid.MAX_GAUSS_POINTS)")


def gauss_nodes(n_elements: int, n_gauss: int):
    """Composite Gauss-Legendre rule on [-1, 1]: ``n_elements`` equal elements of ``n_gauss``
    points each; node positions and weights (NumPy, each (n_elements * n_gauss,)). Exact for
    polynomials of degree < 2 ``n_gauss`` on every element."""
    xi, w = np.polynomial.legendre.leggauss(int(n_gauss))
    edges = np.linspace(-1.0, 1.0, int(n_elements) + 1)
    half = 0.5 * (edges[1:] - edges[:-1])
    mid = 0.5 * (edges[1:] + edges[:-1])
    return (mid[:, None] + half[:, None] * xi[None, :]).ravel(), (half[:, None] * w[None, :]).ravel()


class FourierProfile(eqx.Module):
    r"""Radial deviation from the nominal circle, :math:`\Delta R(\theta) = \sum_m a_m\cos m\theta
    + b_m\sin m\theta` [m] (``m = 1..M``; the mean is the nominal radius). ``cos`` and ``sin``
    are arrays of shape (M,), so the profile is differentiable and sweepable."""

    cos: Float[Array, " M"]
    sin: Float[Array, " M"]

    def __init__(self, cos: ArrayLike = (), sin: ArrayLike | None = None):
        cos = jnp.atleast_1d(jnp.asarray(cos, dtype=float))
        sin = jnp.zeros_like(cos) if sin is None else jnp.atleast_1d(jnp.asarray(sin, dtype=float))
        if cos.shape != sin.shape:
            raise ParameterError(f"profile cos and sin coefficients must have the same length, got {cos.shape} and {sin.shape}")
        self.cos, self.sin = cos, sin

    def __call__(self, theta):
        m = jnp.arange(1, self.cos.shape[0] + 1, dtype=float)
        return jnp.sum(self.cos * jnp.cos(m * theta) + self.sin * jnp.sin(m * theta))

    def extremes(self, n: int = 2048):
        """(min, max) of the deviation on a fine grid [m] (for validation)."""
        th = jnp.linspace(0.0, 2 * jnp.pi, n, endpoint=False)
        dev = jax.vmap(self)(th)
        return float(dev.min()), float(dev.max())


def oval(amplitude: float, orientation: float = 0.0) -> FourierProfile:
    r"""An oval (elliptic to first order) profile: :math:`\Delta R = a\cos 2(\theta - \theta_0)`,
    i.e. semi-axes :math:`R + a` along :math:`\theta_0` and :math:`R - a` across [m]."""
    return FourierProfile(cos=[0.0, amplitude * np.cos(2 * orientation)], sin=[0.0, amplitude * np.sin(2 * orientation)])


#: Why the arc placement refuses profiles.
ARC_PROFILES = ("profiles need placement='fixed' (the contact arc of a non-circular profile is not known in "
                "closed form)")


class HybridLaw(AbstractNormalLaw):
    """The hybrid Gauss-point model (see module docstring).

    Attributes:
        restitution: :math:`c_r \\in (0, 1]` (Qin-Lu damping factor).
        foundation_modulus: :math:`K_f` [Pa] of the journal layer, or ``None`` (from its material).
        thickness: compliant layer thickness h [m] > 0 (``None``: the clearance c; the hybrid
            paper does not give its value).
        n_elements, n_gauss: elements and Gauss points per element (static, >= 1).
        placement: ``"fixed"`` or ``"arc"`` (static).
        damping: ``"joint"`` or ``"point"`` (static).
        geometry: ``"exact"`` or ``"small-gap"`` (static).
        layers: 1 (journal layer) or 2 (journal and bearing layers, overlaps add) (static).
        journal_profile, bearing_profile: :class:`FourierProfile` or ``None`` (circles).
    """

    restitution: Scalar
    foundation_modulus: Scalar | None
    thickness: Scalar | None
    journal_material: Material
    bearing_material: Material
    journal_profile: FourierProfile | None
    bearing_profile: FourierProfile | None
    n_elements: int = eqx.field(static=True)
    n_gauss: int = eqx.field(static=True)
    placement: str = eqx.field(static=True)
    damping: str = eqx.field(static=True)
    geometry: str = eqx.field(static=True)
    layers: int = eqx.field(static=True)

    stiffness_parameter: ClassVar[str] = "foundation_modulus"
    PARAMETERS: ClassVar[dict[str, Parameter]] = law_parameters("foundation_modulus")
    name: ClassVar[str] = "hybrid"

    def __init__(
        self,
        restitution: ArrayLike = 0.9,
        foundation_modulus: ArrayLike | None = None,
        thickness: ArrayLike | None = None,
        n_elements: int | None = None,
        n_gauss: int = 4,
        placement: str = "arc",
        damping: str = "joint",
        geometry: str = "exact",
        layers: int = 1,
        journal_profile: FourierProfile | None = None,
        bearing_profile: FourierProfile | None = None,
        journal_material: Material = STEEL,
        bearing_material: Material = STEEL,
    ):
        if placement not in ("fixed", "arc"):
            raise ParameterError(f"placement must be 'fixed' or 'arc', got {placement!r}")
        if damping not in ("joint", "point"):
            raise ParameterError(f"damping must be 'joint' or 'point', got {damping!r}")
        if geometry not in ("exact", "small-gap"):
            raise ParameterError(f"geometry must be 'exact' or 'small-gap', got {geometry!r}")
        if layers not in (1, 2):
            raise ParameterError(f"layers must be 1 or 2, got {layers!r}")
        if n_elements is None:
            n_elements = 2 if placement == "arc" else 180
        check_gauss_points(n_elements, n_gauss)
        if placement == "arc" and (journal_profile is not None or bearing_profile is not None):
            raise ParameterError(ARC_PROFILES)
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("foundation_modulus", foundation_modulus, low=0.0, low_open=True, unit="Pa")
        check_range("thickness (h)", thickness, low=0.0, low_open=True, unit="m")
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.foundation_modulus = None if foundation_modulus is None else jnp.asarray(foundation_modulus, dtype=float)
        self.thickness = None if thickness is None else jnp.asarray(thickness, dtype=float)
        self.journal_material, self.bearing_material = journal_material, bearing_material
        self.journal_profile, self.bearing_profile = journal_profile, bearing_profile
        self.n_elements, self.n_gauss = int(n_elements), int(n_gauss)
        self.placement, self.damping, self.geometry, self.layers = placement, damping, geometry, layers

    # ---- profiles -------------------------------------------------------------------
    @property
    def profiles(self):
        """``(journal_profile, bearing_profile)``."""
        return self.journal_profile, self.bearing_profile

    def with_profiles(self, journal_profile, bearing_profile):
        """This law with the given profiles (:class:`FourierProfile` or ``None`` each); the arc
        placement raises :class:`~jaxclear.ParameterError` (:data:`ARC_PROFILES`)."""
        if self.placement == "arc" and (journal_profile is not None or bearing_profile is not None):
            raise ParameterError(ARC_PROFILES)
        return eqx.tree_at(lambda m: (m.journal_profile, m.bearing_profile), self, (journal_profile, bearing_profile),
                           is_leaf=lambda x: x is None)

    # ---- parameters -----------------------------------------------------------------
    def checks(self) -> tuple:
        """Restitution in (0, 1], foundation modulus > 0 and thickness > 0 (when given), materials."""
        modulus = 1.0 if self.foundation_modulus is None else self.foundation_modulus
        thickness = 1.0 if self.thickness is None else self.thickness
        return (*super().checks(),
                Rule("foundation_modulus", modulus, RESULTS.invalid_stiffness, low=0.0, low_open=True, unit="Pa"),
                Rule("thickness", thickness, RESULTS.invalid_parameter, low=0.0, low_open=True, unit="m"),
                *self.journal_material.checks("journal_material"), *self.bearing_material.checks("bearing_material"))

    def modulus(self):
        """Effective pressure-per-overlap modulus [Pa] (two layers in series if ``layers == 2``)."""
        k_j = self.stiffness_value(None, None)
        if self.layers == 1:
            return k_j
        return 1.0 / (1.0 / k_j + 1.0 / foundation_modulus(self.bearing_material))

    def stiffness_value(self, radius_bearing, radius_journal):
        """:math:`K_f` [Pa] of the journal layer: the given one, or from its material."""
        return foundation_modulus(self.journal_material) if self.foundation_modulus is None else self.foundation_modulus

    def layer_thickness(self, kin):
        return kin.radius_bearing - kin.radius_journal if self.thickness is None else self.thickness

    def check_geometry(self, radius_bearing: float, radius_journal: float):
        """Raise :class:`ParameterError` if a profile makes the journal reach the bearing radius."""
        j_max = self.journal_profile.extremes()[1] if self.journal_profile is not None else 0.0
        b_min = self.bearing_profile.extremes()[0] if self.bearing_profile is not None else 0.0
        if radius_journal + j_max >= radius_bearing + b_min:
            raise ParameterError(
                f"the profiles make the journal larger than the bearing: largest journal radius "
                f"{radius_journal + j_max:g} m >= smallest bearing radius {radius_bearing + b_min:g} m "
                "(profile deviations must leave a positive clearance everywhere)"
            )

    # ---- quadrature -----------------------------------------------------------------
    def _nodes_numpy(self):
        return gauss_nodes(self.n_elements, self.n_gauss)

    def _nodes(self):
        s, ws = self._nodes_numpy()
        return jnp.asarray(s), jnp.asarray(ws)

    def _contact_arc(self, kin):
        """Half-angle of the contact arc of the two circles, 0 when apart."""
        e, c = kin.e, kin.radius_bearing - kin.radius_journal
        inside = e > c
        e_safe = jnp.where(inside, e, 2.0 * c)
        if self.geometry == "small-gap":
            x = c / e_safe
        else:
            rb, rj = kin.radius_bearing, kin.radius_journal
            x = (rb**2 - rj**2 - e_safe**2) / (2.0 * e_safe * rj)
        # arccos only strictly inside (-1, 1): at x = 1 its derivative is infinite, and a clipped
        # value there would give 0 * inf = NaN cotangents in reverse mode
        ok = inside & (x < 1.0) & (x > -1.0)
        whole = inside & (x <= -1.0)  # the journal overlaps the bearing all round
        x_safe = jnp.where(ok, x, 0.5)
        return jnp.where(ok, jnp.arccos(x_safe), jnp.where(whole, jnp.pi, 0.0))

    def points(self, kin):
        """Global angles (N,) and integration weights [rad] (N,) of the points."""
        s, ws = self._nodes()
        theta_n = jnp.arctan2(kin.normal[1], kin.normal[0])
        if self.placement == "arc":
            half = self._contact_arc(kin)
            return theta_n + half * s, half * ws
        # fixed: body-fixed angles over [0, 2 pi), rotating with the journal
        return kin.journal_angle + jnp.pi * (s + 1.0), jnp.pi * ws

    def _directions(self, kin):
        """``(cos, sin, local angle, weight)`` of every point (each (N,)); the local angle is
        measured from the journal's body axis (for the journal profile).

        Fixed placement: the nodes are body-fixed, so the unit vectors come from the constant
        node angles by the angle-addition formulas (no sine or cosine per point)."""
        if self.placement == "arc":
            angles, weights = self.points(kin)
            return jnp.cos(angles), jnp.sin(angles), angles - kin.journal_angle, weights
        s, ws = self._nodes_numpy()
        local = np.pi * (s + 1.0)
        c0, s0 = jnp.asarray(np.cos(local)), jnp.asarray(np.sin(local))
        cj, sj = jnp.cos(kin.journal_angle), jnp.sin(kin.journal_angle)
        return cj * c0 - sj * s0, sj * c0 + cj * s0, jnp.asarray(local), jnp.asarray(np.pi * ws)

    # ---- one point, then all points -------------------------------------------------
    def _overlap(self, kin, cu, su, local):
        """Overlap [m] of the point in direction ``u = (cu, su)``, its rate [m/s], its slip [m/s]
        (tangential speed of the journal's surface point relative to the bearing's material point
        there) and its angle in the bearing body [rad]. Written with scalar components (no
        2-vector dots), so that ``vmap`` over the points fuses into a few XLA kernels; the
        force path does not use the slip and angle, and XLA drops them there."""
        r_j = kin.radius_journal
        if self.journal_profile is not None:
            r_j = r_j + self.journal_profile(local)
        if self.geometry == "small-gap":
            c = kin.radius_bearing - kin.radius_journal
            delta = kin.ecc[0] * cu + kin.ecc[1] * su - c
            dv = kin.journal_velocity - kin.bearing_velocity
            rate = dv[0] * cu + dv[1] * su
            slip = -dv[0] * su + dv[1] * cu + kin.journal_omega * r_j - kin.bearing_omega * kin.radius_bearing
            return delta, rate, slip, jnp.arctan2(su, cu) - kin.bearing_angle
        rx = kin.journal_centre[0] + r_j * cu - kin.bearing_centre[0]
        ry = kin.journal_centre[1] + r_j * su - kin.bearing_centre[1]
        dist2 = rx * rx + ry * ry
        dist = jnp.sqrt(jnp.where(dist2 > 0, dist2, 1.0))
        beta = jnp.arctan2(ry, rx) - kin.bearing_angle
        r_b = kin.radius_bearing
        if self.bearing_profile is not None:
            r_b = r_b + self.bearing_profile(beta)
        delta = dist - r_b
        # velocity of the journal's surface point minus the bearing's material point there
        vx = (kin.journal_velocity[0] - kin.journal_omega * r_j * su) - (kin.bearing_velocity[0] - kin.bearing_omega * ry)
        vy = (kin.journal_velocity[1] + kin.journal_omega * r_j * cu) - (kin.bearing_velocity[1] + kin.bearing_omega * rx)
        return delta, (vx * rx + vy * ry) / dist, (vy * rx - vx * ry) / dist, beta

    def _point_force(self, kin, delta, rate, weight, deltadot0, modulus, thickness):
        """Normal force [N] of one point: foundation pressure times its area, damped per point
        with ``damping="point"`` (undamped otherwise: the joint's damping scales the resultant)."""
        pressure = modulus * jnp.maximum(delta, 0.0) / thickness
        force = weight * pressure * kin.radius_journal * kin.length
        if self.damping == "point":
            force = jnp.maximum(force * (1.0 + chi_qin_lu(self.restitution) * rate / deltadot0), 0.0)
            force = jnp.where(delta > 0.0, force, 0.0)
        return force

    def _point(self, kin, cu, su, local, weight, deltadot0, modulus, thickness):
        """Force components on the journal ``(f_x, f_y)`` from the point in direction ``u`` and
        its overlap."""
        delta, rate, _, _ = self._overlap(kin, cu, su, local)
        force = self._point_force(kin, delta, rate, weight, deltadot0, modulus, thickness)
        return -force * cu, -force * su, delta

    def _joint_damping(self, kin, deltadot0):
        """Factor :math:`\\max(1 + \\hat\\chi\\dot\\delta/\\dot\\delta^{(-)}, 0)` of ``damping="joint"``."""
        return jnp.maximum(1.0 + chi_qin_lu(self.restitution) * kin.deltadot / deltadot0, 0.0)

    def surface(self, kin, deltadot0):
        r"""The contact field point by point, for wear (Archard): each point's angle in the bearing
        body :math:`\beta_k` [rad], its normal force :math:`f_k = p_k w_k R_J L` [N] (pressure
        times area, with the joint's damping factor for ``damping="joint"``) and its slip speed
        :math:`v_{s,k}` [m/s]; each ``(N,)``. The sum of the :math:`f_k` is the pressure
        integral, which equals the normal force up to the arc's obliquity (:math:`\cos` of the
        point angles from the normal)."""
        cu, su, local, weights = self._directions(kin)
        modulus, thickness = self.modulus(), self.layer_thickness(kin)

        def one(c, s, a, w):
            delta, rate, slip, beta = self._overlap(kin, c, s, a)
            return beta, self._point_force(kin, delta, rate, w, deltadot0, modulus, thickness), slip

        beta, force, slip = jax.vmap(one)(cu, su, local, weights)
        if self.damping == "joint":
            force = force * self._joint_damping(kin, deltadot0)
        return beta, force, slip

    def _resultant(self, kin, deltadot0):
        cu, su, local, weights = self._directions(kin)
        modulus, thickness = self.modulus(), self.layer_thickness(kin)
        fx, fy, deltas = jax.vmap(
            lambda c, s, a, w: self._point(kin, c, s, a, w, deltadot0, modulus, thickness)
        )(cu, su, local, weights)
        return jnp.stack([jnp.sum(fx), jnp.sum(fy)]), deltas

    def elastic_force(self, kin):
        """Elastic resultant on the journal (2,) [N] (no damping)."""
        law = self if self.damping == "joint" else eqx.tree_at(lambda m: m.restitution, self, jnp.ones(()))
        return law._resultant(kin, jnp.ones(()))[0]

    def penetration(self, kin):
        """Deepest overlap [m]: ``e - c`` for circles; the largest point overlap with profiles."""
        if self.journal_profile is None and self.bearing_profile is None:
            return kin.delta
        _, deltas = self._resultant(kin, jnp.ones(()))
        return jnp.max(deltas)

    def contact_force(self, kin, deltadot0):
        """``(F_N, direction)``: normal force magnitude [N] and the unit vector from the bearing
        towards the journal along which it pushes the bearing (``n`` for circles)."""
        vec, _ = self._resultant(kin, deltadot0)
        mag2 = vec @ vec
        nonzero = mag2 > 0.0
        mag = jnp.sqrt(jnp.where(nonzero, mag2, 1.0))
        direction = jnp.where(nonzero, -vec / mag, kin.normal)
        mag = jnp.where(nonzero, mag, 0.0)
        if self.damping == "joint":
            mag = mag * self._joint_damping(kin, deltadot0)
        if self.journal_profile is None and self.bearing_profile is None:
            direction = kin.normal
        return mag, direction

    def normal_force(self, kin, deltadot0):
        return self.contact_force(kin, deltadot0)[0]


def matched_thickness(law: HybridLaw, radius_bearing, radius_journal, length, stiffness, exponent=1.5,
                      delta_ref=1e-5):
    r"""Layer thickness h [m] that makes ``law``'s elastic force equal a power law
    :math:`K\delta^n` at the penetration ``delta_ref`` [m] (the hybrid force scales as 1/h).

    Used to compare the hybrid model with a Hertz-family law at equal stiffness, so that the two
    differ in damping and force shape only (the hybrid paper does not give its h).
    """
    c = radius_bearing - radius_journal
    e = c + delta_ref
    z2, z = jnp.zeros(2), jnp.zeros(())
    kin = ContactKinematics(
        ecc=jnp.array([e, 0.0]), e=jnp.asarray(e), normal=jnp.array([1.0, 0.0]), tangent=jnp.array([0.0, 1.0]),
        delta=jnp.asarray(delta_ref), deltadot=z, slip=z, bearing_centre=z2, journal_centre=jnp.array([e, 0.0]),
        bearing_velocity=z2, journal_velocity=z2, bearing_angle=z, journal_angle=z, bearing_omega=z,
        journal_omega=z, radius_bearing=jnp.asarray(radius_bearing), radius_journal=jnp.asarray(radius_journal),
        length=jnp.asarray(length),
    )
    unit = eqx.tree_at(lambda m: m.thickness, law, jnp.ones(()), is_leaf=lambda x: x is None)
    force_h1 = jnp.linalg.norm(unit.elastic_force(kin))
    return force_h1 / (stiffness * delta_ref**exponent)
