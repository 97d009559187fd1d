r"""What :func:`~jaxclear.fitting.posterior.posterior` returns and writes: the draws in SI units,
their diagnostics (ArviZ), the Gauss-Newton intervals beside the posterior's, the posterior
predictive band over the record, and the files.

Diagnostics (ArviZ; Vehtari et al., *Rank-normalization, folding, and localization: an improved
R-hat*, Bayesian Analysis 16, 2021): the rank-normalised split R-hat and the bulk and tail
effective sample sizes of every sampled quantity, and the divergent transitions of NUTS (none
for the random walk, which has no trajectory to diverge). A
result is ``converged`` when every R-hat is at most :data:`RHAT_LIMIT`; otherwise every summary
it prints or writes says NOT CONVERGED first. Divergences and effective sample sizes below
:data:`MIN_ESS` are warnings.

Intervals: the posterior's 90 % interval is equal-tailed (its 5 % and 95 % quantiles); the
Gauss-Newton one is the fit's ``estimate +- 1.645 std`` (delta method, what ``fit.json``
reports).

The result is an :class:`~jaxclear.AbstractResult` (``to_dict``, ``write``, ``summary``,
``plot``). Files (``write``): ``posterior.nc`` (ArviZ ``InferenceData``, NetCDF 4 groups ``posterior`` and
``sample_stats``), ``posterior.json`` (summary, diagnostics, priors, settings),
``posterior_summary.csv``, ``posterior_predictive.csv`` and the figures ``posterior_pair.png``,
``posterior_predictive.png``.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._results import AbstractResult, SummaryTable, deprecated
from .._storage import atomic_write_by, atomic_write_json, atomic_write_text, jsonable
from ..sweep.lanes import over_lanes
from .parameters import from_z

#: Largest R-hat of a converged result (the issue's and Vehtari et al.'s 1.01 is for final
#: inference with long chains; 1.05 flags chains that plainly do not mix).
RHAT_LIMIT = 1.05
#: Bulk or tail effective sample size below which the quantiles are called imprecise.
MIN_ESS = 100
#: z of the two-sided 90 % normal interval.
Z90 = 1.6448536269514722
NOISE = "noise_sigma"
_STATS = ("lp", "diverging", "acceptance_rate", "n_steps", "tree_depth")


def _arviz():
    """ArviZ, imported on use (it takes seconds and warns about its coming 1.0 at import)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz
    return arviz


def values_of_draws(free, x: np.ndarray, scale: float, mech=None) -> dict:
    """name -> SI values of the unconstrained draws ``x`` ``(..., P)`` (``mech``: the fitted
    mechanism, which knows the names its own classes declare)."""
    return {n: np.asarray(from_z(n, jnp.asarray(x[..., i]), scale, mech)) for i, n in enumerate(free)}


