r"""Tests for chaos on a time series of any named channel: its power spectral density (Welch),
the 0-1 test of Gottwald and Melbourne, and Rosenstein's estimate of the largest Lyapunov
exponent (the time-series method of the literature, to compare with the exponent from the
tangents, :func:`~jaxclear.chaos.lyapunov`).

All take NumPy arrays (after a run) and return NumPy values; :func:`channel_series` reads a
channel of a :class:`~jaxclear.Solution` with its unit and sample step.
"""

from __future__ import annotations

import importlib
import math

import numpy as np

from .._errors import MissingExtraError, ParameterError
from .._extras import extra_message, require_extra
from ..analysis.channels import channel_with_unit
from ..analysis.sections import check_channels
from ..integrate import Solution
from ..model import Mechanism

#: The c values of the 0-1 test are drawn from (pi/5, 4 pi/5), away from the resonances at 0 and
#: pi (Gottwald and Melbourne 2009, sec. 3).
C_RANGE = (math.pi / 5, 4 * math.pi / 5)
#: Fewest samples the 0-1 test runs on (its ``n_cut = N/10`` lags need a series this long).
ZERO_ONE_MIN_SAMPLES = 100


def channel_series(mech: Mechanism, sol: Solution, name: str, start: float | None = None):
    """``(values (T,), dt [s], unit)`` of channel ``name`` on the run's uniform output grid, from
    time ``start`` [s] on (default all); a :class:`~jaxclear.ParameterError` for a channel that
    does not exist or a grid too short."""
    check_channels(mech, name)
    ts = np.asarray(sol.ts, dtype=float)
    values, unit = channel_with_unit(mech, sol, name)
    values = np.asarray(values, dtype=float)
    if start is not None:
        keep = ts >= start - 1e-12 * max(abs(start), 1.0)
        ts, values = ts[keep], values[keep]
    if ts.size < 16:
        raise ParameterError(f"channel {name!r}: {ts.size} samples after start = {start}, outside the allowed range "
                             "[16, inf): a longer run or more output samples")
    return values, float((ts[-1] - ts[0]) / (ts.size - 1)), unit


