"""The figures of a design (matplotlib, Agg canvas; the helpers of :mod:`jaxclear.plot`):
:func:`plot_comparison`, the start design against the optimum (output acceleration, orbit,
contact force, convergence)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..analysis import channels
from ..plot import COLORS, abscissa, angle_ticks, clearance_region, new_figure, save_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _signal_panel(ax, name: str, runs: dict):
    for (label, (mech, sol, ideal_mech, ideal_sol)), color in zip(runs.items(), COLORS):
        x, xlabel, is_angle = abscissa(mech, sol)
        values, unit = channels.channel_with_unit(mech, sol, name)
        ax.plot(x, np.asarray(values, dtype=float), color=color, lw=0.7, label=label)
    if ideal_sol is not None and channels.parse(name).kind in channels.OVERLAY_KINDS:
        xi, _, _ = abscissa(ideal_mech, ideal_sol)
        ax.plot(xi, np.asarray(channels.channel(ideal_mech, ideal_sol, name), dtype=float), color="black", lw=1.4,
                ls="--", label="ideal joint (optimum)")
    if is_angle:
        angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"{name} [{unit}]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.set_title("output", fontsize=10)


def _orbit_panel(ax, runs: dict):
    for (label, (mech, sol, _, _)), color in zip(runs.items(), COLORS):
        ecc = 1e3 * np.asarray(sol.ecc, dtype=float)[:, 0]
        ax.plot(ecc[:, 0], ecc[:, 1], color=color, lw=0.6, label=label)
    joint = mech.clearance_joints[0]
    region = 1e3 * np.asarray(clearance_region(joint), dtype=float)
    ax.plot(region[:, 0], region[:, 1], color="black", lw=1.0, label="clearance (optimum)")
    ax.set_aspect("equal")
    ax.set_xlabel(f"{joint.orbit_labels[0]} [mm]")
    ax.set_ylabel(f"{joint.orbit_labels[1]} [mm]")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"orbit, joint {joint.name}", fontsize=10)


def _force_panel(ax, runs: dict):
    for (label, (mech, sol, _, _)), color in zip(runs.items(), COLORS):
        x, xlabel, is_angle = abscissa(mech, sol)
        ax.plot(x, np.asarray(sol.normal_force, dtype=float).max(axis=1), color=color, lw=0.7, label=label)
    if is_angle:
        angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("normal contact force [N]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.set_title("contact force (largest over the joints)", fontsize=10)


def _convergence_panel(ax, history: list, unit: str):
    it = [h["iteration"] for h in history]
    ax.plot(it, [h["objective"] for h in history], "o-", color=COLORS[0], ms=3, lw=1.0, label="objective")
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"objective [{unit}]" if unit else "objective")
    ax.grid(True, alpha=0.3)
    ax.set_title("convergence", fontsize=10)
    if any(h.get("violation", 0.0) > 0 for h in history):
        ax2 = ax.twinx()
        ax2.semilogy(it, [max(h.get("violation", 0.0), 1e-16) for h in history], "s:", color=COLORS[1], ms=3,
                     label="largest constraint violation")
        ax2.set_ylabel("constraint violation [-]")
        ax2.legend(loc="upper center", fontsize=8)
    ax.legend(loc="upper right", fontsize=8)


def plot_comparison(path, channel: str, start: tuple, optimum: tuple, history: list, unit: str = "",
                    title: str = "") -> Figure:
    """The start design against the optimum: ``start`` and ``optimum`` are ``(mech, sol,
    ideal_mech, ideal_sol)`` on the same settings; panels: ``channel`` (with the optimum's ideal
    joint), the first clearance joint's orbit and the contact force (with clearance joints), the
    objective per iteration from ``history``."""
    runs = {"start design": start, "optimum": optimum}
    contact = bool(start[0].clearance_joints)
    fig = new_figure(figsize=(13.0, 8.0))
    axes = fig.subplots(2, 2)
    _signal_panel(axes[0, 0], channel, runs)
    if contact:
        _orbit_panel(axes[0, 1], runs)
        _force_panel(axes[1, 0], runs)
    else:
        for ax in (axes[0, 1], axes[1, 0]):
            ax.text(0.5, 0.5, "no clearance joint", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
    if history:
        _convergence_panel(axes[1, 1], history, unit)
    else:
        axes[1, 1].set_axis_off()
    fig.suptitle(title or f"{start[0].name}: start design against the optimum", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path)


__all__ = ["plot_comparison"]
