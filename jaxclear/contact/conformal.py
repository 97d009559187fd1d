r"""Line-contact (conformal) laws for a journal of radius :math:`R_J` and length :math:`L` in a
bearing of radius :math:`R_B`, radial clearance :math:`\Delta R = R_B - R_J`, effective
modulus :math:`1/E^* = (1-\nu_i^2)/E_i + (1-\nu_j^2)/E_j`, as compared by Pereira, Ramalho,
Ambrósio, "A critical overview of internal and external cylinder contact force models",
Nonlinear Dyn. 63 (2011) 681-697 (their definitions; the variants chosen are stated per law).

Five of them give the penetration as a function of the force, all of the form

.. math:: \delta(F) = \kappa\,\frac{F}{\pi L E^*}\left[\ln\frac{B}{F} + c\right]

(:func:`log_law_penetration`), with

=========================  ========  ===============================================  =======
law                        kappa     B [N]                                            c
=========================  ========  ===============================================  =======
Johnson (1985)             1         :math:`4\pi L E^*\Delta R`                        -1
Radzimovsky (1953)         1         :math:`4\pi L E^*\Delta R`                        2/3
Goldsmith (1960)           1         :math:`\pi E^* L^3/\Delta R`                      1
Dubowsky-Freudenstein      1         :math:`\pi E^* L^3\Delta R/(R_B R_J)`             1
ESDU-78035 (1978)          pi        :math:`4\pi L E^*\Delta R`                        1
=========================  ========  ===============================================  =======

* Johnson, *Contact Mechanics*, CUP 1985, sec. 5.6: :math:`\delta = \frac{F}{\pi L E^*}
  [\ln(4\pi L E^*\Delta R/F) - 1]`.
* Radzimovsky, "Stress distribution and strength condition of two rolling cylinders pressed
  together", Univ. Illinois Eng. Exp. Station Bull. 408 (1953): :math:`\delta = \frac{F}{\pi L E^*}
  [2/3 + \ln(4R_B/b) + \ln(4R_J/b)]` with the Hertz half-width :math:`b = 2\sqrt{F R^*/(\pi L E^*)}`,
  :math:`R^* = R_B R_J/\Delta R`; substituting b gives the row above (variant: Hertz half-width,
  not Radzimovsky's empirical 1.6 coefficient).
* Goldsmith, *Impact*, Arnold 1960: :math:`\delta = \frac{F\sigma_G}{L}[\ln(L^3/(F\sigma_G\Delta R))
  + 1]`, :math:`\sigma_G = \sum_k (1-\nu_k^2)/(\pi E_k) = 1/(\pi E^*)`.
* Dubowsky & Freudenstein, "Dynamic analysis of mechanical systems with clearances, part 1",
  J. Eng. Ind. 93 (1971) 305-309: as Goldsmith with :math:`\Delta R/(R_B R_J)` in place of
  :math:`1/\Delta R` in the logarithm.
* ESDU-78035, "Contact phenomena I: stresses, deflections and contact dimensions for normally
  loaded unlubricated elastic components" (1978), as quoted by Pereira et al.:
  :math:`\delta = \frac{F}{L E^*}[\ln(4\pi L E^*\Delta R/F) + 1]`.

Pereira et al.'s text could not be read for this implementation: the expressions are the
original sources' in one notation (:math:`\sigma_k = (1-\nu_k^2)/(\pi E_k)`). An independent open
implementation of the same set (L. Škrinjar, ``MBD_system``, ``contact_model_cylinder.py``, GitHub)
agrees on Johnson and on the form of Dubowsky-Freudenstein and ESDU, and differs in three
variants (documentation, "Contact laws"): compliances without the :math:`1/\pi` (penetrations
:math:`\pi` times these), Radzimovsky's half-width :math:`1.6\sqrt{FR^*/(LE^*)}` instead of Hertz's,
and :math:`R^*` in Goldsmith's logarithm (which makes it Dubowsky-Freudenstein's law).

Each is solved for :math:`F(\delta)` by Newton's method on :math:`\ln F` (:func:`log_law_force`,
fixed iteration count, differentiable through the implicit function theorem). The relation is
monotonic while :math:`\ln(B/F) + c > 1`; beyond that penetration (for Johnson
:math:`\delta > 4e^{-2}\Delta R \approx 0.54\,\Delta R`) the force is held at its maximum and the law
is outside its validity.

Pereira et al.'s own law is explicit (:func:`pereira_stiffness`):
:math:`F = K\delta^n`, :math:`K = (a\Delta R + b) L E^*/\Delta R`, :math:`n = Y\Delta R^{-0.005}`,
internal contact :math:`a = 0.965`, :math:`b = 0.0965`,
:math:`Y = 1.51[\ln(1000\Delta R)]^{-0.151}` for :math:`0.005 \le \Delta R \le 0.34954` and
:math:`Y = 0.0151\Delta R + 1.151` for :math:`0.34954 \le \Delta R \le 10`, with :math:`\Delta R` in
millimetres. The whole fit works in millimetres, newtons and megapascals (F [N] for
:math:`\delta` [mm], L [mm], E* [MPa]; the two expressions for Y meet at 0.34954 mm only in
millimetres, and the independent implementation in DyS, L. Škrinjar's ``MBD_system``, evaluates
the law in these units): in SI units :math:`K = (a\Delta R_{mm} + b)/\Delta R_{mm}\,L E^*\,
1000^{n-1}` [N/m^n]. At :math:`\delta` = 1 µm, :math:`\Delta R` = 0.5 mm, L = 10 mm, steel, it
gives 428.4 N against Johnson's 407.3 N; reading the fitted K as N/m^n would give 139.4 N
(the factor :math:`1000^{1-n}` = 0.33).

Persson's law (``persson``; A. Persson, "On the stress distribution of cylindrical elastic bodies
in contact", PhD thesis, Chalmers, Göteborg 1964, as listed by Pereira et al.) is the exact plane
elastic solution for a pin in a hole of the same material (elastic similarity). It relates the
load to the half-angle :math:`\varepsilon` of the contact arc, not to a penetration: an infinite
plate under a net force has no finite rigid approach. The form implemented
(:func:`persson_load`, :func:`persson_force`) has two parts, stated here because neither Pereira et
al.'s own equation nor Persson's thesis could be read for this implementation:

* load against arc, in the closed form Ciavarella & Decuzzi give to Persson's solution (M.
  Ciavarella, P. Decuzzi, "The state of stress induced by the plane frictionless cylindrical
  contact. I. The case of elastic similarity", Int. J. Solids Struct. 38 (2001) 4507-4523), with
  :math:`b = \tan(\varepsilon/2)`:

  .. math:: \frac{E^*\Delta R}{F/L} = \frac{1}{\pi}\left(\frac{1}{b^2} - 1\right),
            \qquad F = \pi L E^*\Delta R\,\frac{b^2}{1 - b^2};

  quoted from that paper as recalled, not verified against its text here. It meets Hertz's
  line contact for a small arc (:math:`F \to \pi L E^*\Delta R\,b^2`, i.e. the half-width
  :math:`a = R\varepsilon` of :math:`a^2 = 4FR^*/(\pi L E^*)`); under a load without bound its arc
  tends to a half circumference (:math:`b \to 1`). Against a numerical solution of the plane
  problem (tests/test_laws_more.py: the exact gap-closure kernel of a disc in a hole of one
  material, from Muskhelishvili's potentials) its arc agrees to 0.2° up to
  :math:`F/(LE^*\Delta R) = 0.1` (an arc of 20°) and is larger beyond: 46.2° against 44.9° at 0.7,
  76.2° against 72.1° at 5, and 90° against 84.8° for a neat fit (the numerical arc of a pin
  without clearance, the same at any load). So it is exact for small arcs and an approximation
  of Persson's relation beyond;
* arc against penetration: the arc on which the rigid journal, displaced by
  :math:`\Delta R + \delta`, overlaps the hole, :math:`\cos\varepsilon = \Delta R/(\Delta R + \delta)`,
  the relation the elastic-foundation laws use (Liu et al. 2007, :mod:`.cylindrical`); it gives
  :math:`b^2 = \delta/(2\Delta R + \delta)`.

Together they give :math:`F = \tfrac12\pi L E^*\delta` exactly: a linear law (any load-arc relation
with Hertz's small-arc limit gives this slope while :math:`\delta \ll \Delta R`, which is where
joints work). E* is the effective modulus of the two bodies; the solution assumes both are of one
material, and the law refuses two different materials (give ``modulus`` to override).

Every law gets the hysteresis damping of the dissipative-Hertz family,
:math:`F_N = F(\delta)(1 + \hat\chi(c_r)\dot\delta/\dot\delta^{(-)})` (default Lankarani-Nikravesh,
as Pereira et al. use). The Lankarani-Nikravesh law "for cylinders" of the same comparison is
:math:`K\delta^{1.5}` with :math:`K = \frac43 E^*\sqrt{R^*}`: the existing ``lankarani-nikravesh``
law with its default stiffness.
"""