def psd(values, dt: float, nperseg: int | None = None):
    r"""Power spectral density of the samples ``values`` (T,) taken every ``dt`` [s]: Welch's
    averaged periodogram (P. Welch, IEEE Trans. Audio Electroacoust. 15 (1967) 70-73;
    :func:`scipy.signal.welch`, Hann window, half-overlapping segments of ``nperseg`` samples,
    default an eighth of the series, a linear trend removed per segment). Returns
    ``(frequencies [Hz], density [unit^2/Hz])``; a periodic motion shows lines at the forcing
    frequency, its harmonics and (period-n) its subharmonics f/n, a chaotic one a broad band."""
    from scipy.signal import welch

    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or x.size < 16 or not np.all(np.isfinite(x)):
        raise ParameterError(f"psd: expected at least 16 finite samples, got {x.shape} (finite: "
                             f"{bool(np.all(np.isfinite(x)))})")
    dt = float(dt)  # a 0-d array too (jc.crank_period): NumPy frequencies
    if not (math.isfinite(dt) and dt > 0):
        raise ParameterError(f"psd: sample step dt = {dt!r} s is outside the allowed range (0, inf)")
    nperseg = max(16, x.size // 8) if nperseg is None else int(nperseg)
    if not 2 <= nperseg <= x.size:
        raise ParameterError(f"psd: nperseg = {nperseg} is outside the allowed range [2, {x.size}]")
    return welch(x, fs=1.0 / dt, nperseg=nperseg, detrend="linear")


def zero_one_test(values, c=None, n_c: int = 100, n_cut: int | None = None, seed: int = 0):
    r"""The 0-1 test for chaos (G.A. Gottwald and I. Melbourne, Proc. R. Soc. A 460 (2004)
    603-611; "On the implementation of the 0-1 test for chaos", SIAM J. Appl. Dyn. Syst. 8 (2009)
    129-145), correlation method.

    For an observable :math:`\phi(j)`, :math:`j = 1..N`, and a frequency :math:`c`, the
    translation variables :math:`p_c(n) = \sum_{j\le n}\phi(j)\cos jc`,
    :math:`q_c(n) = \sum_{j\le n}\phi(j)\sin jc` are bounded for a regular motion and behave
    like a Brownian motion for a chaotic one. Their mean square displacement
    :math:`M_c(n) = \frac{1}{N - n_{cut}}\sum_{j=1}^{N - n_{cut}} [p_c(j+n) - p_c(j)]^2 +
    [q_c(j+n) - q_c(j)]^2`, less its oscillating part :math:`V_{osc} = \bar\phi^2 (1 - \cos
    nc)/(1 - \cos c)`, is :math:`D_c(n)`; :math:`K_c` is the correlation coefficient of
    :math:`D_c(n)` with :math:`n`, :math:`n = 1..n_{cut}` (:math:`n_{cut} = N/10`), and
    :math:`K` the median over ``n_c`` values of :math:`c` drawn uniformly from
    :data:`C_RANGE` (or the given ``c``). :math:`K \approx 0`: regular; :math:`K \approx 1`:
    chaotic. The samples should not oversample the motion (the authors' advice: about one
    sample per forcing period or per mean oscillation). Not on the Poincare section of a
    period-1 orbit: that is a constant plus the integration's noise, whose random walk the test
    reads as chaos (:mod:`.report` thins the samples to 2 a revolution instead: the forcing's harmonics then
    alias to 0 and pi, outside the range of c).

    Written here because no maintained Python library implements it; the formulas are those of
    the 2009 paper, eqs. (2.1)-(2.5) and (3.1)-(3.2).

    Returns ``(K, K_c (n_c,), c (n_c,))``.
    """
    phi = np.asarray(values, dtype=float)
    if phi.ndim != 1 or phi.size < ZERO_ONE_MIN_SAMPLES or not np.all(np.isfinite(phi)):
        raise ParameterError(f"zero_one_test: expected at least {ZERO_ONE_MIN_SAMPLES} finite samples, got {phi.shape}")
    n = phi.size
    n_cut = n // 10 if n_cut is None else int(n_cut)
    if not 2 <= n_cut <= n // 2:
        raise ParameterError(f"zero_one_test: n_cut = {n_cut} is outside the allowed range [2, {n // 2}]")
    if c is None:
        c = np.random.default_rng(seed).uniform(*C_RANGE, n_c)
    c = np.atleast_1d(np.asarray(c, dtype=float))
    j = np.arange(1, n + 1)
    lags = np.arange(1, n_cut + 1)
    mean = phi.mean()
    k = np.empty(c.size)
    for i, ci in enumerate(c):
        p = np.cumsum(phi * np.cos(j * ci))
        q = np.cumsum(phi * np.sin(j * ci))
        m = np.array([np.mean((p[lag:n - n_cut + lag] - p[:n - n_cut]) ** 2
                              + (q[lag:n - n_cut + lag] - q[:n - n_cut]) ** 2) for lag in lags])
        d = m - mean**2 * (1 - np.cos(lags * ci)) / (1 - np.cos(ci))
        k[i] = np.corrcoef(lags, d)[0, 1] if np.std(d) > 0 else 0.0
    return float(np.median(k)), k, c


def _nolds():
    """nolds (the ``chaos`` extra; :func:`rosenstein` checks that it is there before any work),
    imported on first use: :class:`~jaxclear.MissingExtraError` where it cannot be imported
    (nolds 0.6.3 under Python < 3.12, CSchoel/nolds#80, which the extra's pins avoid)."""
    try:
        return importlib.import_module("nolds")
    except Exception as err:
        raise MissingExtraError(extra_message("chaos", "rosenstein", ["nolds"], f"it fails on import: {err}")) from None


def rosenstein(values, dt: float, emb_dim: int = 6, lag: int | None = None, min_tsep: int | None = None,
               trajectory_len: int = 20, fit_offset: int = 0) -> float:
    r"""The largest Lyapunov exponent [1/s] of a time series by Rosenstein's method
    (M.T. Rosenstein, J.J. Collins, C.J. De Luca, "A practical method for calculating largest
    Lyapunov exponents from small data sets", Physica D 65 (1993) 117-134), as implemented by
    ``nolds.lyap_r`` (least-squares line fit): delay-embed the series (``emb_dim``, ``lag``
    samples; default: where the autocorrelation falls below :math:`1 - 1/e`), pair every point
    with its nearest neighbour at least ``min_tsep`` samples away in time (default: the mean
    period), and fit the slope of the mean logarithmic divergence over ``trajectory_len``
    samples.

    Known bias: the slope is fitted on a finite range of a curve that is linear only between the
    noise floor and saturation at the attractor's size, so the estimate depends on
    ``trajectory_len`` and ``fit_offset``, tends to fall short of the true value (the curve
    bends over towards saturation within the fit range), and degrades with short series,
    noise and too small an embedding; Rosenstein et al. report errors within about 10 % on
    the Lorenz, Rossler and Henon systems with 1000-5000 points, more with fewer points or
    noise. It estimates the largest exponent only.
    """
    require_extra("chaos", "rosenstein")  # before any work
    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or x.size < 10 * emb_dim or not np.all(np.isfinite(x)):
        raise ParameterError(f"rosenstein: expected at least {10 * emb_dim} finite samples, got {x.shape}")
    if not (math.isfinite(dt) and dt > 0):
        raise ParameterError(f"rosenstein: sample step dt = {dt!r} s is outside the allowed range (0, inf)")
    return float(_nolds().lyap_r(x, emb_dim=emb_dim, lag=lag, min_tsep=min_tsep, tau=dt,
                                 trajectory_len=trajectory_len, fit="poly", fit_offset=fit_offset))
