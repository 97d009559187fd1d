"""Units and readable names of the columns of a sweep (parameters, metrics, bookkeeping), in the
CF spelling (UDUNITS): the attributes of the labelled dataset (:mod:`jaxclear.sweep.dataset`)
and the axis labels of the figures (:mod:`jaxclear.sweep.figures`). No xarray here, so the
figures do not import it."""

from __future__ import annotations

from .. import params
from .._errors import JaxclearError
from ..analysis.metrics import RUN_METRIC_KEYS

#: Unit strings of the project (``RUN_METRIC_KEYS``, ``params``) -> UDUNITS spelling (CF).
_CF_UNITS = {"-": "1", "": "1", "m/s^2": "m s-2", "m/s": "m s-1", "rad/s": "rad s-1", "kg m^2": "kg m2",
             "m or rad": "m or rad"}
_COLUMN_UNITS = {"t_end_s": "s", "run": "1", "status_message": "", "ideal_status": "1"}


def _cf(unit: str) -> str:
    return _CF_UNITS.get(unit, unit)


def column_unit(name: str) -> str:
    """Unit (CF spelling) of a ``runs.csv`` column: a metric, a parameter, or a bookkeeping column."""
    if name in _COLUMN_UNITS:
        return _COLUMN_UNITS[name]
    if name in RUN_METRIC_KEYS:
        return _cf(RUN_METRIC_KEYS[name])
    try:
        return _cf(params.info(name).unit)
    except (JaxclearError, KeyError):
        return ""


def long_name(name: str) -> str:
    """Readable name of a column: a parameter's description, a metric without its unit suffix."""
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
