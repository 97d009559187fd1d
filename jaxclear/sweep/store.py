"""Sweep folder layout and writing: ``OUT/runs.csv`` (one row per run, appended and fsync-ed
chunk by chunk), ``OUT/manifest.json`` (the sweep's definition and its hash) and
``OUT/chunks/chunk_NNNNNN.npz`` (Poincare points, time series). Crash-safe writes go through
:mod:`jaxclear._storage`.

Resuming: run indices already in the CSV are skipped, a partial last line left by a kill is cut
off, and a folder that holds a *different* sweep (another :meth:`SweepConfig.sweep_hash`) is an
error; so is a damaged file (a bad byte, a garbled row, a cut manifest): the error names the file
and the line, and offers ``--restart``.
"""

from __future__ import annotations

import csv
import io as _io
import json
import math
import os
import warnings

import numpy as np

from .._numbers import as_typed
from .._checkpoint import Work, append_lines, cut_partial_line, damaged as _damaged
from .._storage import atomic_write_json, atomic_write_npz, fsync_append
from .._errors import CheckpointError, ParameterError
from ..analysis.metrics import RUN_METRIC_KEYS
from .._errors import STATUS
from .config import SweepConfig
from .labels import channel_columns, parameter_columns

CSV_NAME = "runs.csv"
MANIFEST_NAME = "manifest.json"
CHUNK_DIR = "chunks"
#: The labelled dataset (:mod:`jaxclear.sweep.dataset`), rewritten when a sweep finishes.
NETCDF_NAME = "results.nc"
FORMAT_VERSION = 1

#: Poincare coordinates, in the order of the last axis of the ``poincare`` arrays.
POINCARE_COORDS = ("e_x", "e_y", "v_x", "v_y")

_CONTACT_KEYS = ("peak_contact_force_n", "rms_contact_force_n", "max_penetration_m", "impacts",
                 "fraction_free_flight", "fraction_impact", "fraction_continuous_contact",
                 "energy_dissipated_j", "energy_dissipated_per_rev_j")
#: CSV columns read back as integers (``impacts`` stays a float: NaN for a failed run).
_INT_READ = ("run", "num_steps", "num_accepted_steps", "num_rejected_steps", "status", "ideal_status")
_INT_COLUMNS = ("run", "impacts", "num_steps", "num_accepted_steps", "num_rejected_steps", "status", "ideal_status")


def csv_columns(cfg: SweepConfig) -> list[str]:
    """Header of ``runs.csv``: run index, parameters, metrics, statuses and the status message."""
    keys = _metric_keys(cfg) + list(channel_columns(cfg.channel_units))
    cols = ["run", *cfg.names, "t_end_s"] + [k for k in keys if k != "status"]
    if cfg.ideal is not None:
        cols.append("ideal_status")
    return cols + ["status", "status_message"]


def _metric_keys(cfg: SweepConfig) -> list[str]:
    """The metrics that apply to the sweep's mechanism (contact ones need a clearance joint,
    slider ones a slider, deviation ones the ideal reference)."""
    mech = cfg.base_mechanism
    keys = list(RUN_METRIC_KEYS)
    if not mech.clearance_joints:
        keys = [k for k in keys if k not in _CONTACT_KEYS]
    if mech.role("slider") is None:
        keys = [k for k in keys if "slider" not in k and "deviation" not in k]
    elif cfg.ideal is None:
        keys = [k for k in keys if "deviation" not in k]
    return keys


def _fmt(col: str, value) -> str:
    """One CSV field: integers as such, floats by ``repr`` (round-trips bit-exactly)."""
    if col == "status_message":
        return str(value)
    v = float(value)
    if col in _INT_COLUMNS and math.isfinite(v):
        return str(int(round(v)))
    if col == "t_end_s":  # the revolutions and the speed the user gave, without their arithmetic's noise
        v = as_typed(v)
    return repr(v)


