"""The figure of a wear run: the worn bearing in polar form (wear magnified) and the depth
against the bearing angle after each update."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from ..plot import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _magnification(x: float) -> float:
    """The largest of 1, 2, 5 times a power of ten not above ``x`` (at least 1)."""
    if x <= 1:
        return 1.0
    decade = 10.0 ** np.floor(np.log10(x))
    return float(max(m * decade for m in (1, 2, 5) if m * decade <= x))


def plot_wear(angles, depth, service_time, clearance: float, path: str | None = None, max_curves: int = 6) -> Figure:
    """Left: polar view of the radial clearance around the bearing [um], unworn (dashed) and
    after the last update, the wear magnified (a round factor that makes it about 30 % of the
    clearance; the title gives it); right: wear depth [um] against the bearing-fixed angle [deg] for up to
    ``max_curves`` updates (labelled by service time). ``angles`` (n,) [rad], ``depth`` (U, n)
    [m] cumulative, ``service_time`` (U,) [s], ``clearance`` [m]. Saved as PNG if ``path``."""
    angles, depth = np.asarray(angles), np.atleast_2d(np.asarray(depth))
    closed = np.append(angles, angles[0] + 2 * np.pi)
    fig = new_figure(figsize=(11, 4.6), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, projection="polar")
    um = 1e6
    magnify = _magnification(0.3 * clearance / depth[-1].max()) if depth[-1].max() > 0 else 1.0
    ax.plot(closed, np.full(closed.shape, clearance * um), "k--", lw=1, label="unworn clearance")
    last = np.append(depth[-1], depth[-1, 0]) * magnify
    ax.plot(closed, (clearance + last) * um, "C3", lw=1.6, label=f"worn, t = {service_time[-1]:.3g} s")
    ax.fill_between(closed, clearance * um, (clearance + last) * um, color="C3", alpha=0.3)
    ax.set_rlim(0, (clearance + last.max()) * um * 1.1)
    ax.set_title(f"radial clearance around the bearing [um], wear x{magnify:g}\n(angle in the bearing body)",
                 fontsize=10)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.1, -0.18), fontsize=8)
    ax2 = fig.add_subplot(1, 2, 2)
    rows = np.unique(np.linspace(0, depth.shape[0] - 1, min(max_curves, depth.shape[0])).round().astype(int))
    for r in rows:
        ax2.plot(np.degrees(closed), np.append(depth[r], depth[r, 0]) * um, lw=1.3,
                 label=f"after {service_time[r]:.3g} s")
    ax2.set_xlabel("bearing angle [deg]")
    ax2.set_ylabel("wear depth [um]")
    ax2.set_xlim(0, 360)
    ax2.set_xticks(np.arange(0, 361, 60))
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8, title="service time", title_fontsize=8)
    ax2.set_title("Archard wear depth of the bearing", fontsize=10)
    if path is not None:
        fig.savefig(os.fspath(path), dpi=110)
    return fig