@dataclass
class PosteriorResult(AbstractResult):
    """The posterior sample and its diagnostics (:meth:`to_dict`, :meth:`write`, :meth:`summary`,
    :meth:`plot`: :class:`~jaxclear.AbstractResult`).

    Attributes:
        samples: name -> ``(chains, draws)`` values (SI; ``noise_sigma`` in the unit of the
            first fitted column, absent when the noise was given).
        stats: per draw ``(chains, draws)``: ``lp`` (log density), ``diverging``, ``acceptance_rate``,
            ``n_steps`` (leapfrog steps = gradient evaluations), ``tree_depth``.
        statistics: name -> ``{mean, sd, q05, q50, q95, ess_bulk, ess_tail, r_hat}`` and for the
            free parameters the Gauss-Newton ``gn_estimate, gn_std, gn_q05, gn_q95`` (the table
            once named ``summary``, now the text :meth:`summary`; ``posterior.json`` keeps the
            key ``"summary"``).
        divergences, warmup_divergences: divergent transitions after / during the warm-up.
        converged: every R-hat <= :data:`RHAT_LIMIT`.
        warnings: what the diagnostics flag (not converged, divergences, small ESS).
        priors: name -> the prior's description. settings: chains, draws, warm-up, seed...
        predictive: ``t`` [s], ``measured``, ``model_q05/q50/q95`` (the model's signal over the
            posterior), ``pred_q05/q95`` (with the noise), ``coverage`` (fraction of measured
            samples inside the 90 % predictive band), first fitted column.
        step_size: per chain, in whitened units (NUTS's leapfrog step; the random walk's
            proposal standard deviation). wall_time_s, sampling_wall_s: total (fit,
            compilation, sampling, outputs) and the chunks' own time [s].
    """

    free: tuple
    samples: dict
    stats: dict
    statistics: dict
    divergences: int
    warmup_divergences: int
    converged: bool
    warnings: list
    priors: dict
    settings: dict
    predictive: dict = field(default_factory=dict)
    step_size: list = field(default_factory=list)
    wall_time_s: float = 0.0
    sampling_wall_s: float = 0.0
    gn: dict = field(default_factory=dict)

    @property
    def sampler_name(self) -> str:
        """``NUTS`` or ``random-walk Metropolis`` (``settings["sampler"]``; NUTS for results of before)."""
        return "random-walk Metropolis" if self.settings.get("sampler") == "random-walk" else "NUTS"

    @property
    def gradient_evaluations(self) -> int:
        return int(np.sum(self.stats["n_steps"]))

    def min_ess(self) -> float:
        """The smallest bulk effective sample size over the sampled quantities."""
        return float(min(s["ess_bulk"] for s in self.statistics.values()))

    def interval(self, name: str, gauss_newton: bool = False) -> tuple[float, float]:
        """The 90 % interval of ``name``: the posterior's quantiles, or the Gauss-Newton one."""
        s = self.statistics[name]
        return (s["gn_q05"], s["gn_q95"]) if gauss_newton else (s["q05"], s["q95"])

    def to_inference_data(self):
        """The draws as an ArviZ ``InferenceData`` (groups ``posterior`` and ``sample_stats``)."""
        az = _arviz()
        stats = {"lp": self.stats["lp"], "diverging": self.stats["diverging"].astype(bool),
                 "acceptance_rate": self.stats["acceptance_rate"], "n_steps": self.stats["n_steps"],
                 "tree_depth": self.stats["tree_depth"]}
        return az.from_dict(posterior=dict(self.samples), sample_stats=stats,
                            attrs={"converged": int(self.converged), "divergences": self.divergences,
                                   "source": f"jaxclear.fitting.posterior (BlackJAX {self.sampler_name})"})

    def summary_frame(self):
        """:attr:`statistics` as a :class:`pandas.DataFrame` (index: the sampled quantities)."""
        import pandas as pd

        df = pd.DataFrame.from_dict(self.statistics, orient="index")
        df.index.name = "parameter"
        df.attrs.update(converged=self.converged, divergences=self.divergences)
        return df

    def status_line(self) -> str:
        """One line: converged or NOT CONVERGED, with the numbers that say so."""
        rhat = max(s["r_hat"] for s in self.statistics.values())
        tail = f"max R-hat {rhat:.3f}, min bulk ESS {self.min_ess():.0f}, {self.divergences} divergent transition(s)"
        if self.converged:
            return f"converged ({tail})"
        return f"NOT CONVERGED: the chains did not mix ({tail}; R-hat limit {RHAT_LIMIT}): these draws are not a " \
               "posterior sample"

    @property
    def summary(self) -> SummaryTable:
        """``summary()``: the statistics as text, the status line first (a few lines for a
        terminal). Read as a table (``res.summary["name"]``, deprecated), :attr:`statistics`."""
        return SummaryTable(self.statistics, self._summary_text, "PosteriorResult.summary",
                            "PosteriorResult.statistics")

    def format_summary(self) -> str:
        """Deprecated: :meth:`summary`."""
        deprecated("PosteriorResult.format_summary()", "PosteriorResult.summary()")
        return self._summary_text()

    def _summary_text(self) -> str:
        lines = [self.status_line()]
        w = max(len(n) for n in self.statistics)
        lines.append(f"  {'':<{w}}  {'mean':>11} {'sd':>10} {'90% interval':>25} {'R-hat':>6} {'ESS':>6}"
                     f"   {'Gauss-Newton 90%':>25}")
        for name, s in self.statistics.items():
            gn = f"[{s['gn_q05']:.5g}, {s['gn_q95']:.5g}]" if "gn_q05" in s else "-"
            lines.append(f"  {name:<{w}}  {s['mean']:>11.5g} {s['sd']:>10.3g} "
                         f"{'[' + format(s['q05'], '.5g') + ', ' + format(s['q95'], '.5g') + ']':>25} "
                         f"{s['r_hat']:>6.3f} {s['ess_bulk']:>6.0f}   {gn:>25}")
        lines += [f"warning: {w_}" for w_ in self.warnings]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The content of ``posterior.json`` (JSON-ready: NaN as None)."""
        return jsonable({"converged": self.converged, "status": self.status_line(), "summary": self.statistics,
                "divergences": self.divergences, "warmup_divergences": self.warmup_divergences,
                "gradient_evaluations": self.gradient_evaluations, "warnings": self.warnings, "priors": self.priors,
                "settings": self.settings, "step_size_whitened": self.step_size, "wall_time_s": self.wall_time_s,
                "sampling_wall_s": self.sampling_wall_s, "gauss_newton": self.gn,
                "predictive_coverage_90": self.predictive.get("coverage"),
                "interval_definition": "posterior: equal-tailed 90 % (5 % and 95 % quantiles); Gauss-Newton: "
                                       "estimate +- 1.645 std (delta method)"})

    def write(self, out, *, plots: bool = True) -> list[str]:
        """Write the files (module docstring; the figures with ``plots``) into ``out``; returns
        their paths."""
        out = os.fspath(out)
        os.makedirs(out, exist_ok=True)
        paths = [atomic_write_by(os.path.join(out, "posterior.nc"),
                                 lambda p: self.to_inference_data().to_netcdf(p, engine="h5netcdf"), ".tmp.nc"),
                 atomic_write_json(os.path.join(out, "posterior.json"), self.to_dict()),
                 atomic_write_text(os.path.join(out, "posterior_summary.csv"), self.summary_frame().to_csv())]
        if self.predictive:
            import pandas as pd

            cols = {k: v for k, v in self.predictive.items() if k != "coverage"}
            paths.append(atomic_write_text(os.path.join(out, "posterior_predictive.csv"),
                                           pd.DataFrame(cols).to_csv(index=False)))
        if plots:
            paths.append(self.plot_pair(os.path.join(out, "posterior_pair.png")))
            if self.predictive:
                paths.append(self.plot_predictive(os.path.join(out, "posterior_predictive.png")))
        return paths

    def plot(self, path=None):
        """The main figure: the pair plot of the draws (:meth:`plot_pair`)."""
        return self.plot_pair(path)

    def plot_pair(self, path=None):
        """Pair plot of the draws (ArviZ, with marginals; divergent draws marked; the
        least-squares optimum as reference). Returns ``path`` or the figure."""
        az = _arviz()
        import matplotlib.pyplot as plt

        ref = {n: v for n, v in self.gn.get("estimates", {}).items()}
        if len(self.samples) < 2:  # one free parameter with the noise given: its marginal alone
            return self._plot_marginal(path, ref)
        with warnings.catch_warnings():  # "no reference value for noise_sigma": the fit has none, by design
            warnings.simplefilter("ignore", UserWarning)
            axes = az.plot_pair(self.to_inference_data(), kind="scatter", marginals=True, divergences=True,
                                reference_values=ref or None, scatter_kwargs={"alpha": 0.5, "s": 10, "color": "C0"},
                                textsize=9, figsize=(2.6 * len(self.samples),) * 2)
        fig = np.ravel(axes)[0].figure
        title = f"posterior ({self.sampler_name})" + ("" if self.converged else " - NOT CONVERGED")
        fig.suptitle(title + "; reference (green): least-squares optimum", fontsize=10, y=1.0)
        if path is None:
            return fig
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        return os.fspath(path)

    def _plot_marginal(self, path, ref: dict):
        """The one sampled quantity's histogram (a pair plot needs two), the least-squares optimum marked."""
        import matplotlib.pyplot as plt

        (name, draws), = self.samples.items()
        fig, ax = plt.subplots(figsize=(5.2, 3.6))
        ax.hist(np.ravel(draws), bins=40, color="C0", alpha=0.7)
        if name in ref:
            ax.axvline(ref[name], color="C2", label="least-squares optimum")
            ax.legend(fontsize=8)
        ax.set_xlabel(name)
        ax.set_title(f"posterior ({self.sampler_name})" + ("" if self.converged else " - NOT CONVERGED"), fontsize=10)
        if path is None:
            return fig
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        return os.fspath(path)

    def plot_predictive(self, path=None):
        """The record with the posterior's 90 % model band and 90 % predictive band."""
        import matplotlib.pyplot as plt

        p = self.predictive
        fig, ax = plt.subplots(figsize=(9, 4))
        ax.fill_between(p["t"] * 1e3, p["pred_q05"], p["pred_q95"], color="C0", alpha=0.2,
                        label="90 % predictive (with noise)")
        ax.fill_between(p["t"] * 1e3, p["model_q05"], p["model_q95"], color="C0", alpha=0.5, label="90 % model")
        ax.plot(p["t"] * 1e3, p["model_q50"], color="C0", lw=0.8, label="median model")
        ax.plot(p["t"] * 1e3, p["measured"], "k.", ms=2, label="measured")
        ax.set_xlabel("time [ms]")
        ax.set_ylabel(self.settings.get("column", "signal"))
        ax.set_title(f"posterior predictive: {100 * p['coverage']:.0f} % of the samples inside the 90 % band"
                     + ("" if self.converged else " - NOT CONVERGED"), fontsize=10)
        ax.legend(fontsize=8, loc="best")
        if path is None:
            return fig
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        return os.fspath(path)


