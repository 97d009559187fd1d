r"""Lubricated revolute joints: a journal in a bearing separated by an oil film, with the
short-bearing (Ocvirk) hydrodynamic force and a C1 transition to dry contact.

References: Flores, Ambrósio, Claro, Lankarani, Koshy, "Lubricated revolute joints in rigid
multibody systems", Nonlinear Dyn. 56 (2009) 277-295; Pinkus and Sternlicht, "Theory of
Hydrodynamic Lubrication", McGraw-Hill 1961, ch. 3; Hamrock, Schmid, Jacobson, "Fundamentals of
Fluid Film Lubrication", 2nd ed., Dekker 2004, ch. 10 (short-bearing theory).

Geometry (SI): radial clearance :math:`c = R_B - R_J`, eccentricity :math:`\mathbf e = P_j - P_i`,
ratio :math:`\varepsilon = e/c`, unit normal :math:`n = \mathbf e/e` and tangent
:math:`t = \mathrm{perp}(n)`. The angle :math:`\psi` is measured on the journal from :math:`n`
(the thinnest film) towards :math:`t`; the film thickness is
:math:`h(\psi) = c(1 - \varepsilon\cos\psi)`.

Short-bearing Reynolds equation in the frame turning with the line of centres (film width
:math:`L` = the joint's ``length``, viscosity :math:`\mu`), integrated over the width:

.. math::

    \bar p(\psi) = \frac{\mu L^3}{c^2}\,
        \frac{\dot\varepsilon\cos\psi - \bar\omega\varepsilon\sin\psi}{(1 - \varepsilon\cos\psi)^3}
    \quad [\mathrm{N/m}],\qquad
    \bar\omega = \tfrac12(\omega_j + \omega_b - 2\dot\gamma),

with :math:`\dot\gamma` the rate of the line of centres. Written with the relative velocity
:math:`v = \dot P_j - \dot P_i`: :math:`\dot\varepsilon = v\cdot n / c` (squeeze) and
:math:`\bar\omega\varepsilon = ((\omega_j+\omega_b) e/2 - v\cdot t)/c` (wedge), so nothing is
divided by :math:`e`. The force on the journal is
:math:`F = -R_J\int \bar p\,(\cos\psi\, n + \sin\psi\, t)\,d\psi`, through its centre; minus it
acts on the bearing body along the same line (applied at the journal centre). The viscous
shear torque is neglected.

Film conditions (``film``):

* ``"half"`` (default, Gümbel / half-Sommerfeld): negative pressures set to zero; the film
  covers the half circle where :math:`\bar p > 0`, whose edges
  :math:`\dot\varepsilon\cos\psi = \bar\omega\varepsilon\sin\psi` move with the squeeze rate;
* ``"full"`` (Sommerfeld, :math:`2\pi` film): the whole circumference;
* ``"pi"`` (the classical fixed-boundary :math:`\pi` film of Pinkus and Sternlicht, ch. 3, as
  Flores et al. (2009) use it for clearance joints): the film covers
  :math:`0 < \theta < \pi` from the line of centres, :math:`\theta` measured from the thickest
  film in the direction of rotation, i.e. :math:`\psi \in [-\pi, 0]` for rotation in the positive
  (counterclockwise) sense; ``"pi-clockwise"``: :math:`\psi \in [0, \pi]`, the same film for a
  journal turning clockwise. The edges never move, so the force is linear in
  :math:`\dot\varepsilon` and :math:`\bar\omega` (a suction where they reverse) and smooth; it
  equals the literature's closed forms

  .. math::

      F_n = -\frac{\mu R_J L^3}{c^2}\left[\frac{2\varepsilon^2\bar\omega}{(1-\varepsilon^2)^2}
            + \frac{\pi(1+2\varepsilon^2)\dot\varepsilon}{2(1-\varepsilon^2)^{5/2}}\right],\quad
      F_t = \frac{\mu R_J L^3}{c^2}\left[\frac{\pi\varepsilon\bar\omega}{2(1-\varepsilon^2)^{3/2}}
            + \frac{2\varepsilon\dot\varepsilon}{(1-\varepsilon^2)^2}\right];

* ``"half-fixed"`` (kept for old runs; prefer ``"pi"``): the :math:`\pi` film whose side follows
  the sign of :math:`\bar\omega` (:math:`\psi \in [-\pi, 0]`, or :math:`[0, \pi]` when
  :math:`\bar\omega < 0`); equal to ``"half"`` only when :math:`\dot\varepsilon = 0`. Its force
  jumps where :math:`\bar\omega` changes sign while :math:`\dot\varepsilon \ne 0` (the squeeze
  term :math:`F_t` changes sign), so a motion that slides along :math:`\bar\omega \approx 0`, as
  the rod-slider joint of a slider-crank does, stalls an adaptive solver.

Closed forms: with the Sommerfeld substitution :math:`1 - \varepsilon\cos\psi =
(1-\varepsilon^2)/(1+\varepsilon\cos\beta)`, i.e. :math:`\tan(\beta/2) =
\sqrt{(1+\varepsilon)/(1-\varepsilon)}\tan(\psi/2)`, the three integrals of
:math:`\{\cos^2\psi, \sin\psi\cos\psi, \sin^2\psi\}/(1-\varepsilon\cos\psi)^3` over any interval
become :math:`(1-\varepsilon^2)^{-5/2}\int(\cos\beta+\varepsilon)^2`,
:math:`(1-\varepsilon^2)^{-2}\int\sin\beta(\cos\beta+\varepsilon)` and
:math:`(1-\varepsilon^2)^{-3/2}\int\sin^2\beta` (:func:`film_integrals`): exact for any film
edges. Steady rotation (:math:`\dot\varepsilon = 0`, stationary bearing, half film) gives the
classical short-bearing loads :math:`W_r = \mu U L^3\varepsilon^2/(c^2(1-\varepsilon^2)^2)`,
:math:`W_t = \pi\mu U L^3\varepsilon/(4c^2(1-\varepsilon^2)^{3/2})`, :math:`U = \omega R_J`.

Transition to dry contact (film rupture): the film force is evaluated at the ratio
:math:`\tilde\varepsilon = g(\varepsilon)` with :math:`g(\varepsilon) = \varepsilon` below
``blend_start`` :math:`\varepsilon_0`, :math:`g = \varepsilon - (\varepsilon-\varepsilon_0)^2 /
(2(\varepsilon_1-\varepsilon_0))` between :math:`\varepsilon_0` and ``blend_end``
:math:`\varepsilon_1`, and :math:`g = (\varepsilon_0+\varepsilon_1)/2` above (C1: value and slope
continuous at both bounds; the film's squeeze and wedge rates are kept). The film force thus stays
finite as :math:`\varepsilon \to 1`, and once the journal touches the bearing
(:math:`\delta = e - c > 0`) the dry normal law of the joint (any law of the catalogue, with its
impact memory) and its friction law add to it: mixed lubrication.

Non-circular journal and bearing (``journal_profile``, ``bearing_profile``: radial deviations
:math:`\Delta_J, \Delta_B` of :class:`~jaxclear.FourierProfile`, body-fixed): the film force is
integrated over the circumference with the composite Gauss-Legendre points of the hybrid contact
model (:func:`gauss_film_force`). In the short-bearing limit the Reynolds equation keeps only the
axial pressure flow, :math:`\partial_z(h^3\partial_z p/12\mu) = \tfrac12(U_J + U_B)\partial_x h
+ \partial_t h` (Hamrock et al., ch. 7 and 10; :math:`x = R_J\theta`, :math:`\partial_t h` at a
fixed point of space), whose solution with :math:`p(\pm L/2) = 0` is
:math:`p = (6\mu/h^3)(\tfrac12(U_J+U_B)\partial_x h + \partial_t h)(z^2 - L^2/4)`; over the
width, :math:`\int(z^2 - L^2/4)dz = -L^3/6`, so

.. math::

    \bar p(\theta) = -\frac{\mu L^3}{h^3} G(\theta),\qquad
    G = \frac{\omega_J + \omega_B}{2}\partial_\theta h + \partial_t h
      = \frac{\omega_J - \omega_B}{2}(\Delta_B' + \Delta_J')
        - \frac{\omega_J + \omega_B}{2}\,\mathbf e\cdot u'(\theta) - \mathbf v\cdot u(\theta),

with the film thickness :math:`h(\theta) = c + \Delta_B(\theta - \phi_B) - \Delta_J(\theta -
\phi_J) - \mathbf e\cdot u(\theta)` at the global angle :math:`\theta`
(:math:`u = (\cos\theta, \sin\theta)`, :math:`u' = \mathrm{perp}(u)`, small gap
:math:`h \ll R_J`), half-Sommerfeld :math:`\bar p \to \max(\bar p, 0)`, and the force on the
journal :math:`F = -R_J\int_0^{2\pi}\bar p\,u\,d\theta`. For circles
(:math:`\Delta = 0`) this is the integrand of the closed forms above (:math:`\psi = \theta -
\theta_n`), which the tests reproduce; a first harmonic :math:`\Delta_J = a\cos(\theta -
\phi_J)` is a circle whose centre is shifted by :math:`a\,u(\phi_J)`, another closed-form check.
The blend applies to the closure of the film, :math:`k(\theta) = c - h(\theta)`, through the
effective ratio :math:`\varepsilon_h = \max_\theta k/c = 1 - h_{min}/c` (the largest over the
Gauss points): :math:`h \to c - (g(\varepsilon_h)/\varepsilon_h)\,k`, so that the thinnest
film is :math:`(1 - g(\varepsilon_h))c \ge (1 - \varepsilon_1)c > 0` whatever the profiles
(circles: :math:`\varepsilon_h = \varepsilon`, :math:`\mathbf e \to \tilde\varepsilon c\,n`
as above; a first harmonic: the blend of the shifted circle). Below ``blend_start`` the film is
untouched; above it the force is continuous, and C1 except where the thinnest Gauss point
changes (the discrete maximum; its kinks shrink with the point spacing).

The dry contact of a profiled joint touches the same profiles: they belong to the joint's dry
law, which must integrate them point by point (:class:`~jaxclear.HybridLaw` with
``placement="fixed"``, :meth:`~jaxclear.contact.base.AbstractNormalLaw.with_profiles`; any
other law raises :class:`~jaxclear.ParameterError`), and the film reads them from there, so that
film and wall (and a wear update of the law's bearing profile) always see one geometry.
"""

