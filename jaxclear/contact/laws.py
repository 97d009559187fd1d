r"""Normal contact force laws for a journal inside its bearing.

All point-contact laws of the Hertz family have the form (Machado, Moreira, Flores,
Lankarani, "Compliant contact force models in multibody dynamics: evolution of the Hertz
contact theory", Mech. Mach. Theory 53 (2012) 99-121)

.. math::  F_N = K \delta^n \left(1 + \hat\chi(c_r)\,\frac{\dot\delta}{\dot\delta^{(-)}}\right),
           \qquad F_N \ge 0,

with penetration :math:`\delta` [m], its rate :math:`\dot\delta` [m/s] (positive while
approaching), the approach speed at the start of the current contact
:math:`\dot\delta^{(-)}` [m/s] (carried in the state, see :mod:`jaxclear.clearance`),
generalized stiffness :math:`K` [N/m^n], exponent :math:`n` (1.5 for Hertz) and a
hysteresis factor :math:`\hat\chi` that depends only on the nominal coefficient of
restitution :math:`c_r \in (0, 1]`. The laws differ only in :math:`\hat\chi`; they are
listed in :data:`HYSTERESIS_FACTORS` with their sources.

Every function here is pure, works on scalars (``vmap`` it for batches) and is safe for
automatic differentiation at and below :math:`\delta = 0`.
"""

from __future__ import annotations

from typing import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ..errors import ParameterError, check_range

Scalar = Float[Array, ""]


# --------------------------------------------------------------------------------------
# Hysteresis factors chi_hat(c_r)
# --------------------------------------------------------------------------------------


def chi_hertz(c_r):
    """Hertz (1882), purely elastic: :math:`\\hat\\chi = 0`."""
    return 0.0 * c_r


def chi_hunt_crossley(c_r):
    """Hunt & Crossley, J. Appl. Mech. 42 (1975) 440-445: :math:`\\hat\\chi = 3(1-c_r)/2`."""
    return 1.5 * (1.0 - c_r)


def chi_herbert_mcwhannell(c_r):
    """Herbert & McWhannell, J. Eng. Ind. 99 (1977) 513-518:
    :math:`\\hat\\chi = 6(1-c_r)/((2c_r-1)^2+3)`."""
    return 6.0 * (1.0 - c_r) / ((2.0 * c_r - 1.0) ** 2 + 3.0)


def chi_lee_wang(c_r):
    """Lee & Wang, J. Eng. Ind. 105 (1983) 292-302: :math:`\\hat\\chi = 3(1-c_r)/4`."""
    return 0.75 * (1.0 - c_r)


def chi_lankarani_nikravesh(c_r):
    """Lankarani & Nikravesh, J. Mech. Des. 112 (1990) 369-376:
    :math:`\\hat\\chi = 3(1-c_r^2)/4`."""
    return 0.75 * (1.0 - c_r**2)


def chi_gonthier(c_r):
    """Gonthier, McPhee, Lange, Piedboeuf, Multibody Syst. Dyn. 11 (2004) 209-233:
    :math:`\\hat\\chi = (1-c_r^2)/c_r`."""
    return (1.0 - c_r**2) / c_r


def chi_qin_lu(c_r):
    """Zhiying & Qishao (Qin & Lu), Sci. China Ser. E 49 (2006) 600-613:
    :math:`\\hat\\chi = 3(1-c_r^2)\\,e^{2(1-c_r)}/4`."""
    return 0.75 * (1.0 - c_r**2) * jnp.exp(2.0 * (1.0 - c_r))


def chi_flores(c_r):
    """Flores, Machado, Silva, Martins, Multibody Syst. Dyn. 25 (2011) 357-375:
    :math:`\\hat\\chi = 8(1-c_r)/(5c_r)`."""
    return 8.0 * (1.0 - c_r) / (5.0 * c_r)


#: Name -> hysteresis factor function, for every law of the dissipative-Hertz family.
HYSTERESIS_FACTORS: dict[str, Callable] = {
    "hertz": chi_hertz,
    "hunt-crossley": chi_hunt_crossley,
    "herbert-mcwhannell": chi_herbert_mcwhannell,
    "lee-wang": chi_lee_wang,
    "lankarani-nikravesh": chi_lankarani_nikravesh,
    "gonthier": chi_gonthier,
    "qin-lu": chi_qin_lu,
    "flores": chi_flores,
}


# --------------------------------------------------------------------------------------
# Force and stiffness formulas
# --------------------------------------------------------------------------------------


def positive_power(delta, exponent):
    """:math:`\\max(\\delta, 0)^n` with finite value and gradients at and below zero."""
    inside = delta > 0.0
    safe = jnp.where(inside, delta, 1.0)
    return jnp.where(inside, safe**exponent, 0.0)


