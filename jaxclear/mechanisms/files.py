"""Mechanism files: any planar mechanism as a TOML document (format in docs/mechanism-files.md).

A file holds what :class:`~jaxclear.Mechanism` holds, in SI units: bodies (mass, inertia, named
points, initial guesses of position and velocity), ideal joints, drivers, force elements (revolute
clearance, lubricated, pin-in-slot and translational clearance joints: geometry, law by name with
its parameters and profiles, friction, film, initial offset), applied loads, gravity, ground points
and roles. :func:`load_mechanism` reads one (the standard ``tomllib``, through the one TOML
reader :func:`jaxclear._storage.parse_toml`) and validates it: every error names the file, the
key and the allowed values. :func:`save_mechanism` writes one
(``tomli-w``); a mechanism written and read back is equal leaf by leaf (``eqx.tree_equal``).

Python functions (:class:`~jaxclear.FunctionDriver`, ``function=`` of a load) cannot be written to a
file; saving one raises :class:`~jaxclear.MechanismError` naming the function and the force element
(spring-damper, rotational spring-damper, bushing: ``loads`` of their own ``type``) to use instead.

This module sits beside :mod:`jaxclear.presets` (it builds laws and force elements, so it is
above ``contact/`` and ``elements/`` in the layers).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import os
import re
import warnings

import numpy as np
import tomli_w

from .._errors import JaxclearError, MechanismError, ParameterError, function_name
from .._storage import atomic_write_text, parse_toml, read_text
from .._units import rpm_to_rad_s
from ..contact import FourierProfile, Friction, Material, make_law
from ..contact.friction import FRICTION_MODELS, friction_name
from ..contact.registry import LAWS, law_names
from ..elements import TranslationalClearanceJoint
from ..model import Body, Mechanism
from .file_keys import (BODY_KEYS, CHOICES, DEPRECATED_KEYS, DRIVER_TYPES, ELEMENT_TYPES, FORMAT_VERSION,
                        INTEGER_KEYS, JOINT_TYPES, LOAD_TYPES, REQUIRED, STRING_KEYS, TABLE_PARAMETERS, TOP_KEYS,
                        VECTOR_KEYS)
from .tables import PROFILE_KINDS, load_tables, read_curve, read_profile
from ..model.mechanism import check_sizes

# ---- writing ------------------------------------------------------------------------------


def _number(value):
    """An array leaf as a TOML float or list of floats (exact: Python's float repr round-trips)."""
    arr = np.asarray(value)
    if arr.dtype.kind in "iub":
        return arr.tolist()
    return np.asarray(arr, dtype=float).tolist()


def _plain(value):  # a tuple of names (a flexible link's elements, its ends' (body, point)) as an array of strings
    return value if isinstance(value, (str, bool, int, float)) else (
        list(value) if isinstance(value, tuple) and all(isinstance(v, str) for v in value) else _number(value))


def _fields(module, keys) -> dict:
    return {k: _plain(getattr(module, k)) for k in keys if getattr(module, k) is not None}


def _no_function(item, where: str):
    """A :class:`~jaxclear.MechanismError` naming a load's Python function and what to do instead."""
    if getattr(item, "function", None) is not None:
        raise MechanismError(
            f"{where} ({item.label}) is given by the Python function {function_name(item.function)}: a mechanism file "
            "holds numbers, not code; a spring or damper between two points is a jaxclear.TranslationalSpringDamper "
            "(linear, preloaded, or with a PolynomialCurve or TableCurve), between two bodies' angles a "
            "RotationalSpringDamper, a compliant mount a Bushing, each saved with the file; any other function: save "
            "without this load and add it again after loading: m = eqx.tree_at(lambda m: m.loads, m, (*m.loads, load))")


def _typed(table: dict, item, where: str, skip=()) -> dict:
    for name, (cls, keys) in table.items():
        if type(item) is cls:
            _no_function(item, where)
            unset = {k for k in VECTOR_KEYS if k in keys and not np.any(np.asarray(getattr(item, k)))}  # the default
            return {"type": name, **_fields(item, [k for k in keys if k not in skip and k not in unset])}
    raise MechanismError(f"{where}: {type(item).__name__} cannot be written to a mechanism file; "
                         f"allowed types: {[c.__name__ for c, _ in table.values()]}")


def law_table(law) -> dict:
    """A contact law as a table: ``name`` plus every parameter that is set (materials and
    profiles as sub-tables)."""
    out = {"name": law.name}
    for f in dataclasses.fields(law):
        value = getattr(law, f.name)
        if f.name == "model" or value is None:
            continue
        if isinstance(value, (Material, FourierProfile)):
            out[f.name] = _fields(value, [g.name for g in dataclasses.fields(value)])
        else:
            out[f.name] = _plain(value)
    return out


def friction_table(friction) -> dict:
    """A friction law as a table: ``model``, ``coefficient`` and the model's own parameters."""
    name = friction_name(friction)
    if name not in FRICTION_MODELS:
        raise MechanismError(f"friction law {type(friction).__name__} cannot be written to a mechanism file; "
                             f"allowed models: {list(FRICTION_MODELS)}")
    return {"model": name, "coefficient": _number(friction.coefficient),
            **_fields(friction, FRICTION_MODELS[name][1])}


def mechanism_dict(mech: Mechanism) -> dict:
    """The TOML document of ``mech`` as nested dicts (what :func:`save_mechanism` writes)."""
    doc = {"format": FORMAT_VERSION, "name": mech.name, "gravity": _number(mech.gravity)}
    if mech.ground_points:
        doc["ground_points"] = {k: _number(v) for k, v in mech.ground_points.items()}
    if mech.roles:
        doc["roles"] = dict(mech.roles)
    doc["bodies"] = [
        {"name": b.name, "mass": _number(b.mass), "inertia": _number(b.inertia),
         "position": _number(b.position), "velocity": _number(b.velocity),
         "points": {k: _number(v) for k, v in b.points.items()}}
        for b in mech.bodies
    ]
    for key, items, table in (("joints", mech.joints, JOINT_TYPES), ("drivers", mech.drivers, DRIVER_TYPES),
                              ("loads", mech.loads, LOAD_TYPES)):
        if items:
            doc[key] = [_typed(table, item, f"{key}[{i}]") for i, item in enumerate(items)]
            for row, item in zip(doc[key], items):
                row.update(load_tables(item))  # a time profile, a spring's curve
    elements = []
    for i, el in enumerate(mech.clearance_joints):
        row = _typed(ELEMENT_TYPES, el, f"clearance_joints[{i}]", skip=("law", "friction"))
        row["law"], row["friction"] = law_table(el.law), friction_table(el.friction)
        elements.append(row)
    if elements:
        doc["clearance_joints"] = elements
    return doc


_NUMBER_ARRAY = re.compile(r"\[\n((?:[ ]+[-+0-9.eEinf]+,\n)+)\]")


def _inline_arrays(text: str) -> str:
    """tomli-w writes one number per line; short number arrays read better on one line."""
    return _NUMBER_ARRAY.sub(lambda m: "[" + ", ".join(v.strip().rstrip(",") for v in m.group(1).splitlines()) + "]",
                             text)


def dumps_mechanism(mech: Mechanism, comment: str = "") -> str:
    """The TOML text of ``mech``; ``comment`` (lines) goes into the header."""
    lines = [f"jaxclear mechanism file (format {FORMAT_VERSION}); SI units: m, kg, kg m^2, rad, s, N, Pa.",
             "Format: docs/mechanism-files.md", *comment.splitlines()]
    header = "".join(f"# {line}".rstrip() + "\n" for line in lines)
    return header + _inline_arrays(tomli_w.dumps(mechanism_dict(mech)))


def save_mechanism(mech: Mechanism, path, comment: str = "") -> str:
    """Write ``mech`` to a TOML file (atomically); returns the path."""
    return atomic_write_text(os.fspath(path), dumps_mechanism(mech, comment))


# ---- reading ------------------------------------------------------------------------------


class _Reader:
    """Validation context: every message starts with the file and the key."""

    def __init__(self, source: str):
        self.source = source
        # relative file names (a profile's CSV table) start from the mechanism file's folder
        self.folder = os.path.dirname(os.path.abspath(source)) if os.path.isfile(source) else os.getcwd()

    def fail(self, key: str, message: str, cls=MechanismError):
        raise cls(f"{self.source}: {key}: {message}")

    def table(self, key: str, value) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f"must be a table, got {type(value).__name__}")
        return value

    def array(self, key: str, value) -> list:
        if not isinstance(value, list):
            self.fail(key, f"must be an array of tables ([[{key}]]), got {type(value).__name__}")
        return value

    def keys(self, key: str, table: dict, allowed, required=()):
        for k in table:
            if k not in allowed:
                self.fail(f"{key}.{k}", f"unknown key; allowed keys: {sorted(allowed)}")
        for k in required:
            if k not in table:
                self.fail(f"{key}.{k}", f"missing (required keys: {sorted(required)})")

    def vector(self, key: str, value, size: int):
        ok = isinstance(value, list) and len(value) == size and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        if not ok:
            self.fail(key, f"must be an array of {size} numbers, got {value!r}", ParameterError)
        return [float(v) for v in value]

    def number(self, key: str, value):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f"must be a number, got {_shown(value)}", ParameterError)
        return value

    def integer(self, key: str, value):
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"must be an integer, got {_shown(value)}", ParameterError)
        return value

    def numbers(self, key: str, value):
        """A number or an array of numbers (a profile's Fourier coefficients)."""
        items = value if isinstance(value, list) else [value]
        if not items or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in items):
            self.fail(key, f"must be a number or an array of numbers, got {_shown(value)}", ParameterError)
        return value

    def string(self, key: str, value):
        if not isinstance(value, str):
            self.fail(key, f"must be a string, got {value!r}")
        return value

    def build(self, key: str, cls, kwargs: dict):
        """``cls(**kwargs)``, with any :class:`JaxclearError` re-raised naming the file and key."""
        try:
            return cls(**kwargs)
        except JaxclearError as err:
            raise type(err)(f"{self.source}: {key}: {err}") from None
        except TypeError as err:  # a key the constructor needs is missing (a force element's name)
            raise MechanismError(f"{self.source}: {key}: {err}") from None

    def points(self, key: str, value) -> dict:
        return {self.string(f"{key}", k): self.vector(f"{key}.{k}", v, 2) for k, v in self.table(key, value).items()}

    def typed(self, key: str, row, types: dict, default_type: str | None = None, skip=()):
        row = self.table(key, row)
        kind = row.get("type", default_type)
        if kind not in types:
            got = "missing" if kind is None else f"{kind!r} is not a valid type"
            self.fail(f"{key}.type", f"{got}; allowed: {sorted(types)}")
        cls, names = types[kind]
        extra = {"type", *skip}
        self.keys(key, row, {*names, *extra}, [n for n in names if n in REQUIRED])
        kwargs = {}
        for name in names:
            if name in row and name not in skip:
                kwargs[name] = self.value(f"{key}.{name}", name, row[name])
        return cls, kwargs

    def value(self, key: str, name: str, value):
        if name in CHOICES:
            if value not in CHOICES[name]:
                self.fail(key, f"{value!r} is not allowed; allowed: {list(CHOICES[name])}", ParameterError)
            return value
        if name in STRING_KEYS:
            return self.string(key, value)
        if name in ("axis", "force", "initial_offset", "initial_velocity"):
            return self.vector(key, value, 2)
        if name in VECTOR_KEYS:  # its length checked by the class (a flexible link's start: one per sde)
            return self.numbers(key, value)
        if name in INTEGER_KEYS:
            return self.integer(key, value)
        if isinstance(value, list) and value and all(isinstance(v, str) for v in value):
            return value  # names (a flexible link's elements and ends), checked by the class
        return self.number(key, value)


