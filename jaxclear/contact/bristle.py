r"""Dynamic friction laws with an internal bristle state: Dahl and LuGre.

The contact is pictured as elastic bristles of mean deflection :math:`z` [m]; the friction force
follows the deflection, so the law has memory (pre-sliding displacement, true sticking under a
load below the static limit, hysteresis). The element that uses the law carries :math:`z` in
the state vector and integrates its rate (``force_and_rate``).

Normalized form used here: every force is proportional to the normal force :math:`F_N`, with a
bristle stiffness :math:`\sigma_0` [1/m] and damping :math:`\sigma_1` [s/m] per newton of normal
force (the absolute stiffness is :math:`\sigma_0 F_N` [N/m]), so that the sliding limits are
:math:`\mu F_N` whatever :math:`F_N`, and the laws vanish out of contact. Slip :math:`v` [m/s] of the
journal relative to the bearing; the returned force acts on the journal, opposing the deflection.

* Dahl (P.R. Dahl, "A solid friction model", Aerospace Corp. TOR-0158(3107-18)-1, 1968; exponent 1):
  :math:`\dot z = v - \sigma_0|v|z/\mu`, :math:`F_T = -F_N\sigma_0 z`; steady sliding gives Coulomb,
  :math:`F_T = -\mu F_N\,\mathrm{sign}(v)`.
* LuGre (Canudas de Wit, Olsson, Åström, Lischinsky, "A new model for control of systems with
  friction", IEEE Trans. Autom. Control 40 (1995) 419-425):
  :math:`\dot z = v - \sigma_0|v|z/g(v)`, :math:`F_T = -F_N(\sigma_0 z + \sigma_1\dot z + \mu_v v)`,
  :math:`g(v) = \mu_k + (\mu_s - \mu_k)e^{-(v/v_s)^2}`; steady sliding gives the Stribeck curve
  (:func:`~jaxclear.contact.friction_laws.stribeck` with exponent 2).

``law(v, F_N)`` (the memoryless call) returns the steady-sliding force; the bristle dynamics
need ``force_and_rate`` with the state.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from .._errors import RESULTS, Rule, check_range
from .._types import ArrayLike, Scalar
from .._parameters import Parameter
from .base import AbstractFriction, friction_parameters
from .friction_laws import (check_static, kinetic, speed, speed_ok, static_ok, stribeck, stribeck_coefficient,
                            viscous_coefficient, viscous_ok)


def _stiffness(value):
    check_range("bristle_stiffness (sigma_0, per newton of normal force)", value, low=0.0, low_open=True, unit="1/m")
    return jnp.asarray(value, dtype=float)


def dahl_rate(z, v_t, mu, sigma0):
    r"""Dahl bristle rate :math:`\dot z = v - \sigma_0|v|z/\mu` [m/s]; 0 for :math:`\mu = 0` (the
    bristle never loads and the law gives no force)."""
    safe = jnp.where(mu > 0.0, mu, 1.0)
    return jnp.where(mu > 0.0, v_t - sigma0 * jnp.abs(v_t) * z / safe, 0.0)


def dahl_force(z, normal_force, sigma0):
    r"""Dahl force on the journal :math:`F_T = -F_N\sigma_0 z` [N]."""
    return -normal_force * sigma0 * z


def lugre_rate(z, v_t, mu_k, mu_s, v_stribeck, sigma0):
    r"""LuGre bristle rate :math:`\dot z = v - \sigma_0|v|z/g(v)` [m/s]
    (:func:`~jaxclear.contact.friction_laws.stribeck_coefficient` g, exponent 2; 0 where
    :math:`g = 0`, i.e. without friction)."""
    g = stribeck_coefficient(v_t, mu_k, mu_s, v_stribeck, 2.0)
    safe = jnp.where(g > 0.0, g, 1.0)
    return jnp.where(g > 0.0, v_t - sigma0 * jnp.abs(v_t) * z / safe, 0.0)


def lugre_force(z, z_rate, v_t, normal_force, sigma0, sigma1, mu_v):
    r"""LuGre force on the journal :math:`F_T = -F_N(\sigma_0 z + \sigma_1\dot z + \mu_v v)` [N]."""
    return -normal_force * (sigma0 * z + sigma1 * z_rate + mu_v * v_t)


class DahlFriction(AbstractFriction):
    r"""Dahl's law (:func:`dahl_rate`, :func:`dahl_force`): ``coefficient`` :math:`\mu > 0` (the
    sliding limit), ``bristle_stiffness`` :math:`\sigma_0` > 0 [1/m]. One internal state."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters("bristle_stiffness")

    coefficient: Scalar
    bristle_stiffness: Scalar
    state_size: ClassVar[int] = 1

    def __init__(self, coefficient: ArrayLike = 0.0, bristle_stiffness: ArrayLike = 1e5):
        self.coefficient = kinetic(coefficient)
        self.bristle_stiffness = _stiffness(bristle_stiffness)

    def checks(self) -> tuple:
        """mu >= 0, sigma_0 > 0 (``invalid_friction``)."""
        return (*super().checks(), Rule("bristle_stiffness sigma_0", self.bristle_stiffness, RESULTS.invalid_friction,
                                        low=0.0, low_open=True, unit="1/m"))

    def force_and_rate(self, state, v_t, normal_force):
        z = state[0]
        rate = dahl_rate(z, v_t, self.coefficient, self.bristle_stiffness)
        return dahl_force(z, normal_force, self.bristle_stiffness), jnp.reshape(rate, (1,))

    def __call__(self, v_t, normal_force):
        """Steady sliding: Coulomb, :math:`-\\mu F_N\\mathrm{sign}(v)`."""
        return -self.coefficient * normal_force * jnp.sign(v_t)


