r"""The planar ANCF cable element: a two-node Euler-Bernoulli beam element in absolute nodal
coordinates (the element of Berzeri and Shabana 2000; its elastic forces as in Gerstmayr and
Irschik 2008 and Exudyn's ``ObjectANCFCable2D``).

An element of reference length :math:`h` [m] has the 8 coordinates

.. math:: e = [\,r_0,\ r'_0,\ r_1,\ r'_1\,] \in \mathbb{R}^8

(the positions [m] and slopes :math:`r' = \partial r/\partial x` [-] of its two nodes, global
axes), and its centre line at :math:`x = \xi h`, :math:`\xi \in [0, 1]`, is the cubic Hermite
interpolation :math:`r(x) = S(\xi)\,e` with

.. math::
    S = [\,S_1 I,\ S_2 I,\ S_3 I,\ S_4 I\,], \quad
    S_1 = 1 - 3\xi^2 + 2\xi^3,\ S_2 = h(\xi - 2\xi^2 + \xi^3),\
    S_3 = 3\xi^2 - 2\xi^3,\ S_4 = h(\xi^3 - \xi^2).

The kinetic energy :math:`T = \tfrac12\dot e^T M \dot e` has the constant mass matrix
:math:`M = \int_0^h \rho A\,S^T S\,dx` (integrated exactly: 4 Gauss points for a degree-6
integrand). The strain energy of the centre line is

.. math:: U = \tfrac12\int_0^h \big(EA\,\varepsilon^2 + EI\,K^2\big)\,dx, \qquad
    \varepsilon = |r'| - 1, \qquad K = \frac{r' \times r''}{|r'|^2},

with the axial strain :math:`\varepsilon` [-] and the material measure of curvature :math:`K`
[1/m] (Gerstmayr and Irschik 2008), the axial stiffness :math:`EA` [N] and the bending stiffness
:math:`EI` [N m^2]; the generalized elastic force is :math:`Q_e = -\partial U/\partial e` (by
reverse-mode differentiation; nobody writes it by hand). The axial term is integrated with 5
Gauss points, the bending term with 3 (Exudyn's full integration: orders 9 and 5). Both strain
measures are exact for large rotations (a rigid rotation leaves them zero), so the centrifugal
tension of a spinning beam stiffens its bending (geometric stiffening) with no extra term.

Material damping is Kelvin-Voigt: stresses :math:`E(\varepsilon + \eta\dot\varepsilon)`, that
is the dissipation function
:math:`\mathcal{D} = \tfrac12\eta\int_0^h (EA\,\dot\varepsilon^2 + EI\,\dot K^2)\,dx` [W] with the
retardation time :math:`\eta` [s] and the force :math:`Q_d = -\partial\mathcal{D}/\partial\dot e`
(linearised about a straight beam: :math:`C = \eta K`, stiffness-proportional Rayleigh damping,
modal damping ratios :math:`\zeta_n = \eta\,\omega_n/2`).

Shapes: ``e`` (8,), ``edot`` (8,); every function is traceable and differentiable.

References: M. Berzeri, A.A. Shabana, J. Sound Vib. 235 (2000) 539-565; J. Gerstmayr,
H. Irschik, J. Sound Vib. 318 (2008) 461-487; J. Gerstmayr, A.A. Shabana, Nonlinear Dyn. 45
(2006) 109-130 (docs/theory/flexible-links.md).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float, Scalar, Vec2


def _gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points on [0, 1] and weights summing to 1 (NumPy constants)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


#: Gauss points and weights on [0, 1]: the mass matrix (exact), axial and bending strain energy
MASS_RULE = _gauss(4)
AXIAL_RULE = _gauss(5)
BENDING_RULE = _gauss(3)


def shape(xi, h) -> Float[Array, "4"]:
    """:math:`S_1 \\dots S_4` at :math:`\\xi` (dimensionless; :math:`S_2, S_4` [m])."""
    return jnp.stack([1 - 3 * xi**2 + 2 * xi**3, h * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3,
                      h * (xi**3 - xi**2)])


def shape_x(xi, h) -> Float[Array, "4"]:
    """:math:`\\partial S/\\partial x` [1/m for S_1, S_3; - for S_2, S_4]."""
    return jnp.stack([(-6 * xi + 6 * xi**2) / h, 1 - 4 * xi + 3 * xi**2, (6 * xi - 6 * xi**2) / h,
                      3 * xi**2 - 2 * xi])


def shape_xx(xi, h) -> Float[Array, "4"]:
    """:math:`\\partial^2 S/\\partial x^2`."""
    return jnp.stack([(-6 + 12 * xi) / h**2, (-4 + 6 * xi) / h, (6 - 12 * xi) / h**2, (6 * xi - 2) / h])


def combine(weights: Float[Array, "4"], e: Float[Array, "8"]) -> Vec2:
    """:math:`\\sum_k w_k\\,e_{2k:2k+2}`: the interpolation :math:`S e` (or its derivatives)."""
    return jnp.sum(weights[:, None] * e.reshape(4, 2), axis=0)


def position(e, xi, h) -> Vec2:
    """:math:`r(\\xi h) = S(\\xi) e` [m]."""
    return combine(shape(xi, h), e)


def slope(e, xi, h) -> Vec2:
    """:math:`r'(\\xi h)` [-]."""
    return combine(shape_x(xi, h), e)


def strains(e, xi, h) -> tuple[Scalar, Scalar]:
    r"""Axial strain :math:`\varepsilon = |r'| - 1` [-] and curvature :math:`K = (r' \times r'')/|r'|^2`
    [1/m] at :math:`\xi`."""
    r1 = slope(e, xi, h)
    r2 = combine(shape_xx(xi, h), e)
    stretch2 = r1[0] ** 2 + r1[1] ** 2
    return jnp.sqrt(stretch2) - 1.0, (r1[0] * r2[1] - r1[1] * r2[0]) / stretch2


def mass_matrix(rho_a, h) -> Float[Array, "8 8"]:
    r""":math:`M = \int_0^h \rho A\,S^T S\,dx` (8, 8) [kg, kg m, kg m^2 by block] for the mass per
    length ``rho_a`` [kg/m]: exact (4 Gauss points)."""
    xs, ws = MASS_RULE
    s = jnp.stack([shape(x, h) for x in xs])  # (4 points, 4 functions)
    m4 = jnp.einsum("p,pi,pj->ij", jnp.asarray(ws), s, s) * (rho_a * h)
    return jnp.kron(m4, jnp.eye(2, dtype=m4.dtype))


def _integrate(fn, rule, h):
    xs, ws = rule
    return h * sum(w * fn(x) for x, w in zip(xs, ws))


def strain_energy(e, h, ea, ei) -> Scalar:
    r""":math:`U = \tfrac12\int_0^h (EA\,\varepsilon^2 + EI\,K^2)\,dx` [J] of one element."""
    axial = _integrate(lambda x: strains(e, x, h)[0] ** 2, AXIAL_RULE, h)
    bending = _integrate(lambda x: strains(e, x, h)[1] ** 2, BENDING_RULE, h)
    return 0.5 * (ea * axial + ei * bending)


def dissipation(e, edot, h, ea, ei, eta) -> Scalar:
    r"""Kelvin-Voigt dissipation function :math:`\mathcal{D} = \tfrac12\eta\int_0^h (EA\,\dot\varepsilon^2
    + EI\,\dot K^2)\,dx` [W] (the dissipated power is :math:`2\mathcal{D}`); the strain rates by
    forward-mode differentiation along ``edot``."""
    def rates(x):
        return jax.jvp(lambda ee: jnp.stack(strains(ee, x, h)), (e,), (edot,))[1]

    axial = _integrate(lambda x: rates(x)[0] ** 2, AXIAL_RULE, h)
    bending = _integrate(lambda x: rates(x)[1] ** 2, BENDING_RULE, h)
    return 0.5 * eta * (ea * axial + ei * bending)