from __future__ import annotations

import math
import warnings
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, ParameterError, Rule, check_range, is_concrete
from .._parameters import POSITIVE, Parameter
from .._types import ArrayLike, Scalar, Vec2
from ..contact.base import AbstractFriction, AbstractNormalLaw, element_friction
from ..contact.friction import Friction
from ..contact.hertz import ContactLaw
from ..contact.hybrid import FourierProfile, check_gauss_points, gauss_nodes
from ..model.mechanism import Mechanism, point_load
from .base import ContactOutput
from .revolute_clearance import AbstractJournalJoint, check_journal_geometry, contact_forces, kinematics

#: Film conditions (module docstring).
FILMS = ("half", "full", "pi", "pi-clockwise", "half-fixed")

#: The fixed-edge films (circles only: their edges follow the line of centres).
FIXED_FILMS = ("pi", "pi-clockwise", "half-fixed")


def film_integrals(eps, a, b):
    r"""``(I_cc, I_cs, I_ss)``: the integrals over :math:`\psi \in [a, b]` of
    :math:`\cos^2\psi`, :math:`\sin\psi\cos\psi`, :math:`\sin^2\psi` over
    :math:`(1 - \varepsilon\cos\psi)^3`, in closed form (Sommerfeld substitution, module
    docstring), for :math:`0 \le \varepsilon < 1` and any real ``a <= b``."""
    k = jnp.sqrt((1.0 + eps) / (1.0 - eps))

    def beta(psi):  # continuous, increasing branch of 2 atan(k tan(psi / 2))
        x = 0.5 * psi
        sx, cx = jnp.sin(x), jnp.cos(x)
        return psi + 2.0 * jnp.arctan2((k - 1.0) * sx * cx, cx * cx + k * sx * sx)

    def antiderivatives(bt):
        s, c, s2 = jnp.sin(bt), jnp.cos(bt), jnp.sin(2.0 * bt)
        return (0.5 * bt + 0.25 * s2 + 2.0 * eps * s + eps * eps * bt, 0.5 * s * s - eps * c, 0.5 * bt - 0.25 * s2)

    (cc1, cs1, ss1), (cc0, cs0, ss0) = antiderivatives(beta(b)), antiderivatives(beta(a))
    one = 1.0 - eps * eps
    return (cc1 - cc0) * one**-2.5, (cs1 - cs0) * one**-2.0, (ss1 - ss0) * one**-1.5


