r"""Conformal (pin-in-hole) laws for a journal in a bearing: Liu et al.'s improved elastic
foundation model and Bai & Zhao's stiffness."""

from __future__ import annotations


import equinox as eqx
import jax.numpy as jnp

from .._errors import ParameterError, check_range
from .._types import Scalar
from .base import STEEL, AbstractModulusLaw, Material
from .hertz import HYSTERESIS_FACTORS, dissipative_hertz, hysteresis_model


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


class CylindricalLaw(AbstractModulusLaw):
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

    @property
    def name(self) -> str:
        return self.model

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
        self.hysteresis = hysteresis_model(default if hysteresis is None else hysteresis)
        self.bearing_material, self.journal_material = bearing_material, journal_material

    def hysteresis_factor(self):
        """:math:`\\hat\\chi(c_r)` of the law's hysteresis model (:meth:`AbstractNormalLaw.hysteresis_factor`)."""
        return HYSTERESIS_FACTORS[self.hysteresis](self.restitution)

    def normal_force(self, kin, deltadot0):
        c = kin.radius_bearing - kin.radius_journal
        chi = self.hysteresis_factor()
        if self.model == "liu":
            elastic = liu_force(kin.delta, c, self.modulus_value(), kin.length)
            return jnp.maximum(elastic * (1.0 + chi * kin.deltadot / deltadot0), 0.0)
        k = bai_zhao_stiffness(kin.delta, c, self.modulus_value())
        return dissipative_hertz(kin.delta, kin.deltadot, deltadot0, k, chi, 1.5)