from __future__ import annotations


import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError, check_range, is_concrete
from .._types import Scalar
from .base import STEEL, AbstractModulusLaw, Material
from .hertz import HYSTERESIS_FACTORS, hysteresis_model, positive_power

#: law -> (kappa, c, which B): the logarithmic line-contact laws (module docstring)
LOG_LAWS = {
    "johnson": (1.0, -1.0, "clearance"),
    "radzimovsky": (1.0, 2.0 / 3.0, "clearance"),
    "goldsmith": (1.0, 1.0, "goldsmith"),
    "dubowsky-freudenstein": (1.0, 1.0, "dubowsky"),
    "esdu-78035": (jnp.pi, 1.0, "clearance"),
}

CONFORMAL_LAWS = (*LOG_LAWS, "pereira", "persson")


def log_law_scale(model, radius_bearing, radius_journal, length, modulus):
    """``(kappa, B [N], c)`` of a logarithmic law (table in the module docstring)."""
    kappa, c, which = LOG_LAWS[model]
    dr = radius_bearing - radius_journal
    if which == "clearance":
        b = 4.0 * jnp.pi * length * modulus * dr
    elif which == "goldsmith":
        b = jnp.pi * modulus * length**3 / dr
    else:
        b = jnp.pi * modulus * length**3 * dr / (radius_bearing * radius_journal)
    return kappa, b, c