def _summaries(samples: dict) -> dict:
    """name -> mean, sd, quantiles, bulk/tail ESS, R-hat (ArviZ)."""
    az = _arviz()
    out = {}
    for name, a in samples.items():
        a = np.asarray(a, dtype=float)
        q05, q50, q95 = np.quantile(a, [0.05, 0.5, 0.95])
        out[name] = dict(mean=float(a.mean()), sd=float(a.std(ddof=1)), q05=float(q05), q50=float(q50),
                         q95=float(q95), ess_bulk=float(az.ess(a, method="bulk")),
                         ess_tail=float(az.ess(a, method="tail")), r_hat=float(az.rhat(a)))
    return out


@eqx.filter_jit
def _signals(lp, xs):
    """Model signals ``(K, C, n_pad)`` at the draws ``xs`` ``(K, D)`` (values only), the draws
    lanes of the lane runner (:func:`jaxclear.sweep.lanes.over_lanes`)."""
    return over_lanes(lambda x: lp.model.signal(x[: lp.n_free], lp.state0, lp.win)[0], xs)


def _predictive(lp, x: np.ndarray, sigma_r: np.ndarray, k: int, seed: int, problem) -> dict:
    """The posterior predictive band of the first column over window 0's fitted samples."""
    if k == 0:
        return {}
    flat, flat_s = x.reshape(-1, x.shape[-1]), np.ravel(sigma_r)
    pick = np.linspace(0, len(flat) - 1, min(k, len(flat))).round().astype(int)
    y = np.asarray(_signals(lp, jnp.asarray(flat[pick])))[:, 0, :]
    keep = np.asarray(lp.win.mask) > 0
    y = y[:, keep]
    sigma = flat_s[pick] * float(lp.sigma_unit)
    noisy = y + np.random.default_rng(seed).standard_normal(y.shape) * sigma[:, None]
    measured = np.asarray(lp.win.data)[0, keep]
    lo, hi = np.quantile(noisy, [0.05, 0.95], axis=0)
    mq = np.quantile(y, [0.05, 0.5, 0.95], axis=0)
    return {"t": np.asarray(lp.win.t_rel)[keep] + problem.win.starts[0], "measured": measured, "model_q05": mq[0],
            "model_q50": mq[1], "model_q95": mq[2], "pred_q05": lo, "pred_q95": hi,
            "coverage": float(np.mean((measured >= lo) & (measured <= hi)))}


