r"""The step-damped impact force of commercial multibody codes (the ``IMPACT`` function of
MSC Adams; the same form is offered by RecurDyn and Simpack): a nonlinear spring plus a
damper whose coefficient ramps up with a cubic step over the first ``damping_depth`` of
penetration,

.. math:: F_N = \max\left(K\delta^n + \mathrm{step}(\delta; 0, 0, d_{max}, c_{max})\,\dot\delta,\ 0\right),
          \qquad \delta > 0,

with the cubic step :math:`\mathrm{step}(x; x_0, h_0, x_1, h_1) = h_0 + (h_1 - h_0) a^2(3 - 2a)`,
:math:`a = \mathrm{clip}((x - x_0)/(x_1 - x_0), 0, 1)` (MSC Adams/Solver reference, functions
``IMPACT`` and ``STEP``; Adams writes the rate of the gap, hence its minus sign; here
:math:`\dot\delta > 0` while approaching). The ramp makes the force continuous at contact onset
without the impact memory: the law does not use :math:`\dot\delta^{(-)}` and has no nominal
restitution (the effective restitution follows from K, n, c_max, d_max, the mass and the
impact speed; see the tests for an independent integration).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from .._errors import RESULTS, Rule, check_range
from .._types import ArrayLike, Scalar
from .._parameters import Parameter
from .base import STEEL, AbstractNormalLaw, law_parameters, Material
from .hertz import cylindrical_stiffness, positive_power


def cubic_step(x, x0, h0, x1, h1):
    r"""The cubic STEP of multibody codes: :math:`h_0` for :math:`x \le x_0`, :math:`h_1` for
    :math:`x \ge x_1`, :math:`h_0 + (h_1 - h_0)a^2(3 - 2a)` between, :math:`a = (x-x_0)/(x_1-x_0)`
    (C1: zero slope at both ends)."""
    a = jnp.clip((x - x0) / (x1 - x0), 0.0, 1.0)
    return h0 + (h1 - h0) * a * a * (3.0 - 2.0 * a)


def step_damped_impact(delta, deltadot, stiffness, exponent, max_damping, damping_depth):
    r""":math:`F_N = \max(K\delta^n + \mathrm{step}(\delta; 0, 0, d_{max}, c_{max})\dot\delta, 0)`
    for :math:`\delta > 0`, else 0.

    Args:
        delta: penetration [m]; deltadot: its rate [m/s] (> 0 approaching).
        stiffness: K [N/m^n]; exponent: n [-].
        max_damping: :math:`c_{max}` [N s/m]; damping_depth: :math:`d_{max}` [m] > 0.
    """
    damping = cubic_step(delta, 0.0, 0.0, damping_depth, max_damping)
    force = stiffness * positive_power(delta, exponent) + damping * deltadot
    return jnp.where(delta > 0.0, jnp.maximum(force, 0.0), 0.0)


class StepDampedImpactLaw(AbstractNormalLaw):
    """The step-damped impact force (:func:`step_damped_impact`), registry name ``"impact"``.

    Attributes:
        stiffness: K [N/m^n] > 0, or ``None`` (from the materials and radii with
            :func:`~jaxclear.contact.hertz.cylindrical_stiffness`, as for the Hertz family).
        exponent: n > 0 (Adams suggests n > 1; 1.5 for Hertzian contact).
        max_damping: :math:`c_{max}` [N s/m] >= 0 (commonly 0.1 % to 1 % of K in N/m).
        damping_depth: :math:`d_{max}` [m] > 0, the penetration at which full damping is reached
            (commonly 0.01 mm to 0.1 mm).
        bearing_material, journal_material: used when ``stiffness`` is ``None``.

    ``restitution`` is accepted (every law of the registry takes it) and range-checked but not
    used by the force: this law's dissipation is set by :math:`c_{max}` and :math:`d_{max}`.
    """

    restitution: Scalar
    stiffness: Scalar | None
    exponent: Scalar
    max_damping: Scalar
    damping_depth: Scalar
    bearing_material: Material
    journal_material: Material

    stiffness_parameter: ClassVar[str] = "stiffness"
    PARAMETERS: ClassVar[dict[str, Parameter]] = law_parameters(exponent=True)
    name: ClassVar[str] = "impact"

    def __init__(self, restitution: ArrayLike = 1.0, stiffness: ArrayLike | None = None, exponent: ArrayLike = 1.5, max_damping: ArrayLike = 1e4,
                 damping_depth: ArrayLike = 1e-5, bearing_material: Material = STEEL,
                 journal_material: Material = STEEL):
        check_range("restitution", restitution, low=0.0, high=1.0, low_open=True)
        check_range("stiffness", stiffness, low=0.0, low_open=True, unit="N/m^n")
        check_range("exponent", exponent, low=0.0, low_open=True)
        check_range("max_damping (c_max)", max_damping, low=0.0, unit="N s/m")
        check_range("damping_depth (d_max)", damping_depth, low=0.0, low_open=True, unit="m")
        self.restitution = jnp.asarray(restitution, dtype=float)
        self.stiffness = None if stiffness is None else jnp.asarray(stiffness, dtype=float)
        self.exponent = jnp.asarray(exponent, dtype=float)
        self.max_damping = jnp.asarray(max_damping, dtype=float)
        self.damping_depth = jnp.asarray(damping_depth, dtype=float)
        self.bearing_material, self.journal_material = bearing_material, journal_material

    def checks(self) -> tuple:
        """Restitution in (0, 1], stiffness > 0 (when given), exponent > 0, c_max >= 0, d_max > 0, the materials."""
        stiffness = 1.0 if self.stiffness is None else self.stiffness
        return (*super().checks(),
                Rule("stiffness K", stiffness, RESULTS.invalid_stiffness, low=0.0, low_open=True, unit="N/m^n"),
                Rule("exponent n", self.exponent, RESULTS.invalid_parameter, low=0.0, low_open=True),
                Rule("max_damping c_max", self.max_damping, RESULTS.invalid_parameter, low=0.0),
                Rule("damping_depth d_max", self.damping_depth, RESULTS.invalid_parameter, low=0.0, low_open=True,
                     unit="m"),
                *self.bearing_material.checks("bearing_material"), *self.journal_material.checks("journal_material"))

    def stiffness_value(self, radius_bearing, radius_journal):
        """K [N/m^n]: the given one, or the cylindrical formula from the materials and radii."""
        if self.stiffness is not None:
            return self.stiffness
        return cylindrical_stiffness(radius_bearing, radius_journal, self.bearing_material.compliance,
                                     self.journal_material.compliance)

    def normal_force(self, kin, deltadot0):
        """Normal force [N]; ``deltadot0`` is not used."""
        k = self.stiffness_value(kin.radius_bearing, kin.radius_journal)
        return step_damped_impact(kin.delta, kin.deltadot, k, self.exponent, self.max_damping, self.damping_depth)