def log_law_penetration(force, kappa, b, c, length, modulus):
    r""":math:`\delta(F) = \kappa F/(\pi L E^*)[\ln(B/F) + c]` [m] for a force F > 0 [N]."""
    return kappa * force / (jnp.pi * length * modulus) * (jnp.log(b / force) + c)


def log_law_force(delta, kappa, b, c, length, modulus, iterations=8):
    r"""Force [N] of a logarithmic law at penetration ``delta`` [m] (0 for delta <= 0): Newton on
    :math:`x = \ln F` for :math:`h(x) = \ln\delta(e^x) - \ln\delta = 0`,
    :math:`h'(x) = 1 - 1/(\ln B - x + c)`, from two fixed-point steps; ``iterations`` Newton steps
    under ``stop_gradient`` and one last step that carries the derivatives (implicit function
    theorem: exact first derivatives at the converged root)."""
    inside = delta > 0.0
    d = jnp.where(inside, delta, 1e-12)
    scale = jnp.log(jnp.pi * length * modulus / kappa)
    log_b = jnp.log(b)
    u_min = 1.0 + 1e-9

    def h(x, log_d, log_b, scale):
        u = jnp.maximum(log_b - x + c, u_min)
        return x - scale + jnp.log(u) - log_d, 1.0 - 1.0 / u

    log_d, lb, sc = jax.lax.stop_gradient((jnp.log(d), log_b, scale))
    x = log_d + sc - jnp.log(15.0)
    for _ in range(2):
        x = log_d + sc - jnp.log(jnp.maximum(lb - x + c, u_min + 0.5))
    x_max = lb + c - u_min  # the force where the relation stops being monotonic
    for _ in range(iterations):
        val, slope = h(x, log_d, lb, sc)
        x = jnp.minimum(x - val / slope, x_max)
    x = jax.lax.stop_gradient(x)
    val, slope = h(x, jnp.log(d), log_b, scale)
    x = jnp.minimum(x - val / jax.lax.stop_gradient(slope), log_b + c - u_min)
    return jnp.where(inside, jnp.exp(x), 0.0)


