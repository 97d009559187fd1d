"""Files in and out: time series CSV and NetCDF (:func:`write_timeseries_netcdf`, an xarray
Dataset with units and the run's settings as attributes), JSON, and measured data
(:func:`read_measurements`); the same tables as pandas DataFrames (:func:`timeseries_frame`,
:meth:`Measurements.to_dataframe`).

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

import csv
import importlib
import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from ._storage import MAX_RECORD_BYTES, atomic_write_json, atomic_write_netcdf, json_text, read_text
from ._errors import ParameterError
from .model import Mechanism
from .integrate import Solution

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


# --------------------------------------------------------------------------------------
# Measured data: a CSV of time_s, slider_acc_m_s2 and optional columns
# --------------------------------------------------------------------------------------

REQUIRED_MEASUREMENT_COLUMNS = ("time_s", "slider_acc_m_s2")
OPTIONAL_MEASUREMENT_COLUMNS = ("crank_angle_rad", "slider_pos_m", "slider_vel_m_s")


@dataclass
class Measurements:
    """Measured time series (SI units, 1-D float arrays of equal length).

    Attributes:
        time_s: sample times [s], strictly increasing.
        slider_acc_m_s2: slider acceleration [m/s^2].
        crank_angle_rad, slider_pos_m, slider_vel_m_s: optional columns (None if absent).
        metadata: ``key: value`` (or ``key = value``) pairs of the leading ``#`` lines; a
            comment line without a separator is kept under ``"comments"``.
        path: the file read.
    """

    time_s: np.ndarray
    slider_acc_m_s2: np.ndarray
    crank_angle_rad: np.ndarray | None = None
    slider_pos_m: np.ndarray | None = None
    slider_vel_m_s: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    path: str = ""

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    @property
    def columns(self) -> list[str]:
        """Names of the columns present."""
        names = REQUIRED_MEASUREMENT_COLUMNS + OPTIONAL_MEASUREMENT_COLUMNS
        return [n for n in names if getattr(self, n) is not None]

    def to_dataframe(self):
        """The record as a :class:`pandas.DataFrame` indexed by ``time_s`` (the columns present;
        units in the names and in ``df.attrs["units"]``; the metadata in ``df.attrs["metadata"]``)."""
        df = _frame({n: getattr(self, n) for n in self.columns}, "time_s")
        df.attrs["metadata"] = dict(self.metadata)
        return df


def _parse_metadata(text: str, metadata: dict):
    for sep in (":", "="):
        if sep in text:
            key, value = text.split(sep, 1)
            if key.strip():
                metadata[key.strip()] = value.strip()
                return
    if text:
        metadata.setdefault("comments", []).append(text)


def _record_lines(path: str, lines: list[str]):
    """Split a record's lines into ``(metadata, header, header_line, rows)``: the leading ``#``
    lines' metadata, the header fields and line number (None, 0 if absent), and ``(line
    number, fields)`` of the data rows; blank lines and later ``#`` lines are skipped."""
    metadata: dict = {}
    header: list[str] | None = None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(lines, start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if header is None:
                _parse_metadata(stripped.lstrip("#").strip(), metadata)
            continue
        fields = [c.strip() for c in next(csv.reader([line]))]
        if header is None:
            header, header_line = fields, lineno
        else:
            rows.append((lineno, fields))
    return metadata, header, header_line, rows


def _record_columns(path: str, header: list[str] | None, header_line: int,
                    required=REQUIRED_MEASUREMENT_COLUMNS, any_column: bool = False) -> dict[str, int]:
    """Known column name -> index in the header (``any_column``: every column); errors for a
    missing header, a duplicate or a missing required column, a warning (at the caller of
    :func:`read_measurements`) for unknown columns."""
    if header is None:
        raise ParameterError(f"{path}: no header row found (expected columns {list(required)})")
    seen = set()
    for name in header:
        if name in seen:
            raise ParameterError(f"{path}, line {header_line}: column {name!r} appears twice in the header")
        seen.add(name)
    missing = [c for c in required if c not in header]
    if missing:
        raise ParameterError(
            f"{path}, line {header_line}: missing required column(s) {missing} in header {header}; "
            f"required: {list(required)}, optional: "
            f"{'any' if any_column else list(OPTIONAL_MEASUREMENT_COLUMNS)}"
        )
    if any_column:
        return {name: header.index(name) for name in header}
    known = REQUIRED_MEASUREMENT_COLUMNS + OPTIONAL_MEASUREMENT_COLUMNS
    unknown = [c for c in header if c not in known]
    if unknown:
        warnings.warn(f"{path}: ignoring unknown column(s) {unknown} (known: {list(known)})", stacklevel=3)
    return {name: header.index(name) for name in known if name in header}


def _record_values(path: str, n_fields: int, header_line: int, rows, used: dict[str, int]) -> dict:
    """Column name -> float array of the data rows; errors name the line and column of a wrong
    number of fields, a non-numeric or a non-finite value."""
    values = {name: np.empty(len(rows)) for name in used}
    for r, (lineno, fields) in enumerate(rows):
        if len(fields) != n_fields:
            raise ParameterError(
                f"{path}, line {lineno}: {len(fields)} fields but the header (line {header_line}) has {n_fields}"
            )
        for name, col in used.items():
            text = fields[col]
            try:
                v = float(text)
            except ValueError:
                raise ParameterError(
                    f"{path}, line {lineno}, column {name!r}: non-numeric value {text!r}"
                ) from None
            if not math.isfinite(v):
                raise ParameterError(f"{path}, line {lineno}, column {name!r}: non-finite value {text!r}")
            values[name][r] = v
    return values


def _read_record_lines(path) -> tuple[str, list[str]]:
    path = os.fspath(path)
    return path, read_text(path, "measurements file", max_bytes=MAX_RECORD_BYTES, encoding="utf-8-sig").splitlines()


def _check_rows_and_time(path: str, rows, t):
    if len(rows) < 2:
        raise ParameterError(f"{path}: {len(rows)} data row(s); at least 2 samples are needed")
    bad = np.nonzero(np.diff(t) <= 0.0)[0]
    if bad.size:
        r = int(bad[0]) + 1
        raise ParameterError(
            f"{path}, line {rows[r][0]}, column 'time_s': time {t[r]:g} s is not greater than the previous "
            f"sample's {t[r - 1]:g} s (line {rows[r - 1][0]}); time must be strictly increasing"
        )


def read_record_columns(path, required=("time_s",)) -> tuple[dict, dict]:
    """Read a record CSV of the format of :func:`read_measurements` with any columns:
    ``(columns: name -> float array, metadata)``; ``required`` columns must be present
    (``time_s`` always). Same checks and messages as :func:`read_measurements`."""
    path, lines = _read_record_lines(path)
    required = tuple(dict.fromkeys(("time_s", *required)))
    metadata, header, header_line, rows = _record_lines(path, lines)
    used = _record_columns(path, header, header_line, required, any_column=True)
    values = _record_values(path, len(header), header_line, rows, used)
    _check_rows_and_time(path, rows, values["time_s"])
    return values, metadata


def read_measurements(path) -> Measurements:
    """Read a measured-data CSV (the record format of ``jaxclear fit``).

    Format: optional leading ``#`` metadata lines, one header row with units in the column
    names, then numeric rows. Required columns ``time_s`` [s] and ``slider_acc_m_s2``
    [m/s^2]; optional ``crank_angle_rad``, ``slider_pos_m``, ``slider_vel_m_s``. Unknown
    columns are ignored with a warning; blank lines and later ``#`` lines are skipped.

    Raises:
        ParameterError: missing file or header, missing required or duplicate column, wrong
            number of fields, non-numeric or non-finite value, time not strictly increasing, or
            fewer than 2 samples; the message names the file, line number and column.
    """
    path, lines = _read_record_lines(path)
    metadata, header, header_line, rows = _record_lines(path, lines)
    used = _record_columns(path, header, header_line)
    values = _record_values(path, len(header), header_line, rows, used)
    _check_rows_and_time(path, rows, values["time_s"])
    t = values["time_s"]
    return Measurements(
        time_s=t,
        slider_acc_m_s2=values["slider_acc_m_s2"],
        crank_angle_rad=values.get("crank_angle_rad"),
        slider_pos_m=values.get("slider_pos_m"),
        slider_vel_m_s=values.get("slider_vel_m_s"),
        metadata=metadata,
        path=path,
    )


__all__ = [
    "write_timeseries_csv",
    "write_timeseries_netcdf",
    "timeseries_dataset",
    "timeseries_table",
    "timeseries_columns",
    "write_json",
    "read_measurements",
    "Measurements",
]
