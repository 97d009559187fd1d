"""How a class declares its named parameters: :class:`Parameter`, one entry of a class-level
``PARAMETERS`` table (parameter base name -> :class:`Parameter`), written next to the class's
fields. :mod:`jaxclear.params` composes these tables into the one map from a name to a leaf of a
mechanism (its names, values, ranges, units and transforms); nothing else lists parameters.

The declaring classes: the contact laws (:class:`~jaxclear.contact.base.AbstractNormalLaw`), the
friction laws (:class:`~jaxclear.contact.base.AbstractFriction`), the force elements with state
(:class:`~jaxclear.elements.base.AbstractForceElement`, which also answer for their law and
friction), the force elements between two bodies
(:class:`~jaxclear.model.connectors.AbstractConnector`), bodies, the crank driver, point loads,
torques and the mechanism (its frame's points).

Layer 0: no import of jaxclear.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple


class Parameter(NamedTuple):
    """One named number of a class.

    Attributes:
        field: the leaf, as a (dotted) attribute path from the declaring object (``"stiffness"``,
            ``"law.modulus"``, ``"initial_offset"``).
        unit: its unit (SI; ``""`` dimensionless).
        low, low_open, high, high_open: the allowed interval (``None``: unbounded; ``*_open``:
            the bound itself excluded).
        transform: the unconstrained coordinate a fit uses: ``log`` (0, inf), ``logit`` (0, 1) or
            ``none``.
        doc: what it is, in a few words.
        derived: whether its leaf may be ``None``, the value then derived from other numbers
            (a law's stiffness from the materials and the radii; ``read`` computes it).
        component: the component of a 2-vector leaf it addresses (``None``: the whole leaf).
        keyed: the leaf is a dict; the name's suffix ends in ``.KEY`` (a body's points).
        read: ``read(owner)``, the value when it is not the leaf itself (a clearance
            ``R_B - R_J``, a speed in rpm, a derived stiffness); ``None``: the leaf.
        write: ``write(owner, value)``, the leaf for a value when it is not the value itself (the
            journal radius for a clearance); ``None``: the value.
        limit: ``limit(owner) -> (bound, what)``, an upper bound (excluded) that depends on the
            owner (a clearance below the bearing radius), checked by
            :func:`jaxclear.params.validate` on concrete values.
    """

    field: str
    unit: str
    low: float | None = None
    low_open: bool = False
    transform: str = "none"
    doc: str = ""
    high: float | None = None
    high_open: bool = False
    derived: bool = False
    component: int | None = None
    keyed: bool = False
    read: Callable[[Any], Any] | None = None
    write: Callable[[Any, Any], Any] | None = None
    limit: Callable[[Any], tuple[float, str]] | None = None

    def range(self) -> tuple:
        """``(unit, low, high, low_open, high_open, transform)``: what two declarations of one
        name must agree on."""
        return (self.unit, self.low, self.high, self.low_open, self.high_open, self.transform)


#: the range of a stiffness or damping constant: [0, inf), log-transformed
NONNEGATIVE = dict(low=0.0, low_open=False, transform="log")
#: a positive number: (0, inf), log-transformed
POSITIVE = dict(low=0.0, low_open=True, transform="log")
#: an unbounded number (a preload, a rest angle, a coordinate)
FREE = dict(low=None, low_open=False, transform="none")


def declared(obj) -> dict[str, Parameter]:
    """The parameters ``obj`` (an instance or a class) declares: its ``parameters()`` for an
    instance that composes its parts' (a clearance joint: its law's and friction's too), else its
    class's ``PARAMETERS`` (empty when it has none)."""
    method = getattr(obj, "parameters", None)
    if method is not None and not isinstance(obj, type):
        return method()
    return dict(getattr(obj if isinstance(obj, type) else type(obj), "PARAMETERS", {}))


def nested(part: str, table: dict[str, Parameter]) -> dict[str, Parameter]:
    """``table`` (the parameters of the object at attribute ``part`` of an owner) as parameters
    of the owner: each leaf path prefixed with ``part.``, ``read``/``write``/``limit`` applied
    to the part."""
    def through(p: Parameter) -> Parameter:
        def at(owner):
            return getattr(owner, part)

        return p._replace(
            field=f"{part}.{p.field}",
            read=None if p.read is None else (lambda owner, f=p.read: f(at(owner))),
            write=None if p.write is None else (lambda owner, v, f=p.write: f(at(owner), v)),
            limit=None if p.limit is None else (lambda owner, f=p.limit: f(at(owner))))

    return {name: through(p) for name, p in table.items()}
