r"""A rotational (torsional) spring-damper between two bodies.

With the relative angle :math:`\theta = \phi_b - \phi_a` [rad] (``ground``: :math:`\phi = 0`) and
its rate :math:`\dot\theta = \dot\phi_b - \dot\phi_a` [rad/s], the moment

.. math:: M = M_0 + k\,(\theta - \theta_0) + c\,\dot\theta

[N m] acts on body :math:`b` as :math:`-M` and on body :math:`a` as :math:`+M` (positive
:math:`M` resists the growth of :math:`\theta`): the generalized force
:math:`Q = -(\partial\theta/\partial q)^T M` (:class:`~jaxclear.model.connectors.AbstractConnector`;
Nikravesh, "Computer-Aided Analysis of Mechanical Systems", Prentice-Hall 1988, the
rotational spring-damper-actuator). :math:`k` [N m/rad], :math:`c` [N m s/rad], the rest angle
:math:`\theta_0` [rad] and the preload :math:`M_0` [N m] (the moment at the rest angle). The angle
is not wrapped: a body that turns a full revolution winds the spring by :math:`2\pi`, as a coil
spring would. Its power on the mechanism is :math:`-M\dot\theta` [W].
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._parameters import FREE, NONNEGATIVE, Parameter
from .._types import Array, Float, Scalar
from .bodies import GROUND
from .connectors import CONNECTORS, AbstractConnector, scalar


class RotationalSpringDamper(AbstractConnector):
    """A torsional spring-damper between ``body_a`` and ``body_b`` (module docstring:
    :math:`M = M_0 + k(\\theta - \\theta_0) + c\\dot\\theta`, :math:`\\theta = \\phi_b - \\phi_a`).

    Attributes:
        name: unique among the loads (parameters ``torsion_*:NAME``, channels ``load:NAME:*``).
        stiffness: k [N m/rad], >= 0 (``torsion_stiffness``).
        damping: c [N m s/rad], >= 0 (``torsion_damping``).
        rest_angle: theta_0 [rad] (``torsion_angle``).
        preload: M_0 [N m], the moment at the rest angle (``torsion_preload``).
        drawn_at: where a drawing puts it: a point of ``body_b`` (the joint it acts across), or
            None (body b's centroid); no effect on the motion.

    Outputs: ``moment`` (M [N m]), ``angle`` (theta [rad]), ``rate`` (dtheta/dt [rad/s]),
    ``power`` (of its moments on the mechanism [W])."""

    name: str = eqx.field(static=True)
    body_a: str = eqx.field(static=True)
    body_b: str = eqx.field(static=True)
    stiffness: Scalar
    damping: Scalar
    rest_angle: Scalar
    preload: Scalar
    drawn_at: str | None = eqx.field(static=True, default=None)

    OUTPUTS: ClassVar[dict[str, str]] = {"moment": "N m", "angle": "rad", "rate": "rad/s", "power": "W"}
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "torsion_stiffness": Parameter("stiffness", "N m/rad", **NONNEGATIVE, doc="stiffness k of a rotational spring"),
        "torsion_damping": Parameter("damping", "N m s/rad", **NONNEGATIVE, doc="damping c of a rotational spring"),
        "torsion_angle": Parameter("rest_angle", "rad", **FREE, doc="rest angle theta_0 of a rotational spring"),
        "torsion_preload": Parameter("preload", "N m", **FREE, doc="moment M_0 of a rotational spring at rest"),
    }

    def __init__(self, name, body_a, body_b, stiffness=0.0, damping=0.0, rest_angle=0.0, preload=0.0,
                 drawn_at=None):
        self.name, self.body_a, self.body_b, self.drawn_at = name, body_a, body_b, drawn_at
        for field, value in (("stiffness", stiffness), ("damping", damping), ("rest_angle", rest_angle),
                             ("preload", preload)):
            setattr(self, field, scalar(f"RotationalSpringDamper {name!r}", field, value))
        self._validate()

    def points(self):
        return () if self.drawn_at is None else ((self.body_b, self.drawn_at),)

    SKETCH_STYLE: ClassVar[dict] = {"color": "tab:cyan", "lw": 1.2}

    def sketch(self, points: dict, size: float) -> np.ndarray:
        """A spiral of two turns at ``drawn_at`` (body b's centroid when None)."""
        centre = (points[self.body_b]["@" if self.drawn_at is None else self.drawn_at] if self.body_b != GROUND
                  else points[GROUND].get(self.drawn_at, np.zeros(2)))
        turn = np.linspace(0.0, 4.0 * np.pi, 60)
        r = 0.035 * size * (0.2 + 0.8 * turn / turn[-1])
        return centre + np.stack([r * np.cos(turn), r * np.sin(turn)], axis=1)

    def coordinates(self, mech, q) -> Float[Array, "1"]:
        return jnp.stack([mech.angle(q, self.body_b) - mech.angle(q, self.body_a)])

    def law(self, d, ddot):
        return self.preload + self.stiffness * (d - self.rest_angle) + self.damping * ddot


CONNECTORS['rotational-spring-damper'] = RotationalSpringDamper