def _shown(value) -> str:
    """A value for a message: a table or array by its kind and size, anything else by ``repr``."""
    if isinstance(value, dict):
        return f"a table of {len(value)} key(s)"
    if isinstance(value, list) and len(value) > 4:
        return f"an array of {len(value)} items"
    return repr(value)


def _field_type(cls, name: str) -> str | None:
    """The annotation of field ``name`` of the module ``cls`` (``"str"``, ``"int"``, ...), or None."""
    return next((str(f.type) for f in dataclasses.fields(cls) if f.name == name), None)


def _law_value(r: _Reader, key: str, cls, name: str, value):
    """A law parameter: a string or an integer where the law's field is one (the hybrid model's
    ``placement``, ``n_gauss``; the hysteresis factor's name), else a number (an unknown name is
    left to the law, whose error lists its parameters)."""
    kind = _field_type(cls, name)
    if kind == "str":
        return r.string(key, value)
    if kind == "int":
        return r.integer(key, value)
    return r.number(key, value)


def _law(r: _Reader, key: str, table) -> object:
    table = dict(r.table(key, table))
    if "name" not in table:
        r.fail(f"{key}.name", "missing: the contact law's name", ParameterError)
    name = r.string(f"{key}.name", table.pop("name"))
    if name not in LAWS:
        r.fail(f"{key}.name", f"unknown contact law {name!r}; allowed: {law_names()}", ParameterError)
    kwargs = {}
    for k, v in table.items():
        suffix = next((s for s in TABLE_PARAMETERS if k.endswith(s)), None)
        if suffix is not None:
            cls, allowed = TABLE_PARAMETERS[suffix]
            sub = r.table(f"{key}.{k}", v)
            r.keys(f"{key}.{k}", sub, allowed)
            check = r.numbers if cls is FourierProfile else r.number
            kwargs[k] = r.build(f"{key}.{k}", cls, {a: check(f"{key}.{k}.{a}", b) for a, b in sub.items()})
        elif isinstance(v, dict):
            r.fail(f"{key}.{k}", f"a table is allowed only for keys ending in {list(TABLE_PARAMETERS)}")
        else:
            kwargs[k] = _law_value(r, f"{key}.{k}", LAWS[name][0], k, v)
    return r.build(key, functools.partial(make_law, name), kwargs)