def pereira_stiffness(radius_bearing, radius_journal, length, modulus):
    r"""``(K [N/m^n], n)`` of Pereira et al.'s internal-contact law (module docstring).

    The law is fitted in millimetres, newtons and megapascals: :math:`F\,[\mathrm N] =
    K_{mm}\,\delta_{mm}^n` with :math:`K_{mm} = (a\Delta R_{mm} + b) L_{mm} E^*_{MPa}/\Delta R_{mm}`
    [N/mm^n]. In SI units that is :math:`K = K_{mm}\cdot 1000^n` [N/m^n], i.e.
    :math:`K = (a\Delta R_{mm} + b)/\Delta R_{mm}\; L E^*\; 1000^{\,n-1}` with L [m] and E* [Pa]:
    since n is not 1, reading the fitted K directly in N/m^n would make the law
    :math:`1000^{n-1}` (about 3 at n = 1.16) too soft."""
    dr_mm = (radius_bearing - radius_journal) * 1e3
    y_small = 1.51 * jnp.log(1000.0 * dr_mm) ** -0.151
    y_large = 0.0151 * dr_mm + 1.151
    y = jnp.where(dr_mm <= 0.34954, y_small, y_large)
    exponent = y * dr_mm**-0.005
    stiffness = (0.965 * dr_mm + 0.0965) / dr_mm * length * modulus * 1000.0 ** (exponent - 1.0)
    return stiffness, exponent


def persson_load(b2, clearance, length, modulus):
    r"""Persson's load [N] for a contact arc of half-angle :math:`\varepsilon`, given as
    ``b2`` = :math:`b^2 = \tan^2(\varepsilon/2) \in [0, 1)`:
    :math:`F = \pi L E^*\Delta R\,b^2/(1 - b^2)` (module docstring: the closed form, its limits)."""
    return _persson_load_of_ratio(b2 / (1.0 - b2), clearance, length, modulus)


def _persson_load_of_ratio(ratio, clearance, length, modulus):
    r""":math:`F = \pi L E^*\Delta R\,r` [N] of the ratio :math:`r = b^2/(1 - b^2)`."""
    return jnp.pi * length * modulus * clearance * ratio


def overlap_arc(delta, clearance):
    r""":math:`b^2 = \tan^2(\varepsilon/2)` [-] of the arc on which a rigid journal at eccentricity
    :math:`\Delta R + \delta` overlaps the hole, :math:`\cos\varepsilon = \Delta R/(\Delta R + \delta)`:
    :math:`b^2 = \delta/(2\Delta R + \delta)` (0 for :math:`\delta \le 0`; squared, so smooth at 0)."""
    pos = jnp.maximum(delta, 0.0)
    return pos / (2.0 * clearance + pos)


def persson_force(delta, clearance, length, modulus):
    r"""Persson's law [N] at penetration ``delta`` [m]: :func:`persson_load` of the
    :func:`overlap_arc` (together :math:`\tfrac12\pi L E^*\delta`); 0 for delta <= 0.

    The ratio :math:`b^2/(1 - b^2)` of the overlap arc is evaluated in its closed form
    :math:`\delta/(2\Delta R)`: computed as ``b2 / (1 - b2)`` it cancels for
    :math:`\delta \gg \Delta R` (``inf`` at the penetrations of an overshooting trial step)."""
    ratio = jnp.maximum(delta, 0.0) / (2.0 * clearance)  # b^2 / (1 - b^2) of overlap_arc
    return _persson_load_of_ratio(ratio, clearance, length, modulus)


#: clearance range [m] of Pereira et al.'s fit
PEREIRA_CLEARANCE = (0.005e-3, 10e-3)