def _csv_quote(text: str) -> str:
    if any(ch in text for ch in ',"\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


RESTART = "--restart (API: restart=True)"


def damaged(path: str, detail: str) -> CheckpointError:
    """The error of a damaged file of a sweep folder (:func:`jaxclear._checkpoint.damaged`):
    names the file and what is wrong with it, and offers ``--restart``."""
    return _damaged(path, detail, RESTART)


def work(cfg: SweepConfig, out: str) -> Work:
    """The sweep in ``out`` as a piece of resumable work (:mod:`jaxclear._checkpoint`): its key
    the sweep's hash, its configuration the sweep's description, its header the manifest's."""
    return Work(out, "sweep", cfg.sweep_hash(), cfg.describe(), version=FORMAT_VERSION, restart=RESTART)


def parse_rows(path: str, data: bytes, columns: list[str] | None = None) -> tuple[list[str], list[list[str]]]:
    """``(header, rows)`` of ``runs.csv``'s complete lines ``data``: every row checked (UTF-8,
    its number of fields, an integer run index >= 0 that appears once, a number in every
    numeric column); ``columns``: the header it must have (else an error naming both). Raises
    :func:`damaged` errors naming the line."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise damaged(path, f"line {line}: byte 0x{data[err.start]:02x} is not UTF-8 text") from None
    try:
        rows = list(csv.reader(_io.StringIO(text)))
    except csv.Error as err:
        raise damaged(path, f"not a CSV table: {err}") from None
    if not rows or not rows[0]:
        raise damaged(path, "line 1: no header")
    header = rows[0]
    if columns is not None and header != columns:
        raise ParameterError(f"{path}: its header {header} is not this sweep's {columns}; "
                             "use another output folder or restart=True (--restart)")
    if header[0] != "run":
        raise damaged(path, f"line 1: the first column is {header[0]!r}, not 'run'")
    numeric = [j for j, col in enumerate(header) if col != "status_message"]
    done: set[int] = set()
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise damaged(path, f"line {lineno}: {len(row)} fields, expected {len(header)}")
        try:
            i = int(row[0])
        except ValueError:
            raise damaged(path, f"line {lineno}: run index {row[0]!r} is not an integer") from None
        if i < 0:
            raise damaged(path, f"line {lineno}: run index {i} is negative")
        if i in done:
            raise damaged(path, f"line {lineno}: run {i} appears twice")
        done.add(i)
        for j in numeric:
            try:
                int(row[j]) if header[j] in _INT_READ else float(row[j])
            except ValueError:
                what = "an integer" if header[j] in _INT_READ else "a number"
                raise damaged(path, f"line {lineno}, column {header[j]!r}: {row[j]!r} is not {what}") from None
    return header, rows[1:]


def repair_csv(path: str, columns: list[str], n_runs: int | None = None) -> set[int]:
    """Cut a partial last line (left by a kill), check the header and every row
    (:func:`parse_rows`), return the run indices present. Raises :class:`ParameterError` for a
    header of another sweep, :class:`~jaxclear.CheckpointError` for a damaged row that is not the
    last, a repeated run index or one outside ``[0, n_runs)``."""
    data = cut_partial_line(path)
    if not data:
        fsync_append(path, ",".join(columns) + "\n", mode="w")
        return set()
    _, rows = parse_rows(path, data, columns)
    done = {int(row[0]) for row in rows}
    if n_runs is not None and done and max(done) >= n_runs:
        raise damaged(path, f"run index {max(done)} is outside this sweep's [0, {n_runs})")
    return done


def read_manifest(out: str) -> dict:
    """``OUT/manifest.json``, checked to be a sweep's manifest (a :func:`damaged` error naming
    the file otherwise)."""
    path = os.path.join(out, MANIFEST_NAME)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as err:
        raise CheckpointError(f"cannot read {path}: {err.strerror or err}") from None
    try:
        doc = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as err:
        raise damaged(path, f"byte 0x{data[err.start]:02x} at offset {err.start} is not UTF-8 text") from None
    except ValueError as err:
        raise damaged(path, f"not valid JSON: {err}") from None
    config = doc.get("config") if isinstance(doc, dict) else None
    if not isinstance(config, dict) or not isinstance(doc.get("names"), list) or \
            not isinstance(config.get("parameters"), dict) or "sweep_hash" not in doc:
        raise damaged(path, "not a jaxclear sweep manifest: 'sweep_hash', 'names' or 'config' missing")
    return doc


def _discard(out: str):
    """Remove a previous sweep's manifest, CSV and chunks from ``out`` (restart)."""
    for name in (MANIFEST_NAME, CSV_NAME):
        if os.path.exists(os.path.join(out, name)):
            os.remove(os.path.join(out, name))
    for name in os.listdir(os.path.join(out, CHUNK_DIR)):
        if name.startswith("chunk_") and name.endswith(".npz"):
            os.remove(os.path.join(out, CHUNK_DIR, name))


