r"""Distributions of named parameters for a tolerance study, their sampling and their TOML form.

A study's inputs are independent marginals (normal, uniform, truncated normal) of parameters
that :mod:`jaxclear.params` names, optionally tied by a correlation matrix through a Gaussian
copula (Nataf's transformation; e.g. Lebrun and Dutfoy, *An innovating analysis of the Nataf
transformation from the copula viewpoint*, Prob. Eng. Mech. 24, 2009): a point ``u`` of the unit
cube becomes standard normal scores ``z = Phi^-1(u)``, correlated ``z' = L z`` (``L L^T`` the
correlation matrix of the scores), and each parameter ``x_i = F_i^-1(Phi(z'_i))``.

Points of the unit cube: scrambled Sobol' (``method="sobol"``, the default; SciPy's
:class:`scipy.stats.qmc.Sobol`, Owen scrambling; the count rounded up to a power of 2, which
keeps the sequence balanced) or plain pseudo-random numbers (``method="mc"``).

TOML form (a file's ``[parameters]`` table; the command ``jaxclear tolerance``)::

    [parameters]
    clearance = {distribution = "normal", mean = 0.5e-3, sd = 0.05e-3, low = 0.0}   # truncated
    "length:crank" = {distribution = "uniform", low = 0.0499, high = 0.0501}
    "mass:slider" = {distribution = "normal", mean = 0.14, sd = 0.0028}

    [correlations]          # optional: pairs of the scores' correlation
    pairs = [["clearance", "mass:slider", 0.3]]

A normal with ``low`` and/or ``high`` is the truncated normal on that interval.

:mod:`scipy.stats` is imported where it is used, not with this module: it was a fifth of the time
``import jaxclear`` spends outside JAX and diffrax (issue 41).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._errors import ParameterError

#: Keys of a parameter's table, per distribution.
DIST_KEYS = {"normal": ("mean", "sd", "low", "high"), "uniform": ("low", "high")}
#: Smallest probability mass of a truncation interval (below it the distribution is called empty).
MIN_MASS = 1e-12
#: Unit-cube points are kept this far from 0 and 1 (an inverse normal CDF there is infinite).
U_EPS = 1e-12


@dataclass(frozen=True)
class Marginal:
    """One parameter's distribution: ``kind`` ``"normal"`` (``a`` mean, ``b`` sd, optional
    truncation ``low``/``high``) or ``"uniform"`` (``low``, ``high``)."""

    name: str
    kind: str
    a: float = 0.0
    b: float = 1.0
    low: float = -math.inf
    high: float = math.inf

    @property
    def frozen(self):
        """The :mod:`scipy.stats` distribution."""
        from scipy import stats  # where used (module docstring)
        if self.kind == "uniform":
            return stats.uniform(self.low, self.high - self.low)
        if math.isinf(self.low) and math.isinf(self.high):
            return stats.norm(self.a, self.b)
        return stats.truncnorm((self.low - self.a) / self.b, (self.high - self.a) / self.b, self.a, self.b)

    def ppf(self, u: np.ndarray) -> np.ndarray:
        return self.frozen.ppf(u)

    @property
    def mean(self) -> float:
        return float(self.frozen.mean())

    @property
    def sd(self) -> float:
        return float(self.frozen.std())

    def describe(self) -> str:
        if self.kind == "uniform":
            return f"uniform({self.low:g}, {self.high:g})"
        trunc = "" if math.isinf(self.low) and math.isinf(self.high) else f" on [{self.low:g}, {self.high:g}]"
        return f"normal(mean={self.a:g}, sd={self.b:g}){trunc}"


def marginal(name: str, spec: dict, where: str = "parameters") -> Marginal:
    """A :class:`Marginal` from its table (module docstring); an improper or empty distribution
    (sd <= 0, low >= high, a truncation with no mass, a number that is not finite) is a
    :class:`~jaxclear.ParameterError` naming the parameter."""
    w = f"{where}.{name}"
    if not isinstance(spec, dict):
        raise ParameterError(f"{w}: expected a table {{distribution = \"normal\", mean = ..., sd = ...}}, got {spec!r}")
    kind = spec.get("distribution")
    if kind not in DIST_KEYS:
        raise ParameterError(f"{w}.distribution = {kind!r}: allowed: {', '.join(DIST_KEYS)}")
    bad = sorted(set(spec) - {"distribution", *DIST_KEYS[kind]})
    if bad:
        raise ParameterError(f"{w}: unknown key(s) {bad} for a {kind} distribution; allowed: {list(DIST_KEYS[kind])}")
    nums = {}
    for k in DIST_KEYS[kind]:
        if k in spec:
            v = spec[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ParameterError(f"{w}.{k} = {v!r}: expected a finite number")
            nums[k] = float(v)
    if kind == "uniform":
        if "low" not in nums or "high" not in nums:
            raise ParameterError(f"{w}: a uniform distribution needs low and high")
        if not nums["low"] < nums["high"]:
            raise ParameterError(f"{w}: uniform(low={nums['low']:g}, high={nums['high']:g}) is empty: low must be < high")
        return Marginal(name, "uniform", low=nums["low"], high=nums["high"])
    if "mean" not in nums or "sd" not in nums:
        raise ParameterError(f"{w}: a normal distribution needs mean and sd")
    if not nums["sd"] > 0:
        raise ParameterError(f"{w}: sd = {nums['sd']:g} must be > 0 (an improper distribution otherwise)")
    m = Marginal(name, "normal", nums["mean"], nums["sd"], nums.get("low", -math.inf), nums.get("high", math.inf))
    if not m.low < m.high:
        raise ParameterError(f"{w}: the truncation [{m.low:g}, {m.high:g}] is empty: low must be < high")
    from scipy import stats

    mass = stats.norm.cdf((m.high - m.a) / m.b) - stats.norm.cdf((m.low - m.a) / m.b)
    if not mass > MIN_MASS:
        raise ParameterError(f"{w}: the truncation [{m.low:g}, {m.high:g}] holds no probability of "
                             f"normal(mean={m.a:g}, sd={m.b:g}) (mass {mass:.2g}): an empty distribution")
    return m


def correlation_matrix(names: list, pairs, where: str = "correlations") -> np.ndarray | None:
    """The scores' correlation matrix from ``[[a, b, rho], ...]`` (None when no pair); an unknown
    name, ``|rho| >= 1`` or a matrix that is not positive definite is a named error."""
    if not pairs:
        return None
    c = np.eye(len(names))
    for item in pairs:
        if not (isinstance(item, (list, tuple)) and len(item) == 3):
            raise ParameterError(f"{where}.pairs: expected [name, name, rho], got {item!r}")
        a, b, rho = item
        for n in (a, b):
            if n not in names:
                raise ParameterError(f"{where}.pairs: {n!r} is not a parameter of the study ({names})")
        if a == b or isinstance(rho, bool) or not isinstance(rho, (int, float)) or not abs(rho) < 1:
            raise ParameterError(f"{where}.pairs: [{a!r}, {b!r}, {rho!r}]: two different names and -1 < rho < 1")
        i, j = names.index(a), names.index(b)
        c[i, j] = c[j, i] = float(rho)
    try:
        np.linalg.cholesky(c)
    except np.linalg.LinAlgError:
        raise ParameterError(f"{where}: the correlation matrix is not positive definite (inconsistent pairs)") from None
    return c


@dataclass(frozen=True)
class Inputs:
    """The study's inputs: marginals (in order) and the scores' correlation (None: independent)."""

    marginals: tuple
    correlation: np.ndarray | None = None

    @property
    def names(self) -> list:
        return [m.name for m in self.marginals]

    def unit_points(self, n: int, method: str = "sobol", seed: int = 0) -> np.ndarray:
        """``(n', P)`` points of the unit cube; Sobol' rounds ``n`` up to a power of 2."""
        d = len(self.marginals)
        if method == "sobol":
            from scipy.stats import qmc

            return qmc.Sobol(d, scramble=True, seed=seed).random_base2(max(0, math.ceil(math.log2(max(n, 1)))))
        if method == "mc":
            return np.random.default_rng(seed).random((n, d))
        raise ParameterError(f"method = {method!r}: allowed: 'sobol' (quasi-Monte Carlo), 'mc' (plain Monte Carlo)")

    def scores_to_values(self, z: np.ndarray) -> np.ndarray:
        """Independent standard normal scores ``(n, P)`` -> parameter values (the copula)."""
        from scipy import stats

        if self.correlation is not None:
            z = z @ np.linalg.cholesky(self.correlation).T
        return self.from_unit(stats.norm.cdf(z), correlated=False)

    def from_unit(self, u: np.ndarray, correlated: bool = True) -> np.ndarray:
        """Unit-cube points ``(n, P)`` -> parameter values (through the copula if ``correlated``)."""
        u = np.clip(np.asarray(u, dtype=float), U_EPS, 1.0 - U_EPS)
        if correlated and self.correlation is not None:
            from scipy import stats

            return self.scores_to_values(stats.norm.ppf(u))
        return np.column_stack([m.ppf(u[:, i]) for i, m in enumerate(self.marginals)])

    def sample(self, n: int, method: str = "sobol", seed: int = 0) -> np.ndarray:
        """``(n', P)`` parameter values (module docstring)."""
        return self.from_unit(self.unit_points(n, method, seed))


def inputs_from_dict(doc: dict, where: str = "<dict>") -> Inputs:
    """:class:`Inputs` from ``{"parameters": {...}, "correlations": {"pairs": [...]}}``."""
    table = doc.get("parameters")
    if not isinstance(table, dict) or not table:
        raise ParameterError(f"{where}: a [parameters] table with at least one distribution is required")
    margs = tuple(marginal(n, s, f"{where}: parameters") for n, s in table.items())
    corr = doc.get("correlations", {})
    if not isinstance(corr, dict) or set(corr) - {"pairs"}:
        raise ParameterError(f"{where}: [correlations] takes one key, pairs = [[name, name, rho], ...]")
    return Inputs(margs, correlation_matrix([m.name for m in margs], corr.get("pairs"), f"{where}: correlations"))
