r"""The Kelvin-Voigt linear spring-damper contact law (Goldsmith, *Impact*, 1960; Machado,
Moreira, Flores, Lankarani, Mech. Mach. Theory 53 (2012) 99-121, sec. 3)."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from .._errors import RESULTS, Rule, check_range
from .._types import ArrayLike, Scalar
from .._parameters import Parameter
from .base import AbstractNormalLaw, law_parameters


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
    ends the contact when the force vanishes, before the unclipped oscillator would return to
    :math:`\delta = 0`, so less energy is dissipated and the effective restitution of a single
    impact is higher than the nominal :math:`c_r` used to compute ``d`` (about 0.25 at
    :math:`c_r = 0.1`)."""
    force = stiffness * delta + damping * deltadot
    return jnp.where(delta > 0.0, jnp.maximum(force, 0.0), 0.0)


class KelvinVoigtLaw(AbstractNormalLaw):
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

    stiffness_parameter: ClassVar[str] = "stiffness"
    PARAMETERS: ClassVar[dict[str, Parameter]] = law_parameters(derived=False)
    name: ClassVar[str] = "kelvin-voigt"

    def __init__(self, stiffness: ArrayLike = 1e8, restitution: ArrayLike = 0.9, effective_mass: ArrayLike = 0.1):
        check_range("stiffness", stiffness, low=0.0, low_open=True, unit="N/m")
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("effective_mass", effective_mass, low=0.0, low_open=True, unit="kg")
        self.stiffness = jnp.asarray(stiffness, dtype=float)
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.effective_mass = jnp.asarray(effective_mass, dtype=float)

    def checks(self) -> tuple:
        """Restitution in (0, 1], stiffness > 0, effective mass > 0."""
        return (*super().checks(),
                Rule("stiffness k", self.stiffness, RESULTS.invalid_stiffness, low=0.0, low_open=True, unit="N/m"),
                Rule("effective_mass", self.effective_mass, RESULTS.invalid_parameter, low=0.0, low_open=True,
                     unit="kg"))

    def stiffness_value(self, radius_bearing, radius_journal):
        return self.stiffness

    def normal_force(self, kin, deltadot0):
        d = kelvin_voigt_damping(self.stiffness, self.restitution, self.effective_mass)
        return kelvin_voigt(kin.delta, kin.deltadot, self.stiffness, d)
