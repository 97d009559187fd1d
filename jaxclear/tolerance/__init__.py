r"""Tolerance analysis: how parts that scatter from piece to piece (clearance, link lengths,
masses) spread a mechanism's behaviour, and how likely a metric is to exceed a limit.

Modules: :mod:`.distributions` (the inputs' distributions, their TOML form, Sobol'/Monte Carlo
points, correlations by a Gaussian copula), :mod:`.estimators` (exceedance probabilities with
confidence intervals, Sobol' indices through SALib, the linearised estimate, importance
sampling), :mod:`.study` (:func:`tolerance_study`: the runs on the sweep's machinery, chunked,
resumable, on every device). Theory: docs/theory/uncertainty.md.
"""

from .distributions import Inputs, Marginal, correlation_matrix, inputs_from_dict, marginal
from .estimators import (
    LINEAR_SD_FACTOR,
    METRIC_RANGES,
    SOBOL_NEGLIGIBLE,
    UnresolvedEstimateWarning,
    check_limit,
    exceedance,
    importance_exceedance,
    index_verdict,
    linearised,
    linearised_against_sample,
    score_gradient,
    sobol_design,
    sobol_indices,
    sobol_warning,
    wilson_interval,
)
from .study import DEFAULT_METRICS, ToleranceResult, tolerance_study

__all__ = ["tolerance_study", "ToleranceResult", "DEFAULT_METRICS", "Inputs", "Marginal", "marginal", "inputs_from_dict", "correlation_matrix", "METRIC_RANGES",
           "check_limit", "exceedance", "wilson_interval", "sobol_design", "sobol_indices", "linearised", "score_gradient",
           "importance_exceedance", "index_verdict", "sobol_warning", "SOBOL_NEGLIGIBLE",
           "UnresolvedEstimateWarning", "linearised_against_sample", "LINEAR_SD_FACTOR"]
