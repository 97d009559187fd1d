"""Sweep results as labelled data: an :class:`xarray.Dataset` (swept parameters as dimensions
of a grid, metrics as variables, units as attributes), a :class:`pandas.DataFrame` (one row per
run) and ``OUT/results.nc`` (NetCDF 3 through xarray's ``scipy`` engine, so no HDF5 library is
needed).

Layout of the dataset (CF-style attributes ``units`` and ``long_name`` on every variable):

* grid sweep: one dimension per swept parameter (first name first), its values as the
  coordinate; a run not on disk yet (an interrupted sweep) is NaN in the float variables, -1 in
  the integer ones (``run``, ``status``, step counts) and ``""`` in ``status_message``;
* list sweep: the dimension ``run`` (the run index), the parameters as coordinates along it;
* variables: every column of ``runs.csv`` that is not a parameter (``t_end_s``, the metrics of
  :data:`jaxclear.analysis.metrics.RUN_METRIC_KEYS`, the named channels' statistics
  ``STAT__KEY`` with the channel's unit and ``long_name`` "STAT of CHANNEL", ``status``,
  ``status_message``, ``run``)
  and ``poincare`` with the extra dimensions ``section``, ``joint`` and ``coordinate``
  (:data:`~jaxclear.sweep.store.POINCARE_COORDS`), where the runs have Poincare points (a
  mechanism without a clearance joint has none);
* dataset attributes: the sweep's mode (``sweep_mode``: a global attribute ``mode`` would
  clash with scipy's NetCDF writer), preset, run settings and hash from the manifest.
"""

from __future__ import annotations

import os

import numpy as np
import pandas as pd
import xarray as xr

from .._storage import atomic_write_netcdf, json_text
from .labels import column_records, column_unit, long_name
from .store import NETCDF_NAME, POINCARE_COORDS

_POINCARE_UNITS = ("m", "m", "m s-1", "m s-1")


def _attrs(name: str, channels: dict | None = None) -> dict:
    """CF attributes of a column (``channels``: the manifest's records of its columns,
    :func:`~jaxclear.sweep.labels.column_records`)."""
    return {"units": column_unit(name, channels), "long_name": long_name(name, channels)}


def _grid_index(table: dict, names, axes: dict) -> tuple:
    """Position of every run on each grid axis (nearest value: the CSV round-trips floats)."""
    return tuple(np.argmin(np.abs(np.asarray(axes[n])[:, None] - table[n][None, :]), axis=0) for n in names)


def _filled(shape, col: np.ndarray, idx) -> np.ndarray:
    if col.dtype == object:
        out = np.full(shape, "", dtype=object)
    elif np.issubdtype(col.dtype, np.integer):
        out = np.full(shape, -1, dtype=np.int64)
    else:
        out = np.full(shape, np.nan)
    out[idx] = col
    return out


def _manifest_attrs(manifest: dict) -> dict:
    """Flat, NetCDF-safe dataset attributes (str and numbers only) from the manifest."""
    cfg = manifest.get("config", {})
    attrs = {"title": "jaxclear sweep", "sweep_mode": cfg.get("mode", ""), "sweep_hash": manifest.get("sweep_hash", ""),
             "mechanism": json_text(cfg.get("mechanism", {}), indent=None),
             "status_codes": json_text(manifest.get("status_codes", {}), indent=None)}
    for key, value in cfg.get("run", {}).items():
        attrs[key] = int(value) if isinstance(value, bool) else value
    return attrs


def to_dataset(table: dict, names, axes: dict, mode: str, poincare: np.ndarray, manifest: dict) -> xr.Dataset:
    """The labelled dataset of a sweep (see the module docstring); the pieces of a
    :class:`~jaxclear.sweep.SweepResult`."""
    names = list(names)
    columns = [c for c in table if c not in names]
    chan = column_records(manifest)
    points = np.asarray(poincare)
    # no points (no clearance joint, or no whole revolution after the transient): no variable, as a
    # dimension of length 0 is NetCDF 3's unlimited one, which scipy writes but cannot read back
    has_points = points.ndim == 4 and points.shape[0] == len(table.get("run", ())) and points.size > 0
    if mode == "grid":
        dims = names
        shape = tuple(len(axes[n]) for n in names)
        idx = _grid_index(table, names, axes)
        coords = {n: (n, np.asarray(axes[n], dtype=float), _attrs(n, chan)) for n in names}
        data = {c: (dims, _filled(shape, table[c], idx), _attrs(c, chan)) for c in columns}
        if "status_message" in data:
            data["status_message"] = (dims, data["status_message"][1].astype(str), _attrs("status_message"))
        if has_points:
            full = np.full(shape + points.shape[1:], np.nan)
            full[idx] = points
            points = full
    else:
        dims = ["run"]
        coords = {"run": ("run", table["run"], _attrs("run"))}
        coords.update({n: ("run", table[n], _attrs(n, chan)) for n in names})
        data = {c: (dims, np.asarray(table[c]).astype(str) if c == "status_message" else table[c], _attrs(c, chan))
                for c in columns if c != "run"}
    if has_points:
        data["poincare"] = (dims + ["section", "joint", "coordinate"], points,
                            {"units": ", ".join(_POINCARE_UNITS), "long_name": "journal state relative to the bearing "
                             "at every whole crank revolution after the transient (Poincare section)"})
        coords["coordinate"] = ("coordinate", list(POINCARE_COORDS), {"long_name": "e_x, e_y [m]; v_x, v_y [m s-1]"})
    return xr.Dataset(data, coords=coords, attrs=_manifest_attrs(manifest))


def to_dataframe(table: dict, names, channels: dict | None = None) -> pd.DataFrame:
    """One row per run, indexed by the run index; ``df.attrs["units"]``: column -> unit
    (``channels``: the manifest's records of its columns, :func:`~jaxclear.sweep.labels.column_records`)."""
    df = pd.DataFrame({c: v for c, v in table.items() if c != "run"}, index=pd.Index(table["run"], name="run"))
    df.attrs["units"] = {c: column_unit(c, channels) for c in df.columns}
    df.attrs["parameters"] = list(names)
    return df


def write_netcdf(ds: xr.Dataset, path) -> str:
    """Write ``ds`` as NetCDF 3 (xarray's ``scipy`` engine) atomically (through
    :func:`jaxclear._storage.atomic_write_bytes`: the file is the old or the new one, never a
    mix). Returns the path."""
    return atomic_write_netcdf(path, ds)


def open_dataset(path) -> xr.Dataset:
    """Read a sweep's ``results.nc`` back (``path``: the file or the sweep folder), loaded into
    memory and the file closed."""
    path = os.fspath(path)
    if os.path.isdir(path):
        path = os.path.join(path, NETCDF_NAME)
    with xr.open_dataset(path, engine="scipy") as ds:
        return ds.load()
