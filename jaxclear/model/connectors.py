r"""Force elements without state between two bodies: springs, dampers, bushings.

Extension point: :class:`AbstractConnector`, an :class:`~jaxclear.model.loads.AbstractLoad`
(it sits in ``mech.loads``) defined by two things only:

* its coordinates :math:`d(q)` (``(k,)``: a spring's length [m], a rotational spring's relative
  angle [rad], a bushing's relative displacement and rotation in its first body's frame), and
* its law :math:`f(d, \dot d)` (``(k,)``): the generalized tension conjugate to :math:`d`
  (a spring's tension [N], a rotational spring's moment [N m]), positive where it resists the
  growth of :math:`d`.

Everything else follows once, here, by the principle of virtual work (Nikravesh, "Computer-Aided
Analysis of Mechanical Systems", Prentice-Hall 1988, its force elements; Shabana, "Computational
Dynamics", 3rd ed., Wiley 2010, generalized forces by virtual work): with
:math:`J = \partial d/\partial q` the element's generalized force on the mechanism is

.. math:: Q = -J(q)^T f(d, \dot d), \qquad \dot d = J(q)\,\dot q,

and the power of its forces on the mechanism is :math:`P = Q^T\dot q = -f^T\dot d` [W] (negative:
the element stores or dissipates energy). :math:`J` is never formed: forward-mode differentiation of :math:`d(q)` along
:math:`\dot q` gives :math:`\dot d`, reverse mode gives :math:`J^T f`.

Each number of a connector named in ``PARAMETERS`` is a named parameter
(:mod:`jaxclear.params`: ``BASE:NAME``, e.g. ``spring_stiffness:strut``) with its unit and
range, which :meth:`AbstractConnector.checks` enforces at run time (status
``invalid_parameter``); each name of ``OUTPUTS`` is an output channel ``load:NAME:OUTPUT``
(:mod:`jaxclear.analysis.channels`).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, MechanismError, ParameterError, Rule, check_range
from .._parameters import Parameter
from .._types import Array, Float, Scalar
from .loads import AbstractLoad


#: mechanism-file ``type`` of each force element -> its class (filled by each element's module)
CONNECTORS: dict[str, type] = {}


class AbstractConnector(AbstractLoad):
    """A stateless force element between two bodies, named (``name``, unique among the loads).

    Subclasses set ``OUTPUTS`` (name -> unit, what :meth:`outputs` returns), ``PARAMETERS``
    (parameter base name -> :class:`Parameter`) and implement :meth:`coordinates` and
    :meth:`law`; the two bodies are ``body_a`` and ``body_b``."""

    name: eqx.AbstractVar[str]
    body_a: eqx.AbstractVar[str]
    body_b: eqx.AbstractVar[str]
    OUTPUTS: ClassVar[dict[str, str]]
    PARAMETERS: ClassVar[dict[str, Parameter]]

    @abc.abstractmethod
    def coordinates(self, mech, q: Float[Array, " n"]) -> Float[Array, " k"]:
        """The element's coordinates :math:`d(q)` (``(k,)``, SI)."""

    @abc.abstractmethod
    def law(self, d: Float[Array, " k"], ddot: Float[Array, " k"]) -> Float[Array, " k"]:
        """The generalized tension :math:`f(d, \\dot d)` (``(k,)``, SI) conjugate to :math:`d`."""

    def bodies(self):
        return (self.body_a, self.body_b)

    @property
    def label(self) -> str:
        return f"{type(self).__name__} {self.name!r}"

    def _validate(self):
        """Eager range checks of the concrete numbers (constructors): each names the parameter."""
        if not isinstance(self.name, str) or not self.name:
            raise MechanismError(f"a {type(self).__name__} needs a name (a non-empty string), got {self.name!r}")
        for base, p in self.PARAMETERS.items():
            check_range(f"{self.label}: {p.field} ({base}:{self.name})", getattr(self, p.field), low=p.low,
                        low_open=p.low_open, high=p.high, high_open=p.high_open, unit=p.unit)

    def checks(self) -> tuple:
        """Traceable range rules of every named number (status ``invalid_parameter``)."""
        return tuple(Rule(f"{p.field} ({base}:{self.name})", getattr(self, p.field), RESULTS.invalid_parameter,
                          low=p.low, low_open=p.low_open, high=p.high, high_open=p.high_open, unit=p.unit)
                     for base, p in self.PARAMETERS.items())

    def evaluate(self, mech, q, qdot) -> tuple[Float[Array, " k"], Float[Array, " k"], Float[Array, " k"], Scalar,
                                                Float[Array, " n"]]:
        r"""``(d, d_dot, f, P, Q)`` at ``(q, qdot)``: coordinates, their rates, the law's tension, its
        power [W] and the generalized force :math:`Q = -J^T f` (``(n,)``)."""
        def coordinates(qq):
            return self.coordinates(mech, qq)

        d, ddot = jax.jvp(coordinates, (q,), (qdot,))
        f = self.law(d, ddot)
        (jtf,) = jax.vjp(coordinates, q)[1](f)
        return d, ddot, f, -jnp.sum(f * ddot), -jtf

    def generalized_force(self, mech, t, q, qdot):
        return self.evaluate(mech, q, qdot)[4]

    def outputs(self, mech, t, q, qdot) -> dict[str, Scalar]:
        """The named outputs (:data:`OUTPUTS`) at one instant, each a scalar."""
        d, ddot, f, power, _ = self.evaluate(mech, q, qdot)
        return self.named_outputs(d, ddot, f, power)

    #: how a drawing draws it (matplotlib line keywords; :meth:`sketch` the line)
    SKETCH_STYLE: ClassVar[dict] = {"color": "tab:gray", "lw": 1.2}

    def sketch(self, points: dict, size: float) -> np.ndarray | None:
        """The polyline ``(k, 2)`` [m] that draws the element (:mod:`jaxclear.plot.drawing`), from
        ``points[body][point]``, the global position of every point (``"@"``: a body's
        centroid), and ``size`` [m], the drawing's size. Default: nothing drawn (``None``);
        :class:`AbstractPointPair` draws a straight line between its points."""
        return None

    def named_outputs(self, d, ddot, f, power) -> dict[str, Scalar]:
        """Default, for one coordinate: the :data:`OUTPUTS` names in the order tension (:math:`f`),
        coordinate (:math:`d`), rate (:math:`\\dot d`), power; others override it."""
        return dict(zip(self.OUTPUTS, (f[0], d[0], ddot[0], power)))


