r"""Normal contact force laws for a journal inside its bearing.

All point-contact laws of the Hertz family have the form (Machado, Moreira, Flores,
Lankarani, "Compliant contact force models in multibody dynamics: evolution of the Hertz
contact theory", Mech. Mach. Theory 53 (2012) 99-121)

.. math::  F_N = K \delta^n \left(1 + \hat\chi(c_r)\,\frac{\dot\delta}{\dot\delta^{(-)}}\right),
           \qquad F_N \ge 0,

with penetration :math:`\delta` [m], its rate :math:`\dot\delta` [m/s] (positive while
approaching), the approach speed at the start of the current contact
:math:`\dot\delta^{(-)}` [m/s] (carried in the state, see :mod:`jaxclear.elements.memory`),
generalized stiffness :math:`K` [N/m^n], exponent :math:`n` (1.5 for Hertz) and a
hysteresis factor :math:`\hat\chi` that depends only on the nominal coefficient of
restitution :math:`c_r \in (0, 1]`. The laws differ only in :math:`\hat\chi`; they are
listed in :data:`HYSTERESIS_FACTORS` with their sources.

Every function here is pure, works on scalars (``vmap`` it for batches) and is safe for
automatic differentiation at and below :math:`\delta = 0`.
"""

from __future__ import annotations

from typing import Callable, ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._errors import RESULTS, ParameterError, Rule, check_range
from .._types import ArrayLike, Scalar
from .._parameters import Parameter
from .base import STEEL, AbstractNormalLaw, law_parameters, Material


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
    """Qin Zhiying, Lu Qishao, "Analysis of impact process model based on restitution coefficient",
    Journal of Dynamics and Control 4(4) (2006) 294-298 (in Chinese; the factor as tabulated by
    Machado et al., Mech. Mach. Theory 53 (2012) 99-121):
    :math:`\\hat\\chi = 3(1-c_r^2)\\,e^{2(1-c_r)}/4`."""
    return 0.75 * (1.0 - c_r**2) * jnp.exp(2.0 * (1.0 - c_r))


def chi_flores(c_r):
    """Flores, Machado, Silva, Martins, Multibody Syst. Dyn. 25 (2011) 357-375:
    :math:`\\hat\\chi = 8(1-c_r)/(5c_r)`."""
    return 8.0 * (1.0 - c_r) / (5.0 * c_r)


def chi_hu_guo(c_r):
    """Hu & Guo, "A dissipative contact force model for impact analysis in multibody
    dynamics", Multibody Syst. Dyn. 35 (2015) 131-151: :math:`\\hat\\chi = 3(1-c_r)/(4c_r)`."""
    return 0.75 * (1.0 - c_r) / c_r


def chi_carvalho_martins(c_r):
    """Carvalho & Martins, "Exact restitution and generalizations for the Hunt-Crossley contact
    model", Mech. Mach. Theory 139 (2019) 174-194, their closed-form approximation of the exact
    restitution relation: :math:`\\hat\\chi = 3(1-c_r)(11-c_r)/(2(1+9c_r))` (the effective
    restitution of a single impact is within 0.01 of :math:`c_r` from :math:`c_r` = 0.215 up and within
    1e-3 from 0.41 up; below, it levels off at 0.061 as :math:`c_r \\to 0` (:math:`\\hat\\chi \\to 16.5`):
    e = 0.129 at :math:`c_r` = 0.1, 0.067 at 0.01)."""
    return 1.5 * (1.0 - c_r) * (11.0 - c_r) / (1.0 + 9.0 * c_r)


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
    "hu-guo": chi_hu_guo,
    "carvalho-martins": chi_carvalho_martins,
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
# The law held by a clearance joint
# --------------------------------------------------------------------------------------


class ContactLaw(AbstractNormalLaw):
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

    stiffness_parameter: ClassVar[str] = "stiffness"
    PARAMETERS: ClassVar[dict[str, Parameter]] = law_parameters(exponent=True)

    @property
    def name(self) -> str:
        return self.model

    def checks(self) -> tuple:
        """Restitution in (0, 1], stiffness > 0 (when given), exponent > 0, the materials."""
        stiffness = 1.0 if self.stiffness is None else self.stiffness
        return (*super().checks(),
                Rule("stiffness K", stiffness, RESULTS.invalid_stiffness, low=0.0, low_open=True, unit="N/m^n"),
                Rule("exponent n", self.exponent, RESULTS.invalid_parameter, low=0.0, low_open=True),
                *self.bearing_material.checks("bearing_material"), *self.journal_material.checks("journal_material"))

    def stiffness_value(self, radius_bearing, radius_journal):
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

    def hysteresis_factor(self):
        """:math:`\\hat\\chi(c_r)` (:meth:`AbstractNormalLaw.hysteresis_factor`)."""
        return self.hysteresis

    def normal_force(self, kin, deltadot0):
        """Normal force [N] for the joint kinematics ``kin`` and the (floored) impact speed."""
        stiffness = self.stiffness_value(kin.radius_bearing, kin.radius_journal)
        return dissipative_hertz(kin.delta, kin.deltadot, deltadot0, stiffness, self.hysteresis, self.exponent)


def hysteresis_model(name: str):
    if name not in HYSTERESIS_FACTORS:
        raise ParameterError(f"unknown hysteresis model {name!r}; valid: {sorted(HYSTERESIS_FACTORS)}")
    return name