def _friction(r: _Reader, key: str, table) -> object:
    table = r.table(key, table)
    allowed = set(inspect.signature(Friction).parameters)
    r.keys(key, table, allowed)
    kwargs = {k: (r.string if k == "model" else r.number)(f"{key}.{k}", v) for k, v in table.items()}
    return r.build(key, Friction, kwargs)


def _element(r: _Reader, key: str, row) -> object:
    row = r.table(key, row)
    kind = row.get("type", "revolute-clearance")
    for old, new in DEPRECATED_KEYS.get(kind, {}).items() if isinstance(kind, str) else ():
        if old in row:
            if new in row:
                r.fail(f"{key}.{old}", f"give {new!r} only ({old!r} is its old name)", ParameterError)
            warnings.warn(f"{r.source}: {key}.{old}: the key {old!r} is deprecated; write {new!r}",
                          DeprecationWarning, stacklevel=2)
            row = {(new if k == old else k): v for k, v in row.items()}
    cls, kwargs = r.typed(key, row, ELEMENT_TYPES, "revolute-clearance", skip=("law", "friction", "clearance"))
    if "law" in row:
        kwargs["law"] = _law(r, f"{key}.law", row["law"])
    if "friction" in row:
        kwargs["friction"] = _friction(r, f"{key}.friction", row["friction"])
    if "clearance" in row:
        c = float(r.number(f"{key}.clearance", row["clearance"]))
        if cls is TranslationalClearanceJoint:
            _guide_from_clearance(r, key, row, c, kwargs)
        else:
            _journal_from_clearance(r, key, row, c, kwargs)
    return r.build(key, cls, kwargs)


