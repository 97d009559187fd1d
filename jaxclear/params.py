"""Named numeric parameters of a mechanism: read, replace (pytree-functionally, so the value may
be a tracer under ``vmap``/``grad``), validate and transform. Fits and sweeps address parameters
by these names; this module is the one place that maps a name to a leaf of the mechanism.

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
rod's centroid 10 mm towards its point of larger x. This is the one place that shift is made.

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

import warnings
from dataclasses import dataclass
from typing import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._errors import JaxclearError, ParameterError, check_range, closest
from ._units import rad_s_to_rpm, rpm_to_rad_s
from .contact.friction import FRICTION_MODELS
from .elements import LubricatedJoint, TranslationalClearanceJoint
from .model import GROUND, Mechanism, crank_driver
from .model.connectors import AbstractConnector, connector_parameters, connector_where


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


INFO = {
    "clearance": ParameterInfo("clearance", "m", 0.0, None, True, False, "log", "radial clearance R_B - R_J"),
    "restitution": ParameterInfo("restitution", "", 0.0, 1.0, True, False, "logit", "nominal coefficient of restitution"),
    "stiffness": ParameterInfo("stiffness", "law unit", 0.0, None, True, False, "log", "contact stiffness of the law"),
    "exponent": ParameterInfo("exponent", "", 0.0, None, True, False, "log", "force exponent n"),
    "friction": ParameterInfo("friction", "", 0.0, None, False, False, "log", "friction coefficient mu"),
    "friction_static": ParameterInfo("friction_static", "", 0.0, None, False, False, "log",
                                     "static friction coefficient mu_s"),
    "friction_viscous": ParameterInfo("friction_viscous", "s/m", 0.0, None, False, False, "log",
                                      "viscous friction coefficient mu_v (per newton of normal force)"),
    "v_stribeck": ParameterInfo("v_stribeck", "m/s", 0.0, None, True, False, "log", "Stribeck speed"),
    "stribeck_exponent": ParameterInfo("stribeck_exponent", "", 0.0, None, True, False, "log",
                                       "exponent of the Stribeck curve"),
    "v_threlfall": ParameterInfo("v_threlfall", "m/s", 0.0, None, True, False, "log", "Threlfall speed"),
    "v_transition": ParameterInfo("v_transition", "m/s", 0.0, None, True, False, "log",
                                  "Brown-McPhee transition speed"),
    "bristle_stiffness": ParameterInfo("bristle_stiffness", "1/m", 0.0, None, True, False, "log",
                                       "bristle stiffness sigma_0 (per newton of normal force)"),
    "bristle_damping": ParameterInfo("bristle_damping", "s/m", 0.0, None, False, False, "log",
                                     "bristle damping sigma_1 (per newton of normal force)"),
    "length": ParameterInfo("length", "m", 0.0, None, True, False, "log",
                            "axial length of the joint (a lubricated joint's film width)"),
    "viscosity": ParameterInfo("viscosity", "Pa s", 0.0, None, True, False, "log", "oil viscosity (lubricated joint)"),
    "speed": ParameterInfo("speed", "rad/s", None, None, False, False, "none", "crank speed"),
    "speed_rpm": ParameterInfo("speed_rpm", "rpm", None, None, False, False, "none", "crank speed"),
    "mass": ParameterInfo("mass", "kg", 0.0, None, True, False, "log", "body mass (mass:BODY)"),
    "inertia": ParameterInfo("inertia", "kg m^2", 0.0, None, True, False, "log", "body inertia (inertia:BODY)"),
    "point_x": ParameterInfo("point_x", "m", None, None, False, False, "none",
                             "x of a body-fixed point (point_x:BODY.POINT)"),
    "point_y": ParameterInfo("point_y", "m", None, None, False, False, "none",
                             "y of a body-fixed point (point_y:BODY.POINT)"),
    "centroid_x": ParameterInfo("centroid_x", "m", None, None, False, False, "none",
                                "shift of a body's centroid along its x axis, its points moving the other way "
                                "(centroid_x:BODY)"),
    "centroid_y": ParameterInfo("centroid_y", "m", None, None, False, False, "none",
                                "shift of a body's centroid along its y axis, its points moving the other way "
                                "(centroid_y:BODY)"),
    "load_x": ParameterInfo("load_x", "N", None, None, False, False, "none",
                            "x of the force of a point load (load_x:K, K its index in mech.loads)"),
    "load_y": ParameterInfo("load_y", "N", None, None, False, False, "none",
                            "y of the force of a point load (load_y:K)"),
    "torque": ParameterInfo("torque", "N m", None, None, False, False, "none",
                            "torque of a torque load (torque:K, K its index in mech.loads)"),
    "angle0": ParameterInfo("angle0", "rad", None, None, False, False, "none", "crank angle at t = 0"),
    "offset_x": ParameterInfo("offset_x", "m", None, None, False, False, "none",
                              "initial offset of the clearance joint, first component"),
    "offset_y": ParameterInfo("offset_y", "m", None, None, False, False, "none",
                              "initial offset of the clearance joint, second component"),
    "velocity_x": ParameterInfo("velocity_x", "m/s", None, None, False, False, "none",
                                "initial relative velocity of the clearance joint, first component"),
    "velocity_y": ParameterInfo("velocity_y", "m/s", None, None, False, False, "none",
                                "initial relative velocity of the clearance joint, second component"),
}

#: a force element's constants (``BASE:NAME``): base name -> the element's field
CONNECTOR_NAMES = {b: p.field for b, p in connector_parameters().items()}
INFO.update({b: ParameterInfo(b, p.unit, p.low, None, p.low_open, False, p.transform, f"{p.doc} ({b}:NAME)")
             for b, p in connector_parameters().items()})
#: names of one component of a 2-vector leaf: name -> (leaf kind, component)
COMPONENTS = {"load_x": ("load", 0), "load_y": ("load", 1), "point_x": ("point", 0), "point_y": ("point", 1), "centroid_x": ("centroid", 0),
              "centroid_y": ("centroid", 1), "offset_x": ("offset", 0), "offset_y": ("offset", 1),
              "velocity_x": ("velocity", 0), "velocity_y": ("velocity", 1)}

#: old parameter name -> the name that replaced it (accepted with a DeprecationWarning)
DEPRECATED = {"width": "length"}

#: parameter name -> field of the joint's friction law (the parameters beyond ``friction``)
FRICTION_FIELDS = {"friction_static": "static", "friction_viscous": "viscous", "v_stribeck": "v_stribeck",
                   "stribeck_exponent": "stribeck_exponent", "v_threlfall": "v_threlfall",
                   "v_transition": "v_transition", "bristle_stiffness": "bristle_stiffness",
                   "bristle_damping": "bristle_damping"}

#: names that need a body (``NAME:BODY``)
BODY_NAMES = ("mass", "inertia", "centroid_x", "centroid_y")
#: names of a load's numbers (``NAME:K``, ``K`` the index of the load in ``mech.loads``)
LOAD_NAMES = ("load_x", "load_y", "torque")
#: derived names: several leaves set by one value (:func:`replace`), read as 0 (the shift from as given)
DERIVED = ("centroid_x", "centroid_y")


def parameter_names() -> list[str]:
    """Base names accepted by :func:`get`/:func:`replace` (see module docstring for suffixes)."""
    return sorted(INFO)


def names(mech: Mechanism) -> list[str]:
    """Every name that addresses a number of ``mech`` (suffixed for each body, point, load and
    clearance joint ``@J``): what :func:`get`, :func:`replace`, :func:`jaxclear.sensitivities`
    and a design accept for this mechanism."""
    out = []
    for k, _ in enumerate(mech.clearance_joints):
        suffix = "" if k == 0 else f"@{k}"
        for base in parameter_names():
            if base in (*BODY_NAMES, "point_x", "point_y", "speed", "speed_rpm", "angle0", *LOAD_NAMES):
                continue
            try:
                _lookup(mech, base + suffix)
            except JaxclearError:
                continue
            out.append(base + suffix)
    if crank_driver(mech) is not None:
        out += ["speed", "speed_rpm", "angle0"]
    for body in mech.bodies:
        out += [f"{base}:{body.name}" for base in BODY_NAMES]
        out += [f"point_{c}:{body.name}.{p}" for p in body.points for c in "xy"]
    out += [f"point_{c}:{GROUND}.{p}" for p in mech.ground_points for c in "xy"]
    for i, load in enumerate(mech.loads):
        if isinstance(load, AbstractConnector):
            out += [f"{base}:{load.name}" for base in load.PARAMETERS]
        else:
            out += [f"torque:{i}"] if "torque" in type(load).__dataclass_fields__ else [f"load_x:{i}", f"load_y:{i}"]
    return out


def split_name(name: str) -> tuple[str, int, str | None]:
    """``(base, joint, suffix)`` of a parameter name: ``"mass:rod"`` -> ``("mass", 0, "rod")``,
    ``"clearance@1"`` -> ``("clearance", 1, None)`` (a deprecated base replaced, with its
    warning); a malformed or unknown name is a :class:`~jaxclear.ParameterError`."""
    base, joint = name, 0
    body = None
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
    if base not in INFO:  # the closest names follow (closest), from check_name, get or info
        raise ParameterError(f"unknown parameter {name!r}")
    if base in BODY_NAMES and body is None:
        raise ParameterError(f"parameter {name!r} needs a body: {base}:BODY")
    if base in LOAD_NAMES and (body is None or not body.isdigit()):
        raise ParameterError(f"parameter {name!r} needs the index of a load: {base}:K (K in mech.loads)")
    if base in ("point_x", "point_y") and (body is None or "." not in body):
        raise ParameterError(f"parameter {name!r} needs a body and a point: {base}:BODY.POINT (ground.POINT for a "
                             "point of the frame)")
    return base, joint, body


def info(name: str) -> ParameterInfo:
    """:class:`ParameterInfo` of a (possibly suffixed) parameter name."""
    try:
        return INFO[split_name(name)[0]]
    except ParameterError as err:
        raise ParameterError(f"{err}{closest(name, parameter_names(), 'jc.params.parameter_names()')}") from None


def _joint(mech: Mechanism, name: str, k: int):
    if not mech.clearance_joints:
        raise ParameterError(f"parameter {name!r} needs a clearance joint; mechanism {mech.name!r} has none")
    if not 0 <= k < len(mech.clearance_joints):
        raise ParameterError(f"parameter {name!r}: joint index {k} outside [0, {len(mech.clearance_joints) - 1}]")
    return mech.clearance_joints[k]


def _driver_index(mech: Mechanism, name: str) -> int:
    found = crank_driver(mech)
    if found is not None:
        return found[0]
    raise ParameterError(f"parameter {name!r} needs an AngleDriver; mechanism {mech.name!r} has none")


def _accessor(mech: Mechanism, name: str) -> tuple[Callable, Callable]:
    """(get, where) for a name; ``where(m)`` selects the leaf for ``eqx.tree_at``. A name that
    addresses no number of ``mech`` is an error of its kind (:class:`~jaxclear.ParameterError`,
    :class:`~jaxclear.MechanismError`) saying why, then the closest names (:func:`closest`)."""
    try:
        return _lookup(mech, name)
    except JaxclearError as err:
        raise type(err)(f"{err}{closest(name, names(mech), 'jc.params.names(mech)')}") from None


def check_name(mech: Mechanism, name: str) -> None:
    """Raise the error of :func:`get` unless ``name`` addresses a number of ``mech``: why, then
    the closest names (:func:`closest`)."""
    _accessor(mech, name)


def _lookup(mech: Mechanism, name: str) -> tuple[Callable, Callable]:
    """:func:`_accessor` without the closest names (what :func:`names` tries each name with)."""
    base, k, body = split_name(name)
    if base in BODY_NAMES:
        i = mech.body_index(body)
        if i < 0:
            raise ParameterError(f"parameter {name!r}: the ground has no {base}")
        if base in DERIVED:  # every point of the body; the value read is the shift from as given: 0
            where = lambda m: m.bodies[i].points  # noqa: E731
            return (lambda m: jnp.zeros((), dtype=float)), where
        where = (lambda m: m.bodies[i].mass) if base == "mass" else (lambda m: m.bodies[i].inertia)
        return where, where
    if base in ("speed", "speed_rpm", "angle0"):
        i = _driver_index(mech, name)
        field = "angle0" if base == "angle0" else "speed"
        w = lambda m: getattr(m.drivers[i], field)  # noqa: E731
        return w, w
    if base in LOAD_NAMES:
        i = int(body)
        if not i < len(mech.loads):
            raise ParameterError(f"parameter {name!r}: load index {i} outside [0, {len(mech.loads) - 1}] "
                                 f"({len(mech.loads)} loads)")
        load, field = mech.loads[i], "torque" if base == "torque" else "force"
        if field not in type(load).__dataclass_fields__:
            raise ParameterError(f"parameter {name!r}: load {i} is a {type(load).__name__}, which has no {field!r}")
        where = lambda m: getattr(m.loads[i], field)  # noqa: E731
        if base == "torque":
            return where, where
        k = COMPONENTS[base][1]
        return (lambda m: where(m)[k]), where
    if base in CONNECTOR_NAMES:
        w = connector_where(mech.loads, base, body)
        return w, w
    if base in ("point_x", "point_y"):
        owner, point = body.split(".", 1)
        if owner == GROUND:
            table = mech.ground_points
            where = lambda m: m.ground_points[point]  # noqa: E731
        else:
            i = mech.body_index(owner)
            if i < 0:
                raise ParameterError(f"parameter {name!r}: no body {owner!r}; bodies: {[b.name for b in mech.bodies]}")
            table = mech.bodies[i].points
            where = lambda m: m.bodies[i].points[point]  # noqa: E731
        if point not in table:
            raise ParameterError(f"parameter {name!r}: {owner!r} has no point {point!r}; its points: {sorted(table)}")
        k = COMPONENTS[base][1]
        return (lambda m: where(m)[k]), where
    if base in ("offset_x", "offset_y", "velocity_x", "velocity_y"):
        joint = _joint(mech, name, k)
        field = "initial_offset" if base.startswith("offset") else "initial_velocity"
        j = COMPONENTS[base][1]
        where = lambda m: getattr(m.clearance_joints[k], field)  # noqa: E731
        return (lambda m: where(m)[j]), where
    joint = _joint(mech, name, k)
    if base == "clearance":
        if isinstance(joint, TranslationalClearanceJoint):  # (W - b)/2: sets the guide width, block kept
            return (lambda m: m.clearance_joints[k].clearance), (lambda m: m.clearance_joints[k].guide_width)
        return (lambda m: m.clearance_joints[k].clearance), (lambda m: m.clearance_joints[k].journal_radius)
    if base == "friction":
        w = lambda m: m.clearance_joints[k].friction.coefficient  # noqa: E731
        return w, w
    if base in FRICTION_FIELDS:
        field = FRICTION_FIELDS[base]
        if field not in type(joint.friction).__dataclass_fields__:
            having = sorted(n for n, (cls, _) in FRICTION_MODELS.items() if field in cls.__dataclass_fields__)
            raise ParameterError(f"parameter {name!r}: friction law {type(joint.friction).__name__} of clearance "
                                 f"joint {k} has no {field!r}; the friction models that have it: {having}")
        w = lambda m: getattr(m.clearance_joints[k].friction, field)  # noqa: E731
        return w, w
    if base == "length":
        if isinstance(joint, TranslationalClearanceJoint):
            raise ParameterError(f"parameter {name!r}: a translational clearance joint has no axial length "
                                 "(its block has slider_length and slider_height)")
        w = lambda m: m.clearance_joints[k].length  # noqa: E731
        return w, w
    if base == "viscosity":
        if not isinstance(joint, LubricatedJoint):
            raise ParameterError(f"parameter {name!r} belongs to a LubricatedJoint; clearance joint {k} is a "
                                 f"{type(joint).__name__}")
        w = lambda m: m.clearance_joints[k].viscosity  # noqa: E731
        return w, w
    field = {"restitution": "restitution", "exponent": "exponent"}.get(base) or joint.law.stiffness_parameter
    if field not in type(joint.law).__dataclass_fields__:
        raise ParameterError(f"parameter {name!r}: contact law {type(joint.law).__name__} has no {field!r}")
    w = lambda m: getattr(m.clearance_joints[k].law, field)  # noqa: E731
    if base == "stiffness" and isinstance(joint, TranslationalClearanceJoint):  # always explicit
        return w, w
    if base == "stiffness":  # the leaf, or the value derived from the materials when it is None
        return (lambda m: m.clearance_joints[k].law.stiffness_value(
            m.clearance_joints[k].bearing_radius, m.clearance_joints[k].journal_radius)), w
    return w, w


def get(mech: Mechanism, name: str):
    """Current value of a named parameter (SI; ``speed_rpm`` in rpm)."""
    getter, _ = _accessor(mech, name)
    value = getter(mech)
    if split_name(name)[0] == "speed_rpm":
        value = rad_s_to_rpm(value)
    return value


def replace(mech: Mechanism, name: str, value) -> Mechanism:
    """A new mechanism with parameter ``name`` set to ``value`` (a float, array or tracer).
    No validation here (``value`` may be traced): see :func:`validate`."""
    _, where = _accessor(mech, name)
    base, k, _ = split_name(name)
    value = jnp.asarray(value, dtype=float)
    if base == "clearance" and isinstance(mech.clearance_joints[k], TranslationalClearanceJoint):
        value = mech.clearance_joints[k].slider_height + 2.0 * value
    elif base == "clearance":
        value = mech.clearance_joints[k].bearing_radius - value
    elif base == "speed_rpm":
        value = rpm_to_rad_s(value)
    elif base in DERIVED:  # the centroid moves by value along one body axis: every point by -value
        shift = jnp.zeros(2, dtype=float).at[COMPONENTS[base][1]].set(value)
        value = {p: jnp.asarray(v, dtype=float) - shift for p, v in where(mech).items()}
    elif base in COMPONENTS:  # one component of a 2-vector leaf
        value = jnp.asarray(where(mech), dtype=float).at[COMPONENTS[base][1]].set(value)
    return eqx.tree_at(where, mech, value, is_leaf=lambda x: x is None)


def replace_many(mech: Mechanism, values: dict) -> Mechanism:
    """Apply :func:`replace` for every ``name: value``."""
    for name, value in values.items():
        mech = replace(mech, name, value)
    return mech


def is_derived(mech: Mechanism, name: str) -> bool:
    """Whether the value of ``name`` in ``mech`` is derived from other numbers rather than set: a
    ``stiffness`` whose law leaf (``law.stiffness_parameter``) is ``None``, computed by
    ``law.stiffness_value(R_B, R_J)`` from the materials (and, for the Hertz-type laws, the
    radii, so it follows ``clearance``). Setting it (:func:`replace`) makes it explicit. (Not to
    be confused with the derived *names* ``centroid_x``/``centroid_y``, one value setting
    several leaves.)"""
    check_name(mech, name)
    base, k, _ = split_name(name)
    if base != "stiffness":
        return False
    law = mech.clearance_joints[k].law
    return getattr(law, law.stiffness_parameter, 0.0) is None


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


def validate(mech: Mechanism, name: str, values) -> np.ndarray:
    """Check concrete ``values`` of parameter ``name`` against its range (and, for
    ``clearance``, against the bearing radius). Returns them as a float array."""
    check_name(mech, name)
    base, k, _ = split_name(name)
    arr = np.asarray(values, dtype=float)
    p = INFO[base]
    check_range(name, arr, low=p.low, high=p.high, low_open=p.low_open, high_open=p.high_open,
                unit="" if p.unit in ("", "law unit") else p.unit)
    if base == "clearance" and not isinstance(mech.clearance_joints[k], TranslationalClearanceJoint):
        rb = float(mech.clearance_joints[k].bearing_radius)
        if np.any(arr >= rb):
            raise ParameterError(f"{name} = {arr.max():g} m must be smaller than the bearing radius {rb:g} m")
    return arr


def to_unconstrained(name: str, value):
    """Map a value in the parameter's range to the real line (``log`` or ``logit``)."""
    t = info(name).transform
    value = jnp.asarray(value, dtype=float)
    if t == "log":
        return jnp.log(value)
    if t == "logit":
        return jnp.log(value) - jnp.log1p(-value)
    return value


def from_unconstrained(name: str, z):
    """Inverse of :func:`to_unconstrained`."""
    t = info(name).transform
    if t == "log":
        return jnp.exp(z)
    if t == "logit":
        return 1.0 / (1.0 + jnp.exp(-z))
    return z


__all__ = ["BODY_NAMES", "COMPONENTS", "CONNECTOR_NAMES", "DEPRECATED", "DERIVED", "FRICTION_FIELDS", "INFO",
           "LOAD_NAMES", "ParameterInfo", "check_name", "closest", "from_unconstrained", "get", "info", "is_derived",
           "names", "parameter_names", "replace", "replace_following", "replace_many", "split_name", "to_unconstrained",
           "validate"]
