r"""Tangential (friction) force laws at the contact point of a clearance joint.

Each law is a pure function and a final :class:`~jaxclear.contact.base.AbstractFriction`
subclass holding its parameters; :func:`Friction` builds one by name. Each law maps the tangential slip velocity :math:`v_T` [m/s] (journal relative to bearing,
along the tangent :math:`t`) and the normal force :math:`F_N \ge 0` [N] to the tangential
force :math:`F_T` [N] acting on the journal along :math:`t` (the bearing gets the opposite);
:math:`F_T v_T \le 0` always, so friction never does positive work.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._errors import RESULTS, ParameterError, Rule, check_range, is_concrete
from .._types import ArrayLike, Scalar
from .base import AbstractFriction
from .bristle import DahlFriction, LuGreFriction
from .friction_laws import BrownMcPheeFriction, StribeckFriction, ThrelfallFriction, ViscousFriction


def ambrosio(v_t, normal_force, mu, v0=1e-4, v1=1e-3):
    r"""Ambrósio's modified Coulomb law (J. Ambrósio, "Impact of rigid and flexible multibody
    systems: deformation description and contact models", in Virtual Nonlinear Multibody
    Systems, NATO ASI 103 (2003) 57-81):

    .. math:: F_T = -\mu\,c_d\,F_N\,\mathrm{sign}(v_T),\quad
              c_d = \begin{cases} 0 & |v_T| < v_0\\ (|v_T|-v_0)/(v_1-v_0) & v_0\le|v_T|\le v_1\\
              1 & |v_T| > v_1\end{cases}

    The dynamic correction :math:`c_d` removes the discontinuity at zero slip
    (typical :math:`v_0 = 10^{-4}`, :math:`v_1 = 10^{-3}` m/s).
    """
    speed = jnp.abs(v_t)
    c_d = jnp.clip((speed - v0) / (v1 - v0), 0.0, 1.0)
    return -mu * c_d * normal_force * jnp.sign(v_t)


def coulomb(v_t, normal_force, mu):
    r"""Plain Coulomb friction :math:`F_T = -\mu F_N \mathrm{sign}(v_T)` (discontinuous at 0)."""
    return -mu * normal_force * jnp.sign(v_t)


def smooth_coulomb(v_t, normal_force, mu, v_s=1e-3):
    r"""Regularized Coulomb friction :math:`F_T = -\mu F_N \tanh(v_T/v_s)`, smooth for gradients
    (a standard regularization, e.g. Pennestrì et al., Nonlinear Dyn. 83 (2016) 1785-1801)."""
    return -mu * normal_force * jnp.tanh(v_t / v_s)


def _coefficient(coefficient):
    check_range("friction (coefficient mu)", coefficient, low=0.0)
    return jnp.asarray(coefficient, dtype=float)


class AmbrosioFriction(AbstractFriction):
    r"""Ambrósio's modified Coulomb law (:func:`ambrosio`): ``coefficient`` :math:`\mu \ge 0`,
    velocity tolerances ``v0``, ``v1`` [m/s], :math:`0 \le v_0 < v_1`."""

    coefficient: Scalar
    v0: Scalar
    v1: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0, v0: ArrayLike = 1e-4, v1: ArrayLike = 1e-3):
        check_range("v0 (Ambrosio lower slip speed)", v0, low=0.0, unit="m/s")
        check_range("v1 (Ambrosio upper slip speed)", v1, low=0.0, low_open=True, unit="m/s")
        if is_concrete((v0, v1)) and float(v1) <= float(v0):
            raise ParameterError(f"v1 = {float(v1):g} m/s must exceed v0 = {float(v0):g} m/s")
        self.coefficient = _coefficient(coefficient)
        self.v0 = jnp.asarray(v0, dtype=float)
        self.v1 = jnp.asarray(v1, dtype=float)

    def checks(self) -> tuple:
        """Coefficient >= 0, 0 <= v0 < v1."""
        return (*super().checks(), Rule("friction v0", self.v0, RESULTS.invalid_parameter, low=0.0, unit="m/s"),
                Rule("friction v1 - v0", self.v1 - self.v0, RESULTS.invalid_parameter, low=0.0, low_open=True,
                     unit="m/s"))

    def __call__(self, v_t, normal_force):
        return ambrosio(v_t, normal_force, self.coefficient, self.v0, self.v1)

    def kinks(self, v_t):
        """The ends of the ramps: :math:`|v_T| = v_0` and :math:`|v_T| = v_1`."""
        return jnp.stack([v_t - self.v1, v_t - self.v0, v_t + self.v0, v_t + self.v1])


class CoulombFriction(AbstractFriction):
    r"""Plain Coulomb friction (:func:`coulomb`), ``coefficient`` :math:`\mu \ge 0`."""

    coefficient: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0):
        self.coefficient = _coefficient(coefficient)

    def __call__(self, v_t, normal_force):
        return coulomb(v_t, normal_force, self.coefficient)

    def kinks(self, v_t):
        """The sign change at zero slip."""
        return jnp.stack([v_t])


class SmoothCoulombFriction(AbstractFriction):
    r"""Regularized Coulomb friction (:func:`smooth_coulomb`), ``coefficient`` :math:`\mu \ge 0`,
    regularization speed ``v_s`` [m/s] > 0."""

    coefficient: Scalar
    v_s: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0, v_s: ArrayLike = 1e-3):
        check_range("v_s (regularization speed)", v_s, low=0.0, low_open=True, unit="m/s")
        self.coefficient = _coefficient(coefficient)
        self.v_s = jnp.asarray(v_s, dtype=float)

    def checks(self) -> tuple:
        """Coefficient >= 0, v_s > 0."""
        return (*super().checks(), Rule("friction v_s", self.v_s, RESULTS.invalid_parameter, low=0.0, low_open=True,
                                        unit="m/s"))

    def __call__(self, v_t, normal_force):
        return smooth_coulomb(v_t, normal_force, self.coefficient, self.v_s)


class NoFriction(AbstractFriction):
    """No tangential force (``coefficient`` kept for a uniform parameter set)."""

    coefficient: Scalar

    def __init__(self, coefficient: ArrayLike = 0.0):
        self.coefficient = _coefficient(coefficient)

    def __call__(self, v_t, normal_force):
        return 0.0 * v_t


#: name -> (class, the parameters of :func:`Friction` it takes)
FRICTION_MODELS = {
    "ambrosio": (AmbrosioFriction, ("v0", "v1")),
    "coulomb": (CoulombFriction, ()),
    "smooth": (SmoothCoulombFriction, ("v_s",)),
    "none": (NoFriction, ()),
    "viscous": (ViscousFriction, ("viscous",)),
    "stribeck": (StribeckFriction, ("static", "v_stribeck", "stribeck_exponent", "viscous")),
    "threlfall": (ThrelfallFriction, ("v_threlfall",)),
    "brown-mcphee": (BrownMcPheeFriction, ("static", "v_transition", "viscous")),
    "dahl": (DahlFriction, ("bristle_stiffness",)),
    "lugre": (LuGreFriction, ("static", "v_stribeck", "bristle_stiffness", "bristle_damping", "viscous")),
}


def Friction(  # noqa: N802 (the old class name, kept as the one factory)
    coefficient: ArrayLike = 0.0,
    model: str = "ambrosio",
    v0: ArrayLike = 1e-4,
    v1: ArrayLike = 1e-3,
    v_s: ArrayLike = 1e-3,
    static: ArrayLike | None = None,
    viscous: ArrayLike = 0.0,
    v_stribeck: ArrayLike = 1e-3,
    stribeck_exponent: ArrayLike = 2.0,
    v_threlfall: ArrayLike = 1e-3,
    v_transition: ArrayLike = 1e-3,
    bristle_stiffness: ArrayLike = 1e5,
    bristle_damping: ArrayLike = 0.0,
) -> AbstractFriction:
    r"""A friction law by name (:data:`FRICTION_MODELS`) with (kinetic) coefficient
    :math:`\mu \ge 0`: ``ambrosio`` (default), ``coulomb``, ``smooth``, ``none``, ``viscous``,
    ``stribeck``, ``threlfall``, ``brown-mcphee`` (:mod:`~jaxclear.contact.friction_laws`) and the
    bristle laws ``dahl``, ``lugre`` (:mod:`~jaxclear.contact.bristle`). Parameters, each used only
    by the laws that name it: ``v0``, ``v1`` [m/s] Ambrósio's tolerances; ``v_s`` [m/s] the
    regularization speed of ``smooth``; ``static`` :math:`\mu_s \ge \mu` (``None``: equal);
    ``viscous`` :math:`\mu_v` [s/m]; ``v_stribeck`` [m/s] and ``stribeck_exponent``; ``v_threlfall``
    [m/s]; ``v_transition`` [m/s] (Brown-McPhee); ``bristle_stiffness`` :math:`\sigma_0` [1/m] and
    ``bristle_damping`` :math:`\sigma_1` [s/m] per newton of normal force. Ambrósio's and the
    smoothing speeds are validated always, the others by the law that uses them."""
    if model not in FRICTION_MODELS:
        raise ParameterError(f"unknown friction model {model!r}; valid: {list(FRICTION_MODELS)}")
    check_range("v0 (Ambrosio lower slip speed)", v0, low=0.0, unit="m/s")
    check_range("v1 (Ambrosio upper slip speed)", v1, low=0.0, low_open=True, unit="m/s")
    check_range("v_s (regularization speed)", v_s, low=0.0, low_open=True, unit="m/s")
    cls, names = FRICTION_MODELS[model]
    given = {"v0": v0, "v1": v1, "v_s": v_s, "static": static, "viscous": viscous, "v_stribeck": v_stribeck,
             "stribeck_exponent": stribeck_exponent, "v_threlfall": v_threlfall, "v_transition": v_transition,
             "bristle_stiffness": bristle_stiffness, "bristle_damping": bristle_damping}
    return cls(coefficient, **{k: given[k] for k in names})


def friction_name(law: AbstractFriction) -> str:
    """The name :func:`Friction` knows ``law`` by."""
    for name, (cls, _) in FRICTION_MODELS.items():
        if type(law) is cls:
            return name
    return type(law).__name__