class ConformalLaw(AbstractModulusLaw):
    r"""The line-contact laws compared by Pereira et al. (2011), selected by ``model``
    (``johnson``, ``radzimovsky``, ``goldsmith``, ``dubowsky-freudenstein``, ``esdu-78035``,
    ``pereira``, ``persson``; module docstring), with hysteresis damping
    :math:`F_N = F(\delta)(1 + \hat\chi(c_r)\dot\delta/\dot\delta^{(-)})`, clipped at 0.

    Attributes:
        model: law name (static).
        restitution: :math:`c_r \in (0, 1]`.
        modulus: :math:`E^*` [Pa] > 0 or ``None`` (from the materials: :func:`effective_modulus`).
        hysteresis: name of the damping factor in :data:`HYSTERESIS_FACTORS` (static; default
            Lankarani-Nikravesh).
        bearing_material, journal_material: used when ``modulus`` is ``None``.
    """

    model: str = eqx.field(static=True)
    restitution: Scalar
    modulus: Scalar | None
    bearing_material: Material
    journal_material: Material
    hysteresis: str = eqx.field(static=True)

    def __init__(self, model="johnson", restitution=0.9, modulus=None, hysteresis=None,
                 bearing_material: Material = STEEL, journal_material: Material = STEEL):
        if model not in CONFORMAL_LAWS:
            raise ParameterError(f"conformal law model must be one of {list(CONFORMAL_LAWS)}, got {model!r}")
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("modulus (E*)", modulus, low=0.0, low_open=True, unit="Pa")
        self.model = model
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.modulus = None if modulus is None else jnp.asarray(modulus, dtype=float)
        self.hysteresis = hysteresis_model("lankarani-nikravesh" if hysteresis is None else hysteresis)
        self.bearing_material, self.journal_material = bearing_material, journal_material
        if model == "persson" and modulus is None and is_concrete((bearing_material, journal_material)):
            same = all(float(getattr(bearing_material, k)) == float(getattr(journal_material, k))
                       for k in ("young", "poisson"))
            if not same:
                raise ParameterError("the persson law is Persson's solution for a pin and a hole of one material "
                                     "(elastic similarity); bearing_material and journal_material differ. Give "
                                     "both the same material, or an explicit modulus (E* [Pa]) to use it anyway")

    @property
    def name(self) -> str:
        return self.model

    def check_geometry(self, radius_bearing, radius_journal):
        """Pereira et al.'s fit covers clearances of 0.005 mm to 10 mm only."""
        if self.model == "pereira":
            lo, hi = PEREIRA_CLEARANCE
            dr = radius_bearing - radius_journal
            if not lo <= dr <= hi:
                raise ParameterError(f"the pereira law is fitted for a radial clearance in [{lo:g}, {hi:g}] m, "
                                     f"got {dr:g} m (R_B - R_J)")

    def elastic_force(self, delta, radius_bearing, radius_journal, length):
        """The undamped force :math:`F(\\delta)` [N] (0 for delta <= 0)."""
        modulus = self.modulus_value()
        if self.model == "pereira":
            k, n = pereira_stiffness(radius_bearing, radius_journal, length, modulus)
            return k * positive_power(delta, n)
        if self.model == "persson":
            return persson_force(delta, radius_bearing - radius_journal, length, modulus)
        kappa, b, c = log_law_scale(self.model, radius_bearing, radius_journal, length, modulus)
        return log_law_force(delta, kappa, b, c, length, modulus)

    def hysteresis_factor(self):
        """:math:`\\hat\\chi(c_r)` of the law's hysteresis model (:meth:`AbstractNormalLaw.hysteresis_factor`)."""
        return HYSTERESIS_FACTORS[self.hysteresis](self.restitution)

    def normal_force(self, kin, deltadot0):
        chi = self.hysteresis_factor()
        elastic = self.elastic_force(kin.delta, kin.radius_bearing, kin.radius_journal, kin.length)
        return jnp.maximum(elastic * (1.0 + chi * kin.deltadot / deltadot0), 0.0)