class LuGreFriction(AbstractFriction):
    r"""The LuGre law (:func:`lugre_rate`, :func:`lugre_force`): kinetic ``coefficient``
    :math:`\mu_k > 0`, ``static`` :math:`\mu_s \ge \mu_k`, ``v_stribeck`` > 0 [m/s],
    ``bristle_stiffness`` :math:`\sigma_0` > 0 [1/m], ``bristle_damping`` :math:`\sigma_1 \ge 0`
    [s/m], ``viscous`` :math:`\mu_v \ge 0` [s/m]. One internal state.

    Typical values: :math:`\sigma_0` such that the pre-sliding displacement :math:`\mu_s/\sigma_0`
    is about a micrometre (1e5 to 1e6 1/m); :math:`\sigma_1` near critical damping of the bristle
    with the sliding mass m, :math:`2\sqrt{\sigma_0 m/F_N}`."""

    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters(
        "friction_static", "v_stribeck", "bristle_stiffness", "bristle_damping", "friction_viscous")

    coefficient: Scalar
    static: Scalar
    v_stribeck: Scalar
    bristle_stiffness: Scalar
    bristle_damping: Scalar
    viscous: Scalar
    state_size: ClassVar[int] = 1

    def __init__(self, coefficient: ArrayLike = 0.0, static: ArrayLike | None = None, v_stribeck: ArrayLike = 1e-3,
                 bristle_stiffness: ArrayLike = 1e5, bristle_damping: ArrayLike = 0.0, viscous: ArrayLike = 0.0):
        self.coefficient = kinetic(coefficient)
        self.static = check_static(coefficient, static)
        self.v_stribeck = speed("v_stribeck (Stribeck speed)", v_stribeck)
        self.bristle_stiffness = _stiffness(bristle_stiffness)
        check_range("bristle_damping (sigma_1, per newton of normal force)", bristle_damping, low=0.0, unit="s/m")
        self.bristle_damping = jnp.asarray(bristle_damping, dtype=float)
        self.viscous = viscous_coefficient(viscous)

    def checks(self) -> tuple:
        """mu_s >= mu_k >= 0, sigma_0 > 0, sigma_1 >= 0, mu_v >= 0 (``invalid_friction``);
        v_stribeck > 0."""
        return (*super().checks(), static_ok(self),
                Rule("bristle_stiffness sigma_0", self.bristle_stiffness, RESULTS.invalid_friction, low=0.0,
                     low_open=True, unit="1/m"),
                Rule("bristle_damping sigma_1", self.bristle_damping, RESULTS.invalid_friction, low=0.0, unit="s/m"),
                viscous_ok(self), speed_ok("v_stribeck", self.v_stribeck))

    def force_and_rate(self, state, v_t, normal_force):
        z = state[0]
        rate = lugre_rate(z, v_t, self.coefficient, self.static, self.v_stribeck, self.bristle_stiffness)
        force = lugre_force(z, rate, v_t, normal_force, self.bristle_stiffness, self.bristle_damping, self.viscous)
        return force, jnp.reshape(rate, (1,))

    def __call__(self, v_t, normal_force):
        """Steady sliding: the Stribeck curve (exponent 2, same mu_v)."""
        return stribeck(v_t, normal_force, self.coefficient, self.static, self.v_stribeck, 2.0, self.viscous)


class FrozenBristles(AbstractFriction):
    """A bristle law with its internal state held fixed: a memoryless law whose call is the
    bristle force at that state. An element that carries the state evaluates its contact with
    this law (so that every friction call site stays ``law(v_t, F_N)``) and integrates the rate
    from :meth:`AbstractFriction.force_and_rate` separately."""

    law: AbstractFriction
    state: Scalar
    coefficient: Scalar

    def __init__(self, law: AbstractFriction, state):
        self.law, self.state, self.coefficient = law, state, law.coefficient

    def check(self) -> RESULTS:
        return self.law.check()

    def checks(self) -> tuple:
        return self.law.checks()

    def __call__(self, v_t, normal_force):
        return self.law.force_and_rate(self.state, v_t, normal_force)[0]
