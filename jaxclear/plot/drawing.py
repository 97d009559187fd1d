"""Drawings of a mechanism: a still picture of one configuration (:func:`plot_mechanism`, used by
``jaxclear check``) and an animation of a solution (:func:`animate`, GIF or MP4).

Bodies are drawn as lines from their centroid to each of their named points (a polygon when a
body has three or more points, a square for a body with one point, e.g. a slider); ideal
revolute joints as small circles, translational joints as their guide line, ground points as
triangles. A clearance joint is drawn magnified: its bearing as a circle of fixed drawing
radius and its journal inside it at the eccentricity multiplied by ``magnify``, so that a
clearance of half a millimetre in a linkage of decimetres is visible; the factor is printed. A
translational clearance joint is drawn the same way at its slider point, the eccentricity being
the slider's lateral offset from the guide line. Force elements among the loads: a spring-damper
as a zigzag between its two points, a bushing as a square at its second point joined to its first,
a rotational spring-damper as a spiral at its ``drawn_at`` point (else the second body's centroid).

Figures use :class:`matplotlib.figure.Figure` (no pyplot state). Animations use matplotlib's
Pillow writer for ``.gif`` (Pillow comes with matplotlib) and its FFMpeg writer for ``.mp4``
when the ``ffmpeg`` program is found (``imageio-ffmpeg`` ships one).
"""

from __future__ import annotations

import os
import shutil
from typing import TYPE_CHECKING

import numpy as np

from .._errors import ParameterError
from ..elements import TranslationalClearanceJoint
from ..integrate import Solution
from ..model import GROUND, AbstractConnector, Mechanism, Translational
from ..model.joints import AbstractJoint
from .figures import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DPI = 110
#: drawn bearing radius as a fraction of the drawing's size
BEARING_SIZE = 0.05
BODY_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive")


