r"""A translational spring-damper between two body points (a strut, a coil spring, a damper).

With :math:`p_a, p_b` the global positions of the two points, the length and its rate are

.. math:: L = |p_b - p_a|, \qquad \dot L = u^T(\dot p_b - \dot p_a), \quad u = (p_b - p_a)/L,

and the tension (positive: the element pulls the points together) is

.. math:: T = F_0 + k\,(L - L_0) + c\,\dot L + g(L - L_0)

[N], with the preload :math:`F_0` [N] (the tension at the rest length), the stiffness :math:`k`
[N/m], the rest length :math:`L_0` [m], the damping :math:`c` [N s/m] and an optional nonlinear
force-deflection curve :math:`g` (:mod:`~jaxclear.model.curves`: smooth polynomial or PCHIP
table). The force on point :math:`b` is :math:`-T u`, on :math:`a` :math:`+T u`: the generalized
force :math:`Q = -(\partial L/\partial q)^T T` (:class:`~jaxclear.model.connectors.AbstractConnector`;
Nikravesh, "Computer-Aided Analysis of Mechanical Systems", Prentice-Hall 1988, the
point-to-point spring-damper-actuator). Its power on the mechanism is :math:`-T\dot L` [W]; the
damper dissipates :math:`c\dot L^2 \ge 0`. At :math:`L = 0` the direction is undefined: the length
is taken with finite derivatives there (:func:`~jaxclear.model.geometry.safe_normal`), but a
spring whose points meet carries no direction; keep :math:`L > 0`.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import numpy as np

from .._errors import ParameterError
from .._parameters import FREE, NONNEGATIVE, Parameter
from .._types import Array, Float, Scalar
from .connectors import CONNECTORS, AbstractPointPair, scalar
from .curves import AbstractCurve
from .geometry import safe_normal


class TranslationalSpringDamper(AbstractPointPair):
    """A spring-damper between point ``point_a`` of ``body_a`` and ``point_b`` of ``body_b``
    (module docstring: tension :math:`T = F_0 + k(L - L_0) + c\\dot L + g(L - L_0)`).

    Attributes:
        name: unique among the loads (parameters ``spring_*:NAME``, channels ``load:NAME:*``).
        stiffness: k [N/m], >= 0 (``spring_stiffness``).
        damping: c [N s/m], >= 0 (``spring_damping``).
        rest_length: L_0 [m], >= 0 (``spring_length``).
        preload: F_0 [N], the tension at the rest length (``spring_preload``; negative: pushes).
        curve: optional nonlinear force g of the deflection L - L_0 (a
            :class:`~jaxclear.model.curves.AbstractCurve`).

    Outputs: ``force`` (tension T [N]), ``length`` (L [m]), ``rate`` (dL/dt [m/s]), ``power``
    (of its forces on the mechanism [W])."""

    name: str = eqx.field(static=True)
    body_a: str = eqx.field(static=True)
    point_a: str = eqx.field(static=True)
    body_b: str = eqx.field(static=True)
    point_b: str = eqx.field(static=True)
    stiffness: Scalar
    damping: Scalar
    rest_length: Scalar
    preload: Scalar
    curve: AbstractCurve | None = None

    OUTPUTS: ClassVar[dict[str, str]] = {"force": "N", "length": "m", "rate": "m/s", "power": "W"}
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "spring_stiffness": Parameter("stiffness", "N/m", **NONNEGATIVE, doc="stiffness k of a spring-damper"),
        "spring_damping": Parameter("damping", "N s/m", **NONNEGATIVE, doc="damping c of a spring-damper"),
        "spring_length": Parameter("rest_length", "m", 0.0, False, "none", "rest length L_0 of a spring-damper"),
        "spring_preload": Parameter("preload", "N", **FREE, doc="tension F_0 of a spring-damper at its rest length"),
    }

    def __init__(self, name, body_a, point_a, body_b, point_b, stiffness=0.0, damping=0.0, rest_length=0.0,
                 preload=0.0, curve=None):
        self.name, self.body_a, self.point_a, self.body_b, self.point_b = name, body_a, point_a, body_b, point_b
        for field, value in (("stiffness", stiffness), ("damping", damping), ("rest_length", rest_length),
                             ("preload", preload)):
            setattr(self, field, scalar(f"TranslationalSpringDamper {name!r}", field, value))
        if curve is not None and not isinstance(curve, AbstractCurve):
            raise ParameterError(f"TranslationalSpringDamper {name!r}: curve must be a force-deflection curve "
                                 f"(jaxclear.PolynomialCurve or jaxclear.TableCurve) or None, got "
                                 f"{type(curve).__name__}")
        self.curve = curve
        self._validate()

    SKETCH_STYLE: ClassVar[dict] = {"color": "tab:green", "lw": 1.2}

    def sketch(self, points: dict, size: float) -> np.ndarray:
        """A zigzag between its points."""
        a, b = np.asarray(points[self.body_a][self.point_a], float), np.asarray(points[self.body_b][self.point_b], float)
        along = b - a
        normal = np.array([-along[1], along[0]]) / max(float(np.hypot(*along)), 1e-12)
        s = np.array([0.0, 0.15, *np.linspace(0.2, 0.8, 13), 0.85, 1.0])
        wiggle = np.concatenate([[0.0, 0.0], 0.02 * size * (-1.0) ** np.arange(13), [0.0, 0.0]])
        wiggle[[2, -3]] = 0.0
        return a + s[:, None] * along + wiggle[:, None] * normal

    def coordinates(self, mech, q) -> Float[Array, "1"]:
        gap = self.gap(mech, q)
        return safe_normal(gap)[0][None]

    def law(self, d, ddot):
        x = d - self.rest_length
        tension = self.preload + self.stiffness * x + self.damping * ddot
        return tension if self.curve is None else tension + self.curve.force(x)


CONNECTORS['spring-damper'] = TranslationalSpringDamper
