"""PNG plots of a simulation (matplotlib, Agg canvas).

The figures are built with :class:`matplotlib.figure.Figure` directly, not with ``pyplot``,
so importing this module never changes the user's matplotlib backend (notebooks keep theirs)
and no global figure state accumulates. Every function saves a PNG when ``path`` is given and
returns the figure.

The horizontal axis is the crank angle in degrees, unwrapped (several revolutions run along
the axis), for mechanisms with a ``crank`` role, and the time in ms otherwise.
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MultipleLocator

from .mechanism import Mechanism
from .solve import Solution

DPI = 130
FIGSIZE = (9.0, 4.8)
COLORS = ("tab:blue", "tab:red", "tab:green", "tab:purple")


def _save(fig: Figure, path) -> Figure:
    if path is not None:
        fig.savefig(os.fspath(path), dpi=DPI)
    return fig


def _abscissa(mech: Mechanism, sol: Solution):
    """(values, label, is_angle): crank angle [deg] if the mechanism has a crank, else time [ms]."""
    crank = mech.role("crank")
    if crank is not None:
        return np.degrees(np.asarray(sol.coordinate(mech, crank, "phi"), dtype=float)), "crank angle [deg]", True
    return 1e3 * np.asarray(sol.ts, dtype=float), "time [ms]", False


def _angle_ticks(ax, x):
    span = float(np.max(x) - np.min(x)) if x.size else 0.0
    step = 360.0 if span > 1440.5 else 90.0 if span > 270.5 else 30.0
    ax.xaxis.set_major_locator(MultipleLocator(step))
    ax.set_xlim(float(np.min(x)), float(np.max(x)))


def law_label(law) -> str:
    """Registered name of a contact law object (``law.model``, else looked up by its class)."""
    name = getattr(law, "model", None)
    if isinstance(name, str):
        return name
    try:
        from .contact.registry import LAWS

        for key, (cls, _) in LAWS.items():
            if type(law) is cls:
                return key
    except Exception:  # pragma: no cover - registry layout changed
        pass
    return type(law).__name__


def joint_label(joint) -> str:
    """``clearance 0.5 mm, lankarani-nikravesh, c_r = 0.9`` for a clearance joint."""
    parts = [f"clearance {1e3 * float(joint.clearance):g} mm", law_label(joint.law)]
    restitution = getattr(joint.law, "restitution", None)
    if restitution is not None:
        parts.append(f"c_r = {float(restitution):g}")
    return ", ".join(parts)


def _title(mech: Mechanism, what: str) -> str:
    extra = f" ({joint_label(mech.clearance_joints[0])})" if mech.clearance_joints else ""
    return f"{mech.name}: {what}{extra}"


def plot_slider_acceleration(path, mech: Mechanism, sol: Solution, ideal_sol: Solution | None = None,
                             ideal_mech: Mechanism | None = None) -> Figure:
    """Slider acceleration [m/s^2] against the crank angle, with the ideal-joint solution
    ``ideal_sol`` (of ``ideal_mech``, default: ``mech``'s roles) overlaid when given."""
    slider = mech.role("slider")
    if slider is None:
        raise ValueError(f"mechanism {mech.name!r} has no 'slider' role: nothing to plot")
    fig = Figure(figsize=FIGSIZE)
    ax = fig.add_subplot()
    x, xlabel, is_angle = _abscissa(mech, sol)
    acc = np.asarray(sol.coordinate(mech, slider, "x", derivative=2), dtype=float)
    label = "clearance joint" if mech.clearance_joints else "ideal joint"
    ax.plot(x, acc, color=COLORS[0], lw=0.8, label=label)
    if ideal_sol is not None:
        im = mech if ideal_mech is None else ideal_mech
        xi, _, _ = _abscissa(im, ideal_sol)
        acc_i = np.asarray(ideal_sol.coordinate(im, im.role("slider") or slider, "x", derivative=2), dtype=float)
        ax.plot(xi, acc_i, color="black", lw=1.6, ls="--", label="ideal joint")
    if is_angle:
        _angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("slider acceleration [m/s$^2$]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.set_title(_title(mech, "slider acceleration"), fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right" if mech.clearance_joints else "best")
    fig.tight_layout()
    return _save(fig, path)


def plot_orbit(path, mech: Mechanism, sol: Solution) -> Figure:
    """Journal-centre orbit: the eccentricity vector [mm] of every clearance joint, inside its
    clearance circle (radius c); start and end marked."""
    k = len(mech.clearance_joints)
    if k == 0:
        raise ValueError(f"mechanism {mech.name!r} has no clearance joint: no orbit to plot")
    fig = Figure(figsize=(5.2 * k, 6.0))
    ecc = 1e3 * np.asarray(sol.ecc, dtype=float)
    theta = np.linspace(0.0, 2.0 * np.pi, 361)
    for j, joint in enumerate(mech.clearance_joints):
        ax = fig.add_subplot(1, k, j + 1)
        c = 1e3 * float(joint.clearance)
        ax.plot(c * np.cos(theta), c * np.sin(theta), color="black", lw=1.2, label=f"clearance circle, c = {c:g} mm")
        ax.plot(ecc[:, j, 0], ecc[:, j, 1], color=COLORS[0], lw=0.7, label="journal centre")
        ax.plot(ecc[0, j, 0], ecc[0, j, 1], "o", color="tab:green", ms=5, label="start")
        ax.plot(ecc[-1, j, 0], ecc[-1, j, 1], "s", color="tab:red", ms=5, label="end")
        lim = 1.15 * max(c, float(np.max(np.abs(ecc[:, j]))))
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.axhline(0.0, color="grey", lw=0.5, alpha=0.5)
        ax.axvline(0.0, color="grey", lw=0.5, alpha=0.5)
        ax.set_xlabel("eccentricity x [mm]")
        ax.set_ylabel("eccentricity y [mm]")
        ax.set_title(f"{mech.name}: journal orbit, joint {joint.name}", fontsize=10)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8, frameon=False)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def plot_contact_force(path, mech: Mechanism, sol: Solution) -> Figure:
    """Normal contact force [N] of every clearance joint against the crank angle."""
    k = len(mech.clearance_joints)
    if k == 0:
        raise ValueError(f"mechanism {mech.name!r} has no clearance joint: no contact force to plot")
    fig = Figure(figsize=FIGSIZE)
    ax = fig.add_subplot()
    x, xlabel, is_angle = _abscissa(mech, sol)
    fn = np.asarray(sol.normal_force, dtype=float)
    ft = np.asarray(sol.friction_force, dtype=float)
    for j, joint in enumerate(mech.clearance_joints):
        color = COLORS[j % len(COLORS)]
        ax.plot(x, fn[:, j], color=color, lw=0.8, label=f"normal force, {joint.name}")
        if np.any(ft[:, j] != 0.0):
            ax.plot(x, np.abs(ft[:, j]), color=color, lw=0.8, ls=":", label=f"|friction force|, {joint.name}")
    if is_angle:
        _angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("contact force [N]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.set_title(_title(mech, "contact force"), fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right")
    fig.tight_layout()
    return _save(fig, path)


__all__ = ["plot_slider_acceleration", "plot_orbit", "plot_contact_force"]
