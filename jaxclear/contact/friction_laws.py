r"""Static (memoryless) friction laws beyond Coulomb: viscous, Stribeck, Karnopp, Threlfall,
Brown-McPhee. Overview of all of them: Marques, Flores, Claro, Lankarani, "A survey and
comparison of several friction force models for dynamic analysis of multibody mechanical
systems", Nonlinear Dyn. 86 (2016) 1407-1443; Pennestrì, Rossi, Salvini, Valentini, "Review and
comparison of dry friction force models", Nonlinear Dyn. 83 (2016) 1785-1801.

Conventions as in :mod:`jaxclear.contact.friction`: slip :math:`v` [m/s] of the journal relative
to the bearing along the tangent, normal force :math:`F_N \ge 0` [N], returned force :math:`F_T`
[N] on the journal, :math:`F_T v \le 0`. Every term is proportional to :math:`F_N` (a viscous
coefficient :math:`\mu_v` is in s/m), so no law acts out of contact. Every function is pure, scalar
(``vmap`` it) and differentiable away from the discontinuities it states.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from .._errors import RESULTS, ParameterError, Rule, check_range, is_concrete
from .._types import ArrayLike, Scalar
from .._parameters import Parameter
from .base import AbstractFriction, friction_parameters


def viscous(v_t, normal_force, mu, mu_v):
    r"""Coulomb plus viscous friction :math:`F_T = -F_N(\mu\,\mathrm{sign}(v) + \mu_v v)`
    (Marques et al. 2016, sec. 3.2); :math:`\mu = 0` is pure viscous friction."""
    return -normal_force * (mu * jnp.sign(v_t) + mu_v * v_t)


def stribeck_coefficient(v_t, mu_k, mu_s, v_stribeck, exponent=2.0):
    r"""The Stribeck curve's coefficient :math:`g(v) = \mu_k + (\mu_s - \mu_k)\exp(-(|v|/v_s)^i)`
    [-] (Stribeck 1902; Armstrong-Hélouvry, Dupont, Canudas de Wit, Automatica 30 (1994) 1083-1138;
    shared by :func:`stribeck` and the LuGre model)."""
    ratio = jnp.abs(v_t) / v_stribeck
    safe = jnp.where(ratio > 0.0, ratio, 1.0)
    power = jnp.where(ratio > 0.0, safe**exponent, 0.0)
    return mu_k + (mu_s - mu_k) * jnp.exp(-power)


def stribeck(v_t, normal_force, mu_k, mu_s, v_stribeck, exponent=2.0, mu_v=0.0):
    r"""Stribeck friction (Coulomb + static peak + viscous):
    :math:`F_T = -F_N(g(v)\,\mathrm{sign}(v) + \mu_v v)` with :func:`stribeck_coefficient` g; it is
    the steady-state curve of the LuGre model (:mod:`jaxclear.contact.bristle`) for ``exponent`` 2.
    Discontinuous at :math:`v = 0` (the force there is 0)."""
    g = stribeck_coefficient(v_t, mu_k, mu_s, v_stribeck, exponent)
    return -normal_force * (g * jnp.sign(v_t) + mu_v * v_t)


def karnopp(v_t, normal_force, applied, mu_k, mu_s, v_stick, mu_v=0.0):
    r"""Karnopp's stick band (D. Karnopp, "Computer simulation of stick-slip friction in mechanical
    dynamic systems", J. Dyn. Syst. Meas. Control 107 (1985) 100-103): for :math:`|v| < D_v` the
    friction balances the tangential load ``applied`` [N] (the sum of the other tangential forces
    on the sliding body) up to the static limit, :math:`F_T = -\mathrm{clip}(F_a, -\mu_s F_N,
    \mu_s F_N)`; outside it :math:`F_T = -F_N(\mu_k\mathrm{sign}(v) + \mu_v v)`."""
    stick = jnp.abs(v_t) < v_stick
    limit = mu_s * normal_force
    return jnp.where(stick, -jnp.clip(applied, -limit, limit), viscous(v_t, normal_force, mu_k, mu_v))


def threlfall(v_t, normal_force, mu, v_threlfall):
    r"""Threlfall's smoothed Coulomb law (D.C. Threlfall, "The inclusion of Coulomb friction in
    mechanisms programs with particular reference to DRAM", Mech. Mach. Theory 13 (1978) 475-483):
    :math:`F_T = -\mu F_N(1 - e^{-3|v|/v_0})\mathrm{sign}(v)` (95 % of the Coulomb force at
    :math:`v_0`; the single exponential over all speeds is the variant used here)."""
    return -mu * normal_force * (1.0 - jnp.exp(-3.0 * jnp.abs(v_t) / v_threlfall)) * jnp.sign(v_t)


def brown_mcphee(v_t, normal_force, mu_k, mu_s, v_transition, mu_v=0.0):
    r"""Brown & McPhee, "A continuous velocity-based friction model for dynamics and control with
    physically meaningful parameters", J. Comput. Nonlinear Dyn. 11 (2016) 054502:

    .. math:: F_T = -F_N\left[\mu_k\tanh\frac{4v}{v_t} + (\mu_s - \mu_k)\frac{v/v_t}
              {\left(\tfrac14(v/v_t)^2 + \tfrac34\right)^2} + \mu_v v\right],

    smooth, with its static peak :math:`\approx\mu_s F_N` at :math:`|v| = v_t` (viscous term
    proportional to :math:`F_N` here)."""
    x = v_t / v_transition
    return -normal_force * (mu_k * jnp.tanh(4.0 * x) + (mu_s - mu_k) * x / (0.25 * x * x + 0.75) ** 2 + mu_v * v_t)


# --------------------------------------------------------------------------------------
# Parameter checks shared by the law classes (here and in bristle.py)
# --------------------------------------------------------------------------------------


def check_static(coefficient, static):
    """Raise :class:`~jaxclear.ParameterError` unless ``static`` (mu_s) >= ``coefficient`` (mu_k);
    returns mu_s as an array (``None`` means mu_s = mu_k)."""
    static = coefficient if static is None else static
    check_range("static (static friction coefficient mu_s)", static, low=0.0)
    if is_concrete((coefficient, static)) and float(static) < float(coefficient):
        raise ParameterError(f"static friction coefficient mu_s = {float(static):g} must be >= the kinetic "
                             f"coefficient mu = {float(coefficient):g} (allowed range [mu, inf))")
    return jnp.asarray(static, dtype=float)


def speed(name, value):
    """A positive speed parameter [m/s] as an array (checked)."""
    check_range(name, value, low=0.0, low_open=True, unit="m/s")
    return jnp.asarray(value, dtype=float)


def viscous_coefficient(value):
    """The viscous coefficient mu_v [s/m] >= 0 as an array (checked)."""
    check_range("viscous (viscous coefficient mu_v)", value, low=0.0, unit="s/m")
    return jnp.asarray(value, dtype=float)


def static_ok(law) -> Rule:
    """mu_s >= mu_k >= 0 (``invalid_friction``)."""
    return Rule("static mu_s - coefficient mu_k", law.static - law.coefficient, RESULTS.invalid_friction, low=0.0)


def viscous_ok(law) -> Rule:
    """mu_v >= 0 (``invalid_friction``)."""
    return Rule("viscous mu_v", law.viscous, RESULTS.invalid_friction, low=0.0, unit="s/m")


def speed_ok(name: str, value) -> Rule:
    """A characteristic speed of a friction law > 0 [m/s] (``invalid_parameter``)."""
    return Rule(name, value, RESULTS.invalid_parameter, low=0.0, low_open=True, unit="m/s")


def kinetic(coefficient):
    check_range("friction (coefficient mu)", coefficient, low=0.0)
    return jnp.asarray(coefficient, dtype=float)


# --------------------------------------------------------------------------------------
# Law classes
# --------------------------------------------------------------------------------------


class ViscousFriction(AbstractFriction):
    r"""Coulomb plus viscous friction (:func:`viscous`): ``coefficient`` :math:`\mu \ge 0`,
    ``viscous`` :math:`\mu_v \ge 0` [s/m]."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters("friction_viscous")

    coefficient: Scalar
    viscous: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0, viscous: ArrayLike = 0.0):
        self.coefficient = kinetic(coefficient)
        self.viscous = viscous_coefficient(viscous)

    def checks(self) -> tuple:
        """mu >= 0, mu_v >= 0."""
        return (*super().checks(), viscous_ok(self))

    def __call__(self, v_t, normal_force):
        return viscous(v_t, normal_force, self.coefficient, self.viscous)

    def kinks(self, v_t):
        """The sign change at zero slip."""
        return jnp.stack([v_t])


