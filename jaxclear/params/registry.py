"""Named numeric parameters of a mechanism: read, replace (pytree-functionally, so the value may
be a tracer under ``vmap``/``grad``), check, validate and transform. Fits, sweeps, designs and
derivatives address parameters by these names; this module is the one place that maps a name to
a leaf of the mechanism.

Where the names come from: every class that holds named numbers declares them in its
``PARAMETERS`` table next to its fields (:class:`~jaxclear._parameters.Parameter`: leaf, unit,
range, transform, whether the value may be derived from others): contact and friction laws
(:mod:`jaxclear.contact.base`), force elements with state (:mod:`jaxclear.elements.base`, which
answer for their law and friction too), force elements between two bodies
(:mod:`jaxclear.model.connectors`), bodies, the crank's :class:`~jaxclear.AngleDriver`, point
loads, torques and the :class:`~jaxclear.Mechanism` (its frame's points). This module composes
them into a mechanism's names (:func:`names`), the catalogue :data:`INFO` and the one check of a
name (:func:`check_name`) and of values (:func:`validate`); a new class is named without editing it.

Names (``J`` = clearance-joint index, default 0, written ``name@J`` e.g. ``clearance@1``):

======================  =======================================================  ============
name                    leaf                                                     unit, range
======================  =======================================================  ============
``clearance``           ``R_B - R_J`` (sets the journal radius, bearing kept);   m, (0, R_B)
                        translational joint: ``(W - b)/2`` (sets the guide width)
``restitution``         ``law.restitution``                                      -, (0, 1]
``stiffness``           the law's stiffness leaf (``law.stiffness_parameter``)      law's unit, (0, inf)
``exponent``            ``law.exponent``                                         -, (0, inf)
``friction``            ``friction.coefficient``                                 -, [0, inf)
``friction_static``     ``friction.static`` (mu_s; Stribeck, LuGre, ...)           -, [0, inf)
``friction_viscous``    ``friction.viscous`` (mu_v: viscous, Stribeck, ...)       s/m, [0, inf)
``v_stribeck``          ``friction.v_stribeck`` (Stribeck, LuGre)                m/s, (0, inf)
``stribeck_exponent``   ``friction.stribeck_exponent`` (Stribeck)                -, (0, inf)
``v_threlfall``         ``friction.v_threlfall`` (Threlfall)                     m/s, (0, inf)
``v_transition``        ``friction.v_transition`` (Brown-McPhee)                 m/s, (0, inf)
``bristle_stiffness``   ``friction.bristle_stiffness`` (sigma_0: Dahl, LuGre)    1/m, (0, inf)
``bristle_damping``     ``friction.bristle_damping`` (sigma_1: LuGre)            s/m, [0, inf)
``length``              joint axial length L (a :class:`LubricatedJoint`'s film  m, (0, inf)
                        width)
``viscosity``           oil viscosity of a :class:`LubricatedJoint`              Pa s, (0, inf)
``speed``               first ``AngleDriver.speed``                              rad/s
``speed_rpm``           the same in rev/min                                      rpm
``mass:BODY``           body mass                                                kg, (0, inf)
``inertia:BODY``        body centroidal inertia                                  kg m^2, (0, inf)
``point_x:BODY.POINT``  x of a body-fixed point (``ground.POINT``: of the frame)  m
``point_y:BODY.POINT``  y of the same point (geometry: link lengths, offsets)    m
``centroid_x:BODY``     shift of the body's centroid along its own x axis        m, 0 = as given
                        relative to its points: every body-fixed point moves by
                        ``-value`` (a derived name, see below)
``centroid_y:BODY``     the same along the body's y axis                         m, 0 = as given
``load_x:K``            x of the force of load ``K`` (a ``PointForce``; ``K`` its   N
                        index in ``mech.loads``), the load's constant part
``load_y:K``            y of the same force                                      N
``torque:K``            torque of load ``K`` (a ``Torque``)                      N m
``angle0``              first ``AngleDriver.angle0`` (crank angle at t = 0)      rad
``offset_x``            ``initial_offset[0]`` of the clearance joint (a journal:  m (rad)
                        eccentricity x; translational: lateral offset)
``offset_y``            ``initial_offset[1]`` (journal: eccentricity y;          m (rad)
                        translational: tilt [rad])
``velocity_x``          ``initial_velocity[0]`` (the rate of ``offset_x``)       m/s (rad/s)
``velocity_y``          ``initial_velocity[1]`` (the rate of ``offset_y``)       m/s (rad/s)
======================  =======================================================  ============

The initial-state names (``offset_*``, ``velocity_*``) set where a clearance joint starts
within its clearance (the assembly holds it there); ``angle0`` and the points move the
mechanism's configuration. Each name is a differentiable input of
:func:`~jaxclear.simulate` (``jaxclear.sensitivities``); the structure (names, which law,
Gauss-point counts, the film variant) is static and has no name here.

``centroid_x:BODY`` and ``centroid_y:BODY`` are derived names: the mass distribution of a link
(where its centroid lies between its joints, as in balancing and in the optimal-design studies
of Varedi et al. 2015) is set by moving every body-fixed point of the body by minus the
shift, in the body's frame; the centroidal inertia, the mass and the body's position guess stay
as given (the assembly places the body). Their value is the shift relative to the mechanism
they are applied to (``get`` reads 0), so ``replace(mech, "centroid_x:rod", 0.01)`` moves the
rod's centroid 10 mm towards its point of larger x (:class:`~jaxclear.Body`'s declaration makes the shift).

A force element among the loads names its constants ``BASE:NAME`` (:data:`CONNECTOR_NAMES`; units,
ranges: its class's ``PARAMETERS``, :mod:`jaxclear.model.connectors`; docs/theory/force-elements.md).

``width`` is an old name of ``length`` for the lubricated joint: still accepted, with a
:class:`DeprecationWarning`.

``stiffness`` of a law whose stiffness is derived (its leaf ``None``: from the materials and,
for the Hertz-type laws, from the joint's radii) reads the derived value and, when set, becomes
explicit. Derived values follow their sources (:func:`is_derived`), also in a derivative
whatever else is asked with it (:func:`replace_following`); to hold the stiffness while the
clearance changes, set it: ``replace(mech, "stiffness", get(mech, "stiffness"))``.
The friction names address the joint's friction law
(:mod:`jaxclear.contact.friction_laws`, :mod:`jaxclear.contact.bristle`); a law without that
parameter raises :class:`~jaxclear.ParameterError` naming the laws that have it.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import JaxclearError, ParameterError, check_range, closest
from .._parameters import Parameter, declared
from ..contact.base import FRICTION_PARAMETERS, AbstractFriction, AbstractNormalLaw
from ..contact.friction import FRICTION_MODELS
from ..contact.friction_laws import KarnoppFriction
from ..contact.registry import LAWS
from ..elements import AbstractForceElement, ClearanceJoint, LubricatedJoint, PinSlotJoint, TranslationalClearanceJoint
from ..model import GROUND, AngleDriver, Body, Mechanism, PointForce, Torque, crank_driver
from ..model.connectors import CONNECTORS, AbstractConnector, connector_index


@dataclass(frozen=True)
class ParameterInfo:
    """What a parameter name means: its unit, its allowed open/closed interval, and the
    unconstrained transform a fit uses (``log``: (0, inf); ``logit``: (0, 1); ``none``)."""

    name: str
    unit: str
    low: float | None
    high: float | None
    low_open: bool
    high_open: bool
    transform: str
    doc: str


def _scope(cls) -> str:
    """Where a class's objects sit in a mechanism, which decides the suffix: ``joint`` (``@J``),
    ``crank`` (none), ``body`` (``:BODY``, ``:BODY.POINT``), ``load`` (``:K``), ``element`` (``:NAME``)."""
    if issubclass(cls, (AbstractForceElement, AbstractNormalLaw, AbstractFriction)):
        return "joint"
    if issubclass(cls, AngleDriver):
        return "crank"
    if issubclass(cls, (Body, Mechanism)):
        return "body"
    return "element" if issubclass(cls, AbstractConnector) else "load"


#: the classes whose names are known without a mechanism (:func:`parameter_names`): the package's own and
#: the mechanism files' (laws, friction, force elements); any other class is named on a mechanism holding it
REGISTERED = (Mechanism, Body, AngleDriver, PointForce, Torque, ClearanceJoint, LubricatedJoint, PinSlotJoint,
              TranslationalClearanceJoint, *dict.fromkeys(cls for cls, *_ in LAWS.values()),
              *(cls for cls, _ in FRICTION_MODELS.values()), KarnoppFriction, *CONNECTORS.values())


class _Entry(NamedTuple):
    scope: str
    parameter: Parameter
    classes: tuple  # the classes declaring it


def _info(name: str, e: _Entry) -> ParameterInfo:
    p = e.parameter
    doc = f"{p.doc} ({name}:NAME)" if e.scope == "element" else p.doc
    return ParameterInfo(name, p.unit, p.low, p.high, p.low_open, p.high_open, p.transform, doc)


def _compose(classes) -> dict[str, _Entry]:
    """Base name -> its scope, its declaration and the classes declaring it; two classes that
    declare one name must agree on its scope, unit, range and transform."""
    out: dict[str, _Entry] = {}
    for cls in classes:
        for name, p in declared(cls).items():
            if name not in out:
                out[name] = _Entry(_scope(cls), p, (cls,))
                continue
            first = out[name]
            if (first.scope, first.parameter.range()) != (_scope(cls), p.range()):
                raise TypeError(f"parameter {name!r}: {cls.__name__} declares {p.range()} ({_scope(cls)}), "
                                f"{first.classes[0].__name__} {first.parameter.range()} ({first.scope})")
            out[name] = first._replace(classes=(*first.classes, cls))
    return out


_CATALOGUE = _compose(REGISTERED)

#: base name -> :class:`ParameterInfo` of every registered class's parameters
INFO = {name: _info(name, e) for name, e in sorted(_CATALOGUE.items())}
#: a force element's constants (``BASE:NAME``): base name -> the element's field
CONNECTOR_NAMES = {n: e.parameter.field for n, e in _CATALOGUE.items() if e.scope == "element"}
#: names of one component of a 2-vector leaf: name -> (leaf, component)
COMPONENTS = {n: (e.parameter.field, e.parameter.component) for n, e in _CATALOGUE.items()
              if e.parameter.component is not None}
#: old parameter name -> the name that replaced it (accepted with a DeprecationWarning)
DEPRECATED = {"width": "length"}
#: parameter name -> field of the joint's friction law (the parameters beyond ``friction``)
FRICTION_FIELDS = {n: p.field for n, p in FRICTION_PARAMETERS.items() if n != "friction"}
#: names that need a body (``NAME:BODY``)
BODY_NAMES = tuple(n for n, p in Body.PARAMETERS.items() if not p.keyed)
#: names of a load's numbers (``NAME:K``, ``K`` the index of the load in ``mech.loads``)
LOAD_NAMES = tuple(n for n, e in _CATALOGUE.items() if e.scope == "load")
#: derived names: several leaves set by one value (:func:`replace`), read as 0 (the shift from as given)
DERIVED = tuple(n for n, p in Body.PARAMETERS.items() if p.field == "points" and not p.keyed)


def parameter_names() -> list[str]:
    """Base names accepted by :func:`get`/:func:`replace` (see module docstring for suffixes):
    those of the registered classes (:data:`REGISTERED`)."""
    return sorted(INFO)


def leaf(owner, p: Parameter, key: str | None = None):
    """The leaf of ``p`` in ``owner`` (the dict entry ``key`` of a keyed leaf)."""
    value = functools.reduce(getattr, p.field.split("."), owner)
    return value[key] if p.keyed else value


class _Owner(NamedTuple):
    scope: str
    key: Any  # joint index, None (crank), body name, load index as text, element name
    where: Callable  # mech -> the owner
    obj: Any
    table: dict  # what it declares (declared(obj)), read once


def _owners(mech: Mechanism) -> list[_Owner]:
    """Everything in ``mech`` that declares parameters, in the order :func:`names` lists them."""
    out = [("joint", k, lambda m, k=k: m.clearance_joints[k], j) for k, j in enumerate(mech.clearance_joints)]
    found = crank_driver(mech)
    if found is not None:
        out.append(("crank", None, lambda m, i=found[0]: m.drivers[i], found[1]))
    out += [("body", b.name, lambda m, i=i: m.bodies[i], b) for i, b in enumerate(mech.bodies)]
    out.append(("body", GROUND, lambda m: m, mech))
    out += [("element", ld.name, lambda m, i=i: m.loads[i], ld) if isinstance(ld, AbstractConnector) else
            ("load", str(i), lambda m, i=i: m.loads[i], ld) for i, ld in enumerate(mech.loads)]
    return [o for o in (_Owner(*o, declared(o[3])) for o in out) if o.scope != "load" or o.table]


def _entries(mech: Mechanism | None, owners: list[_Owner] | None = None) -> dict[str, _Entry]:
    """The catalogue, plus the names declared by the classes in ``mech`` (``owners``) that are not registered."""
    if mech is None:
        return _CATALOGUE
    owners = _owners(mech) if owners is None else owners
    extra = {type(o.obj) for o in owners} - set(REGISTERED)
    extra |= {type(getattr(o.obj, part)) for o in owners if o.scope == "joint" for part in ("law", "friction")
              if getattr(o.obj, part, None) is not None}
    extra -= set(REGISTERED)
    return {**_compose(sorted(extra, key=lambda c: c.__qualname__)), **_CATALOGUE} if extra else _CATALOGUE


def _suffixed(o: _Owner, name: str) -> str:
    if o.scope == "joint":
        return name if o.key == 0 else f"{name}@{o.key}"
    return name if o.scope == "crank" else f"{name}:{o.key}"


def names(mech: Mechanism) -> list[str]:
    """Every name that addresses a number of ``mech`` (suffixed for each body, point, load and
    clearance joint ``@J``): what :func:`get`, :func:`replace`, :func:`jaxclear.sensitivities`
    and a design accept for this mechanism (:func:`jaxclear.differentiable_names`). Composed
    from the declarations of what ``mech`` holds."""
    out = []
    for o in _owners(mech):
        table = o.table
        plain = [n for n, p in table.items() if not p.keyed]
        out += [_suffixed(o, n) for n in (sorted(plain) if o.scope == "joint" else plain)]
        keyed = [n for n, p in table.items() if p.keyed]
        keys = leaf(o.obj, table[keyed[0]]._replace(keyed=False)) if keyed else ()
        out += [f"{n}:{o.key}.{k}" for k in keys for n in keyed]
    return out


def split_name(name: str, mech: Mechanism | None = None) -> tuple[str, int, str | None]:
    """``(base, joint, suffix)`` of a parameter name: ``"mass:rod"`` -> ``("mass", 0, "rod")``,
    ``"clearance@1"`` -> ``("clearance", 1, None)`` (a deprecated base replaced, with its
    warning); a malformed or unknown name is a :class:`~jaxclear.ParameterError`. With ``mech``,
    the names its own classes declare are known too."""
    base, joint, body = name, 0, None
    if "@" in base:
        base, j = base.split("@", 1)
        try:
            joint = int(j)
        except ValueError:
            raise ParameterError(f"parameter {name!r}: joint index after '@' must be an integer") from None
    if ":" in base:
        base, body = base.split(":", 1)
    if base in DEPRECATED:
        warnings.warn(f"parameter name {base!r} is deprecated; use {DEPRECATED[base]!r}", DeprecationWarning,
                      stacklevel=3)
        base = DEPRECATED[base]
    entry = _entries(mech).get(base)
    if entry is None:  # the closest names follow (closest), from check_name, get or info
        raise ParameterError(f"unknown parameter {name!r}")
    if entry.parameter.keyed and (body is None or "." not in body):
        raise ParameterError(f"parameter {name!r} needs a body and a point: {base}:BODY.POINT (ground.POINT for a "
                             "point of the frame)")
    if entry.scope == "body" and body is None:
        raise ParameterError(f"parameter {name!r} needs a body: {base}:BODY")
    if entry.scope == "load" and (body is None or not body.isdigit()):
        raise ParameterError(f"parameter {name!r} needs the index of a load: {base}:K (K in mech.loads)")
    return base, joint, body


def info(name: str, mech: Mechanism | None = None) -> ParameterInfo:
    """:class:`ParameterInfo` of a (possibly suffixed) parameter name; with ``mech``, also of the
    names its own classes declare."""
    try:
        base = split_name(name, mech)[0]
    except ParameterError as err:
        known = parameter_names() if mech is None else names(mech)
        raise ParameterError(f"{err}{closest(name, known, 'jc.params.parameter_names()')}") from None
    return _info(base, _entries(mech)[base])


class Address(NamedTuple):
    """Where a name of a mechanism lies: the object declaring it (``owner``, at
    ``owner_where(mech)``), its :class:`~jaxclear._parameters.Parameter` and, for a keyed leaf
    (a point), the key."""

    name: str
    owner: Any
    owner_where: Callable
    parameter: Parameter
    key: str | None

    def where(self, mech):
        """The leaf in ``mech`` (for ``eqx.tree_at``)."""
        return leaf(self.owner_where(mech), self.parameter, self.key)

    def value(self):
        """The value (the leaf, its component, or what ``read`` makes of it)."""
        p, value = self.parameter, leaf(self.owner, self.parameter, self.key)
        return p.read(self.owner) if p.read is not None else value if p.component is None else value[p.component]

    def check(self, values, context: str | None = None) -> np.ndarray:
        """:func:`validate` at this address (concrete ``values``; a float array back)."""
        p, arr = self.parameter, np.asarray(values, dtype=float)
        unit = "" if p.unit in ("", "law unit") else p.unit
        try:
            check_range(self.name, arr, low=p.low, high=p.high, low_open=p.low_open, high_open=p.high_open, unit=unit)
            if p.limit is not None:
                bound, what = p.limit(self.owner)
                if np.any(arr >= bound):
                    raise ParameterError(f"{self.name} = {arr.max():g} {unit} must be smaller than {what} {bound:g} {unit}")
        except ParameterError as err:
            if context is None:
                raise
            raise ParameterError(f"{context}: {err}") from None
        return arr

    def new_leaf(self, value):
        """The leaf that sets the parameter to ``value``."""
        p = self.parameter
        if p.write is not None:
            return p.write(self.owner, value)
        old = leaf(self.owner, p, self.key)
        return value if p.component is None else jnp.asarray(old, dtype=float).at[p.component].set(value)


def _missing(mech: Mechanism, name: str, base: str, entry: _Entry, k: int) -> JaxclearError:
    """Why a clearance joint has no ``base``, naming who has it."""
    joint = mech.clearance_joints[k]
    field = entry.parameter.field
    if any(issubclass(c, AbstractFriction) for c in entry.classes):
        having = sorted(n for n, (cls, _) in FRICTION_MODELS.items() if base in cls.PARAMETERS)
        return ParameterError(f"parameter {name!r}: friction law {type(joint.friction).__name__} of clearance joint "
                              f"{k} has no {field!r}; the friction models that have it: {having}")
    if any(issubclass(c, AbstractNormalLaw) for c in entry.classes):
        return ParameterError(f"parameter {name!r}: contact law {type(joint.law).__name__} has no {field!r}")
    owners = [c.__name__ for c in entry.classes]
    owners = ", ".join(owners[:-1]) + " or " + owners[-1] if len(owners) > 1 else owners[0]
    return ParameterError(f"parameter {name!r} belongs to a {owners}; clearance joint {k} is a "
                          f"{type(joint).__name__}")


def _lookup(mech: Mechanism, name: str) -> Address:
    """:func:`address` without the closest names (what :func:`check_name` adds them to)."""
    base, k, suffix = split_name(name, mech)
    owners = _owners(mech)
    entry = _entries(mech, owners)[base]
    key = None
    if entry.scope == "joint":
        if not mech.clearance_joints:
            raise ParameterError(f"parameter {name!r} needs a clearance joint; mechanism {mech.name!r} has none")
        if not 0 <= k < len(mech.clearance_joints):
            raise ParameterError(f"parameter {name!r}: joint index {k} outside [0, {len(mech.clearance_joints) - 1}]")
        owner = owners[k]
        if base not in owner.table:
            raise _missing(mech, name, base, entry, k)
    elif entry.scope == "crank":
        owner = next((o for o in owners if o.scope == "crank"), None)
        if owner is None:
            raise ParameterError(f"parameter {name!r} needs an AngleDriver; mechanism {mech.name!r} has none")
    elif entry.scope == "body":
        body, key = suffix.split(".", 1) if entry.parameter.keyed else (suffix, None)
        mech.body_index(body)  # an unknown body: MechanismError
        owner = next(o for o in owners if o.scope == "body" and o.key == body)
        table = owner.table
        if base not in table:
            raise ParameterError(f"parameter {name!r}: the ground has no {base}")
        points = leaf(owner.obj, table[base]._replace(keyed=False)) if key is not None else ()
        if key is not None and key not in points:
            raise ParameterError(f"parameter {name!r}: {body!r} has no point {key!r}; its points: {sorted(points)}")
    elif entry.scope == "load":
        i = int(suffix)
        if not i < len(mech.loads):
            raise ParameterError(f"parameter {name!r}: load index {i} outside [0, {len(mech.loads) - 1}] "
                                 f"({len(mech.loads)} loads)")
        owner = next((o for o in owners if o.scope == "load" and o.key == str(i)), None)
        if owner is None or base not in owner.table:
            raise ParameterError(f"parameter {name!r}: load {i} is a {type(mech.loads[i]).__name__}, which has no "
                                 f"{entry.parameter.field!r}")
    else:
        i = connector_index(mech.loads, base, suffix)
        owner = next(o for o in owners if o.scope == "element" and o.key == mech.loads[i].name)  # names are unique
    return Address(name, owner.obj, owner.where, owner.table[base], key)


def address(mech: Mechanism, name: str) -> Address:
    """Where ``name`` lies in ``mech`` (:class:`Address`). A name that addresses no number of
    ``mech`` is an error of its kind (:class:`~jaxclear.ParameterError`,
    :class:`~jaxclear.MechanismError`) saying why, then the closest names (:func:`closest`)."""
    try:
        return _lookup(mech, name)
    except JaxclearError as err:
        raise type(err)(f"{err}{closest(name, names(mech), 'jc.params.names(mech)')}") from None


def check_name(mech: Mechanism, name: str, context: str | None = None) -> Address:
    """The one check of a name: raise the error of :func:`get` unless ``name`` addresses a number
    of ``mech`` (why, then the closest names, :func:`closest`). With ``context`` (``"design
    variable 'x'"``), a :class:`~jaxclear.ParameterError` whose message is ``context: why``.
    Returns the name's :class:`Address` (its value, its declaration: unit and range)."""
    try:
        return address(mech, name)
    except JaxclearError as err:
        if context is None:
            raise
        raise ParameterError(f"{context}: {err}") from None


def get(mech: Mechanism, name: str):
    """Current value of a named parameter (SI; ``speed_rpm`` in rpm)."""
    return address(mech, name).value()


def replace(mech: Mechanism, name: str, value) -> Mechanism:
    """A new mechanism with parameter ``name`` set to ``value`` (a float, array or tracer).
    No validation here (``value`` may be traced): see :func:`validate`."""
    at = address(mech, name)
    return eqx.tree_at(at.where, mech, at.new_leaf(jnp.asarray(value, dtype=float)), is_leaf=lambda x: x is None)


def replace_many(mech: Mechanism, values: dict) -> Mechanism:
    """Apply :func:`replace` for every ``name: value``."""
    for name, value in values.items():
        mech = replace(mech, name, value)
    return mech


def is_derived(mech: Mechanism, name: str) -> bool:
    """Whether the value of ``name`` in ``mech`` is derived from other numbers rather than set: a
    ``stiffness`` whose law leaf (``law.stiffness_parameter``) is ``None``, computed by
    ``law.stiffness_value(R_B, R_J)`` from the materials (and, for the Hertz-type laws, the
    radii, so it follows ``clearance``); in general a name declared ``derived`` whose leaf is
    ``None``. Setting it (:func:`replace`) makes it explicit. (Not to be confused with the
    derived *names* ``centroid_x``/``centroid_y``, one value setting several leaves.)"""
    at = address(mech, name)
    return at.parameter.derived and leaf(at.owner, at.parameter, at.key) is None


def replace_following(mech: Mechanism, values: dict, base: dict) -> Mechanism:
    """``mech`` with each ``name`` moved from ``base[name]`` (its value in ``mech``) to
    ``values[name]``, derived values still following their sources: the names set in ``mech``
    are replaced (:func:`replace`); each derived one (:func:`is_derived`) is then set to its
    value derived from the new mechanism plus ``values[name] - base[name]``. At
    ``values == base`` the mechanism runs as ``mech``; the derivative with respect to a derived
    name is the change of its value alone (its sources held), and the one with respect to a
    source (``clearance``) carries the derived value along, as when it is asked alone. The rule
    of :func:`jaxclear.sensitivities`: a derivative's meaning does not depend on which other
    names are asked."""
    derived = [n for n in values if is_derived(mech, n)]
    out = replace_many(mech, {n: v for n, v in values.items() if n not in derived})
    return replace_many(out, {n: get(out, n) + (jnp.asarray(values[n], dtype=float) - base[n]) for n in derived})


def validate(mech: Mechanism, name: str, values, context: str | None = None) -> np.ndarray:
    """Check concrete ``values`` of parameter ``name`` against its declared range and a bound that
    depends on the mechanism (a clearance below the bearing radius); a float array back. With
    ``context``, errors read ``context: why`` (:func:`check_name`)."""
    return check_name(mech, name, context).check(values, context)


def to_unconstrained(name: str, value, mech: Mechanism | None = None):
    """Map a value in the parameter's range to the real line (``log`` or ``logit``)."""
    t, value = info(name, mech).transform, jnp.asarray(value, dtype=float)
    return jnp.log(value) if t == "log" else jnp.log(value) - jnp.log1p(-value) if t == "logit" else value


def from_unconstrained(name: str, z, mech: Mechanism | None = None):
    """Inverse of :func:`to_unconstrained`."""
    t = info(name, mech).transform
    return jnp.exp(z) if t == "log" else 1.0 / (1.0 + jnp.exp(-z)) if t == "logit" else z


__all__ = ["Address", "BODY_NAMES", "COMPONENTS", "CONNECTOR_NAMES", "DEPRECATED", "DERIVED", "FRICTION_FIELDS", "INFO",
           "LOAD_NAMES", "Parameter", "ParameterInfo", "REGISTERED", "address", "check_name", "closest", "from_unconstrained",
           "get", "info", "is_derived", "names", "parameter_names", "replace", "replace_following", "replace_many",
           "split_name", "to_unconstrained", "validate"]
