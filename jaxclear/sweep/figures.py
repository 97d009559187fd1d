"""Sweep figures (PNG, thin wrappers over :mod:`jaxclear.plot`): a metric's heat map over a 2-D
grid, the bifurcation diagram of the Poincare section against a parameter, and the Poincare
sections themselves. Axis labels and units come from the labelled dataset
(:meth:`SweepResult.to_xarray`); lengths are shown in mm, other quantities in SI units."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._errors import ParameterError
from .._storage import json_text
from ..plot import plot_bifurcation, plot_heatmap, plot_poincare
from .labels import column_records, column_unit, long_name
from .store import POINCARE_COORDS

if TYPE_CHECKING:  # only the annotations name it: results.py draws through this module
    from .results import SweepResult

#: Metrics drawn as heat maps over a 2-parameter grid (with the min and max of every named channel).
PLOT_METRICS = ("peak_contact_force_n", "energy_dissipated_per_rev_j", "rms_acc_deviation_m_s2", "impacts")

#: Shorter axis names than the parameters' descriptions.
_SHORT = {"clearance": "clearance", "restitution": "restitution c_r", "friction": "friction coefficient",
          "speed_rpm": "crank speed", "speed": "crank speed", "length": "joint length"}


def _label(name: str, unit: str, text: str) -> tuple[str, float]:
    """(label, scale from SI): metres shown in mm, a dimensionless unit as [-]."""
    if unit == "m":
        return f"{text} [mm]", 1e3
    return f"{text} [{'-' if unit in ('', '1') else unit}]", 1.0


def axis_label(name: str, channels: dict | None = None) -> tuple[str, float]:
    """(label, scale) of a parameter or metric for plots: lengths in mm, others in SI
    (``channels``: the manifest's records of its columns, :func:`~jaxclear.sweep.labels.column_records`)."""
    return _label(name, column_unit(name, channels), _SHORT.get(name.split("@")[0], long_name(name, channels)))


def metric_label(metric: str, channels: dict | None = None) -> str:
    """``peak_contact_force_n`` -> ``peak contact force [N]`` (the dataset's units; ``channels``:
    the manifest's records of its columns, :func:`~jaxclear.sweep.labels.column_records`)."""
    unit = column_unit(metric, channels)
    return f"{long_name(metric, channels)} [{'-' if unit in ('', '1') else unit}]"


def _fixed(res: SweepResult) -> str:
    """The mechanism's fixed settings from the manifest: ``preset; name value, ...``."""
    mech = dict(res.manifest.get("config", {}).get("mechanism", {}))
    preset = mech.pop("preset", mech.pop("mechanism", ""))
    mech.pop("leaves_sha256", None), mech.pop("ideal_leaves_sha256", None)
    parts = [f"{k} {json_text(v, indent=None, sort_keys=False) if isinstance(v, (dict, list)) else v}" for k, v in sorted(mech.items())]
    return "; ".join([p for p in [str(preset), ", ".join(parts)] if p])


def heatmap(res: SweepResult, metric: str, x: str, y: str, path=None, log: bool | None = None,
            sel: dict | None = None):
    """PNG heat map of ``metric`` over a grid sweep: ``x`` and ``y`` swept parameters; ``sel``
    picks one value of every other swept parameter (``{"friction": 0.1}``)."""
    if res.mode != "grid":
        raise ParameterError("a 2-D map needs a grid sweep (this one is a list)")
    for n in (x, y):
        if n not in res.axes:
            raise ParameterError(f"{n!r} is not a swept parameter; swept: {list(res.axes)}")
    if metric not in res.table:
        raise ParameterError(f"unknown metric {metric!r}; columns: {list(res.table)}")
    da = res.to_xarray()[metric]
    if sel:
        da = da.sel(sel, method="nearest")
    extra = [d for d in da.dims if d not in (x, y)]
    if extra:
        raise ParameterError(f"the sweep also varies {extra}: pick one value of each with sel={{name: value}}")
    da = da.transpose(y, x)
    records = column_records(res.manifest)
    (xl, xs), (yl, ys) = axis_label(x, records), axis_label(y, records)
    fixed = _fixed(res)
    label = metric_label(metric, records)
    title = f"{label} over {x} x {y}" + (f"\n{fixed}" if fixed else "")
    if sel:
        title += "; " + ", ".join(f"{k} = {v:g}" for k, v in sel.items())
    return plot_heatmap(path, da[x].values * xs, da[y].values * ys, da.values, xlabel=xl, ylabel=yl,
                        zlabel=label, log=log, title=title)


def bifurcation(res: SweepResult, parameter: str, coordinate: str = "e_x", joint: int = 0, path=None):
    """PNG bifurcation diagram: the Poincare coordinate (:data:`POINCARE_COORDS`, or ``e`` for
    the eccentricity magnitude) of every section point of every successful run against
    ``parameter``."""
    values, label = poincare_coordinate(res.poincare, coordinate, joint)
    pl, ps = axis_label(parameter, column_records(res.manifest))
    ok = res.table["status"] == 0
    return plot_bifurcation(path, res.table[parameter][ok] * ps, values[ok], xlabel=pl, ylabel=label,
                            title=f"bifurcation diagram over {parameter} (one point per crank revolution)")


def poincare_coordinate(points: np.ndarray, coordinate: str, joint: int = 0) -> tuple[np.ndarray, str]:
    """(values (n_runs, n_section), axis label) of one Poincare coordinate of ``points``
    (n_runs, n_section, n_joints, 4); lengths in mm, velocities in m/s."""
    p = np.asarray(points)[..., joint, :]
    if coordinate == "e":
        return 1e3 * np.hypot(p[..., 0], p[..., 1]), "eccentricity |e| [mm]"
    if coordinate not in POINCARE_COORDS:
        raise ParameterError(f"unknown Poincare coordinate {coordinate!r}; valid: {list(POINCARE_COORDS) + ['e']}")
    i = POINCARE_COORDS.index(coordinate)
    sym = f"${coordinate[0]}_{coordinate[2]}$"
    if i < 2:
        return 1e3 * p[..., i], f"journal-centre eccentricity {sym} [mm]"
    return p[..., i], f"journal-centre velocity {sym} relative to the bearing [m/s]"


def poincare_plot(res: SweepResult, runs=None, joint: int = 0, path=None, color_by: str | None = None):
    """PNG Poincare sections of the given runs (default all): journal position in the whole
    clearance circle and the (e_x, v_x) plane, one point per crank revolution after the
    transient. Runs are coloured by ``color_by`` (default the first swept parameter), marked by
    the value of the next swept parameter and labelled with every swept parameter's value; the
    title names the fixed settings."""
    runs = np.arange(len(res.table["run"])) if runs is None else np.asarray(runs)
    color_by = color_by or res.names[0]
    records = column_records(res.manifest)
    label, scale = axis_label(color_by, records)
    name = "clearance" if joint == 0 else f"clearance@{joint}"
    if name in res.table:
        clearance = res.table[name][runs]
    elif len(res.base_clearance) > joint:
        clearance = res.base_clearance[joint]
    else:
        clearance = None
    labels = []
    for r in runs:
        parts = []
        for n in res.names:
            text, s = axis_label(n, records)
            unit = text[text.rfind("[") + 1: -1]
            parts.append(f"{_SHORT.get(n, n)} {res.table[n][r] * s:g}{'' if unit == '-' else ' ' + unit}")
        labels.append(", ".join(parts))
    other = [n for n in res.names if n != color_by]
    marker_index = None
    if other:  # one marker per value of the next swept parameter (e.g. the restitution)
        values = np.unique(res.table[other[0]])
        marker_index = np.searchsorted(values, res.table[other[0]][runs])
    return plot_poincare(path, res.poincare[runs, :, joint, :], colors=res.table[color_by][runs] * scale,
                         color_label=label, clearance=clearance, labels=labels, title=_fixed(res),
                         marker_index=marker_index)


def write_figures(res: SweepResult, folder) -> list[str]:
    """The figures of a sweep in ``folder``: heat maps of :data:`PLOT_METRICS` and of the min and
    max of every named channel (2-parameter grids), the bifurcation diagram (1 parameter) and the
    Poincare sections; returns the paths written (none for a sweep with no run on disk)."""
    import os

    folder = os.fspath(folder)
    files = []
    if not len(res.table.get("run", ())):
        return files
    if res.mode == "grid" and len(res.names) == 2:
        channels = tuple(column for column, c in res.manifest.get("channel_columns", {}).items()
                         if c["stat"] in ("min", "max"))
        for metric in PLOT_METRICS + channels:
            if metric in res.table:
                files.append(os.path.join(folder, f"heatmap_{metric}.png"))
                heatmap(res, metric, x=res.names[0], y=res.names[1], path=files[-1])
    if res.poincare.size:
        if len(res.names) == 1:
            files.append(os.path.join(folder, f"bifurcation_{res.names[0].replace(':', '_')}.png"))
            bifurcation(res, res.names[0], path=files[-1])
        files.append(os.path.join(folder, "poincare.png"))
        poincare_plot(res, path=files[-1])
    return files
