"""Sweep folder layout and writing: ``OUT/runs.csv`` (one row per run, appended and fsync-ed
chunk by chunk), ``OUT/manifest.json`` (the sweep's definition and its hash) and
``OUT/chunks/chunk_NNNNNN.npz`` (Poincare points, time series). Crash-safe writes go through
:mod:`jaxclear._storage`.

Resuming: run indices already in the CSV are skipped, a partial last line left by a kill is cut
off, and a folder that holds a *different* sweep (another :meth:`SweepConfig.sweep_hash`) is an
error.
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
from .._storage import atomic_write_json, atomic_write_npz, fsync_append
from .._errors import ParameterError
from ..analysis.metrics import RUN_METRIC_KEYS
from .._errors import STATUS
from .config import SweepConfig

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
_INT_COLUMNS = ("run", "impacts", "num_steps", "num_accepted_steps", "num_rejected_steps", "status", "ideal_status")


def csv_columns(cfg: SweepConfig) -> list[str]:
    """Header of ``runs.csv``: run index, parameters, metrics, statuses and the status message."""
    keys = _metric_keys(cfg)
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


def _repair_csv(path: str, columns: list[str]) -> set[int]:
    """Cut a partial last line (left by a kill), check the header and every row, return the run
    indices present. Raises :class:`ParameterError` for a header of another sweep, a malformed
    row that is not the last, or a repeated run index."""
    with open(path, "rb") as f:
        data = f.read()
    if data and not data.endswith(b"\n"):
        cut = data.rfind(b"\n") + 1
        with open(path, "r+b") as f:
            f.truncate(cut)
            f.flush()
            os.fsync(f.fileno())
        data = data[:cut]
    if not data:
        fsync_append(path, ",".join(columns) + "\n", mode="w")
        return set()
    rows = list(csv.reader(_io.StringIO(data.decode("utf-8"))))
    if rows[0] != columns:
        raise ParameterError(f"{path}: its header {rows[0]} is not this sweep's {columns}; "
                             "use another output folder or restart=True (--restart)")
    done: set[int] = set()
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(columns):
            raise ParameterError(f"{path}, line {lineno}: {len(row)} fields, expected {len(columns)} (corrupt file)")
        i = int(row[0])
        if i in done:
            raise ParameterError(f"{path}, line {lineno}: run {i} appears twice (corrupt file)")
        done.add(i)
    return done


def _discard(out: str):
    """Remove a previous sweep's manifest, CSV and chunks from ``out`` (restart)."""
    for name in (MANIFEST_NAME, CSV_NAME):
        if os.path.exists(os.path.join(out, name)):
            os.remove(os.path.join(out, name))
    for name in os.listdir(os.path.join(out, CHUNK_DIR)):
        if name.startswith("chunk_") and name.endswith(".npz"):
            os.remove(os.path.join(out, CHUNK_DIR, name))


def _check_previous(out: str, digest: str, layout: dict):
    """Refuse a folder holding another sweep; warn when resuming with another batch layout."""
    manifest_path = os.path.join(out, MANIFEST_NAME)
    if not os.path.exists(manifest_path):
        if os.path.exists(os.path.join(out, CSV_NAME)):
            raise ParameterError(f"{os.path.join(out, CSV_NAME)} exists without {MANIFEST_NAME}: not a jaxclear "
                                 "sweep folder; use another output folder or restart=True (--restart)")
        return
    with open(manifest_path, encoding="utf-8") as f:
        old = json.load(f)
    if old.get("sweep_hash") != digest:
        raise ParameterError(
            f"{out} holds a different sweep (manifest hash {str(old.get('sweep_hash'))[:12]}..., this one "
            f"{digest[:12]}...); use another output folder or restart=True (--restart) to discard it")
    for key in ("chunk_size", "devices"):
        if old.get("layout", {}).get(key) != layout[key]:
            warnings.warn(
                f"resuming {out} with {key} = {layout[key]} (the sweep started with {old['layout'].get(key)}): "
                "the runs still to do are batched differently, which changes their results in the last bits "
                "(and the chaotic dynamics amplify that)", stacklevel=4)


def manifest(cfg: SweepConfig, layout: dict) -> dict:
    """The manifest: format, hash, definition, batch layout, status codes, Poincare layout."""
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
    }


def prepare_output(cfg: SweepConfig, out: str, restart: bool, layout: dict) -> set[int]:
    """Create or check the output folder, write the manifest; returns the run indices already
    done (the CSV's, after cutting a partial last line)."""
    os.makedirs(os.path.join(out, CHUNK_DIR), exist_ok=True)
    if restart:
        _discard(out)
    _check_previous(out, cfg.sweep_hash(), layout)
    atomic_write_json(os.path.join(out, MANIFEST_NAME), manifest(cfg, layout))
    csv_path = os.path.join(out, CSV_NAME)
    if not os.path.exists(csv_path):
        fsync_append(csv_path, ",".join(csv_columns(cfg)) + "\n", mode="w")
        return set()
    return _repair_csv(csv_path, csv_columns(cfg))


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
        lines.append(",".join(_csv_quote(_fmt(col, row[col])) for col in columns) + "\n")
    fsync_append(os.path.join(out, CSV_NAME), "".join(lines))
    return len(lines)
