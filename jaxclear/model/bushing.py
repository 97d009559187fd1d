r"""A planar bushing: a linear spring-damper in three directions between two body points, in the
first body's frame (a rubber bush, an elastic mount, a compliant joint).

With :math:`A_a` the rotation of body :math:`a` and :math:`p_a, p_b` the points, the coordinates
are the displacement of :math:`b` from :math:`a` in :math:`a`'s axes and the relative rotation,

.. math:: d = \begin{bmatrix} A_a^T(p_b - p_a) \\ \phi_b - \phi_a \end{bmatrix}
          = \begin{bmatrix} x' \\ y' \\ \theta \end{bmatrix},

and the bushing's force and moment in :math:`a`'s axes are

.. math:: f = \mathrm{diag}(k_x, k_y, k_\theta)\,d + \mathrm{diag}(c_x, c_y, c_\theta)\,\dot d

([N, N, N m]; :math:`\dot d` the rate of :math:`d`, in the moving frame: :math:`\dot x'` is not
the relative velocity's component along :math:`x'` when body :math:`a` turns). The generalized
force is :math:`Q = -(\partial d/\partial q)^T f` (:class:`~jaxclear.model.connectors.AbstractConnector`):
the force on point :math:`b` is :math:`-A_a f_{xy}`, its reaction at point :math:`a`, the moment
:math:`-f_\theta` on :math:`b` and :math:`+f_\theta` on :math:`a`, plus on body :math:`a` the moment of
the force's lever :math:`p_b - p_a` that its frame's rotation turns (the term the virtual work of
:math:`A_a^T` gives). The stored energy is :math:`\tfrac12 d^T K d`, the power on the mechanism
:math:`-f^T\dot d` [W]. References: Nikravesh, "Computer-Aided Analysis of Mechanical Systems",
Prentice-Hall 1988 (force elements by virtual work); Shabana, "Computational Dynamics",
3rd ed., Wiley 2010 (generalized forces); MSC Adams' BUSHING statement, restricted to the plane.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._parameters import NONNEGATIVE, Parameter
from .._types import Array, Float, Scalar
from .connectors import CONNECTORS, AbstractPointPair, scalar
from .geometry import rotate

_FIELDS = ("stiffness_x", "stiffness_y", "stiffness_angle", "damping_x", "damping_y", "damping_angle")


def bushing_coordinates(mech, q, body_a: str, point_a: str, body_b: str, point_b: str) -> Float[Array, "3"]:
    r""":math:`d = [A_a^T(p_b - p_a);\ \phi_b - \phi_a]` (module docstring) of two body points: a
    bushing's coordinates, and those of a flexible link's spring-damping element at a node
    (:class:`~jaxclear.model.discrete_beam.DiscreteBeam`)."""
    phi_a = mech.angle(q, body_a)
    local = rotate(-phi_a, mech.point_position(q, body_b, point_b) - mech.point_position(q, body_a, point_a))
    return jnp.stack([local[0], local[1], mech.angle(q, body_b) - phi_a])


class Bushing(AbstractPointPair):
    """A planar bushing between point ``point_a`` of ``body_a`` and ``point_b`` of ``body_b``, at
    rest where the points coincide and the bodies' angles are equal (module docstring:
    :math:`f = K d + C\\dot d` in ``body_a``'s frame).

    Attributes:
        name: unique among the loads (parameters ``bushing_*:NAME``, channels ``load:NAME:*``).
        stiffness_x, stiffness_y: k_x, k_y [N/m], >= 0 (``bushing_kx``, ``bushing_ky``).
        stiffness_angle: k_theta [N m/rad], >= 0 (``bushing_kt``).
        damping_x, damping_y: c_x, c_y [N s/m], >= 0 (``bushing_cx``, ``bushing_cy``).
        damping_angle: c_theta [N m s/rad], >= 0 (``bushing_ct``).

    Outputs: ``force_x``, ``force_y`` [N], ``moment`` [N m] (f in body a's axes), ``dx``, ``dy``
    [m], ``angle`` [rad] (d), ``rate_x``, ``rate_y`` [m/s], ``rate_angle`` [rad/s], ``power`` [W]."""

    name: str = eqx.field(static=True)
    body_a: str = eqx.field(static=True)
    point_a: str = eqx.field(static=True)
    body_b: str = eqx.field(static=True)
    point_b: str = eqx.field(static=True)
    stiffness_x: Scalar
    stiffness_y: Scalar
    stiffness_angle: Scalar
    damping_x: Scalar
    damping_y: Scalar
    damping_angle: Scalar

    SKETCH_STYLE: ClassVar[dict] = {"color": "tab:brown", "lw": 1.2, "marker": "s", "ms": 7, "markevery": [-1],
                                    "mfc": "none"}
    OUTPUTS: ClassVar[dict[str, str]] = {
        "force_x": "N", "force_y": "N", "moment": "N m", "dx": "m", "dy": "m", "angle": "rad",
        "rate_x": "m/s", "rate_y": "m/s", "rate_angle": "rad/s", "power": "W"}
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "bushing_kx": Parameter("stiffness_x", "N/m", **NONNEGATIVE, doc="stiffness k_x of a bushing"),
        "bushing_ky": Parameter("stiffness_y", "N/m", **NONNEGATIVE, doc="stiffness k_y of a bushing"),
        "bushing_kt": Parameter("stiffness_angle", "N m/rad", **NONNEGATIVE, doc="stiffness k_theta of a bushing"),
        "bushing_cx": Parameter("damping_x", "N s/m", **NONNEGATIVE, doc="damping c_x of a bushing"),
        "bushing_cy": Parameter("damping_y", "N s/m", **NONNEGATIVE, doc="damping c_y of a bushing"),
        "bushing_ct": Parameter("damping_angle", "N m s/rad", **NONNEGATIVE, doc="damping c_theta of a bushing"),
    }

    def __init__(self, name, body_a, point_a, body_b, point_b, stiffness_x=0.0, stiffness_y=0.0,
                 stiffness_angle=0.0, damping_x=0.0, damping_y=0.0, damping_angle=0.0):
        self.name, self.body_a, self.point_a, self.body_b, self.point_b = name, body_a, point_a, body_b, point_b
        values = (stiffness_x, stiffness_y, stiffness_angle, damping_x, damping_y, damping_angle)
        for field, value in zip(_FIELDS, values):
            setattr(self, field, scalar(f"Bushing {name!r}", field, value))
        self._validate()

    def coordinates(self, mech, q) -> Float[Array, "3"]:
        return bushing_coordinates(mech, q, self.body_a, self.point_a, self.body_b, self.point_b)

    def law(self, d, ddot):
        k = jnp.stack([self.stiffness_x, self.stiffness_y, self.stiffness_angle])
        c = jnp.stack([self.damping_x, self.damping_y, self.damping_angle])
        return k * d + c * ddot

    def named_outputs(self, d, ddot, f, power):
        return dict(zip(self.OUTPUTS, (*f, *d, *ddot, power)))


CONNECTORS['bushing'] = Bushing