def _journal_from_clearance(r: _Reader, key: str, row: dict, c: float, kwargs: dict):
    """``clearance`` c instead of ``journal_radius``: R_J = R_B - c, c in (0, R_B)."""
    if "journal_radius" in row:
        r.fail(f"{key}.clearance", "give either clearance or journal_radius, not both", ParameterError)
    rb = float(row["bearing_radius"])
    if not 0.0 < c < rb:
        r.fail(f"{key}.clearance", f"{c:g} m is outside the allowed range (0, bearing_radius = {rb:g} m)",
               ParameterError)
    kwargs["journal_radius"] = rb - c


def _guide_from_clearance(r: _Reader, key: str, row: dict, c: float, kwargs: dict):
    """``clearance`` c per side instead of ``guide_width``: W = b + 2c, c > 0 (needs ``slider_height`` b)."""
    if "guide_width" in row:
        r.fail(f"{key}.clearance", "give either clearance (per side) or guide_width, not both", ParameterError)
    if "slider_height" not in row:
        r.fail(f"{key}.slider_height", "missing (needed with clearance: guide_width = slider_height + 2 clearance)",
               ParameterError)
    if not c > 0.0:
        r.fail(f"{key}.clearance", f"{c:g} m is outside the allowed range (0, inf) m (clearance per side)",
               ParameterError)
    kwargs["guide_width"] = float(row["slider_height"]) + 2.0 * c


