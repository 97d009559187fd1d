r"""Estimators of a tolerance study: exceedance probabilities with confidence intervals,
variance-based sensitivity indices, the linearised (first-order) estimate, and importance
sampling for small probabilities. Each takes the study's :class:`~.distributions.Inputs` and an
``evaluate(X) -> {metric: values}`` (a batch of runs on the sweep's machinery for a mechanism,
:mod:`.study`; any vectorised function for a test such as Ishigami's).

* Exceedance ``P(Y > limit)``: the fraction of runs above the limit with Wilson's score interval
  (Wilson, *Probable inference...*, JASA 22, 1927; for quasi-Monte Carlo points the binomial
  interval is conservative: their error falls faster than ``1/sqrt(n)``).
* Sobol' indices, first order ``S_i`` and total ``S_Ti``: SALib's estimators (Saltelli et al.,
  *Variance based sensitivity analysis of model output*, Comput. Phys. Commun. 181, 2010, and
  Jansen 1999 for the total effect) on SALib's Saltelli design, mapped through the marginals;
  they need independent inputs (a correlation is an error here). Each comes with SALib's 95 %
  bootstrap half-width and a verdict (:func:`index_verdict`): an index is resolved where its
  95 % interval is narrower than the index itself, or lies within +-:data:`SOBOL_NEGLIGIBLE`
  (negligible); one outside [0, 1] (a share of the variance cannot be) by more than that margin
  or beyond its interval, or with a wider interval, is noise of too few base points (at 16 of
  Ishigami's function: 0.82 +- 0.72, -0.15 +- 0.32; of the example study: 1.37 +- 0.68).
* Linearised, in the inputs' independent standard normal scores ``z``: ``Y ~ f(x(0)) + g_z . z``,
  mean ``f(x(0))``, sd ``|g_z|`` (for normal inputs ``g_z . g_z = g^T C g``, ``C`` the inputs'
  covariance, ``g`` the gradient over the values), ``P(Y > limit) ~ 1 - Phi((limit - f(x(0))) / sd)``;
  exact for a linear ``f`` of normal inputs, wrong where ``f`` bends over the inputs' spread or the metric has a kink (a
  peak that jumps from one impact to another, contact that starts or stops). Where its 95 %
  interval ``mean +- 1.96 sd`` leaves the metric's range (:data:`METRIC_RANGES`: a fraction
  outside [0, 1], a negative force) the estimate is flagged (``outside_range``, a warning): the
  normal model puts a share of its mass on values the metric cannot take. Where its sd differs
  from the sample's by more than a factor :data:`LINEAR_SD_FACTOR` either way
  (:func:`linearised_against_sample`) it is flagged too: the model does not describe the metric
  over the inputs' spread (the example study: 7.8e3 against 1.1e3 m/s^2).
* Importance sampling (e.g. Rubinstein and Kroese, *Simulation and the Monte Carlo method*, 3rd
  ed., 2017, section 5.7): the standard normal scores ``z`` of the inputs drawn around the
  linearised design point ``z* = beta g_z / |g_z|`` (``beta = (limit - f(x(0))) / |g_z|``, ``g_z`` the
  gradient over the scores), weighted by ``phi(z) / phi(z - z*) = exp(-z.z* + |z*|^2 / 2)``;
  unbiased whatever the linearisation's error (a poor one only costs variance), with the
  standard error of the weighted indicators.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .._errors import ParameterError
from .distributions import Inputs

#: Ranges of the metrics a limit may be set in (a limit outside is an error): name -> (low, high).
METRIC_RANGES = {"peak_contact_force_n": (0.0, math.inf), "rms_contact_force_n": (0.0, math.inf),
                 "max_penetration_m": (0.0, math.inf), "peak_acc_deviation_m_s2": (0.0, math.inf),
                 "rms_acc_deviation_m_s2": (0.0, math.inf), "peak_slider_acc_m_s2": (0.0, math.inf),
                 "fraction_free_flight": (0.0, 1.0), "fraction_impact": (0.0, 1.0),
                 "fraction_continuous_contact": (0.0, 1.0), "energy_dissipated_j": (0.0, math.inf)}
#: z of the two-sided 95 % normal interval.
Z95 = 1.959963984540054
#: A Sobol' index whose 95 % interval lies within +- this is resolved as negligible (the input
#: explains under 5 % of the variance), however wide the interval relative to the index.
SOBOL_NEGLIGIBLE = 0.05


#: A linearised sd more than this factor from the sample's (either way) is flagged: the sample's
#: sd is known to about 1/sqrt(2 (n - 1)) of itself (9 % at 64 runs, 27 % at 8), far inside it.
LINEAR_SD_FACTOR = 2.0


class UnresolvedEstimateWarning(UserWarning):
    """A tolerance study's estimate that its runs do not resolve: a Sobol' index within noise
    (:func:`index_verdict`) or a linearised estimate outside the metric's range
    (:func:`linearised`)."""


def check_limit(metric: str, limit, ranges: dict | None = None) -> float:
    """``limit`` as a float; a limit outside the metric's range (:data:`METRIC_RANGES`), where the
    probability is 0 or 1 by definition, is a :class:`~jaxclear.ParameterError`."""
    if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not math.isfinite(limit):
        raise ParameterError(f"limit of {metric!r} = {limit!r}: expected a finite number")
    low, high = (ranges if ranges is not None else METRIC_RANGES).get(metric, (-math.inf, math.inf))
    if not low <= limit < high:
        raise ParameterError(f"limit of {metric!r} = {limit:g} is outside the metric's range [{low:g}, {high:g}): "
                             "the probability of exceeding it is 0 or 1 by definition")
    return float(limit)


def wilson_interval(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson's score interval of a binomial proportion ``k / n`` (module docstring)."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, centre - half), min(1.0, centre + half))


def exceedance(values, limit: float) -> dict:
    """``P(Y > limit)`` from the runs' values (failed runs, NaN, are left out and counted), its 95 %
    Wilson interval."""
    y = np.asarray(values, dtype=float)
    ok = np.isfinite(y)
    k, n = int(np.sum(y[ok] > limit)), int(ok.sum())
    lo, hi = wilson_interval(k, n)
    return {"limit": float(limit), "probability": k / n if n else float("nan"), "ci95": [lo, hi], "exceeding": k,
            "runs": n, "failed_runs": int((~ok).sum())}


def sobol_design(inputs: Inputs, n: int, seed: int = 0):
    """SALib's problem and Saltelli design (``n (P + 2)`` rows, first and total order), mapped
    through the marginals: ``(problem, X)``."""
    from SALib.sample import sobol as sobol_sample

    if inputs.correlation is not None:
        raise ParameterError("Sobol' indices need independent inputs: remove [correlations] for the sensitivity "
                             "indices (they are defined for independent inputs)")
    p = len(inputs.marginals)
    problem = {"num_vars": p, "names": inputs.names, "bounds": [[0.0, 1.0]] * p}
    u = sobol_sample.sample(problem, n, calc_second_order=False, scramble=True, seed=seed)
    return problem, inputs.from_unit(u)


def index_verdict(value: float, conf: float) -> str | None:
    """``None`` where a Sobol' index ``value`` [-] with 95 % half-width ``conf`` is resolved,
    else why not: its interval lies within +-:data:`SOBOL_NEGLIGIBLE` (resolved: negligible),
    else it is outside [0, 1], where a share of the variance cannot be, by more than that margin
    or beyond its interval (``value - conf > 1`` or ``value + conf < 0``: the estimator's noise),
    or the interval is wider than the index (``2 conf > |value|``)."""
    if abs(value) + conf <= SOBOL_NEGLIGIBLE:
        return None
    if not -SOBOL_NEGLIGIBLE <= value <= 1.0 + SOBOL_NEGLIGIBLE or value - conf > 1.0 or value + conf < 0.0:
        return f"{value:.3g} +- {conf:.2g} lies outside [0, 1], where a share of the variance cannot be"
    if 2.0 * conf > abs(value):
        return f"{value:.3g} +- {conf:.2g}: the 95 % interval is wider than the index"
    return None


def sobol_warning(metric: str, indices: dict, base_points: int) -> str | None:
    """One line on the indices of ``metric`` (:func:`sobol_indices`) that are not resolved
    (:func:`index_verdict`), saying how to resolve them; ``None`` where every one is."""
    bad = [f"{label} of {name!r} {why}" for name, si in indices.items()
           for kind, label in (("S1", "first-order"), ("ST", "total"))
           if (why := index_verdict(si[kind], si[kind + "_conf"]))]
    if not bad:
        return None
    return (f"Sobol' indices of {metric!r} not resolved: " + "; ".join(bad) + f". sobol_n = {base_points} base "
            "points are too few for them (the half-widths fall like 1/sqrt(sobol_n))")


def sobol_indices(problem: dict, y, seed: int = 0) -> dict:
    """name -> ``{S1, S1_conf, ST, ST_conf, S1_resolved, ST_resolved}`` of the design's values:
    the indices [-], their 95 % bootstrap half-widths (bootstrap seeded by ``seed``: the same
    for the same values) and whether each is resolved (:func:`index_verdict`)."""
    from SALib.analyze import sobol as sobol_analyze

    y = np.asarray(y, dtype=float)
    if not np.all(np.isfinite(y)):
        raise ParameterError(f"Sobol' indices: {int((~np.isfinite(y)).sum())} run(s) failed (NaN): the indices "
                             "need every run of the design")
    # SALib reads a seed of 0 as none (``if seed:``) and bootstraps from NumPy's global state: seed + 1
    s = sobol_analyze.analyze(problem, y, calc_second_order=False, seed=seed + 1)
    out = {}
    for i, n in enumerate(problem["names"]):
        out[n] = {k: float(s[k][i]) for k in ("S1", "S1_conf", "ST", "ST_conf")}
        out[n].update({k + "_resolved": index_verdict(out[n][k], out[n][k + "_conf"]) is None for k in ("S1", "ST")})
    return out


def linearised(f0: float, grad_scores, limit: float | None = None, metric: str | None = None,
               ranges: dict | None = None) -> dict:
    """Mean, sd and (with ``limit``) exceedance probability of the first-order model in the
    inputs' independent standard normal scores ``z`` (module docstring): ``Y ~ f0 + g_z . z``,
    so ``sd = |g_z|``; ``f0`` the metric at ``z = 0`` (the marginals' medians), ``grad_scores``
    ``(P,)`` its gradient over ``z`` (:func:`score_gradient` from one over the values). For normal
    inputs ``|g_z|^2 = g^T C g`` with ``C`` the covariance. With ``metric``, the model's 95 %
    interval ``f0 +- 1.96 sd`` is checked against the metric's range (``ranges``, default
    :data:`METRIC_RANGES`): ``outside_range`` and, where true, a ``warning`` (also issued as
    :class:`UnresolvedEstimateWarning`)."""
    g = np.asarray(grad_scores, dtype=float)
    s = float(np.linalg.norm(g))
    out = {"mean": float(f0), "sd": s, "gradient_scores": g.tolist()}
    if limit is not None:
        from scipy import stats  # where used: scipy.stats is a fifth of `import jaxclear`'s own time

        out["probability"] = float(stats.norm.sf((limit - f0) / s)) if s > 0 else float(f0 > limit)
    if metric is not None:
        low, high = (ranges if ranges is not None else METRIC_RANGES).get(metric, (-math.inf, math.inf))
        lo, hi = f0 - Z95 * s, f0 + Z95 * s
        out["outside_range"] = bool(lo < low or hi > high)
        if out["outside_range"]:
            out["warning"] = (f"linearised {metric!r}: mean {f0:.4g}, sd {s:.3g}, so its 95 % interval [{lo:.3g}, "
                              f"{hi:.3g}] leaves the metric's range [{low:g}, {high:g}"
                              f"{')' if math.isinf(high) else ']'}: the metric is not linear over "
                              "the inputs' spread (it bends, or jumps as contact starts or stops); use the sampled "
                              "distribution and probability")
            warnings.warn(out["warning"], UnresolvedEstimateWarning, stacklevel=2)
    return out


def linearised_against_sample(metric: str, lin: dict, sample_sd: float, runs: int) -> str | None:
    """A line where the linearised estimate ``lin`` (:func:`linearised`) of ``metric`` has a
    standard deviation more than :data:`LINEAR_SD_FACTOR` times (or less than its inverse) the
    sample's ``sample_sd`` of ``runs`` runs; ``None`` where they agree or both are 0. Sets
    ``lin["sd_ratio_to_sample"]`` and ``lin["departs_from_sample"]``."""
    sd = lin["sd"]
    if not sd > 0 and not sample_sd > 0:
        return None
    ratio = sd / sample_sd if sample_sd > 0 else math.inf
    lin["sd_ratio_to_sample"] = ratio
    lin["departs_from_sample"] = not 1.0 / LINEAR_SD_FACTOR <= ratio <= LINEAR_SD_FACTOR
    if not lin["departs_from_sample"]:
        return None
    return (f"linearised {metric!r}: sd {sd:.3g} against the sample's {sample_sd:.3g} ({runs} runs), {ratio:.2g} times "
            "it: the first-order model does not describe the metric over the inputs' spread (it bends, or jumps as "
            "contact starts or stops); use the sampled distribution and probability")


def score_gradient(inputs: Inputs, grad) -> np.ndarray:
    """The gradient over the independent scores ``z`` at ``z = 0`` from the one over the values:
    ``dx_i / dz'_i = phi(0) / pdf_i(x_i(0))`` (the copula's marginal step), times ``L``."""
    from scipy import stats

    g = np.asarray(grad, dtype=float)
    dxdz = np.array([stats.norm.pdf(0.0) / m.frozen.pdf(m.ppf(0.5)) for m in inputs.marginals])
    lower = np.linalg.cholesky(inputs.correlation) if inputs.correlation is not None else np.eye(len(g))
    return lower.T @ (dxdz * g)


def importance_exceedance(inputs: Inputs, evaluate, metric: str, limit: float, f_median: float, grad_scores,
                          n: int, seed: int = 0) -> dict:
    """``P(Y > limit)`` by importance sampling around the linearised design point (module
    docstring). ``f_median``: the metric at ``x(z = 0)`` (the marginals' medians), ``grad_scores``:
    its gradient over the scores there (:func:`score_gradient`). Returns the probability, its standard error and 95 %
    interval, the design point and the runs."""
    gz = np.asarray(grad_scores, dtype=float)
    norm = float(np.linalg.norm(gz))
    if not norm > 0:
        raise ParameterError(f"importance sampling of {metric!r}: the gradient is zero at the medians (no "
                             "direction to shift the sampling to)")
    beta = (limit - f_median) / norm
    if not beta > 0:
        raise ParameterError(f"importance sampling of {metric!r}: the limit {limit:g} is not above the metric at the "
                             f"medians ({f_median:g}), so the probability is not small (> 0.5 by the linear model): "
                             "the plain sample estimates it")
    zstar = beta * gz / norm
    z = np.random.default_rng(seed).standard_normal((n, len(gz))) + zstar
    y = np.asarray(evaluate(inputs.scores_to_values(z))[metric], dtype=float)
    w = np.exp(-z @ zstar + 0.5 * zstar @ zstar)
    ok = np.isfinite(y)
    terms = np.where(ok, (y > limit) * w, 0.0)
    p = float(terms.mean())
    se = float(terms.std(ddof=1) / math.sqrt(n))
    return {"limit": float(limit), "probability": p, "std_error": se, "ci95": [max(0.0, p - Z95 * se), p + Z95 * se],
            "design_point_scores": zstar.tolist(), "beta": float(beta), "runs": int(n),
            "exceeding": int(np.sum(y[ok] > limit)), "failed_runs": int((~ok).sum())}
