r"""The elastic part of a flexible link made of rigid finite elements: the spring-damping
elements between a chain of rigid bodies (the rigid finite element method of Kruszewski and
Wittbrodt; Wittbrodt, Adamiec-Wojcik and Wojciech, "Dynamics of Flexible Multibody Systems: Rigid
Finite Element Method", Springer 2006, chapters 2-3; the "discrete flexible link" of MSC Adams).

A link of length :math:`L` is cut into :math:`m` equal parts of length :math:`\Delta = L/m`; a
spring-damping element (sde) sits at the middle of each part, at the node
:math:`s_k = (k - \tfrac12)\Delta`, :math:`k = 1..m`, and the rigid elements lie between the nodes
(the two end elements :math:`\Delta/2` long, the others :math:`\Delta`): Wittbrodt's secondary
division, whose :math:`m` sdes carry the bending of the parts they stand for. Each sde's
coordinates are those of a planar bushing between the two elements it joins, at their common node
(:class:`~jaxclear.model.bushing.Bushing`'s :math:`d`, in the first element's axes),

.. math:: d_k = \begin{bmatrix} A_{k-1}^T (p_k^{(k)} - p_k^{(k-1)}) \\ \phi_k - \phi_{k-1} \end{bmatrix},
          \qquad f_k = K\,(d_k + \eta\,\dot d_k),
          \qquad K = \mathrm{diag}\!\left(\frac{EA}{\Delta}, \frac{\kappa G A}{\Delta}, \frac{EI}{\Delta}\right)

(:math:`E` Young's modulus [Pa], :math:`G` the shear modulus [Pa], :math:`\kappa` the shear factor,
:math:`A` [m^2], :math:`I` [m^4] the section's area and second moment, :math:`\eta` [s] the
Kelvin-Voigt material damping: a mode of frequency :math:`\omega` is damped at
:math:`\zeta = \eta\omega/2`). With ``axial="rigid"`` the elements are pinned at the nodes by ideal
revolute joints (an inextensible Euler-Bernoulli link, what slender connecting rods are) and
:math:`d_k` is the relative angle only. The generalized forces follow by virtual work
(:class:`~jaxclear.model.connectors.AbstractConnector`: :math:`Q = -J^T f`); the strain energy is
:math:`\tfrac12\sum_k d_k^T K d_k`.

For a cantilever of this model under a tip load :math:`P` the tip deflection is, in closed form,
:math:`\frac{P}{EI}\sum_k (L - s_k)^2\Delta = \frac{PL^3}{3EI}\left(1 - \frac{1}{4m^2}\right)`
(the midpoint rule of :math:`\int_0^L (L-s)^2 ds`): the model converges to the Euler-Bernoulli beam
at second order in :math:`1/m`, and so do its natural frequencies (``tests/test_flexible_link.py``).

:func:`~jaxclear.flexible_link` turns a rigid body of a mechanism into such a chain; this class is
its elastic part, one force element among the loads whose constants are named parameters
(``beam_modulus:NAME``, ...): swept, differentiated and fitted like any other.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .._parameters import NONNEGATIVE, POSITIVE, Parameter
from .._types import Array, Float, Scalar
from .bushing import bushing_coordinates
from .connectors import CONNECTORS, AbstractConnector, scalar
from .geometry import cross2

AXIAL = ("rigid", "elastic")


def _start_vector(name: str, field: str, value, k: int) -> Float[Array, " k"]:
    """``value`` (None: zeros) as a float64 vector of the ``k`` sde coordinates; a
    :class:`~jaxclear.ParameterError` naming the field for another shape or a value that is not
    finite."""
    out = jnp.zeros((k,)) if value is None else jnp.asarray(value, dtype=float)
    if out.shape != (k,):
        raise ParameterError(f"DiscreteBeam {name!r}: {field} must hold {k} numbers (one per sde coordinate), got "
                             f"shape {out.shape}")
    if not bool(jnp.all(jnp.isfinite(out))):
        raise ParameterError(f"DiscreteBeam {name!r}: {field} must be finite, got {np.asarray(out).tolist()}")
    return out


def node_name(k: int) -> str:
    """The name of node ``k`` (1-based, the sde between rigid elements ``k - 1`` and ``k``) as a
    point of both elements."""
    return f"node{k}"


class DiscreteBeam(AbstractConnector):
    """The spring-damping elements of a flexible link of rigid finite elements (module docstring).

    Attributes:
        name: unique among the loads (parameters ``beam_*:NAME``, channels ``load:NAME:*``).
        segments: the rigid elements' body names, in order from end ``a`` to end ``b`` (static).
        end_a, end_b, middle: ``(body, point)`` of the link's two ends and of its middle (static;
            the outputs' chord and midpoint).
        axial: ``"rigid"`` (the elements pinned at the nodes; bending only) or ``"elastic"``
            (axial and shear springs too), static.
        spacing: Delta = L / m [m], the length each sde stands for.
        youngs_modulus: E [Pa] > 0 (``beam_modulus``).
        second_moment: I [m^4] > 0 of the section (``beam_second_moment``).
        area: A [m^2] > 0 (``beam_area``; axial and shear stiffness, ``axial="elastic"`` only).
        shear_modulus: G [Pa] > 0 (``beam_shear_modulus``; ``"elastic"`` only).
        shear_factor: kappa > 0 (``beam_shear_factor``; 5/6 for a rectangle, 0.9 for a circle).
        damping: eta [s] >= 0, Kelvin-Voigt (``beam_damping``).
        start, start_rate: ``(k,)`` the sdes' coordinates (:meth:`coordinates`) and their rates
            that the start's assembly holds (``Mechanism.held_at_start``); zeros (default): the
            link starts straight and moving rigidly. :meth:`with_shape` sets them from a
            deflection curve (a link that starts bent or vibrating).

    Outputs: ``deflection`` [m] (the middle's distance from the chord through the ends, positive
    to the left of the chord from end ``a`` to end ``b``), ``moment_middle`` [N m] (the bending
    moment at the middle: the mean of the one or two nodes nearest it), ``moment_max`` [N m] (the
    largest absolute bending moment over the nodes), ``energy`` [J] (strain energy), ``power`` [W]
    (of the sdes' forces on the mechanism), and at each node ``k = 1 .. m`` (arc length
    s_k = (k - 1/2) Delta from end ``a``) ``deflection_k`` [m] (as ``deflection``)
    and ``moment_k`` [N m] (the sde's bending moment)."""

    name: str = eqx.field(static=True)
    segments: tuple[str, ...] = eqx.field(static=True)
    end_a: tuple[str, str] = eqx.field(static=True)
    end_b: tuple[str, str] = eqx.field(static=True)
    middle: tuple[str, str] = eqx.field(static=True)
    axial: str = eqx.field(static=True)
    spacing: Scalar
    youngs_modulus: Scalar
    second_moment: Scalar
    area: Scalar
    shear_modulus: Scalar
    shear_factor: Scalar
    damping: Scalar
    start: Float[Array, " k"]
    start_rate: Float[Array, " k"]

    LINK_OUTPUTS: ClassVar[dict[str, str]] = {"deflection": "m", "moment_middle": "N m", "moment_max": "N m",
                                              "energy": "J", "power": "W"}
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "beam_modulus": Parameter("youngs_modulus", "Pa", **POSITIVE, doc="Young's modulus E of a flexible link"),
        "beam_second_moment": Parameter("second_moment", "m^4", **POSITIVE,
                                        doc="second moment of area I of a flexible link's section"),
        "beam_area": Parameter("area", "m^2", **POSITIVE, doc="section area A of a flexible link (axial, shear)"),
        "beam_shear_modulus": Parameter("shear_modulus", "Pa", **POSITIVE, doc="shear modulus G of a flexible link"),
        "beam_shear_factor": Parameter("shear_factor", "", **POSITIVE, doc="shear factor kappa of a flexible link"),
        "beam_damping": Parameter("damping", "s", **NONNEGATIVE,
                                  doc="Kelvin-Voigt damping eta of a flexible link (zeta = eta omega / 2)"),
    }
    SKETCH_STYLE: ClassVar[dict] = {"color": "tab:purple", "lw": 2.0, "marker": "o", "ms": 3}

    def __init__(self, name, segments, end_a, end_b, middle, spacing, youngs_modulus, second_moment, area=1.0,
                 shear_modulus=1.0, shear_factor=5.0 / 6.0, damping=0.0, axial="rigid", start=None, start_rate=None):
        if axial not in AXIAL:
            raise ParameterError(f"DiscreteBeam {name!r}: axial = {axial!r} is not allowed; allowed: {list(AXIAL)}")
        segments = tuple(segments)
        if len(segments) < 2 or not all(isinstance(b, str) for b in segments):
            raise ParameterError(f"DiscreteBeam {name!r}: segments must name at least 2 rigid elements (body names), "
                                 f"got {segments!r}")
        for field, pair in (("end_a", end_a), ("end_b", end_b), ("middle", middle)):
            if len(pair) != 2 or not all(isinstance(v, str) for v in pair):
                raise ParameterError(f"DiscreteBeam {name!r}: {field} must be a (body, point) pair of names, got {pair!r}")
        self.name, self.segments, self.axial = name, segments, axial
        self.end_a, self.end_b, self.middle = tuple(end_a), tuple(end_b), tuple(middle)
        self.spacing = scalar(f"DiscreteBeam {name!r}", "spacing", spacing)
        for field, value in (("youngs_modulus", youngs_modulus), ("second_moment", second_moment), ("area", area),
                             ("shear_modulus", shear_modulus), ("shear_factor", shear_factor), ("damping", damping)):
            setattr(self, field, scalar(f"DiscreteBeam {name!r}", field, value))
        k = (len(segments) - 1) * (1 if axial == "rigid" else 3)
        self.start, self.start_rate = (_start_vector(name, field, value, k)
                                       for field, value in (("start", start), ("start_rate", start_rate)))
        self._validate()
        if not float(self.spacing) > 0.0:
            raise ParameterError(f"DiscreteBeam {name!r}: spacing = {float(self.spacing)!r} m is outside the allowed "
                                 "range (0, inf) m")

    # ---- structure ----------------------------------------------------------------
    @property
    def body_a(self) -> str:
        return self.segments[0]

    @property
    def body_b(self) -> str:
        return self.segments[-1]

    @property
    def n_nodes(self) -> int:
        """m, the number of sdes."""
        return len(self.segments) - 1

    def bodies(self):
        return self.segments

    def points(self):
        nodes = [(self.segments[k + j], node_name(k + 1)) for k in range(self.n_nodes) for j in (0, 1)]
        return (self.end_a, self.end_b, self.middle, *nodes)

    # ---- the start: the link as given (Mechanism.held_at_start) --------------------------
    @property
    def n_equations(self) -> int:
        """The sdes' coordinates, held at their start values by the start's assembly."""
        return self.n_nodes if self.axial == "rigid" else 3 * self.n_nodes

    def equations(self, mech, q, t):
        """:math:`d(q) = d_0`: every sde at its start value (zero: the link straight)."""
        return self.coordinates(mech, q) - self.start

    def assembly_velocity(self):
        """:math:`\\dot d = \\dot d_0` at the start (zero: the link moves rigidly)."""
        return self.start_rate

    def node_positions(self) -> np.ndarray:
        """``(m + 2,)`` [m]: the distances from end ``a`` of the rigid elements' ends along the
        undeformed link: 0, the nodes :math:`(k - \\tfrac12)\\Delta`, and :math:`L = m\\Delta`."""
        m, spacing = self.n_nodes, float(self.spacing)
        return np.concatenate([[0.0], (np.arange(1, m + 1) - 0.5) * spacing, [m * spacing]])

    def with_shape(self, deflection, rate=None) -> "DiscreteBeam":
        r"""This link started bent (and bending): ``deflection(s)`` [m], the lateral deflection at
        the distance ``s`` [m] from end ``a`` along the link (positive to the left of the line from
        end ``a`` to end ``b``, as the ``deflection`` output), and ``rate(s)`` [m/s] its rate (None:
        zero). Each rigid element is the chord of the curve between its ends
        (:meth:`node_positions`), turned by :math:`\phi_j = \arctan(\Delta w_j / \Delta s_j)`; an
        sde's start angle is the difference of its two elements' (:math:`\dot\phi_j =
        \Delta\dot w_j / \Delta s_j \cos^2\phi_j`), its axial and shear coordinates (``"elastic"``)
        zero. Only the curvature enters: a straight ``deflection`` (a turn of the whole link) gives
        zeros. The assembly then holds the link in that shape, the joints at its ends moving as
        the shortened chord needs."""
        s = self.node_positions()
        ds = np.diff(s)

        def relative(curve, slope_rate: bool, phi=None):
            w = np.array([float(curve(v)) for v in s])
            if not np.all(np.isfinite(w)):
                raise ParameterError(f"DiscreteBeam {self.name!r}: the start's {'rate' if slope_rate else 'deflection'} "
                                     "is not finite at every element's end")
            turn = np.diff(w) / ds * np.cos(phi) ** 2 if slope_rate else np.arctan(np.diff(w) / ds)
            return turn, np.diff(turn)

        phi, angles = relative(deflection, False)
        rates = relative(rate, True, phi)[1] if rate is not None else np.zeros_like(angles)

        def coordinates(bend):
            if self.axial == "rigid":
                return bend
            out = np.zeros(3 * self.n_nodes)
            out[2::3] = bend
            return out

        return eqx.tree_at(lambda b: (b.start, b.start_rate), self,
                           (jnp.asarray(coordinates(angles)), jnp.asarray(coordinates(rates))))

    # ---- the force element --------------------------------------------------------
    def stiffness(self) -> Float[Array, " k"]:
        """The sdes' stiffnesses, in the order of :meth:`coordinates`: ``(m,)`` EI / Delta [N m/rad]
        (``"rigid"``) or ``(3 m,)`` EA / Delta, kappa G A / Delta [N/m], EI / Delta."""
        bend = self.youngs_modulus * self.second_moment / self.spacing
        if self.axial == "rigid":
            return jnp.full((self.n_nodes,), bend)
        one = jnp.stack([self.youngs_modulus * self.area, self.shear_factor * self.shear_modulus * self.area,
                         self.youngs_modulus * self.second_moment]) / self.spacing
        return jnp.tile(one, self.n_nodes)

    def coordinates(self, mech, q) -> Float[Array, " k"]:
        pairs = zip(self.segments[:-1], self.segments[1:])
        if self.axial == "rigid":  # the relative angles only (the elements pinned at the nodes)
            return jnp.stack([mech.angle(q, b) - mech.angle(q, a) for a, b in pairs])
        return jnp.concatenate([bushing_coordinates(mech, q, a, node_name(k + 1), b, node_name(k + 1))
                                for k, (a, b) in enumerate(pairs)])

    @property
    def OUTPUTS(self) -> dict[str, str]:  # noqa: N802 (the connectors' name): the link's, then each node's
        nodes = {f"{what}_{k}": unit for k in range(1, self.n_nodes + 1) for what, unit in (("deflection", "m"),
                                                                                            ("moment", "N m"))}
        return {**self.LINK_OUTPUTS, **nodes}

    def law(self, d, ddot):
        return self.stiffness() * (d + self.damping * ddot)

    def moments(self, f) -> Float[Array, " m"]:
        """The bending moments [N m] at the nodes from the law's tension ``f``."""
        return f if self.axial == "rigid" else f[2::3]

    def outputs(self, mech, t, q, qdot) -> dict[str, Array]:
        d, ddot, f, power, _ = self.evaluate(mech, q, qdot)
        a = mech.point_position(q, *self.end_a)
        chord = mech.point_position(q, *self.end_b) - a
        length = jnp.sqrt(jnp.sum(chord**2))
        deflection = cross2(chord, mech.point_position(q, *self.middle) - a) / length
        moments = self.moments(f)
        m = self.n_nodes
        nearest = [m // 2] if m % 2 else [m // 2 - 1, m // 2]  # node (m + 1) / 2, or nodes m / 2 and m / 2 + 1
        out = {"deflection": deflection, "moment_middle": jnp.mean(moments[jnp.asarray(nearest)]),
               "moment_max": jnp.max(jnp.abs(moments)), "energy": 0.5 * jnp.sum(self.stiffness() * d**2),
               "power": power}
        for k in range(m):
            node = mech.point_position(q, self.segments[k], node_name(k + 1))
            out[f"deflection_{k + 1}"] = cross2(chord, node - a) / length
            out[f"moment_{k + 1}"] = moments[k]
        return out

    def sketch(self, points: dict, size: float) -> np.ndarray:
        """The centre line: end a, the nodes, end b."""
        nodes = [points[self.segments[k]][node_name(k + 1)] for k in range(self.n_nodes)]
        return np.array([points[self.end_a[0]][self.end_a[1]], *nodes, points[self.end_b[0]][self.end_b[1]]],
                        dtype=float)


CONNECTORS['discrete-beam'] = DiscreteBeam