def diagnose(summary: dict, divergences: int) -> tuple[bool, list]:
    """``(converged, warnings)`` of a :func:`_summaries` table: not converged when an R-hat is above
    :data:`RHAT_LIMIT` (or not a number); warnings also for divergences and small ESS."""
    warn = []
    bad = {n: s["r_hat"] for n, s in summary.items() if not (s["r_hat"] <= RHAT_LIMIT)}
    if bad:
        warn.append("the chains did not mix: R-hat " + ", ".join(f"{n} = {r:.3f}" for n, r in bad.items()) +
                    f" > {RHAT_LIMIT}; run more warm-up and draws (--warmup, --draws), or check that the fit "
                    "converged to one optimum")
    if divergences:
        warn.append(f"{divergences} divergent transition(s) after the warm-up: the sampler missed part of the "
                    "posterior (curvature it cannot follow, or runs that failed); the intervals may be too narrow")
    small = {n: min(s["ess_bulk"], s["ess_tail"]) for n, s in summary.items()
             if not (min(s["ess_bulk"], s["ess_tail"]) >= MIN_ESS)}
    if small:
        warn.append("effective sample size below " + str(MIN_ESS) + ": " +
                    ", ".join(f"{n} {v:.0f}" for n, v in small.items()) + "; the quantiles are imprecise (more draws)")
    return not bad, warn