def dissipative_hertz(delta, deltadot, deltadot0, stiffness, chi, exponent=1.5):
    r"""The dissipative Hertz family :math:`F_N = K\delta^n(1+\hat\chi\dot\delta/\dot\delta^{(-)})`.

    Args:
        delta: penetration [m] (no force when :math:`\le 0`).
        deltadot: penetration rate [m/s], positive while approaching.
        deltadot0: approach speed at contact onset [m/s], already floored to a positive value.
        stiffness: K [N/m^n].
        chi: hysteresis factor :math:`\hat\chi` [-].
        exponent: n [-].

    Returns:
        :math:`F_N \ge 0` [N]; a law never pulls (the clip models separation during unloading).
    """
    force = stiffness * positive_power(delta, exponent) * (1.0 + chi * deltadot / deltadot0)
    return jnp.maximum(force, 0.0)


def compliance(young, poisson):
    r"""Material compliance :math:`\sigma = (1-\nu^2)/E` [1/Pa]."""
    return (1.0 - poisson**2) / young


def cylindrical_stiffness(radius_bearing, radius_journal, sigma_bearing, sigma_journal):
    r"""Generalized stiffness of a journal in a bearing, as used with the Lankarani-Nikravesh
    law in revolute clearance joints (Flores, Ambrósio, Claro, Lankarani, "Kinematics and
    Dynamics of Multibody Systems with Imperfect Joints", Springer 2008, eq. 4.8):

    .. math:: K = \frac{4}{3(\sigma_i+\sigma_j)}\sqrt{\frac{R_B R_J}{R_B - R_J}}
              \quad [\mathrm{N/m^{1.5}}].

    For :math:`R_B = 10` mm, :math:`R_J = 9.5` mm and steel (207 GPa, 0.3): 6.61e10.
    """
    return (4.0 / 3.0) / (sigma_bearing + sigma_journal) * jnp.sqrt(
        radius_bearing * radius_journal / (radius_bearing - radius_journal)
    )


# --------------------------------------------------------------------------------------
# Data: materials and the law object held by a clearance joint
# --------------------------------------------------------------------------------------


class Material(eqx.Module):
    """An isotropic elastic material: Young's modulus ``young`` [Pa], Poisson ratio ``poisson``."""

    young: Scalar
    poisson: Scalar

    def __init__(self, young: ArrayLike = 207e9, poisson: ArrayLike = 0.3):
        check_range("young (Young's modulus)", young, low=0.0, low_open=True, unit="Pa")
        check_range("poisson (Poisson ratio)", poisson, low=-1.0, high=0.5, low_open=True, high_open=True)
        self.young = jnp.asarray(young, dtype=float)
        self.poisson = jnp.asarray(poisson, dtype=float)

    @property
    def compliance(self):
        """:math:`(1-\\nu^2)/E` [1/Pa]."""
        return compliance(self.young, self.poisson)


#: Structural steel as used in the Flores benchmark (E = 207 GPa, nu = 0.3).
STEEL = Material(207e9, 0.3)


class ContactLaw(eqx.Module):
    r"""A law of the dissipative-Hertz family, selected by name (see :data:`HYSTERESIS_FACTORS`).

    Attributes:
        model: law name (static), e.g. ``"lankarani-nikravesh"``.
        restitution: nominal coefficient of restitution :math:`c_r \in (0, 1]`.
        stiffness: K [N/m^n]; ``None`` derives it from the materials and radii with
            :func:`cylindrical_stiffness`.
        exponent: n (1.5 for Hertzian contact).
        bearing_material, journal_material: used when ``stiffness`` is ``None``.
    """

    model: str = eqx.field(static=True)
    restitution: Scalar
    stiffness: Scalar | None
    exponent: Scalar
    bearing_material: Material
    journal_material: Material

    def __init__(
        self,
        model: str = "lankarani-nikravesh",
        restitution: ArrayLike = 0.9,
        stiffness: ArrayLike | None = None,
        exponent: ArrayLike = 1.5,
        bearing_material: Material = STEEL,
        journal_material: Material = STEEL,
    ):
        if model not in HYSTERESIS_FACTORS:
            raise ParameterError(
                f"unknown contact law {model!r}; valid laws of this family: {sorted(HYSTERESIS_FACTORS)}"
            )
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("stiffness", stiffness, low=0.0, low_open=True, unit="N/m^n")
        check_range("exponent", exponent, low=0.0, low_open=True)
        self.model = model
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.stiffness = None if stiffness is None else jnp.asarray(stiffness, dtype=float)
        self.exponent = jnp.asarray(exponent, dtype=float)
        self.bearing_material = bearing_material
        self.journal_material = journal_material

    stiffness_field = "stiffness"

    def stiffness_for(self, radius_bearing, radius_journal):
        """K [N/m^n]: the given one, or the cylindrical formula from the materials and radii."""
        if self.stiffness is not None:
            return self.stiffness
        return cylindrical_stiffness(
            radius_bearing,
            radius_journal,
            self.bearing_material.compliance,
            self.journal_material.compliance,
        )

    @property
    def hysteresis(self):
        """:math:`\\hat\\chi(c_r)` of this law."""
        return HYSTERESIS_FACTORS[self.model](self.restitution)

    def penetration(self, kin):
        """Penetration that decides contact [m]; for a circular pin and hole it is ``e - c``."""
        return kin.delta

    def normal_force(self, kin, deltadot0):
        """Normal force [N] for the joint kinematics ``kin`` and the (floored) impact speed."""
        stiffness = self.stiffness_for(kin.radius_bearing, kin.radius_journal)
        return dissipative_hertz(kin.delta, kin.deltadot, deltadot0, stiffness, self.hysteresis, self.exponent)


