"""Measured data in: a CSV of ``time_s``, ``slider_acc_m_s2`` and optional columns
(:func:`read_measurements`, :class:`Measurements`, and :meth:`Measurements.to_dataframe`), and the
columns of a record file (:func:`read_record_columns`)."""

from __future__ import annotations

import csv
import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._errors import ParameterError
from .._storage import MAX_RECORD_BYTES, read_text
from .timeseries import _frame

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


__all__ = ["read_measurements", "Measurements", "read_record_columns", "REQUIRED_MEASUREMENT_COLUMNS",
           "OPTIONAL_MEASUREMENT_COLUMNS"]