def build_result(lp, run: dict, info: dict, settings: dict, fit_result, predictive_draws: int, seed: int,
                 wall: float) -> PosteriorResult:
    """The :class:`PosteriorResult` of the chains' draws ``run`` (:func:`posterior`)."""
    free, scale = info["free"], info["scale"]
    x = run["x"]
    samples = values_of_draws(free, x, scale, lp.model.mech)
    if not settings["noise_fixed"]:
        sigma_r = np.exp(x[..., len(free)])
        samples[NOISE] = sigma_r * float(lp.sigma_unit)
    else:
        sigma_r = np.full(x.shape[:-1], float(np.exp(lp.noise_log)))
    table = _summaries(samples)
    for name in free:
        est, std = fit_result.estimates[name], fit_result.std[name]
        table[name].update(gn_estimate=est, gn_std=std, gn_q05=est - Z90 * std, gn_q95=est + Z90 * std)
    stats = {k: np.asarray(run[k], dtype=float) for k in _STATS}
    div = int(stats["diverging"].sum())
    wdiv = int(np.sum(run["warmup_divergences"]))
    converged, warn = diagnose(table, div)
    for w_ in warn:
        warnings.warn(w_, stacklevel=3)
    pred = _predictive(lp, x, sigma_r, predictive_draws, seed, info["problem"])
    gn = {"estimates": dict(fit_result.estimates), "std": dict(fit_result.std),
          "noise_sigma": info["gn_sigma"], "fitted_samples": info["n"]}
    return PosteriorResult(free=tuple(free), samples=samples, stats=stats, statistics=table, divergences=div,
                           warmup_divergences=wdiv, converged=converged, warnings=warn, priors=info["priors"],
                           settings={**settings, "column": info["problem"].columns[0],
                                     "resumed": bool(run["resumed"])},
                           predictive=pred, step_size=[float(s) for s in np.ravel(run["step_size"])],
                           wall_time_s=wall, sampling_wall_s=run["sampling_wall_s"], gn=gn)