def film_limits(eps_dot, wedge, film: str):
    """Edges ``(a, b)`` of the pressurised film in :math:`\\psi` for the film condition."""
    if film == "full":
        return jnp.asarray(-math.pi), jnp.asarray(math.pi)
    if film == "pi":
        return jnp.asarray(-math.pi), jnp.asarray(0.0)
    if film == "pi-clockwise":
        return jnp.asarray(0.0), jnp.asarray(math.pi)
    if film == "half-fixed":
        a = jnp.where(wedge >= 0.0, -math.pi, 0.0)
        return a, a + math.pi
    # positive pressure where eps_dot cos(psi) - wedge sin(psi) = A cos(psi - psi0) > 0
    ok = eps_dot * eps_dot + wedge * wedge > 0.0
    psi0 = jnp.arctan2(jnp.where(ok, -wedge, 0.0), jnp.where(ok, eps_dot, 1.0))
    return psi0 - 0.5 * math.pi, psi0 + 0.5 * math.pi


def film_force(eps, eps_dot, wedge, radius, clearance, length, viscosity, film: str = "half"):
    r"""Short-bearing film force on the journal, ``(F_n, F_t)`` [N] along :math:`n` and :math:`t`.

    Args:
        eps: eccentricity ratio :math:`\varepsilon \in [0, 1)`.
        eps_dot: squeeze rate :math:`\dot\varepsilon` [1/s].
        wedge: :math:`\bar\omega\varepsilon` [1/s].
        radius: journal radius :math:`R_J` [m]; clearance :math:`c` [m]; length: film width L [m].
        viscosity: dynamic viscosity :math:`\mu` [Pa s].
        film: one of :data:`FILMS` (module docstring).
    """
    a, b = film_limits(eps_dot, wedge, film)
    i_cc, i_cs, i_ss = film_integrals(eps, a, b)
    scale = radius * viscosity * length**3 / clearance**2
    return -scale * (eps_dot * i_cc - wedge * i_cs), -scale * (eps_dot * i_cs - wedge * i_ss)


