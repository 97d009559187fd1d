r"""Force-deflection curves of a nonlinear spring (:class:`~jaxclear.TranslationalSpringDamper`'s
``curve``): a force :math:`g(x)` [N] of the deflection :math:`x = L - L_0` [m], added to the
spring's linear tension. Extension point: :class:`AbstractCurve` (``force(x)``).

=====================  ======================================================  ==========================
class                  :math:`g(x)`                                            mechanism file ``curve``
=====================  ======================================================  ==========================
``PolynomialCurve``    :math:`\sum_{i=1}^m a_i x^i` (smooth: a hardening        ``kind = "polynomial"``,
                       Duffing spring is :math:`a_3 > 0`)                      ``coefficients``
``TableCurve``         the monotone piecewise-cubic (PCHIP) interpolant of      ``kind = "table"``,
                       :math:`(x_k, g_k)`; beyond the table the tangent line   ``deflection``, ``forces``
                       at its end (a spring keeps its end stiffness)
=====================  ======================================================  ==========================

The table is interpolated as the time tables of :mod:`~jaxclear.model.profiles` (Fritsch and
Carlson 1980, SciPy's ``PchipInterpolator`` for the coefficients, evaluated here in JAX): C1,
no overshoot between the points of a monotone curve. Its numbers are arrays (differentiable);
the table's points are read once, when it is built.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .._types import Array, Float, Scalar
from .profiles import cubic, cubic_slope, table_piece


class AbstractCurve(eqx.Module):
    """A force [N] of a deflection [m]."""

    kind: eqx.AbstractClassVar[str]

    @abc.abstractmethod
    def force(self, x: Scalar) -> Scalar:
        """:math:`g(x)` [N]."""


class PolynomialCurve(AbstractCurve):
    """:math:`g(x) = \\sum_{i=1}^m a_i x^i` [N]; ``coefficients`` ``(m,)`` = :math:`[a_1, ..., a_m]`
    [N/m, N/m^2, ...], finite, ``m >= 1`` (no constant term: that is the spring's preload)."""

    kind: ClassVar[str] = "polynomial"
    coefficients: Float[Array, " m"]

    def __init__(self, coefficients):
        a = np.asarray(coefficients, dtype=float).ravel()
        if a.size < 1 or not np.all(np.isfinite(a)):
            raise ParameterError(f"polynomial curve: coefficients must be 1 or more finite numbers [a_1, a_2, ...] "
                                 f"(N/m, N/m^2, ...), got {np.asarray(coefficients).tolist()}")
        self.coefficients = jnp.asarray(a)

    def force(self, x):
        out = jnp.zeros_like(x)
        for a in self.coefficients[::-1]:  # Horner: (((a_m x + a_{m-1}) x + ...) + a_1) x
            out = (out + a) * x
        return out


class TableCurve(AbstractCurve):
    """The PCHIP interpolant of ``(deflection [m], forces [N])``: at least 2 points, deflections
    strictly increasing, all finite; linear beyond the ends with the end slopes."""

    kind: ClassVar[str] = "table"
    deflection: Float[Array, " n"]
    forces: Float[Array, " n"]
    coefficients: Float[Array, "4 m"]  # the cubic of each interval in powers of x - x_k

    def __init__(self, deflection, forces):
        from scipy.interpolate import PchipInterpolator

        x, g = np.asarray(deflection, dtype=float).ravel(), np.asarray(forces, dtype=float).ravel()
        if x.size < 2 or x.size != g.size:
            raise ParameterError(f"table curve: deflection and forces must have the same length >= 2, got {x.size} "
                                 f"and {g.size}")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(g))):
            raise ParameterError("table curve: deflection [m] and forces [N] must be finite numbers")
        if not np.all(np.diff(x) > 0.0):
            raise ParameterError(f"table curve: deflection must increase strictly, got {x[:4].tolist()}...")
        self.deflection, self.forces = jnp.asarray(x), jnp.asarray(g)
        self.coefficients = jnp.asarray(PchipInterpolator(x, g).c)

    def force(self, x):
        xc, k, dx = table_piece(self.deflection, x)
        c = self.coefficients[:, k]
        return cubic(c, dx) + cubic_slope(c, dx) * (x - xc)  # the tangent line beyond the ends
