r"""Statistics of an acceleration record per crank revolution, and their synthetic likelihood
(:func:`~jaxclear.fitting.statistics_fit.fit_statistics`; theory: docs/theory/statistics_fit.md).

Revolutions
-----------
A record sampled every :math:`\Delta t` [s] is cut into blocks of one crank revolution,
:math:`T = 2\pi/|\omega|` [s]: block :math:`k` holds the :math:`n_b = \lfloor T/\Delta t\rfloor`
samples from index :math:`\mathrm{round}(k\,T/\Delta t)` on (:func:`revolution_blocks`). The model's
blocks begin at the same crank angle as the record's (the statistics below are not invariant
under a shift of the block boundaries: measured, a model blocked from crank angle 0 against a
record blocked from 37 degrees differed in two band powers by 2-4 standard errors, and by less
than 1.5 once aligned).

The statistic vector of one revolution
--------------------------------------
Of the block :math:`y_1 \dots y_{n_b}` [m/s^2] with its mean removed (:math:`x = y - \bar y`: a
sensor's bias and the slow drift drop out; over a revolution the slider's true acceleration
averages to its velocity change over :math:`T`, about zero):

* ``peaks``: :math:`\log Q_p(|x|)` [log m/s^2] for :math:`p \in` :data:`PEAK_LEVELS` (0.5, 0.9,
  0.99, 1): the median, the upper quantiles and the largest absolute acceleration of the
  revolution (the impact peaks; :func:`numpy.quantile`, linear interpolation);
* ``spectrum``: :math:`\log \sum_{f_i \in B_j} P(f_i)` [log (m/s^2)^2/Hz] over the frequency bands
  :math:`B_j` of :func:`band_edges`, :math:`P` Welch's power spectral density of the block
  (P. Welch, IEEE Trans. Audio Electroacoust. 15 (1967) 70-73; :func:`scipy.signal.welch`: Hann
  window, segments of :math:`n_b / 6` samples overlapping by half, a linear trend removed per
  segment, the conventions of :func:`jaxclear.chaos.psd`). The first band is
  :math:`[0, 2 f_r)` with :math:`f_r` the segments' resolution, the others
  :data:`SPECTRUM_BANDS` geometric bands up to the Nyquist frequency (at 50 kHz and 5000 rpm:
  0-1 kHz, then 1, 1.5, 2.2, 3.3, 5, 7.5, 11, 17, 25 kHz): the crank's harmonics, the journal's
  ringing in continuous contact (about 1.5 kHz on the Flores benchmark), the impacts' broad band
  whose high end the contact stiffness sets, and the noise floor.

Every statistic is the logarithm of a function homogeneous in the signal, of degree
:math:`w = 1` (peaks) or 2 (band powers), so a sensor gain :math:`g` shifts it by exactly
:math:`w \log g` (:func:`statistic_weights`): a gain is fitted without new simulations.

The synthetic likelihood
------------------------
(S. N. Wood, "Statistical inference for noisy nonlinear ecological dynamic systems", Nature 466
(2010) 1102-1104.) The model at parameters :math:`\theta` gives the statistics of
:math:`n_m` revolutions; their mean :math:`\mu(\theta)` and covariance :math:`\hat\Sigma(\theta)`
(divisor :math:`n_m - 1`). The record's statistic :math:`s` is the mean over its :math:`n_r`
revolutions, taken to be normal about :math:`\mu` with covariance
:math:`C = \Sigma\,(1/n_r + 1/n_m)` (the revolutions as independent draws: the e-folding time
:math:`1/\lambda_1` of the benchmark is a fifth of a revolution; the model's own Monte-Carlo
error is the :math:`1/n_m`). With :math:`r = s - \mu - w \log g`,

.. math::
    \log L(\theta, g) = -\tfrac12\, c\, r^\mathsf{T} \hat\Sigma^{-1} r / (1/n_r + 1/n_m)
                        - \tfrac12 \log\det\hat\Sigma + \text{const},
    \qquad c = \frac{n_m - d - 2}{n_m - 1},

where :math:`c` makes :math:`c\hat\Sigma^{-1}` an unbiased estimate of :math:`\Sigma^{-1}` for
normal statistics (:math:`d` statistics; the expectation of the inverse Wishart matrix,
e.g. Anderson, *An Introduction to Multivariate Statistical Analysis*, 3rd ed., 2003, sec. 7.2),
without which :math:`n_m = 60` revolutions and :math:`d = 13` statistics would make the
posterior 1.3 times too narrow. The constant (it depends on :math:`n_m`, :math:`d` only) is left out.
"""

from __future__ import annotations

import math

import numpy as np

from .._errors import ParameterError

