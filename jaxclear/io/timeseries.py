"""Files out: time series CSV and NetCDF (:func:`write_timeseries_netcdf`, an xarray Dataset
with units and the run's settings as attributes) and JSON; the same table as a pandas DataFrame
(:func:`timeseries_frame`). Measured data in: :mod:`jaxclear.io.records`.

Output CSV columns (:func:`timeseries_columns`), units in the names:

``time_s, crank_angle_rad, slider_pos_m, slider_vel_m_s, slider_acc_m_s2, ecc_x_m, ecc_y_m,
penetration_m, contact_force_n, friction_force_n``

The crank column appears only for a mechanism with a ``crank`` role, the slider columns only
with a ``slider`` role (its global x coordinate and derivatives), the contact columns only
with clearance joints, each followed by the element's own outputs (``type(joint).OUTPUTS``,
named with their unit: ``film_force_n``, ``min_film_thickness_m``, ``eccentricity_ratio``,
``rear_lower_normal_force_n``, ``feature``...); with several joints they get the suffixes
``_1``, ``_2``...
"""

from __future__ import annotations

import importlib
import os

import numpy as np

from .._storage import atomic_write_json, atomic_write_netcdf, json_text
from .._errors import ParameterError
from ..model import Mechanism
from ..integrate import Solution

CONTACT_COLUMNS = ("ecc_x_m", "ecc_y_m", "penetration_m", "contact_force_n", "friction_force_n")
SLIDER_COLUMNS = ("slider_pos_m", "slider_vel_m_s", "slider_acc_m_s2")


def timeseries_table(mech: Mechanism, sol: Solution) -> dict[str, np.ndarray]:
    """Column name -> 1-D array, in CSV order (see the module docstring)."""
    cols: dict[str, np.ndarray] = {"time_s": np.asarray(sol.ts, dtype=float)}
    crank = mech.role("crank")
    if crank is not None:
        cols["crank_angle_rad"] = np.asarray(sol.coordinate(mech, crank, "phi"), dtype=float)
    slider = mech.role("slider")
    if slider is not None:
        for d, name in enumerate(SLIDER_COLUMNS):
            cols[name] = np.asarray(sol.coordinate(mech, slider, "x", derivative=d), dtype=float)
    k = len(mech.clearance_joints)
    ecc = np.asarray(sol.ecc, dtype=float)
    per_joint = {
        "penetration_m": np.asarray(sol.penetration, dtype=float),
        "contact_force_n": np.asarray(sol.normal_force, dtype=float),
        "friction_force_n": np.asarray(sol.friction_force, dtype=float),
    }
    for j in range(k):
        suffix = f"_{j + 1}" if k > 1 else ""
        cols["ecc_x_m" + suffix] = ecc[:, j, 0]
        cols["ecc_y_m" + suffix] = ecc[:, j, 1]
        for name, arr in per_joint.items():
            cols[name + suffix] = arr[:, j]
        own = sol.element_outputs(mech, j)
        for name, unit in type(mech.clearance_joints[j]).OUTPUTS.items():
            cols[output_column(name, unit) + suffix] = np.asarray(own[name], dtype=float)
    return cols


#: unit of an element output -> the suffix of its column name
UNIT_SUFFIXES = {"N": "_n", "m": "_m", "-": ""}


def output_column(name: str, unit: str) -> str:
    """Column name of an element's own output ``name`` [``unit``] (e.g. ``film_force_n``)."""
    return name + UNIT_SUFFIXES[unit]


def timeseries_columns(mech: Mechanism) -> list[str]:
    """Header of :func:`write_timeseries_csv` for ``mech`` (no simulation needed)."""
    cols = ["time_s"]
    if mech.role("crank") is not None:
        cols.append("crank_angle_rad")
    if mech.role("slider") is not None:
        cols.extend(SLIDER_COLUMNS)
    k = len(mech.clearance_joints)
    for j in range(k):
        suffix = f"_{j + 1}" if k > 1 else ""
        cols.extend(c + suffix for c in CONTACT_COLUMNS)
        cols.extend(output_column(n, u) + suffix for n, u in type(mech.clearance_joints[j]).OUTPUTS.items())
    return cols


#: Unit of each time-series column (the suffix of its name), for DataFrame attributes.
COLUMN_UNITS = {"time_s": "s", "crank_angle_rad": "rad", "slider_pos_m": "m", "slider_vel_m_s": "m/s",
                "slider_acc_m_s2": "m/s^2", "ecc_x_m": "m", "ecc_y_m": "m", "penetration_m": "m",
                "contact_force_n": "N", "friction_force_n": "N"}


