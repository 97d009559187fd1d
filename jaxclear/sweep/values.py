"""Parsing the swept values of one parameter (a list, one number or a range) and recognising
names that address the same quantity."""

from __future__ import annotations

import math

import numpy as np

from .. import params
from .._errors import ParameterError
from .._numbers import as_typed

#: Largest number of runs of one sweep (the (runs, parameters) table is built before anything
#: is compiled; a grid's size is the product of its axes' lengths), and so of one axis's values:
#: a range's ``num`` is checked against it before its values are made.
MAX_RUNS = 10_000_000
#: Keys of a range ``{start, stop, num, spacing}``.
RANGE_KEYS = ("start", "stop", "num", "spacing")


def _number(where: str, value) -> float:
    """``value`` as a finite float, or a :class:`ParameterError` naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{where}: expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{where}: values must be finite, got {value!r}")
    return v


def _range(where: str, spec: dict) -> np.ndarray:
    """``{start, stop, num, spacing: "linear" | "log"}`` -> (num,) values (both ends included),
    without the rounding noise of the spacing (:func:`~jaxclear._numbers.as_typed`: 0.7, not
    ``numpy.linspace``'s 0.7000000000000001)."""
    unknown = sorted(set(spec) - set(RANGE_KEYS))
    if unknown:
        raise ParameterError(f"{where}: unknown key(s) {unknown} in a range; allowed: {list(RANGE_KEYS)}")
    missing = [k for k in ("start", "stop", "num") if k not in spec]
    if missing:
        raise ParameterError(f"{where}: a range needs start, stop and num (missing {missing})")
    start, stop = _number(f"{where}.start", spec["start"]), _number(f"{where}.stop", spec["stop"])
    num = spec["num"]
    if isinstance(num, bool) or not isinstance(num, (int, np.integer)) or not 1 <= num <= MAX_RUNS:
        raise ParameterError(f"{where}.num = {num!r}: expected an integer in the allowed range [1, {MAX_RUNS}] "
                             "(jaxclear.sweep.config.MAX_RUNS, the most runs of a sweep)")
    spacing = spec.get("spacing", "linear")
    if spacing == "linear":
        return as_typed(np.linspace(start, stop, int(num)))
    if spacing == "log":
        if start <= 0 or stop <= 0:
            raise ParameterError(f"{where}: a log range needs start, stop > 0 (got {start:g}, {stop:g})")
        return as_typed(np.geomspace(start, stop, int(num)))
    raise ParameterError(f"{where}.spacing = {spacing!r}: expected 'linear' or 'log'")


def _values(name: str, spec) -> np.ndarray:
    """A parameter's values (float64, 1-D) from a list, a single number or a range dict."""
    where = f"parameter {name!r}"
    if isinstance(spec, dict):
        return _range(where, spec)
    if isinstance(spec, (list, tuple, np.ndarray)):
        if len(spec) > MAX_RUNS:
            raise ParameterError(f"{where}: {len(spec)} values, outside the allowed range [1, {MAX_RUNS}] "
                                 "(jaxclear.sweep.config.MAX_RUNS, the most runs of a sweep)")
        arr = np.asarray(spec, dtype=object).ravel()
        if arr.size == 0:
            raise ParameterError(f"{where}: empty list of values (give at least one)")
        return np.array([_number(f"{where}, value #{i + 1}", v) for i, v in enumerate(arr)], dtype=float)
    return np.array([_number(where, spec)])


def _canonical(name: str, mech) -> tuple:
    """What ``name`` addresses in ``mech`` (:func:`jaxclear.params.address`): the declaring object
    and its leaf, so that ``speed``/``speed_rpm`` and ``clearance``/``clearance@0`` are recognised
    as the same leaf, whichever class declares them (a force element of the user's included)."""
    at = params.address(mech, name)
    return (id(at.owner), at.parameter.field, at.key, at.parameter.component)


def _is_speed(name: str, mech) -> bool:
    """Whether ``name`` sets the crank speed (``speed`` or ``speed_rpm``)."""
    return params.split_name(name, mech)[0] in ("speed", "speed_rpm")
