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
from typing import TYPE_CHECKING

import numpy as np

from ..model import Mechanism
from ..integrate import Solution
from ..integrate import jit

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DPI = 130
FIGSIZE = (9.0, 4.8)
COLORS = ("tab:blue", "tab:red", "tab:green", "tab:purple")


@jit
def clearance_region(joint):
    """``joint.clearance_region()`` as one compiled program (op by op, several small ones)."""
    return joint.clearance_region()


def new_figure(**kwargs) -> Figure:
    """A :class:`matplotlib.figure.Figure` (``kwargs`` its own: ``figsize``, ``layout``, ``dpi``,
    ...), the one way jaxclear makes a figure. matplotlib is imported here, at the first figure,
    not with jaxclear: it was a fifth of the time ``import jaxclear`` spends outside JAX and diffrax
    (issue 41)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def save_figure(fig: Figure, path) -> Figure:
    """Write ``fig`` to ``path`` (a PNG at :data:`DPI`) unless ``path`` is None; returns ``fig``."""
    if path is not None:
        fig.savefig(os.fspath(path), dpi=DPI)
    return fig


def abscissa(mech: Mechanism, sol: Solution):
    """(values, label, is_angle): crank angle [deg] if the mechanism has a crank, else time [ms]."""
    crank = mech.role("crank")
    if crank is not None:
        return np.degrees(np.asarray(sol.coordinate(mech, crank, "phi"), dtype=float)), "crank angle [deg]", True
    return 1e3 * np.asarray(sol.ts, dtype=float), "time [ms]", False


def angle_ticks(ax, x):
    """Crank-angle ticks [deg] on ``ax`` every 30, 90 or 360 degrees as the span ``x`` grows."""
    span = float(np.max(x) - np.min(x)) if x.size else 0.0
    step = 360.0 if span > 1440.5 else 90.0 if span > 270.5 else 30.0
    from matplotlib.ticker import MultipleLocator

    ax.xaxis.set_major_locator(MultipleLocator(step))
    ax.set_xlim(float(np.min(x)), float(np.max(x)))


def law_label(law) -> str:
    """Registered name of a contact law object (:attr:`AbstractNormalLaw.name`)."""
    return law.name


def joint_label(joint) -> str:
    """``clearance 0.5 mm, lankarani-nikravesh, c_r = 0.9`` for a clearance joint."""
    parts = [f"clearance {1e3 * float(joint.clearance):g} mm", law_label(joint.law),
             f"c_r = {float(joint.law.restitution):g}"]
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
    fig = new_figure(figsize=FIGSIZE)
    ax = fig.add_subplot()
    x, xlabel, is_angle = abscissa(mech, sol)
    acc = np.asarray(sol.coordinate(mech, slider, "x", derivative=2), dtype=float)
    label = "clearance joint" if mech.clearance_joints else "ideal joint"
    ax.plot(x, acc, color=COLORS[0], lw=0.8, label=label)
    if ideal_sol is not None:
        im = mech if ideal_mech is None else ideal_mech
        xi, _, _ = abscissa(im, ideal_sol)
        acc_i = np.asarray(ideal_sol.coordinate(im, im.role("slider") or slider, "x", derivative=2), dtype=float)
        ax.plot(xi, acc_i, color="black", lw=1.6, ls="--", label="ideal joint")
    if is_angle:
        angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("slider acceleration [m/s$^2$]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.set_title(_title(mech, "slider acceleration"), fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right" if mech.clearance_joints else "best")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_channel(path, mech: Mechanism, sol: Solution, name: str, values, unit: str, ideal_values=None) -> Figure:
    """One named output channel (:mod:`jaxclear.analysis.channels`) against the crank angle (or
    time), with its ideal-joint counterpart ``ideal_values`` (same output grid) overlaid."""
    fig = new_figure(figsize=FIGSIZE)
    ax = fig.add_subplot()
    x, xlabel, is_angle = abscissa(mech, sol)
    ax.plot(x, np.asarray(values, dtype=float), color=COLORS[0], lw=0.8,
            label="clearance joint" if mech.clearance_joints else "ideal joint")
    if ideal_values is not None:
        ax.plot(x, np.asarray(ideal_values, dtype=float), color="black", lw=1.6, ls="--", label="ideal joint")
    if is_angle:
        angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"{name} [{unit}]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.set_title(_title(mech, name), fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_orbit(path, mech: Mechanism, sol: Solution) -> Figure:
    """Orbit of every force element in its clearance region, to scale [mm]: the journal centre
    inside its clearance circle (revolute and lubricated joints), the pin centre inside the
    stadium of its slot, the slider's lateral offset and tilt inside its guide
    (``element.clearance_region()``); start and end marked."""
    k = len(mech.clearance_joints)
    if k == 0:
        raise ValueError(f"mechanism {mech.name!r} has no clearance joint: no orbit to plot")
    fig = new_figure(figsize=(5.2 * k, 6.0))
    ecc = 1e3 * np.asarray(sol.ecc, dtype=float)
    for j, joint in enumerate(mech.clearance_joints):
        ax = fig.add_subplot(1, k, j + 1)
        c = 1e3 * float(joint.clearance)
        region = 1e3 * np.asarray(clearance_region(joint), dtype=float)
        ax.plot(region[:, 0], region[:, 1], color="black", lw=1.2, label=f"clearance region, c = {c:g} mm")
        ax.plot(ecc[:, j, 0], ecc[:, j, 1], color=COLORS[0], lw=0.7, label="orbit")
        ax.plot(ecc[0, j, 0], ecc[0, j, 1], "o", color="tab:green", ms=5, label="start")
        ax.plot(ecc[-1, j, 0], ecc[-1, j, 1], "s", color="tab:red", ms=5, label="end")
        lim = 1.15 * max(float(np.max(np.abs(region))), float(np.max(np.abs(ecc[:, j]))))
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.axhline(0.0, color="grey", lw=0.5, alpha=0.5)
        ax.axvline(0.0, color="grey", lw=0.5, alpha=0.5)
        ax.set_xlabel(f"{joint.orbit_labels[0]} [mm]")
        ax.set_ylabel(f"{joint.orbit_labels[1]} [mm]")
        ax.set_title(f"{mech.name}: orbit, joint {joint.name}", fontsize=10)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8, frameon=False)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_contact_force(path, mech: Mechanism, sol: Solution) -> Figure:
    """Normal contact force [N] of every clearance joint against the crank angle."""
    k = len(mech.clearance_joints)
    if k == 0:
        raise ValueError(f"mechanism {mech.name!r} has no clearance joint: no contact force to plot")
    fig = new_figure(figsize=FIGSIZE)
    ax = fig.add_subplot()
    x, xlabel, is_angle = abscissa(mech, sol)
    fn = np.asarray(sol.normal_force, dtype=float)
    ft = np.asarray(sol.friction_force, dtype=float)
    for j, joint in enumerate(mech.clearance_joints):
        color = COLORS[j % len(COLORS)]
        ax.plot(x, fn[:, j], color=color, lw=0.8, label=f"normal force, {joint.name}")
        if np.any(ft[:, j] != 0.0):
            ax.plot(x, np.abs(ft[:, j]), color=color, lw=0.8, ls=":", label=f"|friction force|, {joint.name}")
    if is_angle:
        angle_ticks(ax, x)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("contact force [N]")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax.set_title(_title(mech, "contact force"), fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_simulation(folder, mech: Mechanism, sol: Solution, ideal_sol: Solution | None = None,
                    ideal_mech: Mechanism | None = None) -> list[str]:
    """Every plot that applies to ``mech``, saved in ``folder`` (which must exist):
    ``slider_acceleration.png`` with a ``slider`` role (the ideal-joint ``ideal_sol`` of
    ``ideal_mech`` overlaid when given), ``orbit.png`` and ``contact_force.png`` with clearance
    joints. Returns the paths written."""
    folder = os.fspath(folder)
    paths = []
    if mech.role("slider") is not None:
        paths.append(os.path.join(folder, "slider_acceleration.png"))
        plot_slider_acceleration(paths[-1], mech, sol, ideal_sol, ideal_mech)
    if mech.clearance_joints:
        for name, fn in (("orbit.png", plot_orbit), ("contact_force.png", plot_contact_force)):
            paths.append(os.path.join(folder, name))
            fn(paths[-1], mech, sol)
    return paths


# --------------------------------------------------------------------------------------
# Sweeps: heat maps, bifurcation diagrams, Poincare sections
# --------------------------------------------------------------------------------------


def _edges(centres: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted cell centres (geometric midpoints on a log axis)."""
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        return np.array([c[0] * 0.9, c[0] * 1.1]) if log else np.array([c[0] - 0.5, c[0] + 0.5])
    if log:
        m = np.sqrt(c[:-1] * c[1:])
        return np.concatenate([[c[0] ** 2 / m[0]], m, [c[-1] ** 2 / m[-1]]])
    m = 0.5 * (c[:-1] + c[1:])
    return np.concatenate([[2 * c[0] - m[0]], m, [2 * c[-1] - m[-1]]])


