r"""A planar flexible beam (:class:`AncfBeam`): a straight, uniform Euler-Bernoulli beam meshed
into ANCF cable elements (:mod:`jaxclear.flexible.ancf`), with named points along its centre line.

Coordinates: node :math:`k = 0 \dots N` of the :math:`N` elements carries
:math:`[r_k, r'_k]` (4 numbers: position [m] and slope [-], global axes), so the beam has
:math:`n = 4(N + 1)` coordinates ``e`` and element :math:`j` reads ``e[4j : 4j + 8]``. Every
element has the same length :math:`h = L/N`, mass matrix and stiffnesses, so the element terms
are one ``jax.vmap`` over the elements' coordinates (the program does not grow with :math:`N`),
and the global mass matrix is their scatter-add (constant, banded, symmetric positive definite).

Energies of the beam (all [J]): kinetic :math:`\tfrac12\dot e^T M\dot e`; strain
:math:`\sum_j U_j`; gravity :math:`-\int_0^L \rho A\,g\cdot r\,dx = -e_g^T M e`, where
:math:`e_g` holds :math:`g` in every node's position slots and zeros in its slopes (the cubic
interpolation reproduces a constant field exactly, so :math:`S e_g = g` and the gravity force
:math:`M e_g` is exact).

A point at arc length :math:`s` [m] of the reference line lies in element
:math:`j = \min(\lfloor s/h\rfloor, N - 1)` at :math:`\xi = s/h - j`; a force :math:`f` [N]
there has the generalized force :math:`S(\xi)^T f` in that element's coordinates (virtual work).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, MechanismError, ParameterError, Rule, check_finite, check_range, first_failure
from .._types import Array, ArrayLike, Float, Scalar, Vec2
from . import ancf

#: Most elements of one beam (4 (N + 1) coordinates; the dynamics solve a dense system of that size).
MAX_ELEMENTS = 200


def _scalar(owner: str, field: str, value) -> Scalar:
    value = jnp.asarray(value, dtype=float)
    if jnp.shape(value) != ():
        raise ParameterError(f"{owner}: {field} must be a number, got shape {jnp.shape(value)}")
    return value


class AncfBeam(eqx.Module):
    """A straight uniform beam of ANCF cable elements (module docstring), stress-free in its
    reference configuration: the segment from ``start`` at ``angle`` to the x axis.

    Attributes:
        name: unique name (static).
        n_elements: number of elements N (static), 1 to :data:`MAX_ELEMENTS`.
        length: L [m] > 0.
        modulus: Young's modulus E [Pa] > 0.
        density: rho [kg/m^3] > 0.
        area: cross-section area A [m^2] > 0.
        second_moment: second moment of area I [m^4] > 0 (about the axis normal to the plane).
        retardation: Kelvin-Voigt retardation time eta [s] >= 0 (material damping; 0: none).
        start: reference position of the end s = 0 [m], (2,).
        angle: reference orientation [rad].
        points: named points along the centre line: name -> arc length s [m] in [0, L] of the
            reference line (``"start"`` (s = 0) and ``"end"`` (s = L) are always defined).
    """

    name: str = eqx.field(static=True)
    n_elements: int = eqx.field(static=True)
    length: Scalar
    modulus: Scalar
    density: Scalar
    area: Scalar
    second_moment: Scalar
    retardation: Scalar
    start: Vec2
    angle: Scalar
    points: dict[str, Scalar]

    NODE_SIZE: ClassVar[int] = 4

    def __init__(self, name: str, length: ArrayLike, modulus: ArrayLike, density: ArrayLike, area: ArrayLike,
                 second_moment: ArrayLike, n_elements: int = 8, retardation: ArrayLike = 0.0,
                 start: ArrayLike = (0.0, 0.0), angle: ArrayLike = 0.0, points: dict[str, ArrayLike] | None = None):
        owner = f"beam {name!r}"
        if not isinstance(name, str) or not name:
            raise MechanismError(f"a beam needs a name (a non-empty string), got {name!r}")
        if isinstance(n_elements, bool) or not isinstance(n_elements, (int, np.integer)) or not (
                1 <= n_elements <= MAX_ELEMENTS):
            raise ParameterError(f"{owner}: n_elements = {n_elements!r} must be an integer in [1, {MAX_ELEMENTS}]")
        self.name, self.n_elements = name, int(n_elements)
        for field, value in (("length", length), ("modulus", modulus), ("density", density), ("area", area),
                             ("second_moment", second_moment), ("retardation", retardation), ("angle", angle)):
            setattr(self, field, _scalar(owner, field, value))
        for rule in self.checks():
            check_range(f"{owner}: {rule.name}", rule.value, low=rule.low, low_open=rule.low_open, unit=rule.unit)
        check_finite(f"{owner}: angle", self.angle)
        self.start = jnp.asarray(start, dtype=float)
        if self.start.shape != (2,):
            raise ParameterError(f"{owner}: start must be a 2-vector [x, y] in metres, got shape {self.start.shape}")
        check_finite(f"{owner}: start", self.start)
        named = {"start": 0.0, "end": self.length, **(points or {})}
        self.points = {k: _scalar(owner, f"point {k!r}", v) for k, v in named.items()}
        for k, v in self.points.items():
            check_range(f"{owner}: arc length of point {k!r}", v, low=0.0, high=float(self.length), unit="m")

    # ---- checks -------------------------------------------------------------------------
    def checks(self) -> tuple:
        """Range rules (:class:`~jaxclear._errors.Rule`): length, E, A, I > 0 and eta >= 0
        (``invalid_parameter``), density > 0 (``invalid_mass``)."""
        p = RESULTS.invalid_parameter
        return (Rule("length L", self.length, p, low=0.0, low_open=True, unit="m"),
                Rule("modulus E", self.modulus, p, low=0.0, low_open=True, unit="Pa"),
                Rule("density rho", self.density, RESULTS.invalid_mass, low=0.0, low_open=True, unit="kg/m^3"),
                Rule("area A", self.area, p, low=0.0, low_open=True, unit="m^2"),
                Rule("second moment I", self.second_moment, p, low=0.0, low_open=True, unit="m^4"),
                Rule("retardation eta", self.retardation, p, low=0.0, unit="s"))

    def check(self) -> RESULTS:
        """Traceable range check of :meth:`checks` (run time)."""
        return first_failure(*self.checks())

    # ---- sizes and layout ---------------------------------------------------------------
    @property
    def n_coordinates(self) -> int:
        """:math:`4(N + 1)`."""
        return self.NODE_SIZE * (self.n_elements + 1)

    @property
    def element_length(self) -> Scalar:
        """:math:`h = L/N` [m]."""
        return self.length / self.n_elements

    def element_indices(self) -> np.ndarray:
        """(N, 8) integer indices of each element's coordinates in ``e`` (static)."""
        return self.NODE_SIZE * np.arange(self.n_elements)[:, None] + np.arange(8)[None, :]

    def node_index(self, node: int) -> int:
        """Index in ``e`` of node ``node``'s first coordinate (``node`` in 0..N; -1: the last)."""
        node = range(self.n_elements + 1)[node]
        return self.NODE_SIZE * node

    def point(self, name: str) -> Scalar:
        """Arc length [m] of a named point; :class:`MechanismError` naming the points otherwise."""
        if name not in self.points:
            raise MechanismError(f"unknown point {name!r} on beam {self.name!r}; its points are {sorted(self.points)}")
        return self.points[name]

    # ---- configurations -----------------------------------------------------------------
    def reference(self) -> Float[Array, " n"]:
        """The straight, stress-free reference coordinates (n,)."""
        u = jnp.stack([jnp.cos(self.angle), jnp.sin(self.angle)])
        s = jnp.linspace(0.0, 1.0, self.n_elements + 1) * self.length
        nodes = jnp.concatenate([self.start[None, :] + s[:, None] * u[None, :],
                                 jnp.broadcast_to(u, (self.n_elements + 1, 2))], axis=1)
        return nodes.reshape(-1)

    def elements(self, e: Float[Array, " n"]) -> Float[Array, "N 8"]:
        """Each element's 8 coordinates, (N, 8)."""
        return e[self.element_indices()]

    def locate(self, s) -> tuple[Array, Scalar]:
        """Element index and :math:`\\xi` of arc length ``s`` [m] (traceable)."""
        u = jnp.asarray(s, float) / self.element_length
        j = jnp.clip(jnp.floor(u), 0, self.n_elements - 1).astype(int)
        return j, u - j

    def _element_at(self, e, s):
        j, xi = self.locate(s)
        return jax.lax.dynamic_slice(e, (self.NODE_SIZE * j,), (8,)), xi

    def position(self, e, s) -> Vec2:
        """Global position [m] of the centre-line point at arc length ``s``: :math:`S e`."""
        ee, xi = self._element_at(e, s)
        return ancf.position(ee, xi, self.element_length)

    def slope(self, e, s) -> Vec2:
        """Slope :math:`r'` [-] at arc length ``s`` (tangent times :math:`1 + \\varepsilon`)."""
        ee, xi = self._element_at(e, s)
        return ancf.slope(ee, xi, self.element_length)

    def strains(self, e, s) -> tuple[Scalar, Scalar]:
        """Axial strain [-] and curvature [1/m] at arc length ``s``."""
        ee, xi = self._element_at(e, s)
        return ancf.strains(ee, xi, self.element_length)

    # ---- inertia, energies and forces -----------------------------------------------------
    def mass_matrix(self) -> Float[Array, "n n"]:
        """The constant global mass matrix (n, n), scatter-added from the elements'."""
        me = ancf.mass_matrix(self.density * self.area, self.element_length)
        idx = self.element_indices()
        n = self.n_coordinates
        return jnp.zeros((n, n), me.dtype).at[idx[:, :, None], idx[:, None, :]].add(
            jnp.broadcast_to(me, (self.n_elements, 8, 8)))

    def strain_energy(self, e) -> Scalar:
        """:math:`U(e)` [J], summed over the elements (one ``vmap``)."""
        h, ea, ei = self.element_length, self.modulus * self.area, self.modulus * self.second_moment
        return jnp.sum(jax.vmap(lambda ee: ancf.strain_energy(ee, h, ea, ei))(self.elements(e)))

    def elastic_force(self, e) -> Float[Array, " n"]:
        """:math:`Q_e = -\\partial U/\\partial e` (n,) [N, N m]."""
        return -jax.grad(self.strain_energy)(e)

    def dissipation(self, e, edot) -> Scalar:
        """Kelvin-Voigt dissipation function :math:`\\mathcal{D}(e, \\dot e)` [W] (half the
        dissipated power)."""
        h, ea, ei = self.element_length, self.modulus * self.area, self.modulus * self.second_moment
        fn = jax.vmap(lambda ee, ed: ancf.dissipation(ee, ed, h, ea, ei, self.retardation))
        return jnp.sum(fn(self.elements(e), self.elements(edot)))

    def damping_force(self, e, edot) -> Float[Array, " n"]:
        """:math:`Q_d = -\\partial\\mathcal{D}/\\partial\\dot e` (n,)."""
        return -jax.grad(self.dissipation, argnums=1)(e, edot)

    def gravity_coordinates(self, gravity) -> Float[Array, " n"]:
        """:math:`e_g`: ``gravity`` [m/s^2] in every node's position slots, zeros in its slopes."""
        g = jnp.asarray(gravity, float)
        return jnp.concatenate([jnp.broadcast_to(g, (self.n_elements + 1, 2)),
                                jnp.zeros((self.n_elements + 1, 2), g.dtype)], axis=1).reshape(-1)

    def gravity_force(self, gravity, mass=None) -> Float[Array, " n"]:
        """:math:`\\int_0^L \\rho A\\,S^T g\\,dx = M e_g` (n,) [N] (``mass``: M if already formed)."""
        mass = self.mass_matrix() if mass is None else mass
        return mass @ self.gravity_coordinates(gravity)

    def point_force(self, s, force) -> Float[Array, " n"]:
        """Generalized force (n,) of a global ``force`` [N] at arc length ``s``: :math:`S(s)^T f`."""
        zero = jnp.zeros(self.n_coordinates)
        return jax.vjp(lambda e: self.position(e, s), zero)[1](jnp.asarray(force, float))[0]

    def kinetic_energy(self, edot, mass=None) -> Scalar:
        """:math:`\\tfrac12\\dot e^T M\\dot e` [J]."""
        mass = self.mass_matrix() if mass is None else mass
        return 0.5 * edot @ (mass @ edot)

    def energy(self, e, edot, gravity=(0.0, 0.0), mass=None) -> Scalar:
        """Kinetic + strain + gravitational potential energy [J] (potential zero at the origin)."""
        mass = self.mass_matrix() if mass is None else mass
        potential = -self.gravity_coordinates(gravity) @ (mass @ e)
        return self.kinetic_energy(edot, mass) + self.strain_energy(e) + potential
