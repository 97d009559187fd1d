"""Time profiles in mechanism files: the ``profile`` table of a ``speed-profile`` driver or of a
load (docs/mechanism-files.md), read into a :mod:`~jaxclear.model.profiles` profile and written
back; and the ``curve`` table of a nonlinear spring (:mod:`~jaxclear.model.curves`). Only numbers,
arrays of numbers and a CSV file of numbers are read: no text is evaluated.

A table's values may come inline (``time = [...]``, ``values = [...]``) or from ``file``, a CSV
of two columns (time [s], value; an optional header row), relative to the mechanism file's
folder. A driver's profile is a speed in rad/s, or in rev/min with ``unit = "rpm"``.
"""

from __future__ import annotations

import csv
import os

import numpy as np

from .._errors import JaxclearError, MechanismError, ParameterError
from .._units import rpm_to_rad_s
from ..model.curves import PolynomialCurve, TableCurve
from ..model.profiles import PROFILE_KINDS, ConstantProfile, HarmonicProfile, RampProfile, TableProfile

#: kind -> (keys with numbers, keys scaled by a speed unit)
PROFILE_KEYS = {
    "constant": (("value",), ("value",)),
    "ramp": (("value", "ramp_time"), ("value",)),
    "harmonic": (("value", "amplitude", "frequency", "phase"), ("value", "amplitude")),
    "table": (("time", "values", "file"), ("values",)),
}
#: a spring's ``curve`` table: kind -> (class, its array keys in constructor order)
CURVE_KINDS = {"polynomial": (PolynomialCurve, ("coefficients",)), "table": (TableCurve, ("deflection", "forces"))}
#: speed units of a driver's profile -> factor to rad/s
SPEED_UNITS = {"rad/s": 1.0, "rpm": rpm_to_rad_s(1.0)}


def profile_table(profile) -> dict:
    """A profile as a mechanism-file table (driver speeds in rad/s)."""
    if isinstance(profile, ConstantProfile):
        return {"kind": "constant", "value": float(profile.value0)}
    if isinstance(profile, RampProfile):
        return {"kind": "ramp", "value": float(profile.value0), "ramp_time": float(profile.ramp_time)}
    if isinstance(profile, HarmonicProfile):
        return {"kind": "harmonic", "value": float(profile.value0), "amplitude": float(profile.amplitude),
                "frequency": float(profile.frequency), "phase": float(profile.phase)}
    if isinstance(profile, TableProfile):
        return {"kind": "table", "time": np.asarray(profile.time).tolist(), "values": np.asarray(profile.values).tolist()}
    raise MechanismError(f"a {type(profile).__name__} cannot be written to a mechanism file; allowed: "
                         f"{sorted(PROFILE_KINDS)}")


def read_csv_table(path: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    """``(time, values)`` of a two-column CSV of numbers (first row skipped if it is a header)."""
    if not os.path.isfile(path):
        raise ParameterError(f"{where}: file {path!r} does not exist")
    with open(path, newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    out = []
    for i, row in enumerate(rows):
        try:
            values = [float(c) for c in row]
        except ValueError:
            if i == 0:
                continue  # a header row
            raise ParameterError(f"{where}: {path}: row {i + 1} is not two numbers: {row!r}") from None
        if len(values) != 2:
            raise ParameterError(f"{where}: {path}: row {i + 1} has {len(values)} columns; expected 2 (time [s], value)")
        out.append(values)
    if len(out) < 2:
        raise ParameterError(f"{where}: {path}: needs at least 2 rows of (time [s], value)")
    data = np.asarray(out)
    return data[:, 0], data[:, 1]


def read_profile(reader, key: str, table, base_dir: str, speed: bool = False):
    """The profile of table ``table`` at ``key`` (``reader``: the mechanism file's validation
    context, whose messages name the file and key); ``speed``: a driver's (``unit`` allowed)."""
    table = dict(reader.table(key, table))
    kind = table.pop("kind", None)
    if kind not in PROFILE_KINDS:
        got = "missing" if kind is None else f"{kind!r} is not a profile kind"
        reader.fail(f"{key}.kind", f"{got}; allowed: {sorted(PROFILE_KINDS)}", ParameterError)
    scale = 1.0
    if speed:
        unit = table.pop("unit", "rad/s")
        if unit not in SPEED_UNITS:
            reader.fail(f"{key}.unit", f"{unit!r} is not allowed; allowed: {list(SPEED_UNITS)}", ParameterError)
        scale = SPEED_UNITS[unit]
    keys, scaled = PROFILE_KEYS[kind]
    reader.keys(key, table, keys)
    args = {}
    for name, value in table.items():
        if name == "file":
            args["file"] = reader.string(f"{key}.file", value)
        elif name in ("time", "values"):
            if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                      for v in value):
                reader.fail(f"{key}.{name}", f"must be an array of numbers, got {value!r}", ParameterError)
            args[name] = np.asarray(value, dtype=float)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            args[name] = float(value)
        else:
            reader.fail(f"{key}.{name}", f"must be a number, got {value!r}", ParameterError)
    if kind == "table":
        if "file" in args:
            if "time" in args or "values" in args:
                reader.fail(f"{key}.file", "give either file or time and values, not both", ParameterError)
            path = os.path.join(base_dir, args.pop("file"))
            args["time"], args["values"] = read_csv_table(path, f"{reader.source}: {key}.file")
        elif "time" not in args or "values" not in args:
            reader.fail(f"{key}.values", "a table needs time and values (or file)", ParameterError)
    for name in scaled:
        if name in args:
            args[name] = args[name] * scale
    try:
        return PROFILE_KINDS[kind](**args)
    except JaxclearError as err:
        raise type(err)(f"{reader.source}: {key}: {err}") from None


def load_tables(item) -> dict:
    """The tables of a load in a mechanism file: its time ``profile`` and a spring's ``curve``
    (``{kind, coefficients}`` or ``{kind, deflection, forces}``), those it has."""
    out = {}
    if getattr(item, "profile", None) is not None:
        out["profile"] = profile_table(item.profile)
    curve = getattr(item, "curve", None)
    if curve is not None:
        keys = CURVE_KINDS[curve.kind][1]
        out["curve"] = {"kind": curve.kind, **{k: np.asarray(getattr(curve, k)).tolist() for k in keys}}
    return out


def read_curve(reader, key: str, table):
    """A spring's force-deflection curve from its ``curve`` table (``reader``: the mechanism file's
    validation context)."""
    table = dict(reader.table(key, table))
    kind = table.pop("kind", None)
    if kind not in CURVE_KINDS:
        got = "missing" if kind is None else f"{kind!r} is not a curve kind"
        reader.fail(f"{key}.kind", f"{got}; allowed: {sorted(CURVE_KINDS)}", ParameterError)
    cls, keys = CURVE_KINDS[kind]
    reader.keys(key, table, keys, keys)
    for name, value in table.items():
        if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                  for v in value):
            reader.fail(f"{key}.{name}", f"must be an array of numbers, got {value!r}", ParameterError)
    return reader.build(key, cls, {k: np.asarray(table[k], dtype=float) for k in keys})