def gauss_film_force(ecc, vel, omega_j, omega_b, phi_j, phi_b, radius, clearance, length, viscosity,
                     journal_profile=None, bearing_profile=None, n_elements: int = 180, n_gauss: int = 4,
                     film: str = "half", blend=None):
    r"""Short-bearing film force on the journal (2,) [N, global axes] for journal and bearing
    profiles, by composite Gauss-Legendre quadrature over :math:`\theta \in [0, 2\pi)` (module
    docstring for :math:`\bar p(\theta)`).

    Args:
        ecc: eccentricity :math:`\mathbf e` (2,) [m] (bearing centre to journal centre).
        vel: journal-centre velocity relative to the bearing centre (2,) [m/s].
        omega_j, omega_b, phi_j, phi_b: angular velocities [rad/s] and angles [rad] of journal
            and bearing body (profiles are body-fixed).
        radius: :math:`R_J` [m]; clearance: :math:`c` [m]; length: film width L [m];
            viscosity: :math:`\mu` [Pa s].
        journal_profile, bearing_profile: :class:`~jaxclear.FourierProfile` or ``None``.
        n_elements, n_gauss: elements and Gauss points per element.
        film: ``"half"`` (:math:`\bar p \ge 0`) or ``"full"``.
        blend: ``(blend_start, blend_end)`` of the film's saturation (module docstring), or
            ``None`` (the film thickness as it is; it must stay positive).
    """
    s, w = gauss_nodes(n_elements, n_gauss)
    theta, weight = jnp.asarray(np.pi * (s + 1.0)), jnp.asarray(np.pi * w)
    cu, su = jnp.cos(theta), jnp.sin(theta)
    zero = jnp.zeros_like(theta)

    def profile(p, phi):  # deviation and its slope at the body-fixed angle theta - phi
        if p is None:
            return zero, zero
        return jax.vmap(jax.value_and_grad(p))(theta - phi)

    d_j, dd_j = profile(journal_profile, phi_j)
    d_b, dd_b = profile(bearing_profile, phi_b)
    closure = d_j - d_b + ecc[0] * cu + ecc[1] * su  # c - h
    if blend is not None:
        eps_h = jnp.max(closure) / clearance
        ok = eps_h > blend[0]  # below blend_start g is the identity: scale 1 (also keeps 0/0 out)
        eps_safe = jnp.where(ok, eps_h, 1.0)
        closure = closure * jnp.where(ok, film_ratio(eps_safe, blend[0], blend[1]) / eps_safe, 1.0)
    h = clearance - closure
    g = (0.5 * (omega_j - omega_b) * (dd_b + dd_j) - 0.5 * (omega_j + omega_b) * (ecc[1] * cu - ecc[0] * su)
         - (vel[0] * cu + vel[1] * su))
    p = -viscosity * length**3 * g / h**3
    if film == "half":
        p = jnp.maximum(p, 0.0)
    return -radius * jnp.stack([jnp.sum(weight * p * cu), jnp.sum(weight * p * su)])