def effective_modulus(bearing: Material, journal: Material):
    r""":math:`E^* = 1/(\sigma_i + \sigma_j)` [Pa]."""
    return 1.0 / (bearing.compliance + journal.compliance)


def _hysteresis_model(name: str):
    if name not in HYSTERESIS_FACTORS:
        raise ParameterError(f"unknown hysteresis model {name!r}; valid: {sorted(HYSTERESIS_FACTORS)}")
    return name


# --------------------------------------------------------------------------------------
# Kelvin-Voigt
# --------------------------------------------------------------------------------------


def kelvin_voigt_damping(stiffness, restitution, effective_mass):
    r"""Damping d [N s/m] of the linear law from :math:`c_r = \exp(-\pi\zeta/\sqrt{1-\zeta^2})`:
    :math:`\zeta = -\ln c_r/\sqrt{\pi^2 + \ln^2 c_r}`, :math:`d = 2\zeta\sqrt{k\,m_{eff}}`
    (the unclipped half-period of a damped linear oscillator; Machado et al. 2012, sec. 3)."""
    log_cr = jnp.log(restitution)
    zeta = -log_cr / jnp.sqrt(jnp.pi**2 + log_cr**2)
    return 2.0 * zeta * jnp.sqrt(stiffness * effective_mass)


def kelvin_voigt(delta, deltadot, stiffness, damping):
    r"""Kelvin-Voigt linear spring-damper :math:`F_N = \max(k\delta + d\dot\delta, 0)` for
    :math:`\delta > 0` (Goldsmith, *Impact*, 1960; Machado et al. 2012). The clip (no pulling)
    ends the contact when the force vanishes, so the effective restitution of a single impact
    is somewhat lower than the nominal :math:`c_r` used to compute ``d``."""
    force = stiffness * delta + damping * deltadot
    return jnp.where(delta > 0.0, jnp.maximum(force, 0.0), 0.0)


class KelvinVoigtLaw(eqx.Module):
    """Kelvin-Voigt law (see :func:`kelvin_voigt`).

    Attributes:
        stiffness: k [N/m] > 0.
        restitution: nominal :math:`c_r \\in (0, 1]` giving the damping through
            :func:`kelvin_voigt_damping`.
        effective_mass: :math:`m_{eff}` [kg] > 0 of the contact (e.g. the journal-side mass).
    """

    stiffness: Scalar
    restitution: Scalar
    effective_mass: Scalar

    stiffness_field = "stiffness"

    def __init__(self, stiffness: ArrayLike = 1e8, restitution: ArrayLike = 0.9, effective_mass: ArrayLike = 0.1):
        check_range("stiffness", stiffness, low=0.0, low_open=True, unit="N/m")
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("effective_mass", effective_mass, low=0.0, low_open=True, unit="kg")
        self.stiffness = jnp.asarray(stiffness, dtype=float)
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.effective_mass = jnp.asarray(effective_mass, dtype=float)

    def penetration(self, kin):
        return kin.delta

    def normal_force(self, kin, deltadot0):
        d = kelvin_voigt_damping(self.stiffness, self.restitution, self.effective_mass)
        return kelvin_voigt(kin.delta, kin.deltadot, self.stiffness, d)


# --------------------------------------------------------------------------------------
# Cylindrical (conformal) laws: Liu et al. and Bai-Zhao
# --------------------------------------------------------------------------------------