def _check_previous(out: str, sweep: Work, layout: dict):
    """The checkpoint protocol's rules on the manifest (a folder holding another sweep is
    refused, naming what changed; another format is an error); warn when resuming with another
    batch layout."""
    manifest_path = os.path.join(out, MANIFEST_NAME)
    if not os.path.exists(manifest_path):
        if os.path.exists(os.path.join(out, CSV_NAME)):
            raise ParameterError(f"{os.path.join(out, CSV_NAME)} exists without {MANIFEST_NAME}: not a jaxclear "
                                 "sweep folder; use another output folder or restart=True (--restart)")
        return
    old = read_manifest(out)
    sweep.check({"kind": "sweep", "format": old.get("format_version"), "key": old.get("sweep_hash"),
                 "config": old.get("config")}, manifest_path)
    started = old.get("layout") if isinstance(old.get("layout"), dict) else {}
    for key in ("chunk_size", "devices"):
        if started.get(key) != layout[key]:
            warnings.warn(
                f"resuming {out} with {key} = {layout[key]} (the sweep started with {started.get(key)}): "
                "the runs still to do are batched differently, which changes their results in the last bits "
                "(and the chaotic dynamics amplify that)", stacklevel=4)


def manifest(cfg: SweepConfig, layout: dict) -> dict:
    """The manifest: format, hash, definition, batch layout, status codes, Poincare layout, the
    units and names of the channel and parameter columns (not hashed: rewritten on resume)."""
    return {
        "format_version": FORMAT_VERSION,
        "sweep_hash": cfg.sweep_hash(),
        "n_runs": cfg.n_runs,
        "names": list(cfg.names),
        "columns": csv_columns(cfg),
        "config": cfg.describe(),
        "layout": layout,
        "status_codes": {str(k): v for k, v in STATUS.items()},
        "poincare_coords": list(POINCARE_COORDS),
        "base_clearance_m": [float(c.clearance) for c in cfg.base_mechanism.clearance_joints],
        "section_samples": list(cfg.section),
        "channel_columns": channel_columns(cfg.channel_units),
        "parameter_columns": parameter_columns(cfg.names, cfg.base_mechanism),
    }


def prepare_output(cfg: SweepConfig, out: str, restart: bool, layout: dict) -> set[int]:
    """Create or check the output folder, write the manifest; returns the run indices already
    done (the CSV's, after cutting a partial last line)."""
    os.makedirs(os.path.join(out, CHUNK_DIR), exist_ok=True)
    if restart:
        _discard(out)
    _check_previous(out, work(cfg, out), layout)
    atomic_write_json(os.path.join(out, MANIFEST_NAME), manifest(cfg, layout))
    csv_path = os.path.join(out, CSV_NAME)
    if not os.path.exists(csv_path):
        fsync_append(csv_path, ",".join(csv_columns(cfg)) + "\n", mode="w")
        return set()
    return repair_csv(csv_path, csv_columns(cfg), cfg.n_runs)


def write_chunk(cfg: SweepConfig, out: str, c: int, lo: int, res: dict, done: set[int]) -> int:
    """Store chunk ``c`` (runs ``lo .. lo + len``): its NPZ (all runs), then one CSV row per run
    not already ``done``, appended and fsync-ed. ``res``: output key -> (len, ...) arrays.
    Returns the number of rows written."""
    n = len(res["status"])
    arrays = {"run": np.arange(lo, lo + n), "poincare": res["poincare"]}
    arrays.update({k: v for k, v in res.items() if k.startswith("traj_")})
    atomic_write_npz(os.path.join(out, CHUNK_DIR, f"chunk_{c:06d}.npz"), arrays)
    columns = csv_columns(cfg)
    lines = []
    for j, i in enumerate(range(lo, lo + n)):
        if i in done:
            continue
        row = {"run": i, **{n_: cfg.values[i, p] for p, n_ in enumerate(cfg.names)}}
        row.update({k: res[k][j] for k in columns if k in res})
        row["status_message"] = STATUS.get(int(res["status"][j]), "unknown status")
        lines.append(",".join(_csv_quote(_fmt(col, row[col])) for col in columns))
    append_lines(os.path.join(out, CSV_NAME), lines)
    return len(lines)
