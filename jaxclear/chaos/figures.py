"""Figures of the chaos tools: the running Lyapunov estimate, the channels' power spectral
densities, their Poincare sections (matplotlib's object interface, no global state)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..plot import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_running(result, path: str | None = None) -> Figure:
    """The running estimate of every exponent against time (convergence)."""
    fig = new_figure(figsize=(6.4, 4.0), layout="constrained")
    ax = fig.add_subplot()
    t, running = np.asarray(result.times), np.asarray(result.running)
    for i in range(running.shape[1]):
        ax.plot(t, running[:, i], label=f"$\\lambda_{i + 1}$ = {running[-1, i]:.4g} 1/s")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("running estimate [1/s]")
    ax.set_title("Lyapunov exponents (Benettin, tangent dynamics)")
    ax.legend(fontsize=8)
    if path:
        fig.savefig(path, dpi=120)
    return fig


def plot_spectra(reports, path: str | None = None) -> Figure:
    """Welch power spectral density of each channel (log scale)."""
    fig = new_figure(figsize=(6.4, 2.6 * max(1, len(reports))), layout="constrained")
    for i, c in enumerate(reports):
        ax = fig.add_subplot(len(reports), 1, i + 1)
        ax.semilogy(c.frequency[1:], c.density[1:])
        ax.set_ylabel(f"PSD [{c.unit}$^2$/Hz]")
        ax.set_title(f"{c.name}: peak {c.peak_frequency:.4g} Hz, 0-1 test K = {c.k:.2f}" if c.k == c.k else
                     f"{c.name}: peak {c.peak_frequency:.4g} Hz (0-1 test: too few samples)", fontsize=9)
    ax.set_xlabel("frequency [Hz]")
    if path:
        fig.savefig(path, dpi=120)
    return fig


def plot_sections(reports, path: str | None = None) -> Figure:
    """Poincare section (once per revolution): the first channel against the second, or, with
    one channel, its value against the next revolution's (a return map)."""
    fig = new_figure(figsize=(5.0, 4.6), layout="constrained")
    ax = fig.add_subplot()
    a = reports[0]
    if len(reports) > 1:
        b = reports[1]
        ax.plot(a.section, b.section, ".", ms=4)
        ax.set_xlabel(f"{a.name} [{a.unit}]")
        ax.set_ylabel(f"{b.name} [{b.unit}]")
    else:
        ax.plot(a.section[:-1], a.section[1:], ".", ms=4)
        ax.set_xlabel(f"{a.name}, revolution k [{a.unit}]")
        ax.set_ylabel(f"revolution k + 1 [{a.unit}]")
    from ..analysis.sections import period_name

    ax.set_title(f"Poincare section, once per revolution: {period_name(a.period, a.longest)}", fontsize=9)
    if path:
        fig.savefig(path, dpi=120)
    return fig