def _driver(r: _Reader, key: str, row) -> object:
    row = r.table(key, row)
    if row.get("type") == "speed-profile":
        cls, kwargs = r.typed(key, row, DRIVER_TYPES, skip=("profile",))
        if "profile" not in row:
            r.fail(f"{key}.profile", f"missing: the speed profile table (kind: {sorted(PROFILE_KINDS)})",
                   ParameterError)
        kwargs["profile"] = read_profile(r, f"{key}.profile", row["profile"], r.folder, speed=True)
        return r.build(key, cls, kwargs)
    cls, kwargs = r.typed(key, row, DRIVER_TYPES, "angle", skip=("speed_rpm",))
    if "speed_rpm" in row:
        if "speed" in row:
            r.fail(f"{key}.speed_rpm", "give either speed [rad/s] or speed_rpm, not both", ParameterError)
        kwargs["speed"] = rpm_to_rad_s(float(r.number(f"{key}.speed_rpm", row["speed_rpm"])))
    if "speed" not in kwargs:
        r.fail(f"{key}.speed", "missing: the driver speed [rad/s] (or speed_rpm)", ParameterError)
    return r.build(key, cls, kwargs)


def _load(r: _Reader, key: str, row) -> object:
    cls, kwargs = r.typed(key, row, LOAD_TYPES, skip=("profile", "curve"))
    if "profile" in row:
        kwargs["profile"] = read_profile(r, f"{key}.profile", row["profile"], r.folder)
    if "curve" in row:
        kwargs["curve"] = read_curve(r, f"{key}.curve", row["curve"])
    return r.build(key, cls, kwargs)


def _body(r: _Reader, key: str, row) -> Body:
    row = r.table(key, row)
    r.keys(key, row, BODY_KEYS, ("name", "mass", "inertia"))
    kwargs = {"name": r.string(f"{key}.name", row["name"]),
              "mass": r.number(f"{key}.mass", row["mass"]), "inertia": r.number(f"{key}.inertia", row["inertia"]),
              "points": r.points(f"{key}.points", row.get("points", {}))}
    for k in ("position", "velocity"):
        if k in row:
            kwargs[k] = r.vector(f"{key}.{k}", row[k], 3)
    return r.build(key, Body, kwargs)


def mechanism_from_dict(doc: dict, source: str = "<mechanism>") -> Mechanism:
    """Build a :class:`~jaxclear.Mechanism` from a parsed document (``source`` names it in errors)."""
    r = _Reader(source)
    r.keys("(top level)", doc, TOP_KEYS, ("bodies",))
    if doc.get("format", FORMAT_VERSION) != FORMAT_VERSION:
        r.fail("format", f"unsupported format {doc['format']!r}; this version reads format {FORMAT_VERSION}")
    # sizes first: nothing of a size beyond the bounds is built
    check_sizes({key.replace("_", " "): len(doc[key]) for key in ("bodies", "joints", "drivers", "clearance_joints",
                                                                "loads") if isinstance(doc.get(key), list)},
                where=f"{source}: ")
    bodies = [_body(r, f"bodies[{i}]", row) for i, row in enumerate(r.array("bodies", doc["bodies"]))]
    joints = [r.build(f"joints[{i}]", *r.typed(f"joints[{i}]", row, JOINT_TYPES))
              for i, row in enumerate(r.array("joints", doc.get("joints", [])))]
    drivers = [_driver(r, f"drivers[{i}]", row) for i, row in enumerate(r.array("drivers", doc.get("drivers", [])))]
    loads = [_load(r, f"loads[{i}]", row) for i, row in enumerate(r.array("loads", doc.get("loads", [])))]
    elements = [_element(r, f"clearance_joints[{i}]", row)
                for i, row in enumerate(r.array("clearance_joints", doc.get("clearance_joints", [])))]
    roles = {k: r.string(f"roles.{k}", v) for k, v in r.table("roles", doc.get("roles", {})).items()}
    kwargs = dict(bodies=bodies, joints=joints, drivers=drivers, clearance_joints=elements, loads=loads,
                  ground_points=r.points("ground_points", doc.get("ground_points", {})), roles=roles,
                  name=r.string("name", doc.get("name", "mechanism")))
    if "gravity" in doc:
        kwargs["gravity"] = r.vector("gravity", doc["gravity"], 2)
    return r.build("(mechanism)", Mechanism, kwargs)


def loads_mechanism(text: str, source: str = "<string>") -> Mechanism:
    """Parse TOML text into a mechanism."""
    return mechanism_from_dict(parse_toml(text, source, MechanismError), source)


def load_mechanism(path) -> Mechanism:
    """Read a mechanism file (TOML, docs/mechanism-files.md)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise MechanismError(f"mechanism file {path!r} does not exist")
    return loads_mechanism(read_text(path, "mechanism file", MechanismError), path)


def is_mechanism_file(name) -> bool:
    """Whether a name given on the command line or in a sweep config is a file (``.toml``)."""
    return os.fspath(name).endswith(".toml")