def liu_force(delta, clearance, modulus, length):
    r"""Liu, Zhang, Wang improved elastic foundation model for a pin in a hole (C.S. Liu,
    K. Zhang, R. Yang, "The FEM analysis and approximate model for cylindrical joints with
    clearances", Mech. Mach. Theory 42 (2007) 183-197):

    .. math:: F = \tfrac12\pi E^*\delta\sqrt{\frac{\delta}{2(c+\delta)}}\,L \quad [\mathrm N].
    """
    pos = jnp.maximum(delta, 0.0)
    inside = delta > 0.0
    ratio = jnp.where(inside, pos / (2.0 * (clearance + pos)), 1.0)
    return jnp.where(inside, 0.5 * jnp.pi * modulus * pos * jnp.sqrt(ratio) * length, 0.0)


def bai_zhao_stiffness(delta, clearance, modulus):
    r"""Bai & Zhao improved-EFM stiffness (Z.F. Bai, Y. Zhao, "Dynamic behaviour analysis of
    planar mechanical systems with clearance in revolute joints using a new hybrid contact force
    model", Int. J. Mech. Sci. 54 (2012) 190-205):

    .. math:: K_n(\delta) = \frac{\pi E^*}{8}\sqrt{\frac{2\delta(3c+2\delta)^2}{(c+\delta)^3}}

    (:math:`dF_{Liu}/d\delta` per unit length), used as published in
    :math:`F_N = K_n\delta^{1.5}(\ldots)`, i.e. with :math:`K_n` read as N/m^1.5.
    """
    pos = jnp.maximum(delta, 0.0)
    inside = delta > 0.0
    arg = jnp.where(inside, 2.0 * pos * (3.0 * clearance + 2.0 * pos) ** 2 / (clearance + pos) ** 3, 1.0)
    return jnp.where(inside, jnp.pi * modulus / 8.0 * jnp.sqrt(arg), 0.0)


class CylindricalLaw(eqx.Module):
    r"""The conformal (pin-in-hole) laws, selected by ``model``:

    * ``"liu"``: :math:`F_N = F_{Liu}(\delta)(1 + \hat\chi(c_r)\dot\delta/\dot\delta^{(-)})` with
      :func:`liu_force` (Liu et al. 2007) and, by default, the Lankarani-Nikravesh factor;
    * ``"bai-zhao"``: :math:`F_N = K_n(\delta)\delta^{1.5}(1 + \hat\chi(c_r)\dot\delta/
      \dot\delta^{(-)})` with :func:`bai_zhao_stiffness` (Bai & Zhao 2012) and, by default, the
      Qin-Lu factor.

    Attributes:
        model: ``"liu"`` or ``"bai-zhao"`` (static).
        restitution: :math:`c_r \in (0, 1]`.
        modulus: :math:`E^*` [Pa] or ``None`` (from the materials: :func:`effective_modulus`).
        hysteresis: name of the damping factor in :data:`HYSTERESIS_FACTORS` (static).
    """

    model: str = eqx.field(static=True)
    restitution: Scalar
    modulus: Scalar | None
    bearing_material: Material
    journal_material: Material
    hysteresis: str = eqx.field(static=True)

    stiffness_field = "modulus"

    def __init__(self, model="liu", restitution=0.9, modulus=None, hysteresis=None,
                 bearing_material: Material = STEEL, journal_material: Material = STEEL):
        if model not in ("liu", "bai-zhao"):
            raise ParameterError(f"cylindrical law model must be 'liu' or 'bai-zhao', got {model!r}")
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("modulus (E*)", modulus, low=0.0, low_open=True, unit="Pa")
        self.model = model
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.modulus = None if modulus is None else jnp.asarray(modulus, dtype=float)
        default = "lankarani-nikravesh" if model == "liu" else "qin-lu"
        self.hysteresis = _hysteresis_model(default if hysteresis is None else hysteresis)
        self.bearing_material, self.journal_material = bearing_material, journal_material

    def modulus_value(self):
        return effective_modulus(self.bearing_material, self.journal_material) if self.modulus is None else self.modulus

    def penetration(self, kin):
        return kin.delta

    def normal_force(self, kin, deltadot0):
        c = kin.radius_bearing - kin.radius_journal
        chi = HYSTERESIS_FACTORS[self.hysteresis](self.restitution)
        if self.model == "liu":
            elastic = liu_force(kin.delta, c, self.modulus_value(), kin.length)
            return jnp.maximum(elastic * (1.0 + chi * kin.deltadot / deltadot0), 0.0)
        k = bai_zhao_stiffness(kin.delta, c, self.modulus_value())
        return dissipative_hertz(kin.delta, kin.deltadot, deltadot0, k, chi, 1.5)
