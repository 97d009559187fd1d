r"""What :func:`~jaxclear.fitting.statistics_fit.fit_statistics` returns: the posterior on the
grid, its marginals, estimates, standard deviations and 90 % intervals, and whether they are a
result (:class:`StatisticsFitResult`, an :class:`~jaxclear.AbstractResult`: ``to_dict``,
``write`` (``statistics_fit.json``, ``statistics_fit.png``), ``summary``, ``plot``).

Grid quadrature
---------------
Each parameter's grid lives in a coordinate :math:`u`: :math:`u = \log\theta` for a positive
parameter with the ``log`` transform (stiffness, ``sensor_gain``, the noise level), else
:math:`u = \theta` (restitution). Node :math:`i` stands for the cell between the midpoints to its
neighbours (the outer cells reach half a spacing beyond the outer nodes), of width
:math:`\Delta u_i`; the posterior mass of a node is :math:`p_i \propto L_i\,\pi(u_i)\,\Delta u_i`
(the midpoint rule), and within its cell the density is taken constant in :math:`u`. So the
marginal's distribution function is piecewise linear in :math:`u`, the 90 % interval is its
5 % and 95 % points, and the mean and standard deviation are exact moments of that density in
the parameter's own unit (for :math:`u = \log\theta`, a cell contributes
:math:`\int e^{u} du / \Delta u`). A posterior narrower than one cell is then reported with the
cell's width, never as a point.

Verdict (``failures``; ``ok`` when there is none)
-------------------------------------------------
* more than :data:`EDGE_MASS` of a marginal in an outer cell of its grid, where the grid does not
  end at the parameter's bound: the posterior is cut off, widen the grid;
* failed runs whose grid neighbours carry more than :data:`FAILED_NEIGHBOUR_MASS` of the posterior
  (failed points are excluded: the posterior there is unknown);
* the record's statistics out of the model's reach: the Mahalanobis distance at the maximum of the
  posterior has a chi-squared (``d`` degrees of freedom) tail probability below :data:`MISFIT_P`;
* no grid point with a finite likelihood.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from .._results import AbstractResult, deprecated
from .._storage import atomic_write_json, jsonable

#: Largest posterior mass in an outer grid cell before the grid is called too narrow.
EDGE_MASS = 0.05
#: Largest posterior mass next to failed grid points.
FAILED_NEIGHBOUR_MASS = 0.01
#: Smallest chi-squared tail probability of the record's statistics at the posterior's maximum.
MISFIT_P = 1e-3
#: Name of the noise level [unit of the record].
NOISE = "noise_std"
#: A profiled noise level within this factor of the searched range's ends is at its end.
NOISE_EDGE = 1.01


def cell_edges(u) -> np.ndarray:
    """Edges of the cells of the nodes ``u`` ``(n,)`` (module docstring): ``(n + 1,)``."""
    u = np.asarray(u, dtype=float)
    if u.size == 1:
        return np.array([u[0], u[0]])
    mid = 0.5 * (u[1:] + u[:-1])
    return np.concatenate([[u[0] - (mid[0] - u[0])], mid, [u[-1] + (u[-1] - mid[-1])]])


def to_coordinate(values, kind: str) -> np.ndarray:
    """Grid coordinate ``u`` of ``values``: ``kind`` ``"log"`` (log), ``"logit"`` or ``"none"``."""
    v = np.asarray(values, dtype=float)
    return np.log(v) if kind == "log" else np.log(v) - np.log1p(-v) if kind == "logit" else v


def from_coordinate(u, kind: str) -> np.ndarray:
    """Inverse of :func:`to_coordinate`."""
    u = np.asarray(u, dtype=float)
    return np.exp(u) if kind == "log" else 1.0 / (1.0 + np.exp(-u)) if kind == "logit" else u


def log_jacobian(values, kind: str) -> np.ndarray:
    """``log |d value / d u|`` (a prior density of the value times it is one of ``u``)."""
    v = np.asarray(values, dtype=float)
    return np.log(v) if kind == "log" else np.log(v) + np.log1p(-v) if kind == "logit" else np.zeros(v.shape)


def _cell_moments(a, b, kind: str):
    """First and second moments of the value over cells ``[a, b]`` of ``u``, the density
    constant in ``u``: exact integrals of ``e^u``, the logistic function or ``u``."""
    if kind == "log":
        return (np.exp(b) - np.exp(a)) / (b - a), (np.exp(2 * b) - np.exp(2 * a)) / (2 * (b - a))
    if kind == "logit":  # int sigma = softplus, int sigma^2 = softplus - sigma
        sp, sg = (lambda u: np.logaddexp(0.0, u)), (lambda u: 1.0 / (1.0 + np.exp(-u)))
        return (sp(b) - sp(a)) / (b - a), ((sp(b) - sg(b)) - (sp(a) - sg(a))) / (b - a)
    return 0.5 * (a + b), (b**3 - a**3) / (3 * (b - a))


def marginal_summary(values, probs, kind: str, edge_cells: int = 1) -> dict:
    """Mean, std, 5 % and 95 % points and mode of a marginal on the grid ``values`` with masses
    ``probs`` (summing to 1), the density constant in the grid coordinate (``kind``, see
    :func:`to_coordinate`) within each cell; ``edge_mass``: the mass of the ``edge_cells``
    outermost cells at either end."""
    values, p = np.asarray(values, dtype=float), np.asarray(probs, dtype=float)
    u = to_coordinate(values, kind)
    e = cell_edges(u)
    if values.size == 1:
        m1, m2 = values, values**2
    else:
        m1, m2 = _cell_moments(e[:-1], e[1:], kind)
    mean = float(np.sum(p * m1))
    var = max(float(np.sum(p * m2)) - mean**2, 0.0)
    cdf = np.concatenate([[0.0], np.cumsum(p)])

    def quantile(q):
        return float(from_coordinate(np.interp(q, cdf, e) if values.size > 1 else u[0], kind))

    k = max(1, int(edge_cells))
    return {"mean": mean, "std": math.sqrt(var), "q05": quantile(0.05), "q95": quantile(0.95),
            "mode": float(values[int(np.argmax(p))]), "edge_mass": (float(p[:k].sum()), float(p[-k:].sum()))}


@dataclass
class StatisticsFitResult(AbstractResult):
    """The result of a statistics fit (module docstring; :meth:`to_dict`, :meth:`write`,
    :meth:`summary`, :meth:`plot`: :class:`~jaxclear.AbstractResult`).

    Attributes:
        free: the fitted names (mechanism parameters, then ``sensor_gain`` if free).
        estimates: name -> posterior mean (SI). map: name -> the grid node of largest posterior
            mass (mechanism parameters and gain jointly). std: name -> posterior standard
            deviation. intervals: name -> equal-tailed 90 % interval ``(q05, q95)``.
        grid: name -> the values ``(n_name,)`` where the posterior is evaluated (the nodes
            refined, :mod:`.statistics_surrogate`). nodes: name -> the simulated nodes.
        posterior: the normalised posterior mass on the grid of ``free``, shape
            ``(n_free_0, n_free_1, ...)``.
        log_likelihood: the synthetic log-likelihood with the noise profiled, shape
            ``(n_mech_0, ..., n_gain)`` (a gain axis of length 1 when the gain is fixed; ``-inf``
            where the moments could not be interpolated: next to failed nodes).
        marginals: name -> masses on its grid.
        noise: ``estimate`` (the record's noise standard deviation at the posterior's maximum
            [m/s^2, record units at the sensor's gain]), ``profiled``, ``range`` searched.
        noise_profile: the profiled noise level at every point of the mechanism parameters' grid [m/s^2].
        statistics: names of the statistics; observed: the record's mean statistic ``(d,)``;
            model_mean: the model's mean statistic at the posterior's maximum ``(d,)``; chi2: the
            Mahalanobis distance there (about ``d`` for a model that fits).
        record_revolutions, model_revolutions: ``n_r`` and ``n_m``.
        failed_points: the failed grid points: ``{name: value, ..., "status": code}`` each.
        failures: why the estimates are no result (empty: they are one). notes: what is worth knowing.
        settings: the fit's settings. wall_time_s: seconds, compilation included.
    """

    free: tuple
    estimates: dict
    map: dict
    std: dict
    intervals: dict
    grid: dict
    nodes: dict
    posterior: np.ndarray
    log_likelihood: np.ndarray
    marginals: dict
    noise: dict
    noise_profile: np.ndarray
    statistics: list
    observed: np.ndarray
    model_mean: np.ndarray
    chi2: float
    record_revolutions: int
    model_revolutions: int
    failed_points: list = field(default_factory=list)
    failures: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)
    wall_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether the estimates are a result (no failure)."""
        return not self.failures

    def summary(self) -> str:
        """A few lines: estimates, std, intervals, the verdict."""
        lines = [f"statistics fit: {self.record_revolutions} record revolutions, {self.model_revolutions} model "
                 f"revolutions per grid point, {len(self.statistics)} statistics, chi2 {self.chi2:.1f} at the maximum"]
        for n in self.free:
            lo, hi = self.intervals[n]
            lines.append(f"  {n:<12} {self.estimates[n]:.6g} +- {self.std[n]:.3g}  90 % [{lo:.6g}, {hi:.6g}]  "
                         f"(grid maximum {self.map[n]:.6g})")
        lines.append(f"  {NOISE:<12} {self.noise['estimate']:.4g} m/s^2 "
                     f"({'profiled' if self.noise['profiled'] else 'given'})")
        lines += [f"  note: {n}" for n in self.notes]
        lines += ["  ok"] if self.ok else [f"  FAILED: {f}" for f in self.failures]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """Everything as JSON-ready numbers and lists."""
        d = {k: getattr(self, k) for k in ("free", "estimates", "map", "std", "intervals", "grid", "nodes", "posterior",
                                           "log_likelihood", "marginals", "noise", "noise_profile", "statistics",
                                           "observed",
                                           "model_mean", "chi2", "record_revolutions", "model_revolutions",
                                           "failed_points", "failures", "notes", "settings", "wall_time_s")}
        d["ok"] = self.ok
        return jsonable(d)

    def write(self, folder, *, plots: bool = True) -> list[str]:
        """``statistics_fit.json`` (:meth:`to_dict`) and, with ``plots``, ``statistics_fit.png``
        (:meth:`plot`) in ``folder``; returns their paths. A ``folder`` ending in ``.json`` is the
        old call ``write(path)`` (deprecated): :meth:`to_dict` written there, its path returned."""
        folder = os.fspath(folder)
        if folder.endswith(".json"):
            deprecated("StatisticsFitResult.write(path.json)", "StatisticsFitResult.write(folder), which writes "
                       "statistics_fit.json (and statistics_fit.png)")
            return atomic_write_json(folder, self.to_dict())
        os.makedirs(folder, exist_ok=True)
        paths = [atomic_write_json(os.path.join(folder, "statistics_fit.json"), self.to_dict())]
        if plots:
            paths.append(self.plot(os.path.join(folder, "statistics_fit.png")))
        return paths

    def plot(self, path=None):
        """The posterior's marginal of every fitted name on its grid (masses), the estimate and
        the 90 % interval marked: the figure, or ``path`` once saved there."""
        from ..plot import new_figure

        names = [n for n in self.free if n in self.marginals] or list(self.marginals)
        fig = new_figure(figsize=(4.2 * max(1, len(names)), 3.4), layout="constrained")
        for i, n in enumerate(names):
            ax = fig.add_subplot(1, max(1, len(names)), i + 1)
            values = np.asarray(self.grid[n], dtype=float)
            ax.plot(values, np.asarray(self.marginals[n], dtype=float), "o-", ms=3)
            if values.size and values.min() > 0 and values.max() > 20 * values.min():
                ax.set_xscale("log")
            if n in self.estimates:
                ax.axvline(self.estimates[n], color="C1", label="estimate (posterior mean)")
            if n in self.intervals:
                ax.axvspan(*self.intervals[n], color="C1", alpha=0.15, label="90 % interval")
            ax.set_xlabel(n)
            ax.set_ylabel("posterior mass")
            if n in self.estimates or n in self.intervals:
                ax.legend(fontsize=7)
        fig.suptitle("statistics fit" + ("" if self.ok else ": FAILED (see the summary)"), fontsize=10)
        if path is None:
            return fig
        fig.savefig(os.fspath(path), dpi=110)
        return os.fspath(path)


def _at_bound(name: str, value: float, which: int) -> bool:
    """Whether a grid of ``name`` ending at ``value`` ends at the parameter's bound (``which``: 0
    low, 1 high), where a posterior may pile up legitimately."""
    from .. import params

    if name in ("noise_std", "sensor_gain") or ":" in name:
        return False
    info = params.info(name.split("@")[0])
    bound = info.low if which == 0 else info.high
    return bound is not None and value == bound


def verdict(result: StatisticsFitResult, summaries: dict, failed, point_mass, finite: bool) -> tuple[list, list]:
    """``(failures, notes)`` of a statistics fit (module docstring). ``failed``: the failed grid
    points, ``point_mass``: the posterior mass of each point, both shaped as the mechanism's grid."""
    from scipy.stats import chi2 as chi2_dist

    failures, notes = [], []
    n_failed, n_points = int(np.sum(failed)), int(np.size(failed))
    if not finite:
        return [f"no grid point has a finite synthetic likelihood ({n_failed} of {n_points} points failed to run; "
                "the others' statistics are not finite or their covariance is singular)"], notes
    for name, s in summaries.items():
        values = result.grid[name]
        if len(values) < 2:
            continue
        for which, mass in enumerate(s["edge_mass"]):
            end = float(values[0] if which == 0 else values[-1])
            if mass > EDGE_MASS and not _at_bound(name, end, which):
                failures.append(f"{name}: {mass:.0%} of the posterior lies within one node spacing of the grid's "
                                f"{('first', 'last')[which]} value ({end:.6g}), more than {EDGE_MASS:.0%}: the "
                                f"posterior is cut off there; widen grid[{name!r}]")
        if name in result.free and max(result.marginals[name]) > 0.9:
            notes.append(f"{name}: the posterior lies within one grid cell (mass {max(result.marginals[name]):.2f} at "
                         f"{s['mode']:.6g}); its std and interval are that cell's: refine the grid around it")
    if n_failed:
        near = np.zeros_like(failed)
        for ax in range(failed.ndim):
            near |= np.roll(failed, 1, axis=ax) & (np.arange(failed.shape[ax]) > 0).reshape(
                [-1 if i == ax else 1 for i in range(failed.ndim)])
            near |= np.roll(failed, -1, axis=ax) & (np.arange(failed.shape[ax]) < failed.shape[ax] - 1).reshape(
                [-1 if i == ax else 1 for i in range(failed.ndim)])
        mass = float(np.sum(point_mass[near & ~failed]))
        codes = sorted({p["status"] for p in result.failed_points})
        line = f"{n_failed} of {n_points} grid points failed to run (status {codes}) and are excluded"
        if mass > FAILED_NEIGHBOUR_MASS:
            failures.append(f"{line}; their neighbours carry {mass:.0%} of the posterior, so the posterior there is "
                            "unknown (result.failed_points; a larger max_steps or a tighter grid)")
        else:
            notes.append(f"{line}; their neighbours carry {mass:.1%} of the posterior")
    if result.noise["profiled"]:
        lo, hi = result.noise["range"]
        if not lo * NOISE_EDGE < result.noise["estimate"] < hi / NOISE_EDGE:
            failures.append(f"{NOISE}: the profiled noise level {result.noise['estimate']:.4g} m/s^2 is at the end of "
                            f"the range searched [{lo:.4g}, {hi:.4g}] m/s^2: give noise_std if it is known")
    d = len(result.statistics)
    p = float(chi2_dist.sf(result.chi2, d))
    if not p >= MISFIT_P:
        failures.append(f"the record's statistics are out of the model's reach: chi2 = {result.chi2:.1f} for {d} "
                        f"statistics at the posterior's maximum (tail probability {p:.1e} < {MISFIT_P:g}); check "
                        "the sensor (cut-off, order), the contact law and the known parameters")
    if result.record_revolutions < 4:
        notes.append(f"the record holds {result.record_revolutions} revolutions: the normal model of their mean "
                     "statistic is rough (4 or more are better)")
    return failures, notes