def plot_heatmap(path, x, y, z, xlabel: str = "x", ylabel: str = "y", zlabel: str = "", title: str = "",
                 log: bool | None = None, annotate: bool | None = None) -> Figure:
    """Heat map of ``z`` (len(y), len(x)) over the grid axes ``x``, ``y`` (cell centres; uneven
    spacing is drawn as such). NaN cells (failed runs) are hatched grey. ``log``: logarithmic
    colour scale (default: when the positive values span more than two decades).
    ``annotate``: write the value in each cell (default: up to 144 cells)."""
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Rectangle

    x, y, z = np.asarray(x, float), np.asarray(y, float), np.asarray(z, float)
    finite = z[np.isfinite(z)]
    if log is None:
        pos = finite[finite > 0]
        log = bool(pos.size == finite.size and pos.size and pos.max() > 100 * pos.min())
    fig = new_figure(figsize=(7.2, 5.6))
    ax = fig.add_subplot()
    ax.set_facecolor("0.85")
    xo, yo = np.argsort(x), np.argsort(y)
    xs, ys, zs = x[xo], y[yo], z[np.ix_(yo, xo)]
    logx = bool(xs.size > 2 and np.all(xs > 0) and np.ptp(np.diff(np.log(xs))) < 1e-6 * abs(np.log(xs[-1] / xs[0])))
    logy = bool(ys.size > 2 and np.all(ys > 0) and np.ptp(np.diff(np.log(ys))) < 1e-6 * abs(np.log(ys[-1] / ys[0])))
    norm = LogNorm(vmin=finite.min(), vmax=finite.max()) if (log and finite.size) else None
    mesh = ax.pcolormesh(_edges(xs, logx), _edges(ys, logy), np.ma.masked_invalid(zs), cmap="viridis",
                         norm=norm, shading="flat")
    ax.add_patch(Rectangle((0, 0), 1, 1, transform=ax.transAxes, fill=False, hatch="//", edgecolor="0.6", lw=0,
                           zorder=0))  # shows through the masked (failed) cells
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    cb = fig.colorbar(mesh, ax=ax)
    cb.set_label(zlabel)
    if annotate is None:
        annotate = zs.size <= 144
    if annotate and finite.size:
        lo, hi = (np.log(finite.min()), np.log(finite.max())) if norm is not None else (finite.min(), finite.max())
        for i, yv in enumerate(ys):
            for j, xv in enumerate(xs):
                v = zs[i, j]
                if not np.isfinite(v):
                    ax.text(xv, yv, "failed", ha="center", va="center", fontsize=7, color="black")
                    continue
                level = ((np.log(v) if norm is not None else v) - lo) / ((hi - lo) or 1.0)
                ax.text(xv, yv, f"{v:.3g}", ha="center", va="center", fontsize=7,
                        color="white" if level < 0.6 else "black")
    ax.set_xticks(xs)
    ax.set_yticks(ys)
    ax.set_xticklabels([f"{v:g}" for v in xs], rotation=45 if xs.size > 6 else 0)
    ax.set_yticklabels([f"{v:g}" for v in ys])
    ax.minorticks_off()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_bifurcation(path, parameter, points, xlabel: str = "parameter", ylabel: str = "Poincare coordinate",
                     title: str = "") -> Figure:
    """Bifurcation diagram: for each run (value ``parameter[i]``) its Poincare points
    ``points[i, :]`` (one per crank revolution after the transient) as dots above that value."""
    p = np.asarray(parameter, dtype=float)
    v = np.asarray(points, dtype=float).reshape(p.shape[0], -1)
    fig = new_figure(figsize=FIGSIZE)
    ax = fig.add_subplot()
    xs = np.repeat(p, v.shape[1])
    ax.plot(xs, v.ravel(), ls="none", marker=".", ms=3.0, color="black", alpha=0.7)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_poincare(path, points, colors=None, color_label: str = "", clearance=None, labels=None,
                  title: str = "", marker_index=None) -> Figure:
    """Poincare sections of one or several runs: ``points`` (n_runs, n_section, 4) journal states
    (e_x, e_y [m], v_x, v_y [m/s]) once per crank revolution. Left: the journal-centre position
    [mm] inside the whole clearance circle(s) (``clearance`` [m], one per run or one value);
    right: the (e_x, v_x) plane. Runs are coloured by ``colors`` (e.g. a swept parameter);
    ``labels`` (one per run) make a legend, ``title`` a figure title; ``marker_index`` (one
    integer per run, default the run's position) picks each run's marker, e.g. the index of a
    second swept parameter's value."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    pts = np.asarray(points, dtype=float)
    if pts.ndim == 2:
        pts = pts[None]
    n = pts.shape[0]
    fig = new_figure(figsize=(12.0, 5.6), layout="constrained")
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    cmap = colormaps["viridis"]
    cvals = np.arange(n, dtype=float) if colors is None else np.asarray(colors, dtype=float)
    norm = Normalize(vmin=float(np.nanmin(cvals)), vmax=float(np.nanmax(cvals)) if n > 1 else float(np.nanmin(cvals)) + 1)
    markers = "osD^vP*X"
    for r in range(n):
        color = cmap(norm(cvals[r]))
        m = r if marker_index is None else int(marker_index[r])
        style = dict(ls="none", marker=markers[m % len(markers)], ms=4.0, color=color, mec="black", mew=0.3)
        ax1.plot(1e3 * pts[r, :, 0], 1e3 * pts[r, :, 1], label=None if labels is None else labels[r], **style)
        ax2.plot(1e3 * pts[r, :, 0], pts[r, :, 2], **style)
    if clearance is not None:  # the whole clearance circle(s), the points inside
        theta = np.linspace(0.0, 2.0 * np.pi, 721)
        cs = np.unique(np.atleast_1d(np.asarray(clearance, dtype=float)))
        for c in cs:
            ax1.plot(1e3 * c * np.cos(theta), 1e3 * c * np.sin(theta), color="0.4", lw=0.8)
        xs, ys = 1e3 * pts[..., 0], 1e3 * pts[..., 1]
        finite = np.isfinite(xs) & np.isfinite(ys)
        reach = max([1e3 * float(cs.max())] + ([float(np.hypot(xs, ys)[finite].max())] if finite.any() else []))
        ax1.set_xlim(-1.1 * reach, 1.1 * reach)
        ax1.set_ylim(-1.1 * reach, 1.1 * reach)
    ax1.set_aspect("equal", adjustable="box")
    ax1.set_xlabel("journal e$_x$ [mm]")
    ax1.set_ylabel("journal e$_y$ [mm]")
    ax1.set_title("journal centre in the clearance circle, once per crank revolution", fontsize=10)
    ax2.set_xlabel("journal e$_x$ [mm]")
    ax2.set_ylabel("journal v$_x$ relative to bearing [m/s]")
    ax2.set_title("Poincare section (e$_x$, v$_x$)", fontsize=10)
    from matplotlib.ticker import MaxNLocator

    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
        ax.xaxis.set_major_locator(MaxNLocator(5))
    if labels is not None and n <= 12:
        fig.legend(fontsize=8, loc="outside lower center", ncols=min(n, 3), frameon=False)
    if n > 1:
        from matplotlib.cm import ScalarMappable

        cb = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=[ax1, ax2])
        cb.set_label(color_label)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


def plot_fit(path, result) -> Figure:
    """The fit plot of a :class:`jaxclear.fitting.FitResult`: measured and fitted sensor signal
    [m/s^2] against time [ms] (the model at the start values dashed), window starts marked,
    and the residual measured - fitted below it with its +-2 sigma band."""
    t = 1e3 * np.asarray(result.t, dtype=float)
    meas = np.asarray(result.measured, dtype=float)
    fitted = np.asarray(result.fitted, dtype=float)
    fig = new_figure(figsize=(9.0, 6.4))
    ax1 = fig.add_subplot(2, 1, 1)
    ax2 = fig.add_subplot(2, 1, 2, sharex=ax1)
    ax1.plot(t, meas, ".", color="0.55", ms=2.0, label="measured")
    if result.initial is not None:
        ax1.plot(t, np.asarray(result.initial, dtype=float), color="tab:orange", lw=0.8, ls="--",
                 label="model at the start values")
    ax1.plot(t, fitted, color=COLORS[0], lw=1.0, label="fitted")
    for t0 in result.window_starts[1:]:
        for ax in (ax1, ax2):
            ax.axvline(1e3 * t0, color="black", lw=0.6, ls=":")
    values = ", ".join(
        f"{k} = {v:.4g} ± {result.std.get(k, float('nan')):.2g}" for k, v in result.estimates.items())
    ax1.set_title(f"fit: {values}", fontsize=9)
    chans = (getattr(result, "settings", None) or {}).get("channels") or {}
    first = next(iter(chans), "slider_acc_m_s2")
    ax1.set_ylabel("slider acceleration [m/s$^2$]" if first == "slider_acc_m_s2" else
                   f"{first}\n({chans[first]['channel']})", fontsize=None if first == "slider_acc_m_s2" else 8)
    ax1.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    ax1.legend(loc="upper right", fontsize=8)
    res = meas - fitted
    ax2.plot(t, res, color="tab:red", lw=0.6)
    sigma = float(result.noise_sigma_m_s2)
    if np.isfinite(sigma):
        ax2.axhspan(-2 * sigma, 2 * sigma, color="tab:red", alpha=0.12, label="±2σ (residual std)")
        ax2.legend(loc="upper right", fontsize=8)
    ax2.axhline(0.0, color="black", lw=0.5)
    ax2.set_xlabel("time [ms]")
    ax2.set_ylabel("residual [m/s$^2$]" if first == "slider_acc_m_s2" else "residual")
    ax2.set_title(f"residual: loss {result.loss:.4g} (normalised), lag-1 autocorrelation "
                  f"{result.residual_autocorrelation:.2f}", fontsize=9)
    ax2.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_profiles(path, result) -> Figure:
    """The profile likelihoods of a :class:`jaxclear.fitting.FitResult` (``fit(profile=...)``),
    one panel per profiled parameter: the deviance ``D = (L - L_min) / s^2`` of the refits
    against the held value (SI), the 90 % threshold 2.706 and the interval it cuts, and the
    parabola ``((value - estimate) / std_GN)^2`` the Gauss-Newton std implies (where the two
    differ, the profile is the honest one). A point below 0 fits better than the estimate."""
    names = list(result.profiles)
    fig = new_figure(figsize=(4.6 * max(len(names), 1), 3.8))
    for j, name in enumerate(names):
        p = result.profiles[name]
        ax = fig.add_subplot(1, max(len(names), 1), j + 1)
        v, d = np.asarray(p["values"], dtype=float), np.asarray(p["deviance"], dtype=float)
        est, sd = float(result.estimates[name]), float(p["std_gauss_newton"])
        ax.plot(v, d, "o-", color=COLORS[0], ms=4, lw=1.0, label="profile (refits)")
        if np.isfinite(sd) and sd > 0:
            grid = np.linspace(v.min(), v.max(), 200)
            ax.plot(grid, ((grid - est) / sd) ** 2, color="tab:orange", lw=0.9, ls="--", label="Gauss-Newton")
        ax.axhline(2.706, color="black", lw=0.6, ls=":", label="90 % threshold")
        lo, hi = p["interval"]
        ax.axvspan(lo if lo is not None else v.min(), hi if hi is not None else v.max(), color=COLORS[0], alpha=0.12,
                   label="90 % interval" + (" (open)" if None in (lo, hi) else ""))
        ax.axvline(est, color="black", lw=0.6)
        ax.set_ylim(min(-0.5, float(np.nanmin(d)) - 0.5), max(8.0, min(float(np.nanmax(d)), 30.0)))
        ax.set_xlabel(name)
        ax.set_ylabel("deviance (L - L_min) / s²")
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper center")
    fig.tight_layout()
    return save_figure(fig, path)


__all__ = ["plot_slider_acceleration", "plot_orbit", "plot_contact_force", "plot_simulation", "plot_heatmap",
           "plot_bifurcation", "plot_poincare", "plot_fit", "plot_profiles"]