#: Kinds of statistics (``fit_statistics(statistics=...)``).
STATISTICS = ("peaks", "spectrum")
#: Quantile levels of |acceleration| per revolution (``peaks``); 1 is the revolution's maximum.
PEAK_LEVELS = (0.5, 0.9, 0.99, 1.0)
#: Welch segments of a revolution: a segment is ``n_b // SEGMENTS_PER_REVOLUTION`` samples.
SEGMENTS_PER_REVOLUTION = 6
#: Geometric frequency bands above the first (``spectrum``).
SPECTRUM_BANDS = 8
#: A revolution needs at least this many samples for a spectrum of its segments.
MIN_BLOCK_SAMPLES = 12 * SEGMENTS_PER_REVOLUTION


def check_kinds(kinds) -> tuple:
    """``kinds`` as a tuple of names of :data:`STATISTICS`; a ParameterError names a bad one."""
    kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    bad = [k for k in kinds if k not in STATISTICS]
    if bad or not kinds or len(set(kinds)) != len(kinds):
        raise ParameterError(f"statistics = {list(kinds)!r}: allowed a non-empty selection without repeats "
                             f"of {list(STATISTICS)}")
    return kinds


def block_starts(count: int, samples_per_revolution: float) -> np.ndarray:
    """First index of each of ``count`` revolution blocks: ``round(k T / dt)``, ``(count,)``."""
    return np.rint(np.arange(count) * samples_per_revolution).astype(np.int64)


def whole_revolutions(n_samples: int, samples_per_revolution: float) -> int:
    """How many whole revolution blocks ``n_samples`` samples hold."""
    nb = int(math.floor(samples_per_revolution))
    count = int(math.floor(n_samples / samples_per_revolution)) + 1
    while count > 0 and block_starts(count, samples_per_revolution)[-1] + nb > n_samples:
        count -= 1
    return count


def revolution_blocks(y, samples_per_revolution: float, count: int | None = None) -> np.ndarray:
    """The samples ``y`` ``(..., N)`` cut into revolution blocks ``(..., count, n_b)`` (module
    docstring), ``count`` default every whole revolution."""
    y = np.asarray(y, dtype=float)
    nb = int(math.floor(samples_per_revolution))
    if count is None:
        count = whole_revolutions(y.shape[-1], samples_per_revolution)
    index = block_starts(count, samples_per_revolution)[:, None] + np.arange(nb)[None, :]
    return y[..., index]


