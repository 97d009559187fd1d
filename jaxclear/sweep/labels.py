"""Units and readable names of the columns of a sweep (parameters, metrics, bookkeeping), in the
CF spelling (UDUNITS): the attributes of the labelled dataset (:mod:`jaxclear.sweep.dataset`)
and the axis labels of the figures (:mod:`jaxclear.sweep.figures`). No xarray here, so the
figures do not import it."""

from __future__ import annotations

import re

from .. import params
from .._errors import JaxclearError
from ..analysis.metrics import CHANNEL_STATS, RUN_METRIC_KEYS

#: Unit strings of the project (``RUN_METRIC_KEYS``, ``params``) -> UDUNITS spelling (CF).
_CF_UNITS = {"-": "1", "": "1", "m/s^2": "m s-2", "m/s": "m s-1", "rad/s": "rad s-1", "kg m^2": "kg m2",
             "m or rad": "m or rad"}
_COLUMN_UNITS = {"t_end_s": "s", "run": "1", "status_message": "", "ideal_status": "1"}


def _cf(unit: str) -> str:
    return _CF_UNITS.get(unit, unit)


def channel_key(channel: str) -> str:
    """A channel name as a column name: every character but letters, digits and ``_`` becomes
    ``_`` (NetCDF variable names), e.g. ``joint:0:min_film_thickness`` -> ``joint_0_min_film_thickness``."""
    return re.sub(r"[^A-Za-z0-9_]", "_", channel)


def channel_column(channel: str, stat: str) -> str:
    """The ``runs.csv`` column of statistic ``stat`` (:data:`CHANNEL_STATS`) of a named output
    channel: ``STAT__KEY`` (:func:`channel_key`), e.g. ``min__joint_0_min_film_thickness``."""
    return f"{stat}__{channel_key(channel)}"


def channel_columns(channels: dict) -> dict:
    """``{column: {"channel", "stat", "unit"}}`` of the sweep's channels ``{name: unit}`` (the
    manifest's ``channel_columns``: the units and names of those columns)."""
    return {channel_column(c, s): {"channel": c, "stat": s, "unit": u} for c, u in channels.items()
            for s in CHANNEL_STATS}


def column_unit(name: str, channels: dict | None = None) -> str:
    """Unit (CF spelling) of a ``runs.csv`` column: a metric, a parameter, or a bookkeeping column;
    ``channels``: the manifest's ``channel_columns`` (:func:`channel_columns`) for the statistics
    of named channels."""
    if channels and name in channels:
        return _cf(channels[name]["unit"])
    if name in _COLUMN_UNITS:
        return _COLUMN_UNITS[name]
    if name in RUN_METRIC_KEYS:
        return _cf(RUN_METRIC_KEYS[name])
    try:
        return _cf(params.info(name).unit)
    except (JaxclearError, KeyError):
        return ""


def long_name(name: str, channels: dict | None = None) -> str:
    """Readable name of a column: a parameter's description, a metric without its unit suffix,
    ``rms of joint:0:film_force`` for a channel statistic (``channels``: as in :func:`column_unit`)."""
    if channels and name in channels:
        return f"{channels[name]['stat']} of {channels[name]['channel']}"
    if name in RUN_METRIC_KEYS:
        for suffix in ("_m_s2", "_n", "_m", "_j", "_s"):
            if name.endswith(suffix):
                return name[: -len(suffix)].replace("_", " ")
        return name.replace("_", " ")
    try:
        doc = params.info(name).doc
    except (JaxclearError, KeyError):
        return name.replace("_", " ")
    return doc if "@" not in name else f"{doc} ({name})"
