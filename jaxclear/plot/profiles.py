"""Drawings of a mechanism's time profiles (``jaxclear check``): for each ``speed-profile``
driver its prescribed angle [rad], speed [rad/s] and angular acceleration [rad/s^2], for each
load with a profile its time factor [-], over a span that shows each profile whole
(:meth:`~jaxclear.model.profiles.AbstractProfile.end_time`). Figures use
:class:`matplotlib.figure.Figure` (no pyplot state)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np

from ..model import Mechanism, ProfileDriver
from .figures import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def mechanism_profiles(mech: Mechanism) -> list[tuple[str, object, bool]]:
    """``(label, profile, is a driver's speed)`` for every time profile of ``mech``."""
    out = [(d.label, d.profile, True) for d in mech.drivers if isinstance(d, ProfileDriver)]
    return out + [(ld.label, ld.profile, False) for ld in mech.loads if getattr(ld, "profile", None) is not None]


def plot_profiles(path, mech: Mechanism, n: int = 801) -> Figure | None:
    """Write the profiles' figure to ``path`` (PNG); ``None`` (nothing written) without any."""
    found = mechanism_profiles(mech)
    if not found:
        return None
    fig = new_figure(figsize=(11, 2.6 * len(found)), layout="constrained")
    axes = fig.subplots(len(found), 3, squeeze=False)
    for row, (label, prof, speed) in zip(axes, found):
        t = np.linspace(0.0, prof.end_time(), n)
        ts = jnp.asarray(t)
        curves = ([(jax.vmap(prof.integral)(ts), "angle [rad]"), (jax.vmap(prof.value)(ts), "speed [rad/s]"),
                   (jax.vmap(prof.derivative)(ts), "acceleration [rad/s^2]")] if speed else
                  [(jax.vmap(prof.value)(ts), "load factor [-]"), (jax.vmap(prof.derivative)(ts), "its rate [1/s]")])
        for ax, (values, ylabel) in zip(row, curves):
            ax.plot(t, np.asarray(values), lw=1.2)
            ax.set_xlabel("time [s]")
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
        row[0].set_title(f"{label}: {prof.kind} profile", loc="left", fontsize=10)
        for ax in row[len(curves):]:
            ax.set_axis_off()
    fig.savefig(path, dpi=110)
    return fig