def _points_global(mech: Mechanism, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """Global coordinates of every named point (and the centroid ``"@"``) of every body."""
    out = {GROUND: {k: np.asarray(v, float) for k, v in mech.ground_points.items()}}
    for i, b in enumerate(mech.bodies):
        x, y, phi = q[3 * i: 3 * i + 3]
        c, s = np.cos(phi), np.sin(phi)
        pts = {"@": np.array([x, y])}
        for name, p in b.points.items():
            p = np.asarray(p, float)
            pts[name] = np.array([x + c * p[0] - s * p[1], y + s * p[0] + c * p[1]])
        out[b.name] = pts
    return out


def extent(mech: Mechanism, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(lower corner, upper corner, size) [m] of everything drawn over the configurations ``qs``."""
    pts = [p for q in np.atleast_2d(qs) for body in _points_global(mech, q).values() for p in body.values()]
    pts = np.array(pts) if pts else np.zeros((1, 2))
    lo, hi = pts.min(0), pts.max(0)
    return lo, hi, float(max(np.max(hi - lo), 1e-3))


def default_magnify(mech: Mechanism, size: float) -> float:
    """Factor that draws the largest clearance as 1.5 % of the drawing's size, 30 % of the drawn
    bearing radius (1 without clearance joints)."""
    if not mech.clearance_joints:
        return 1.0
    c = max(float(j.clearance) for j in mech.clearance_joints)
    return 0.3 * BEARING_SIZE * size / c


class _Artist:
    """Draws one configuration on an axes and updates it (for animations)."""

    def __init__(self, ax, mech: Mechanism, size: float, magnify: float):
        self.mech, self.ax, self.size, self.magnify = mech, ax, size, magnify
        self.bodies = []
        for i, b in enumerate(mech.bodies):
            color = BODY_COLORS[i % len(BODY_COLORS)]
            (line,) = ax.plot([], [], "-", color=color, lw=3, solid_capstyle="round", label=b.name, zorder=2)
            (dots,) = ax.plot([], [], "o", color=color, ms=3, zorder=3)
            self.bodies.append((b, line, dots))
        self.pins = [ax.plot([], [], "o", mfc="white", mec="k", ms=7, zorder=4, label="revolute joint" if k == 0 else None)[0]
                     for k, j in enumerate(j for j in mech.joints
                                           if isinstance(j, AbstractJoint) and not isinstance(j, Translational))]
        self.guides = [ax.plot([], [], "--", color="0.4", lw=1, zorder=1)[0]
                       for j in mech.joints if isinstance(j, Translational)]
        grounds = np.array(list(mech.ground_points.values()), float).reshape(-1, 2)
        ax.plot(grounds[:, 0], grounds[:, 1] - 0.02 * size, "^", color="0.3", ms=9, zorder=1)
        self.radius = BEARING_SIZE * size
        self.clearances = []
        from matplotlib.patches import Circle

        for k, j in enumerate(mech.clearance_joints):
            bearing = Circle((0, 0), self.radius, fill=False, ec="k", lw=1.2, zorder=5,
                             label=f"clearance joint (gap x{magnify:.3g})" if k == 0 else None)
            journal = Circle((0, 0), self.radius - magnify * float(j.clearance), fc="0.85", ec="tab:red", lw=1.2,
                             zorder=6)
            ax.add_patch(bearing)
            ax.add_patch(journal)
            self.clearances.append((j, bearing, journal))
        self.connectors = []  # each force element between two bodies draws itself (AbstractConnector.sketch)
        for load in mech.loads:
            if isinstance(load, AbstractConnector):
                (line,) = ax.plot([], [], zorder=7, label=f"{load.label}", **load.SKETCH_STYLE)
                self.connectors.append((load, line))

    def update(self, q: np.ndarray):
        pts = _points_global(self.mech, q)
        for b, line, dots in self.bodies:
            body = pts[b.name]
            names = [k for k in body if k != "@"]
            centre = body["@"]
            if len(names) >= 3:
                ring = sorted(names, key=lambda k: np.arctan2(*(body[k] - centre)[::-1]))
                xy = np.array([body[k] for k in ring + ring[:1]])
            elif names:
                xy = np.array([body[k] for k in names]) if len(names) == 2 else np.array([centre, body[names[0]]])
            else:
                xy = centre[None]
            if len(names) == 1 and np.allclose(xy[0], xy[-1]):  # a slider: a square around its point
                h = 0.03 * self.size
                xy = centre + h * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]])
            line.set_data(xy[:, 0], xy[:, 1])
            dots.set_data([p[0] for p in body.values()], [p[1] for p in body.values()])
        joints = [j for j in self.mech.joints if isinstance(j, AbstractJoint) and not isinstance(j, Translational)]
        for pin, j in zip(self.pins, joints):
            p = pts[j.body_i][j.point_i]
            pin.set_data([p[0]], [p[1]])
        for guide, j in zip(self.guides, [j for j in self.mech.joints if isinstance(j, Translational)]):
            p = pts[j.body_i][j.point_i]
            phi = 0.0 if j.body_i == GROUND else q[3 * self.mech.body_index(j.body_i) + 2]
            ax = np.asarray(j.axis, float)
            d = np.array([np.cos(phi) * ax[0] - np.sin(phi) * ax[1], np.sin(phi) * ax[0] + np.cos(phi) * ax[1]])
            ends = np.array([p - 2 * self.size * d, p + 2 * self.size * d])
            guide.set_data(ends[:, 0], ends[:, 1])
        for j, bearing, journal in self.clearances:
            (seat_body, seat_point), (body, point) = j.points()
            pb, pj = pts[seat_body][seat_point], pts[body][point]
            if isinstance(j, TranslationalClearanceJoint):  # the slider's lateral offset in its guide
                phi = 0.0 if seat_body == GROUND else q[3 * self.mech.body_index(seat_body) + 2]
                ax = np.asarray(j.axis, float)
                c, s = np.cos(phi), np.sin(phi)
                normal = np.array([-s * ax[0] - c * ax[1], c * ax[0] - s * ax[1]])  # perp of the guide axis
                ecc = float(np.dot(pj - pb, normal)) * normal
                pb = pj - ecc
            else:
                ecc = pj - pb
            bearing.center = tuple(pb)
            journal.center = tuple(pb + self.magnify * ecc)
        for load, line in self.connectors:
            xy = load.sketch(pts, self.size)
            if xy is not None:
                line.set_data(xy[:, 0], xy[:, 1])


def _axes(fig: Figure, mech: Mechanism, qs: np.ndarray, rect=(0.08, 0.08, 0.88, 0.84)):
    ax = fig.add_axes(rect)
    lo, hi, size = extent(mech, qs)
    mid, half = 0.5 * (lo + hi), 0.5 * size + 0.12 * size
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax, size


def plot_mechanism(path, mech: Mechanism, q, magnify: float | None = None, title: str | None = None) -> Figure:
    """Draw ``mech`` in configuration ``q`` (n,) [m, rad]; save a PNG when ``path`` is given."""
    q = np.asarray(q, float)
    fig = new_figure(figsize=(7.0, 6.0), dpi=DPI)
    ax, size = _axes(fig, mech, q)
    magnify = default_magnify(mech, size) if magnify is None else float(magnify)
    art = _Artist(ax, mech, size, magnify)
    art.update(q)
    notes = [f"{j.name}: c = {float(j.clearance) * 1e6:.4g} um, drawn x{magnify:.3g}" for j in mech.clearance_joints]
    if notes:
        ax.text(0.02, 0.02, "\n".join(notes), transform=ax.transAxes, fontsize=8, color="tab:red", va="bottom")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or f"{mech.name}: assembled configuration")
    if path is not None:
        fig.savefig(os.fspath(path), dpi=DPI)
    return fig


def animate(mech: Mechanism, sol: Solution, path, fps: int = 25, frames: int = 100, magnify: float | None = None,
            joint: int = 0) -> str:
    """Write an animation of ``sol`` (GIF for ``.gif``, MP4 for ``.mp4``), with ``frames``
    frames spread uniformly over the output samples and the orbit of clearance joint ``joint``'s
    journal centre inside its clearance circle (true scale, in micrometres) in an inset.
    Returns the path."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    from matplotlib import animation

    if ext not in (".gif", ".mp4"):
        raise ParameterError(f"animation file {path!r}: the extension must be .gif or .mp4")
    if ext == ".mp4" and not animation.FFMpegWriter.isAvailable() and shutil.which("ffmpeg") is None:
        raise ParameterError("writing .mp4 needs ffmpeg (pip install imageio-ffmpeg, or a system ffmpeg); "
                             "write a .gif instead")
    if int(frames) < 1 or int(fps) < 1:
        raise ParameterError(f"frames = {frames} and fps = {fps} must be >= 1")
    qs = np.asarray(sol.q, float)
    idx = np.unique(np.linspace(0, qs.shape[0] - 1, int(frames)).round().astype(int))
    fig = new_figure(figsize=(9.0, 6.0), dpi=DPI)
    ax, size = _axes(fig, mech, qs[idx], rect=(0.08, 0.09, 0.60, 0.82))
    magnify = default_magnify(mech, size) if magnify is None else float(magnify)
    art = _Artist(ax, mech, size, magnify)
    ts = np.asarray(sol.ts, float)
    label = ax.text(0.02, 0.96, "", transform=ax.transAxes, fontsize=9, va="top")
    orbit = None
    if mech.clearance_joints:
        if not 0 <= joint < len(mech.clearance_joints):
            raise ParameterError(f"joint = {joint} outside [0, {len(mech.clearance_joints) - 1}]")
        c = float(mech.clearance_joints[joint].clearance) * 1e6
        ecc = np.asarray(sol.ecc, float)[:, joint, :] * 1e6
        inset = fig.add_axes((0.73, 0.50, 0.25, 0.375))
        th = np.linspace(0, 2 * np.pi, 200)
        inset.plot(c * np.cos(th), c * np.sin(th), "k-", lw=1)
        inset.set_aspect("equal")
        inset.set_xlim(-1.15 * c, 1.15 * c)
        inset.set_ylim(-1.15 * c, 1.15 * c)
        inset.set_title(f"journal orbit [um]\n{mech.clearance_joints[joint].name}, true scale", fontsize=8)
        inset.tick_params(labelsize=6)
        (trace,) = inset.plot([], [], "-", color="tab:red", lw=0.8)
        (dot,) = inset.plot([], [], "o", color="tab:red", ms=3)
        orbit = (ecc, trace, dot)
    ax.set_title(f"{mech.name}" + (f" (clearances x{magnify:.3g})" if mech.clearance_joints else ""))

    def frame(k):
        i = idx[k]
        art.update(qs[i])
        label.set_text(f"t = {1e3 * ts[i]:.2f} ms")
        if orbit is not None:
            ecc, trace, dot = orbit
            trace.set_data(ecc[: i + 1, 0], ecc[: i + 1, 1])
            dot.set_data([ecc[i, 0]], [ecc[i, 1]])
        return ()

    anim = animation.FuncAnimation(fig, frame, frames=len(idx), blit=False)
    writer = animation.PillowWriter(fps=int(fps)) if ext == ".gif" else animation.FFMpegWriter(fps=int(fps))
    anim.save(path, writer=writer, dpi=DPI)
    return path
