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
  they need independent inputs (a correlation is an error here).
* Linearised, in the inputs' independent standard normal scores ``z``: ``Y ~ f(x(0)) + g_z . z``,
  mean ``f(x(0))``, sd ``|g_z|`` (for normal inputs ``g_z . g_z = g^T C g``, ``C`` the inputs'
  covariance, ``g`` the gradient over the values), ``P(Y > limit) ~ 1 - Phi((limit - f(x(0))) / sd)``;
  exact for a linear ``f`` of normal inputs, wrong where ``f`` bends over the inputs' spread or the metric has a kink (a
  peak that jumps from one impact to another, contact that starts or stops).
* Importance sampling (e.g. Rubinstein and Kroese, *Simulation and the Monte Carlo method*, 3rd
  ed., 2017, section 5.7): the standard normal scores ``z`` of the inputs drawn around the
  linearised design point ``z* = beta g_z / |g_z|`` (``beta = (limit - f(x(0))) / |g_z|``, ``g_z`` the
  gradient over the scores), weighted by ``phi(z) / phi(z - z*) = exp(-z.z* + |z*|^2 / 2)``;
  unbiased whatever the linearisation's error (a poor one only costs variance), with the
  standard error of the weighted indicators.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

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


def sobol_indices(problem: dict, y, seed: int = 0) -> dict:
    """name -> ``{S1, S1_conf, ST, ST_conf}`` (95 % bootstrap half-widths) of the design's values."""
    from SALib.analyze import sobol as sobol_analyze

    y = np.asarray(y, dtype=float)
    if not np.all(np.isfinite(y)):
        raise ParameterError(f"Sobol' indices: {int((~np.isfinite(y)).sum())} run(s) failed (NaN): the indices "
                             "need every run of the design")
    s = sobol_analyze.analyze(problem, y, calc_second_order=False, seed=seed)
    return {n: {k: float(s[k][i]) for k in ("S1", "S1_conf", "ST", "ST_conf")} for i, n in enumerate(problem["names"])}


def linearised(f0: float, grad_scores, limit: float | None = None) -> dict:
    """Mean, sd and (with ``limit``) exceedance probability of the first-order model in the
    inputs' independent standard normal scores ``z`` (module docstring): ``Y ~ f0 + g_z . z``,
    so ``sd = |g_z|``; ``f0`` the metric at ``z = 0`` (the marginals' medians), ``grad_scores``
    ``(P,)`` its gradient over ``z`` (:func:`score_gradient` from one over the values). For normal
    inputs ``|g_z|^2 = g^T C g`` with ``C`` the covariance."""
    g = np.asarray(grad_scores, dtype=float)
    s = float(np.linalg.norm(g))
    out = {"mean": float(f0), "sd": s, "gradient_scores": g.tolist()}
    if limit is not None:
        out["probability"] = float(stats.norm.sf((limit - f0) / s)) if s > 0 else float(f0 > limit)
    return out


def score_gradient(inputs: Inputs, grad) -> np.ndarray:
    """The gradient over the independent scores ``z`` at ``z = 0`` from the one over the values:
    ``dx_i / dz'_i = phi(0) / pdf_i(x_i(0))`` (the copula's marginal step), times ``L``."""
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
