r"""A tolerance study of a mechanism: :func:`tolerance_study` (API) and ``jaxclear tolerance``.

Every batch of runs is a sweep (:func:`jaxclear.sweep.run_sweep`, a ``list`` of the sampled
values): vmapped runs compiled once, on every device (several hosts through
``jax.distributed``), written chunk by chunk, resumed by the same call. The study's folder
holds one sweep folder per batch, each with its own ``runs.csv``:

* ``runs/``: the sample (Sobol' points by default) for the distributions and exceedance
  probabilities of the metrics;
* ``linearised/``: the run at the marginals' medians (``z = 0``) and ``2 P`` runs at
  ``z = +-h e_i`` (``h`` = :data:`SCORE_STEP` standard deviations of the scores): the central
  differences give the gradient over the scores, ``g_z``, for the linearised estimate
  (:func:`~.estimators.linearised`). Differences, not :func:`jaxclear.sensitivities`: the metrics
  are maxima and fractions of samples whose exact derivative is the slope of one impact's peak
  or zero (a fraction of samples is piecewise constant); a difference over a tenth of the
  tolerance is the slope the tolerance sees. With ``derivatives=True`` the gradient at the medians
  is also taken from the derivatives (``jax.jacfwd`` of one run's metrics: the engine's
  error-controlled sensitivities, :func:`_derivative_gradients`) and written beside the
  differences' with their relative distance: where the two part (a maximum whose sample moves, a
  fraction of samples, whose derivative is zero), the first-order model fails;
* ``sobol/``: SALib's Saltelli design (``sobol_n (P + 2)`` runs) for the first and total indices;
* ``importance/``: ``importance_n`` runs around the linearised design point of the first limit.

Metrics (:func:`jaxclear.analysis.metrics.run_metrics`, after ``transient_revolutions``):
``peak_contact_force_n``, ``rms_acc_deviation_m_s2`` (the slider acceleration against the
ideal-joint mechanism's), ``fraction_free_flight`` (time out of contact), or any other sweep
metric.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .._extras import require_extra
from .._results import AbstractResult, SummaryTable
from .._storage import atomic_write_json, atomic_write_text, jsonable
from ..integrate import Settings, check_settings, deprecated_keywords, option_values, settings_from_options
from ..model import Mechanism
from .distributions import Inputs
from .estimators import (UnresolvedEstimateWarning, check_limit, exceedance, importance_exceedance, linearised,
                         linearised_against_sample, score_gradient, sobol_design, sobol_indices, sobol_warning)

#: Metrics of a study by default.
DEFAULT_METRICS = ("peak_contact_force_n", "rms_acc_deviation_m_s2", "fraction_free_flight")
#: Step of the central differences over the scores [standard deviations].
SCORE_STEP = 0.1
#: Run settings passed to each batch's :class:`~jaxclear.sweep.SweepConfig` (``solver``, ``rtol``,
#: ``atol``, ``max_steps``: deprecated, :data:`OLD_RUN_SETTINGS`).
RUN_OPTIONS = ("revolutions", "transient_revolutions", "samples_per_revolution", "solver", "rtol", "atol",
               "max_steps", "chunk_size", "devices")
#: The run options that moved to ``settings=`` (accepted with a ``DeprecationWarning`` for one release).
OLD_RUN_SETTINGS = ("solver", "rtol", "atol", "max_steps")


def _settings(settings: Settings | None, run_options: dict) -> Settings | None:
    """The study's runs' settings: ``settings``, or the sweep's default with the deprecated run
    options (``solver``, ``rtol``, ``atol``, ``max_steps``: removed from ``run_options``)."""
    check_settings("tolerance_study", settings)
    old = deprecated_keywords("tolerance_study", settings,
                              **{k: run_options.get(k) for k in OLD_RUN_SETTINGS})
    if not old:
        return settings
    from ..sweep.config import MAX_STEPS

    try:
        return settings_from_options(old, Settings(t_end=jnp.asarray(1.0), max_steps=MAX_STEPS),
                                     source="tolerance_study")
    finally:
        for k in old:
            run_options.pop(k, None)


@dataclass
class ToleranceResult(AbstractResult):
    """What :func:`tolerance_study` returns and writes (``tolerance.json``, ``tolerance_runs.csv``,
    ``tolerance.png``): :meth:`to_dict`, :meth:`write`, :meth:`summary`, :meth:`plot`
    (:class:`~jaxclear.AbstractResult`).

    Attributes: ``names``, ``values`` ``(n, P)`` the sampled inputs, ``metrics`` name -> ``(n,)``,
    ``statistics`` metric -> mean, sd, quantiles, failed runs (the table once named ``summary``,
    now the text :meth:`summary`; ``tolerance.json`` keeps the key ``"summary"``); ``exceedance`` metric -> sampled
    probability with its 95 % interval, the linearised one beside it (and importance sampling's
    for the first limit); ``sobol`` metric -> name -> S1, ST, their 95 % half-widths and whether
    each is resolved; ``linearised`` metric -> mean, sd, gradient over the scores, whether its
    95 % interval leaves the metric's range; ``warnings``: the estimates the runs do not resolve
    (each also issued as :class:`~.estimators.UnresolvedEstimateWarning`); ``settings``."""

    names: list
    values: np.ndarray
    metrics: dict
    statistics: dict
    exceedance: dict = field(default_factory=dict)
    sobol: dict = field(default_factory=dict)
    linearised: dict = field(default_factory=dict)
    importance: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """The content of ``tolerance.json`` (JSON-ready: NaN as None)."""
        return jsonable({"parameters": self.names, "summary": self.statistics, "exceedance": self.exceedance,
                         "sobol": self.sobol, "linearised": self.linearised, "importance": self.importance,
                         "warnings": self.warnings, "settings": self.settings})

    def write(self, out, *, plots: bool = True) -> list:
        """``tolerance.json``, ``tolerance_runs.csv`` (the sampled inputs and metrics, one row a
        run) and, with ``plots``, ``tolerance.png`` in ``out``; returns their paths."""
        import pandas as pd

        out = os.fspath(out)
        os.makedirs(out, exist_ok=True)
        table = pd.DataFrame({**{n: self.values[:, i] for i, n in enumerate(self.names)}, **self.metrics})
        paths = [atomic_write_json(os.path.join(out, "tolerance.json"), self.to_dict()),
                 atomic_write_text(os.path.join(out, "tolerance_runs.csv"), table.to_csv(index_label="run"))]
        if plots:
            paths.append(self.plot(os.path.join(out, "tolerance.png")))
        return paths

    @property
    def summary(self) -> SummaryTable:
        """``summary()``: a few lines per metric (its distribution, the linearised estimate, the
        exceedance probability, importance sampling, Sobol' indices), then the warnings. Read as
        a table (``res.summary["metric"]``, deprecated), :attr:`statistics`."""
        return SummaryTable(self.statistics, self._summary_text, "ToleranceResult.summary",
                            "ToleranceResult.statistics")

    def _summary_text(self) -> str:
        lines = [f"{len(self.values)} runs of {', '.join(self.names)}"]
        for m, s in self.statistics.items():
            if "mean" in s:
                lines.append(f"  {m}: mean {s['mean']:.5g}, sd {s['sd']:.3g}, 90 % range [{s['q05']:.5g}, "
                             f"{s['q95']:.5g}]" + (f", {s['failed_runs']} failed run(s)" if s["failed_runs"] else ""))
            lin = self.linearised.get(m)
            if lin:
                lines.append(f"    linearised: mean {lin['mean']:.5g}, sd {lin['sd']:.3g}"
                             + _flags(["leaves the metric's range"] * bool(lin.get("outside_range"))
                                      + [f"{lin.get('sd_ratio_to_sample', 0):.2g} times the sample's sd"]
                                      * bool(lin.get("departs_from_sample")))
                             + (f"; from derivatives sd {lin['derivatives']['sd']:.3g} (gradient "
                                f"{100 * lin['derivatives']['distance_to_differences']:.3g} % from the differences)"
                                if "derivatives" in lin else ""))
            ex = self.exceedance.get(m)
            if ex:
                lines.append(f"    P({m} > {ex['limit']:g}) = {ex['probability']:.4g}, 95 % interval "
                             f"[{ex['ci95'][0]:.3g}, {ex['ci95'][1]:.3g}]"
                             + (f"; linearised {ex['linearised_probability']:.3g}"
                                if "linearised_probability" in ex else ""))
            imp = self.importance.get(m)
            if imp:
                lines.append(f"    importance sampling ({imp['runs']} runs): {imp['probability']:.3g} +- "
                             f"{imp['std_error']:.2g}")
            for name, si in self.sobol.get(m, {}).items():
                lines.append(f"    Sobol' {name}: first {si['S1']:.3f} +- {si['S1_conf']:.3f}"
                             + ("" if si["S1_resolved"] else " (not resolved)") + f", total {si['ST']:.3f} +- "
                             f"{si['ST_conf']:.3f}" + ("" if si["ST_resolved"] else " (not resolved)"))
        lines += [f"warning: {said}" for said in self.warnings]
        return "\n".join(lines)

    def plot(self, path=None):
        """Histograms of the metrics, the limits and the linearised normal density over them."""
        import matplotlib.pyplot as plt
        from scipy import stats

        names = list(self.metrics)
        fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.4), squeeze=False)
        for ax, m in zip(axes[0], names):
            y = self.metrics[m][np.isfinite(self.metrics[m])]
            ax.hist(y, bins=30, density=True, color="C0", alpha=0.6, label=f"{len(y)} runs")
            lin = self.linearised.get(m)
            if lin and lin["sd"] > 0:
                lo, hi = lin["mean"] - 3 * lin["sd"], lin["mean"] + 3 * lin["sd"]
                g = np.linspace(min(lo, y.min()) if y.size else lo, max(hi, y.max()) if y.size else hi, 200)
                ax.plot(g, stats.norm.pdf(g, lin["mean"], lin["sd"]), "C1", ls=":" if lin.get("outside_range") else "-",
                        label="linearised" + (" (leaves the range)" if lin.get("outside_range") else ""))
            ex = self.exceedance.get(m)
            if ex:
                ax.axvline(ex["limit"], color="C3", ls="--",
                           label=f"limit: P = {ex['probability']:.3g} [{ex['ci95'][0]:.2g}, {ex['ci95'][1]:.2g}]")
            ax.set_xlabel(m)
            ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
            ax.legend(fontsize=7)
        axes[0][0].set_ylabel("density")
        fig.tight_layout()
        if path is None:
            return fig
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return os.fspath(path)


def _sweep_config(mech: Mechanism | None, preset: str | None, run: dict, names: list, x: np.ndarray, out: str,
                  tag: str, progress: bool):
    """The :class:`~jaxclear.sweep.SweepConfig` of the runs ``x`` ``(n, P)`` in ``out/tag``."""
    from ..sweep import SweepConfig

    return SweepConfig(list={n: [float(v) for v in x[:, i]] for i, n in enumerate(names)}, mechanism=mech,
                       preset=preset if mech is None else None, out=os.path.join(out, tag), progress=progress,
                       source=f"tolerance study ({tag})", **run)


def _evaluator(mech: Mechanism | None, preset: str | None, run: dict, metrics: tuple, names: list, out: str,
               restart: bool, progress: bool):
    """``evaluate(tag, X) -> {metric: (n,)}``: the runs of ``X`` as a sweep in ``out/tag``."""
    from ..sweep import run_sweep

    def evaluate(tag: str, x: np.ndarray) -> dict:
        cfg = _sweep_config(mech, preset, run, names, x, out, tag, progress)
        res = run_sweep(cfg, restart=restart)
        missing = [m for m in metrics if m not in res.table]
        if missing:
            raise ParameterError(f"tolerance study: unknown metric(s) {missing}; this mechanism's: "
                                 f"{[c for c in res.table if c not in names and c not in ('run', 't_end_s')]}")
        return {m: np.asarray(res.table[m], dtype=float) for m in metrics}

    return evaluate


def _derivative_gradients(mech: Mechanism | None, preset: str | None, run: dict, metrics: tuple, names: list,
                          x0: np.ndarray, out: str) -> dict:
    """metric -> ``(P,)`` its gradient over the input values at ``x0``, by forward-mode
    differentiation of one run of the same sweep configuration (:func:`jaxclear.sweep.batch.run_outputs`)."""
    import jax
    import jax.numpy as jnp

    from ..sweep.batch import run_outputs
    from ..sweep.plan import make_plan

    cfg = _sweep_config(mech, preset, run, names, np.asarray(x0, dtype=float)[None], out, "derivatives", False)
    plan = make_plan(cfg, None, trajectories=False)
    jac = jax.jit(jax.jacfwd(lambda row: {m: run_outputs(plan, cfg.base_mechanism, cfg.ideal, row)[m] for m in metrics}))
    return {m: np.asarray(g, dtype=float) for m, g in jac(jnp.asarray(x0, dtype=float)).items()}


def tolerance_study(inputs: Inputs, mech: Mechanism | None = None, *, preset: str = "flores-slider-crank",
                    n: int = 256, method: str = "sobol", seed: int = 0, metrics=DEFAULT_METRICS,
                    limits: dict | None = None, linearise: bool = True, derivatives: bool = False,
                    sobol_n: int = 0, importance_n: int = 0,
                    out="tolerance-out", restart: bool = False, progress: bool = True,
                    settings: Settings | None = None, **run_options) -> ToleranceResult:
    """Sample the inputs, run the mechanism for each sample, and estimate (module docstring).

    Args:
        inputs: the distributions (:func:`~.distributions.inputs_from_dict`).
        mech: the mechanism (default: the ``preset``).
        n: runs of the sample (Sobol': rounded up to a power of 2); method: ``"sobol"`` or ``"mc"``.
        metrics: sweep metric names; limits: metric -> limit for the exceedance probability.
        linearise: also the linearised estimate (``2 P + 1`` runs).
        derivatives: also the linearised estimate's gradient from the engine's derivatives
            (one forward-mode run at the medians, ``P`` tangents), beside the differences'.
        sobol_n: base points of the Sobol' indices (0: none; ``sobol_n (P + 2)`` runs).
        importance_n: runs of importance sampling for the first limit (0: none; needs ``linearise``).
        out: the study's folder (one sweep folder per batch); restart: discard earlier results.
        settings: how every run is integrated (:class:`~jaxclear.Settings`, whole: solver,
            tolerances, step limit, the derivatives' ``Sensitivity(tolerance)`` of the estimate
            from ``derivatives``...); each batch's sweep replaces only ``t_end``, ``n_out``,
            ``throw`` and ``progress`` (:class:`~jaxclear.sweep.SweepConfig`). Default None:
            the sweep's default.
        run_options: :data:`RUN_OPTIONS` of each batch's :class:`~jaxclear.sweep.SweepConfig`
            (``revolutions``, ``samples_per_revolution``...); its ``solver``, ``rtol``, ``atol``,
            ``max_steps`` are deprecated (a ``DeprecationWarning``, one release):
            ``settings=jc.settings(1.0, rtol=...)``; with ``settings`` too, a
            :class:`~jaxclear.ParameterError`.
    """
    bad = sorted(set(run_options) - set(RUN_OPTIONS))
    if bad:
        raise ParameterError(f"tolerance_study: unknown option(s) {bad}; allowed: {list(RUN_OPTIONS)}")
    settings = _settings(settings, run_options)
    metrics = tuple(metrics)
    limits = {m: check_limit(m, v) for m, v in (limits or {}).items()}
    unknown = sorted(set(limits) - set(metrics))
    if unknown:
        raise ParameterError(f"tolerance_study: limits given for {unknown}, which are not among the metrics {metrics}")
    for name, count, low in (("n", n, 2), ("sobol_n", sobol_n, 0), ("importance_n", importance_n, 0)):
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < low:
            raise ParameterError(f"tolerance_study: {name} = {count!r}: expected an integer >= {low}")
    if sobol_n:  # before any run: the Sobol' indices need SALib
        require_extra("uncertainty", "tolerance_study with sobol_n > 0 (Sobol' indices)", ["SALib"])
    if derivatives and not linearise:
        raise ParameterError("tolerance_study: derivatives=True adds to the linearised estimate: it needs linearise=True")
    if importance_n and not (limits and linearise):
        raise ParameterError("tolerance_study: importance_n needs a limit and linearise=True (the design point)")
    names = inputs.names
    run = dict(run_options, settings=settings)
    run_options = {k: v for k, v in run_options.items() if k not in OLD_RUN_SETTINGS}  # the result: in integration
    evaluate = _evaluator(mech, preset, run, metrics, names, os.fspath(out), restart, progress)
    x = inputs.sample(n, method, seed)
    y = evaluate("runs", x)
    statistics = {m: _describe(v) for m, v in y.items()}
    res = ToleranceResult(names, x, y, statistics, settings=dict(n=int(len(x)), method=method, seed=seed,
                                                               inputs={m.name: m.describe() for m in inputs.marginals},
                                                               correlation=None if inputs.correlation is None
                                                               else inputs.correlation.tolist(), **run_options,
                                                               **({} if settings is None else
                                                                  {"integration": option_values(settings)})))
    for m, lim in limits.items():
        res.exceedance[m] = exceedance(y[m], lim)
    if linearise:
        p = len(names)
        z = np.vstack([np.zeros(p), SCORE_STEP * np.eye(p), -SCORE_STEP * np.eye(p)])
        yl = evaluate("linearised", inputs.scores_to_values(z))
        for m, v in yl.items():
            g = (v[1: p + 1] - v[p + 1:]) / (2 * SCORE_STEP)
            res.linearised[m] = linearised(v[0], g, limits.get(m), metric=m)
            if res.linearised[m]["outside_range"]:
                res.warnings.append(res.linearised[m]["warning"])
            if (said := linearised_against_sample(m, res.linearised[m], statistics[m].get("sd", 0.0), len(x))):
                res.warnings.append(said)
                warnings.warn(said, UnresolvedEstimateWarning, stacklevel=2)
            if m in res.exceedance:
                res.exceedance[m]["linearised_probability"] = res.linearised[m]["probability"]
        if derivatives:
            grads = _derivative_gradients(mech, preset, run, metrics, names,
                                          inputs.scores_to_values(np.zeros((1, len(names))))[0], os.fspath(out))
            for m, g in grads.items():
                gz = score_gradient(inputs, g)
                fd = np.asarray(res.linearised[m]["gradient_scores"])
                lin = linearised(res.linearised[m]["mean"], gz, limits.get(m))
                lin["gradient_values"] = g.tolist()
                # where the first-order model fails, the slope at the medians and the one over a tenth of
                # the tolerance part
                lin["distance_to_differences"] = float(np.linalg.norm(gz - fd) / max(np.linalg.norm(fd), 1e-300))
                res.linearised[m]["derivatives"] = lin
        if importance_n:
            m0 = next(iter(limits))
            lin = res.linearised[m0]
            res.importance[m0] = importance_exceedance(inputs, lambda xx: evaluate("importance", xx), m0, limits[m0],
                                                       lin["mean"], lin["gradient_scores"], importance_n, seed)
    if sobol_n:
        problem, xs = sobol_design(inputs, sobol_n, seed)
        ys = evaluate("sobol", xs)
        res.sobol = {m: sobol_indices(problem, v, seed) for m, v in ys.items()}
        for m, idx in res.sobol.items():
            if said := sobol_warning(m, idx, sobol_n):
                res.warnings.append(said)
                warnings.warn(said, UnresolvedEstimateWarning, stacklevel=2)
    res.write(os.fspath(out))
    return res


def _flags(notes: list) -> str:
    """`` (note; note: see the warnings below)``, or nothing."""
    return f" ({'; '.join(notes)}: see the warnings below)" if notes else ""


def _describe(v: np.ndarray) -> dict:
    ok = v[np.isfinite(v)]
    if not ok.size:
        return {"failed_runs": int(v.size)}
    q = np.quantile(ok, [0.05, 0.5, 0.95])
    return {"mean": float(ok.mean()), "sd": float(ok.std(ddof=1)) if ok.size > 1 else 0.0, "q05": float(q[0]),
            "q50": float(q[1]), "q95": float(q[2]), "min": float(ok.min()), "max": float(ok.max()),
            "failed_runs": int(v.size - ok.size)}