class StribeckFriction(AbstractFriction):
    r"""Stribeck friction (:func:`stribeck`): kinetic ``coefficient`` :math:`\mu_k \ge 0`,
    ``static`` :math:`\mu_s \ge \mu_k` (``None``: equal), Stribeck speed ``v_stribeck`` > 0 [m/s],
    ``stribeck_exponent`` > 0 (2: Gaussian), ``viscous`` :math:`\mu_v \ge 0` [s/m]."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters(
        "friction_static", "v_stribeck", "stribeck_exponent", "friction_viscous")

    coefficient: Scalar
    static: Scalar
    v_stribeck: Scalar
    stribeck_exponent: Scalar
    viscous: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0, static: ArrayLike | None = None, v_stribeck: ArrayLike = 1e-3,
                 stribeck_exponent: ArrayLike = 2.0, viscous: ArrayLike = 0.0):
        self.coefficient = kinetic(coefficient)
        self.static = check_static(coefficient, static)
        self.v_stribeck = speed("v_stribeck (Stribeck speed)", v_stribeck)
        check_range("stribeck_exponent", stribeck_exponent, low=0.0, low_open=True)
        self.stribeck_exponent = jnp.asarray(stribeck_exponent, dtype=float)
        self.viscous = viscous_coefficient(viscous)

    def checks(self) -> tuple:
        """mu_s >= mu_k >= 0, mu_v >= 0 (``invalid_friction``); v_stribeck, exponent > 0."""
        return (*super().checks(), static_ok(self), viscous_ok(self), speed_ok("v_stribeck", self.v_stribeck),
                Rule("stribeck_exponent", self.stribeck_exponent, RESULTS.invalid_parameter, low=0.0, low_open=True))

    def __call__(self, v_t, normal_force):
        return stribeck(v_t, normal_force, self.coefficient, self.static, self.v_stribeck, self.stribeck_exponent,
                        self.viscous)

    def kinks(self, v_t):
        """The sign change at zero slip."""
        return jnp.stack([v_t])


class KarnoppFriction(AbstractFriction):
    r"""Karnopp's stick band (:func:`karnopp`): ``coefficient`` :math:`\mu_k`, ``static``
    :math:`\mu_s \ge \mu_k`, band half-width ``v_stick`` :math:`D_v` > 0 [m/s], ``viscous``
    :math:`\mu_v` [s/m]. Call it with the tangential load as third argument. It is offered for
    models that supply that load, not in ``FRICTION_MODELS``: every force element refuses it with a
    :class:`~jaxclear.ParameterError` (``needs_applied_load``;
    :func:`~jaxclear.contact.base.element_friction`). Why: the stick force is the tangential
    component of all the other forces on the journal or slider, constraint reactions and the
    inertia of the linked bodies included, which depend on the friction force itself; only the
    solve of the whole system knows them, while an element computes its contact from its own
    kinematics. Taking the applied loads alone would be Karnopp's law only for a free body.
    LuGre (:mod:`~jaxclear.contact.bristle`) sticks under a load below its static limit and works
    in every joint."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters("friction_static", "friction_viscous")

    coefficient: Scalar
    static: Scalar
    v_stick: Scalar
    viscous: Scalar
    needs_applied_load: ClassVar[bool] = True

    def __init__(self, coefficient: ArrayLike = 0.0, static: ArrayLike | None = None, v_stick: ArrayLike = 1e-4,
                 viscous: ArrayLike = 0.0):
        self.coefficient = kinetic(coefficient)
        self.static = check_static(coefficient, static)
        self.v_stick = speed("v_stick (Karnopp band half-width)", v_stick)
        self.viscous = viscous_coefficient(viscous)

    def checks(self) -> tuple:
        """mu_s >= mu_k >= 0, mu_v >= 0 (``invalid_friction``); v_stick > 0."""
        return (*super().checks(), static_ok(self), viscous_ok(self), speed_ok("v_stick", self.v_stick))

    def __call__(self, v_t, normal_force, applied=0.0):
        return karnopp(v_t, normal_force, applied, self.coefficient, self.static, self.v_stick, self.viscous)