def segment_length(nb: int) -> int:
    """Samples per Welch segment of a block of ``nb`` samples."""
    return max(8, nb // SEGMENTS_PER_REVOLUTION)


def band_edges(fs: float, nb: int) -> np.ndarray:
    """Edges [Hz] of the ``spectrum`` bands for a block of ``nb`` samples at ``fs`` [Hz]:
    ``0``, then :data:`SPECTRUM_BANDS` + 1 geometric edges from twice the segments' resolution
    to the Nyquist frequency ``fs / 2`` (``(SPECTRUM_BANDS + 2,)``)."""
    first = 2.0 * fs / segment_length(nb)
    return np.concatenate([[0.0], np.geomspace(first, fs / 2.0, SPECTRUM_BANDS + 1)])


def statistic_names(kinds, fs: float, nb: int) -> list[str]:
    """Names of the statistics in vector order, e.g. ``log_q0.99_abs_acc``,
    ``log_power_1000_1495_hz``."""
    names = []
    for kind in check_kinds(kinds):
        if kind == "peaks":
            names += [f"log_q{p:g}_abs_acc" if p < 1 else "log_max_abs_acc" for p in PEAK_LEVELS]
        else:
            e = band_edges(fs, nb)
            names += [f"log_power_{lo:.0f}_{hi:.0f}_hz" for lo, hi in zip(e[:-1], e[1:])]
    return names


def statistic_weights(kinds) -> np.ndarray:
    """Degree ``w`` of each statistic (1: peaks, 2: band powers): a gain ``g`` adds ``w log g``."""
    w = []
    for kind in check_kinds(kinds):
        w += [1.0] * len(PEAK_LEVELS) if kind == "peaks" else [2.0] * (SPECTRUM_BANDS + 1)
    return np.asarray(w)


def block_statistics(blocks, fs: float, kinds) -> np.ndarray:
    """The statistic vector of every revolution block: ``blocks`` ``(..., n, n_b)`` [m/s^2] ->
    ``(..., n, d)`` (module docstring). A block that is constant gives ``-inf`` (a log of 0)."""
    from scipy.signal import welch

    x = np.asarray(blocks, dtype=float)
    nb = x.shape[-1]
    if nb < MIN_BLOCK_SAMPLES:
        raise ParameterError(f"a revolution of the record holds {nb} samples, outside the allowed range "
                             f"[{MIN_BLOCK_SAMPLES}, inf) for per-revolution statistics: a higher sample rate")
    x = x - x.mean(axis=-1, keepdims=True)
    out = []
    with np.errstate(divide="ignore"):
        for kind in check_kinds(kinds):
            if kind == "peaks":
                q = np.quantile(np.abs(x), PEAK_LEVELS, axis=-1)  # (levels, ..., n)
                out.append(np.log(np.moveaxis(q, 0, -1)))
            else:
                nper = segment_length(nb)
                f, p = welch(x, fs=fs, nperseg=nper, noverlap=nper // 2, detrend="linear", axis=-1)
                e = band_edges(fs, nb)
                inside = [(f >= lo) & ((f < hi) if k < len(e) - 2 else (f <= hi))
                          for k, (lo, hi) in enumerate(zip(e[:-1], e[1:]))]
                out.append(np.log(np.stack([p[..., m].sum(axis=-1) for m in inside], axis=-1)))
    return np.concatenate(out, axis=-1)


def precision_factor(n_model: int, d: int) -> float:
    """``c = (n_m - d - 2) / (n_m - 1)`` (module docstring); needs ``n_m > d + 2``."""
    return (n_model - d - 2) / (n_model - 1)


def moments(stats) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``(..., d)`` and covariance ``(..., d, d)`` (divisor ``n - 1``) of per-revolution
    statistics ``(..., n, d)``."""
    s = np.asarray(stats, dtype=float)
    mu = s.mean(axis=-2)
    x = s - mu[..., None, :]
    return mu, np.einsum("...ni,...nj->...ij", x, x) / (s.shape[-2] - 1)


def quadratic_terms(observed, mu, cov, weights):
    """The pieces of the misfit ``r^T Sigma^-1 r`` with ``r = s - mu - w t`` as a function of
    ``t = log g``: ``r^T Sigma^-1 r = a0 - 2 t a1 + t^2 a2``. ``observed`` ``(d,)``, ``mu``
    ``(..., d)``, ``cov`` ``(..., d, d)``, ``weights`` ``(d,)``. Returns ``(a0, a1, a2, logdet)``,
    each ``(...)``; ``a0 = inf`` where the moments are not finite or the covariance is not
    positive definite."""
    mu, cov = np.asarray(mu, dtype=float), np.asarray(cov, dtype=float)
    shape, d = mu.shape[:-1], mu.shape[-1]
    mu, cov = mu.reshape(-1, d), cov.reshape(-1, d, d)
    r0 = np.asarray(observed, dtype=float)[None, :] - mu
    ok = np.all(np.isfinite(mu), axis=1) & np.all(np.isfinite(cov), axis=(1, 2))
    safe = np.where(ok[:, None, None], cov, np.eye(d))
    sign, logdet = np.linalg.slogdet(safe)
    ok &= sign > 0
    rhs = np.stack([np.where(ok[:, None], r0, 0.0), np.broadcast_to(weights, r0.shape)], axis=-1)
    sol = np.linalg.solve(np.where(ok[:, None, None], safe, np.eye(d)), rhs)
    a0 = np.einsum("ni,ni->n", np.where(ok[:, None], r0, 0.0), sol[..., 0])
    a1 = np.einsum("ni,ni->n", np.where(ok[:, None], r0, 0.0), sol[..., 1])
    a2 = np.einsum("i,ni->n", np.asarray(weights, dtype=float), sol[..., 1])
    a0, logdet = np.where(ok, a0, np.inf), np.where(ok, logdet, np.inf)
    return tuple(x.reshape(shape) for x in (a0, a1, a2, logdet))


def synthetic_loglik(terms, log_gains, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Synthetic log-likelihood (module docstring) at every ``t = log g`` of ``log_gains``
    ``(G,)`` from :func:`quadratic_terms` ``terms`` (each ``(...)``), ``scale = c / (1/n_r + 1/n_m)``.
    Returns ``(loglik (..., G), chi2 (..., G))``: ``chi2`` the Mahalanobis distance ``r^T C^-1 r``
    (about chi-squared with ``d`` degrees of freedom at the truth); ``-inf`` / ``inf`` where
    :func:`quadratic_terms` found no positive definite covariance."""
    a0, a1, a2, logdet = (np.asarray(x, dtype=float)[..., None] for x in terms)
    t = np.asarray(log_gains, dtype=float)
    with np.errstate(invalid="ignore"):
        chi2 = scale * (a0 - 2.0 * t * a1 + t * t * a2)
        chi2 = np.where(np.isfinite(a0), chi2, np.inf)
    return np.where(np.isfinite(chi2), -0.5 * chi2 - 0.5 * logdet, -np.inf), chi2