def film_ratio(eps, blend_start, blend_end):
    r"""The ratio :math:`\tilde\varepsilon = g(\varepsilon)` the film force is evaluated at
    (C1 saturation between ``blend_start`` and ``blend_end``; module docstring)."""
    width = blend_end - blend_start
    inside = eps - (eps - blend_start) ** 2 / (2.0 * width)
    return jnp.where(eps <= blend_start, eps, jnp.where(eps >= blend_end, 0.5 * (blend_start + blend_end), inside))


class LubricatedJoint(AbstractJournalJoint):
    """A revolute joint with an oil film in its clearance (module docstring for the model).

    Attributes (besides those of :class:`~jaxclear.ClearanceJoint`, whose meaning they keep):
        length: the joint's axial length L [m], which is the film width (one name for both, as
            for every journal joint; the old name ``width`` of mechanism files, parameter names and
            this attribute still works, with a DeprecationWarning).
        viscosity: dynamic viscosity :math:`\\mu` of the oil [Pa s] > 0.
        blend_start, blend_end: eccentricity ratios :math:`0 < \\varepsilon_0 < \\varepsilon_1 < 1`
            of the film's C1 saturation (transition to dry contact).
        film: film condition, one of :data:`FILMS` (static); ``"half"`` or ``"full"`` with profiles.
        journal_profile, bearing_profile (properties, the dry law's :attr:`profiles`):
            :class:`~jaxclear.FourierProfile` radial deviations [m] (body-fixed) or ``None``
            (circles: the closed forms). Given to the constructor, they are handed to the law
            (:meth:`~jaxclear.contact.base.AbstractNormalLaw.with_profiles`: a law that
            integrates profiles, ``HybridLaw(placement="fixed")``; the default law assumes
            circles and raises :class:`~jaxclear.ParameterError`; so does a law that has its own
            profiles). With a profile the film force is integrated at ``n_elements`` x
            ``n_gauss`` Gauss points (:func:`gauss_film_force`; static, >= 1; default 180 x 4: the
            half film's edges fall inside elements, where the rule loses its order, error
            O(element width^2), 1e-5 of the force at 180 elements).
    """

    bearing_body: str = eqx.field(static=True)
    bearing_point: str = eqx.field(static=True)
    journal_body: str = eqx.field(static=True)
    journal_point: str = eqx.field(static=True)
    bearing_radius: Scalar
    journal_radius: Scalar
    length: Scalar
    viscosity: Scalar
    blend_start: Scalar
    blend_end: Scalar
    law: AbstractNormalLaw
    friction: AbstractFriction
    impact_velocity_floor: Scalar
    initial_offset: Vec2
    initial_velocity: Vec2
    film: str = eqx.field(static=True)
    n_elements: int = eqx.field(static=True)
    n_gauss: int = eqx.field(static=True)
    name: str = eqx.field(static=True)

    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        **AbstractJournalJoint.PARAMETERS,
        "viscosity": Parameter("viscosity", "Pa s", **POSITIVE, doc="oil viscosity (lubricated joint)"),
    }

    def describe(self) -> str:
        return (f"{super().describe()}, oil film: viscosity {float(self.viscosity):.4g} Pa s, film width (length) "
                f"{float(self.length) * 1e3:.4g} mm")

    def __init__(
        self,
        bearing_body: str,
        bearing_point: str,
        journal_body: str,
        journal_point: str,
        bearing_radius: ArrayLike = 0.010,
        journal_radius: ArrayLike = 0.0095,
        length: ArrayLike = 0.010,
        viscosity: ArrayLike = 0.4,
        law=None,
        friction: AbstractFriction | None = None,
        film: str = "half",
        blend_start: ArrayLike = 0.95,
        blend_end: ArrayLike = 0.99,
        impact_velocity_floor: ArrayLike = 1e-4,
        initial_offset: ArrayLike = (0.0, 0.0),
        initial_velocity: ArrayLike = (0.0, 0.0),
        name: str = "lubricated",
        journal_profile: FourierProfile | None = None,
        bearing_profile: FourierProfile | None = None,
        n_elements: int = 180,
        n_gauss: int = 4,
    ):
        check_range("viscosity", viscosity, low=0.0, low_open=True, unit="Pa s")
        check_range("length (the film width)", length, low=0.0, low_open=True, unit="m")
        check_range("blend_start", blend_start, low=0.0, high=1.0, low_open=True, high_open=True)
        check_range("blend_end", blend_end, low=0.0, high=1.0, low_open=True, high_open=True)
        if is_concrete(blend_start) and is_concrete(blend_end) and not float(blend_start) < float(blend_end):
            raise ParameterError(
                f"blend_start = {float(blend_start):g} must be smaller than blend_end = {float(blend_end):g} "
                "(allowed: 0 < blend_start < blend_end < 1)"
            )
        if film not in FILMS:
            raise ParameterError(f"film = {film!r} is not a film condition; valid: {list(FILMS)}")
        law = ContactLaw() if law is None else law
        if journal_profile is not None or bearing_profile is not None:
            if any(p is not None for p in law.profiles):
                raise ParameterError("profiles given twice: to the joint and to its law (give them once; the "
                                     "joint hands its profiles to the law)")
            law = law.with_profiles(journal_profile, bearing_profile)
        if film in FIXED_FILMS and any(p is not None for p in law.profiles):
            raise ParameterError(f"film = {film!r} has no meaning for profiles (its edges follow the line of "
                                 "centres of circles); valid with profiles: ['half', 'full']")
        check_gauss_points(n_elements, n_gauss)
        # the law refuses profiles that close the clearance (HybridLaw.check_geometry)
        rb, rj, offset = check_journal_geometry(bearing_radius, journal_radius, length, impact_velocity_floor, law,
                                                initial_offset)
        self.bearing_body, self.bearing_point = bearing_body, bearing_point
        self.journal_body, self.journal_point = journal_body, journal_point
        self.bearing_radius, self.journal_radius = rb, rj
        self.length = jnp.asarray(length, dtype=float)
        self.viscosity = jnp.asarray(viscosity, dtype=float)
        self.blend_start = jnp.asarray(blend_start, dtype=float)
        self.blend_end = jnp.asarray(blend_end, dtype=float)
        self.law = law
        self.friction = element_friction(friction, "LubricatedJoint", Friction())
        self.impact_velocity_floor = jnp.asarray(impact_velocity_floor, dtype=float)
        self.initial_offset = offset
        self.initial_velocity = jnp.asarray(initial_velocity, dtype=float).reshape(2)
        self.film = film
        self.n_elements, self.n_gauss = int(n_elements), int(n_gauss)
        self.name = name

    @property
    def journal_profile(self) -> FourierProfile | None:
        """The journal's radial deviation [m] (the dry law's), or ``None`` (circle)."""
        return self.law.profiles[0]

    @property
    def bearing_profile(self) -> FourierProfile | None:
        """The bearing's radial deviation [m] (the dry law's), or ``None`` (circle)."""
        return self.law.profiles[1]

    @property
    def width(self):
        """Deprecated name of :attr:`length` (the film width L [m])."""
        warnings.warn("LubricatedJoint.width is deprecated; use length (the film width)", DeprecationWarning,
                      stacklevel=2)
        return self.length

    def checks(self) -> tuple:
        """The journal joint's checks (radii, clearance, length > 0, floor, laws), then
        viscosity > 0 and blend bounds :math:`0 < \\varepsilon_0 < \\varepsilon_1 < 1`
        (``invalid_parameter``)."""
        unit = dict(low=0.0, high=1.0, low_open=True, high_open=True)
        return (
            *super().checks(),
            Rule("viscosity", self.viscosity, RESULTS.invalid_parameter, low=0.0, low_open=True, unit="Pa s"),
            Rule("blend_start", self.blend_start, RESULTS.invalid_parameter, **unit),
            Rule("blend_end", self.blend_end, RESULTS.invalid_parameter, **unit),
            Rule("blend_end - blend_start", self.blend_end - self.blend_start, RESULTS.invalid_parameter, low=0.0,
                 low_open=True),
        )

    def kinematics(self, mech: Mechanism, q, qdot):
        return kinematics(mech, self, q, qdot)

    def film_force(self, mech: Mechanism, q, qdot) -> tuple[Scalar, Scalar]:
        """Film force on the journal ``(F_n, F_t)`` [N] along the normal :math:`n` (from the
        bearing centre to the journal centre) and the tangent :math:`t` at ``(q, qdot)``."""
        kin = self.kinematics(mech, q, qdot)
        return self._film(kin)

    def _film(self, kin):
        c = self.clearance
        v = kin.journal_velocity - kin.bearing_velocity
        if self.journal_profile is not None or self.bearing_profile is not None:
            f = gauss_film_force(kin.ecc, v, kin.journal_omega, kin.bearing_omega, kin.journal_angle,
                                 kin.bearing_angle, self.journal_radius, c, self.length, self.viscosity,
                                 self.journal_profile, self.bearing_profile, self.n_elements, self.n_gauss,
                                 self.film, (self.blend_start, self.blend_end))
            return f[0] * kin.normal[0] + f[1] * kin.normal[1], f[0] * kin.tangent[0] + f[1] * kin.tangent[1]
        eps = film_ratio(kin.e / c, self.blend_start, self.blend_end)
        eps_dot = (v[0] * kin.normal[0] + v[1] * kin.normal[1]) / c
        wedge = (0.5 * (kin.journal_omega + kin.bearing_omega) * kin.e - (v[0] * kin.tangent[0] + v[1] * kin.tangent[1])) / c
        return film_force(eps, eps_dot, wedge, self.journal_radius, c, self.length, self.viscosity, self.film)

    #: film force on the journal along n (bearing centre to journal centre) and t, along the
    #: global axes and its magnitude; e/c; the thinnest film (0 once the surfaces touch)
    OUTPUTS = {"film_force_normal": "N", "film_force_tangential": "N", "film_force_x": "N", "film_force_y": "N",
               "film_force": "N", "eccentricity_ratio": "-", "min_film_thickness": "m"}

    def outputs(self, mech: Mechanism, t, q, qdot, state, continuous_after):
        """The film's force (:meth:`film_force`: components along n and t and the global axes, its
        magnitude) [N], the eccentricity ratio :math:`e/c` [-] and the minimum film thickness [m]:
        :math:`c - e` for circles, the smallest gap over the Gauss points with profiles, 0 once the
        surfaces touch (the geometric film, before the blend's saturation)."""
        kin = self.kinematics(mech, q, qdot)
        f_n, f_t = self._film(kin)
        f = f_n * kin.normal + f_t * kin.tangent
        c = self.clearance
        if self.journal_profile is None and self.bearing_profile is None:
            h_min = c - kin.e
        else:
            s, _ = gauss_nodes(self.n_elements, self.n_gauss)
            theta = jnp.asarray(np.pi * (s + 1.0))
            dev = lambda p, phi: 0.0 if p is None else jax.vmap(p)(theta - phi)  # noqa: E731
            closure = (dev(self.journal_profile, kin.journal_angle) - dev(self.bearing_profile, kin.bearing_angle)
                       + kin.ecc[0] * jnp.cos(theta) + kin.ecc[1] * jnp.sin(theta))
            h_min = c - jnp.max(closure)
        return {"film_force_normal": f_n, "film_force_tangential": f_t, "film_force_x": f[0], "film_force_y": f[1],
                "film_force": jnp.sqrt(f_n * f_n + f_t * f_t), "eccentricity_ratio": kin.e / c,
                "min_film_thickness": jnp.maximum(h_min, 0.0)}

    def contact(self, mech: Mechanism, q, qdot, impact_velocity):
        """Dry contact (law and friction, :func:`contact_forces`) plus the film force. The output's
        ``normal_force`` is the total force pushing the journal towards the bearing centre
        (dry :math:`F_N` minus the film's :math:`F_n`), ``friction_force`` the dry friction."""
        kin = self.kinematics(mech, q, qdot)
        gen, dry = contact_forces(mech, self, kin, q, qdot, impact_velocity)
        f_n, f_t = self._film(kin)
        f = f_n * kin.normal + f_t * kin.tangent
        gen = gen + point_load(mech, q, self.journal_body, kin.journal_centre, f) + point_load(
            mech, q, self.bearing_body, kin.journal_centre, -f
        )
        out = ContactOutput(ecc=dry.ecc, penetration=dry.penetration, normal_force=dry.normal_force - f_n,
                            friction_force=dry.friction_force, power=jnp.sum(gen * qdot))
        return gen, out
