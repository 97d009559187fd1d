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


def parameter_columns(names, mech) -> dict:
    """``{name: {"unit", "doc"}}`` of the swept parameters ``names`` (the manifest's
    ``parameter_columns``), asked of the registry with the mechanism (:func:`jaxclear.params.info`
    with ``mech``): a parameter of a class that the registry knows only through ``mech`` (a
    user's force element) has its unit and description in the results too, also when the folder
    is read back without the mechanism."""
    infos = {n: params.info(n, mech) for n in names}
    return {n: {"unit": i.unit, "doc": i.doc} for n, i in infos.items()}


def column_records(manifest: dict) -> dict:
    """The units and names a sweep's manifest records for its columns: its ``parameter_columns``
    (:func:`parameter_columns`) and ``channel_columns`` (:func:`channel_columns`); the
    ``channels`` of :func:`column_unit` and :func:`long_name`."""
    return {**manifest.get("parameter_columns", {}), **manifest.get("channel_columns", {})}


def column_unit(name: str, channels: dict | None = None) -> str:
    """Unit (CF spelling) of a ``runs.csv`` column: a metric, a parameter, or a bookkeeping column;
    ``channels``: the manifest's records of its columns (:func:`column_records`: the swept
    parameters as the mechanism declares them, the statistics of named channels); a parameter
    not recorded there is looked up in the registry's catalogue (without a mechanism)."""
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
    entry = channels.get(name) if channels else None
    if entry is not None:
        if "stat" in entry:
            return f"{entry['stat']} of {entry['channel']}"
        doc = entry["doc"]
    elif name in RUN_METRIC_KEYS:
        for suffix in ("_m_s2", "_n", "_m", "_j", "_s"):
            if name.endswith(suffix):
                return name[: -len(suffix)].replace("_", " ")
        return name.replace("_", " ")
    else:
        try:
            doc = params.info(name).doc
        except (JaxclearError, KeyError):
            return name.replace("_", " ")
    return doc if "@" not in name else f"{doc} ({name})"
