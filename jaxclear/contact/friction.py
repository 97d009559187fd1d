r"""Tangential (friction) force laws at the contact point of a clearance joint.

Each law maps the tangential slip velocity :math:`v_T` [m/s] (journal relative to bearing,
along the tangent :math:`t`) and the normal force :math:`F_N \ge 0` [N] to the tangential
force :math:`F_T` [N] acting on the journal along :math:`t` (the bearing gets the opposite);
:math:`F_T v_T \le 0` always, so friction never does positive work.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ..errors import ParameterError, check_range

Scalar = Float[Array, ""]


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


FRICTION_MODELS = ("ambrosio", "coulomb", "smooth", "none")


class Friction(eqx.Module):
    """A friction law selected by name: ``ambrosio`` (default), ``coulomb``, ``smooth``, ``none``.

    Attributes:
        model: law name (static).
        coefficient: :math:`\\mu \\ge 0`.
        v0, v1: Ambrósio's velocity tolerances [m/s], :math:`0 \\le v_0 < v_1`.
        v_s: regularization speed of ``smooth`` [m/s], > 0.
    """

    model: str = eqx.field(static=True)
    coefficient: Scalar
    v0: Scalar
    v1: Scalar
    v_s: Scalar

    def __init__(
        self,
        coefficient: ArrayLike = 0.0,
        model: str = "ambrosio",
        v0: ArrayLike = 1e-4,
        v1: ArrayLike = 1e-3,
        v_s: ArrayLike = 1e-3,
    ):
        if model not in FRICTION_MODELS:
            raise ParameterError(f"unknown friction model {model!r}; valid: {list(FRICTION_MODELS)}")
        check_range("friction (coefficient mu)", coefficient, low=0.0)
        check_range("v0 (Ambrosio lower slip speed)", v0, low=0.0, unit="m/s")
        check_range("v1 (Ambrosio upper slip speed)", v1, low=0.0, low_open=True, unit="m/s")
        check_range("v_s (regularization speed)", v_s, low=0.0, low_open=True, unit="m/s")
        try:
            if float(v1) <= float(v0):
                raise ParameterError(f"v1 = {float(v1):g} m/s must exceed v0 = {float(v0):g} m/s")
        except TypeError:  # tracers
            pass
        self.model = model
        self.coefficient = jnp.asarray(coefficient, dtype=float)
        self.v0 = jnp.asarray(v0, dtype=float)
        self.v1 = jnp.asarray(v1, dtype=float)
        self.v_s = jnp.asarray(v_s, dtype=float)

    def __call__(self, v_t, normal_force):
        """Tangential force on the journal [N] for slip ``v_t`` [m/s] and normal force [N]."""
        if self.model == "ambrosio":
            return ambrosio(v_t, normal_force, self.coefficient, self.v0, self.v1)
        if self.model == "coulomb":
            return coulomb(v_t, normal_force, self.coefficient)
        if self.model == "smooth":
            return smooth_coulomb(v_t, normal_force, self.coefficient, self.v_s)
        return 0.0 * v_t
