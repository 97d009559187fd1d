"""Sweep figures (PNG, thin wrappers over :mod:`jaxclear.plot`): a metric's heat map over a 2-D
grid, the bifurcation diagram of the Poincare section against a parameter, and the Poincare
sections themselves. Lengths are shown in mm, other quantities in SI units."""

from __future__ import annotations

import numpy as np

from .. import params
from .._errors import JaxclearError, ParameterError
from ..analysis.metrics import RUN_METRIC_KEYS
from ..plot import plot_bifurcation, plot_heatmap, plot_poincare
from .results import SweepResult
from .store import POINCARE_COORDS

#: (axis label, scale from SI) of the common parameters.
_UNITS = {"clearance": ("clearance [mm]", 1e3), "speed_rpm": ("crank speed [rpm]", 1.0),
          "speed": ("crank speed [rad/s]", 1.0), "restitution": ("restitution c_r [-]", 1.0),
          "friction": ("friction coefficient [-]", 1.0), "length": ("joint length [mm]", 1e3)}


def axis_label(name: str) -> tuple[str, float]:
    """(label, scale) of a parameter for plots: clearance in mm, others in SI."""
    base = name.split("@")[0]
    if base in _UNITS:
        return _UNITS[base]
    try:
        unit = params.info(name).unit
    except JaxclearError:
        unit = ""
    return (f"{name} [{unit or '-'}]", 1.0)


def metric_label(metric: str) -> str:
    """``peak_contact_force_n`` -> ``peak contact force [N]`` (unit from ``RUN_METRIC_KEYS``)."""
    unit = RUN_METRIC_KEYS.get(metric, "-")
    text = metric
    for suffix in ("_n", "_m", "_j", "_m_s2", "_s"):
        if text.endswith(suffix):
            text = text[: -len(suffix)]
            break
    return f"{text.replace('_', ' ')} [{unit}]"


def heatmap(res: SweepResult, metric: str, x: str, y: str, path=None, log: bool | None = None):
    """PNG heat map of ``metric`` over a 2-D grid sweep (``x`` and ``y`` swept parameters)."""
    z = res.grid(metric, x, y)
    (xl, xs), (yl, ys) = axis_label(x), axis_label(y)
    return plot_heatmap(path, res.axes[x] * xs, res.axes[y] * ys, z, xlabel=xl, ylabel=yl,
                        zlabel=metric_label(metric), log=log, title=f"{metric_label(metric)} over {x} x {y} ({metric})")


def bifurcation(res: SweepResult, parameter: str, coordinate: str = "e_x", joint: int = 0, path=None):
    """PNG bifurcation diagram: the Poincare coordinate (:data:`POINCARE_COORDS`, or ``e`` for
    the eccentricity magnitude) of every section point of every successful run against
    ``parameter``."""
    values, label = poincare_coordinate(res.poincare, coordinate, joint)
    pl, ps = axis_label(parameter)
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
    """PNG Poincare sections of the given runs (default all): journal position in the clearance
    circle and the (e_x, v_x) plane, one point per crank revolution after the transient."""
    runs = np.arange(len(res.table["run"])) if runs is None else np.asarray(runs)
    color_by = color_by or res.names[0]
    label, scale = axis_label(color_by)
    name = "clearance" if joint == 0 else f"clearance@{joint}"
    if name in res.table:
        clearance = res.table[name][runs]
    elif len(res.base_clearance) > joint:
        clearance = res.base_clearance[joint]
    else:
        clearance = None
    return plot_poincare(path, res.poincare[runs, :, joint, :], colors=res.table[color_by][runs] * scale,
                         color_label=label, clearance=clearance)