class ThrelfallFriction(AbstractFriction):
    r"""Threlfall's law (:func:`threlfall`): ``coefficient`` :math:`\mu \ge 0`, ``v_threlfall``
    :math:`v_0` > 0 [m/s]."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters("v_threlfall")

    coefficient: Scalar
    v_threlfall: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0, v_threlfall: ArrayLike = 1e-3):
        self.coefficient = kinetic(coefficient)
        self.v_threlfall = speed("v_threlfall (Threlfall speed)", v_threlfall)

    def checks(self) -> tuple:
        """mu >= 0, v_threlfall > 0."""
        return (*super().checks(), speed_ok("v_threlfall", self.v_threlfall))

    def __call__(self, v_t, normal_force):
        return threlfall(v_t, normal_force, self.coefficient, self.v_threlfall)


class BrownMcPheeFriction(AbstractFriction):
    r"""Brown-McPhee law (:func:`brown_mcphee`): kinetic ``coefficient`` :math:`\mu_k`, ``static``
    :math:`\mu_s \ge \mu_k`, transition speed ``v_transition`` > 0 [m/s], ``viscous`` [s/m]."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters(
        "friction_static", "v_transition", "friction_viscous")

    coefficient: Scalar
    static: Scalar
    v_transition: Scalar
    viscous: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0, static: ArrayLike | None = None,
                 v_transition: ArrayLike = 1e-3, viscous: ArrayLike = 0.0):
        self.coefficient = kinetic(coefficient)
        self.static = check_static(coefficient, static)
        self.v_transition = speed("v_transition (Brown-McPhee transition speed)", v_transition)
        self.viscous = viscous_coefficient(viscous)

    def checks(self) -> tuple:
        """mu_s >= mu_k >= 0, mu_v >= 0 (``invalid_friction``); v_transition > 0."""
        return (*super().checks(), static_ok(self), viscous_ok(self), speed_ok("v_transition", self.v_transition))

    def __call__(self, v_t, normal_force):
        return brown_mcphee(v_t, normal_force, self.coefficient, self.static, self.v_transition, self.viscous)