def column_unit(column: str) -> str:
    """Unit of a time-series column, from its name (a joint suffix ``_1``, ``_2`` allowed): the
    legacy columns' table, else the unit suffix of an element output (``_n``, ``_m``; none: -)."""
    base = column if column in COLUMN_UNITS else column.rsplit("_", 1)[0] if column[-1].isdigit() else column
    if base in COLUMN_UNITS:
        return COLUMN_UNITS[base]
    for unit, suffix in UNIT_SUFFIXES.items():
        if suffix and base.endswith(suffix):
            return unit
    return "-" if base else ""


def _pandas():
    """pandas, imported on first use (it adds about 0.6 s to ``import jaxclear``)."""
    return importlib.import_module("pandas")


def _frame(cols: dict, index: str):
    """DataFrame of ``cols`` indexed by column ``index``; ``df.attrs["units"]``: column -> unit."""
    pd = _pandas()
    df = pd.DataFrame({k: v for k, v in cols.items() if k != index}, index=pd.Index(cols[index], name=index))
    df.attrs["units"] = {c: column_unit(c) for c in cols}
    return df


def timeseries_frame(mech: Mechanism, sol: Solution):
    """The sampled solution as a :class:`pandas.DataFrame` indexed by ``time_s``: the columns of
    :func:`write_timeseries_csv` (crank angle, slider position/velocity/acceleration, per
    clearance joint eccentricity, penetration, contact and friction force), SI units in the
    names and in ``df.attrs["units"]``."""
    return _frame(timeseries_table(mech, sol), "time_s")


def write_timeseries_csv(path, mech: Mechanism, sol: Solution) -> str:
    """Write the sampled solution as CSV (header row, then one row per sample, 12 significant
    digits). Returns the path."""
    return write_table_csv(path, timeseries_table(mech, sol))


def _netcdf_name(column: str) -> tuple[str, str, str]:
    """``(variable name, long name, unit)`` of a time-series column: a legacy or element column
    keeps its name (unit from :func:`column_unit`); a channel column ``"NAME [UNIT]"`` becomes the
    variable ``NAME`` with ``:`` and other separators as ``_`` (the channel name as long name)."""
    if column.endswith("]") and " [" in column:
        name, unit = column[:-1].rsplit(" [", 1)
        var = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in name)
        return var, name, unit
    return column, column, column_unit(column)


def _attribute(value):
    """A run setting as a NetCDF 3 attribute (text or number; None as "none", a table as JSON)."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, (int, float, str)):
        return value
    if isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                for v in value):
        return np.asarray(value, dtype=float)
    return json_text(value, indent=None, sort_keys=False, default=str)


def timeseries_dataset(cols: dict, attrs: dict | None = None):
    """The time-series columns (name -> (T,) array, ``time_s`` first, as :func:`write_table_csv`
    takes them) as an :class:`xarray.Dataset` on the coordinate ``time`` [s]: one variable per
    column with ``units`` and ``long_name``, and ``attrs`` (the run's settings) as global
    attributes (None as "none", tables as JSON)."""
    xr = importlib.import_module("xarray")
    time = np.asarray(cols["time_s"], dtype=float)
    data, seen = {}, set()
    for column, values in cols.items():
        if column == "time_s":
            continue
        var, long, unit = _netcdf_name(column)
        if var in seen:
            raise ParameterError(f"time-series columns {column!r} and another one share the NetCDF name {var!r}")
        seen.add(var)
        data[var] = ("time", np.asarray(values, dtype=float), {"units": unit, "long_name": long})
    coords = {"time": ("time", time, {"units": "s", "long_name": "time"})}
    return xr.Dataset(data, coords=coords, attrs={k: _attribute(v) for k, v in (attrs or {}).items()})


def write_timeseries_netcdf(path, cols: dict, attrs: dict | None = None) -> str:
    """Write :func:`timeseries_dataset` as NetCDF (atomically). Returns the path."""
    return atomic_write_netcdf(path, timeseries_dataset(cols, attrs))


def write_table_csv(path, cols: dict) -> str:
    """Write columns (name -> 1-D array, equal lengths) as CSV, 12 significant digits."""
    data = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
    path = os.fspath(path)
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.12g")
    return path


def write_json(path, obj) -> str:
    """Write ``obj`` as indented JSON (arrays become lists, NaN/inf become null; keys in their
    order), atomically: a reader sees the old file or the new one, never a part. Returns the path."""
    return atomic_write_json(path, obj, sort_keys=False)


__all__ = ["write_timeseries_csv", "write_timeseries_netcdf", "timeseries_dataset", "timeseries_table",
           "timeseries_columns", "timeseries_frame", "write_table_csv", "write_json", "output_column",
           "column_unit", "CONTACT_COLUMNS", "SLIDER_COLUMNS", "COLUMN_UNITS", "UNIT_SUFFIXES"]