class AbstractPointPair(AbstractConnector):
    """A force element between point ``point_a`` of ``body_a`` and ``point_b`` of ``body_b``."""

    point_a: eqx.AbstractVar[str]
    point_b: eqx.AbstractVar[str]

    def points(self):
        return ((self.body_a, self.point_a), (self.body_b, self.point_b))

    def sketch(self, points: dict, size: float) -> np.ndarray:
        """A straight line from ``point_a`` to ``point_b``."""
        return np.array([points[self.body_a][self.point_a], points[self.body_b][self.point_b]], dtype=float)

    def gap(self, mech, q) -> Float[Array, "2"]:
        """:math:`p_b - p_a` [m], global axes."""
        return mech.point_position(q, self.body_b, self.point_b) - mech.point_position(q, self.body_a, self.point_a)


def connector_index(loads, base: str, name: str | None) -> int:
    """The index among ``loads`` of the force element ``name`` that declares parameter ``base``
    (``BASE:NAME``); a :class:`~jaxclear.ParameterError` naming the force elements (and which
    have ``base``) otherwise."""
    having = [ld.name for ld in loads if isinstance(ld, AbstractConnector) and base in ld.PARAMETERS]
    if not name:
        raise ParameterError(f"parameter {base!r} needs the name of a force element: {base}:NAME (NAME among the "
                             f"loads; those with {base!r}: {having})")
    found = [i for i, ld in enumerate(loads) if isinstance(ld, AbstractConnector) and ld.name == name]
    if not found:
        raise ParameterError(f"parameter {base}:{name}: no force element (spring, damper, bushing) named {name!r} "
                             f"among the loads; those with {base!r}: {having}")
    element = loads[found[0]]
    if base not in element.PARAMETERS:
        raise ParameterError(f"parameter {base}:{name}: {element.label} has no {base!r} (its parameters: "
                             f"{sorted(element.PARAMETERS)}); the force elements that have it: {having}")
    return found[0]


def scalar(owner: str, field: str, value) -> Scalar:
    """``value`` as a float64 scalar; a :class:`~jaxclear.ParameterError` naming the field if it is
    not one number (its range: :meth:`AbstractConnector._validate`)."""
    value = jnp.asarray(value, dtype=float)
    if jnp.shape(value) != ():
        raise ParameterError(f"{owner}: {field} must be a number, got shape {jnp.shape(value)}")
    return value
