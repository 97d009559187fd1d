r"""The synthetic likelihood between the grid's nodes, with the noise level profiled out
(:func:`~jaxclear.fitting.statistics_fit.fit_statistics`; the likelihood: :mod:`.statistics`).

Why between the nodes
---------------------
A record of tens of revolutions fixes its mean statistics to a few hundredths (in log units),
finer than they change from one node of a practical grid to the next (a factor 1.4 in stiffness,
0.05 in restitution near 0.9): evaluated at the nodes alone, the likelihood is a lottery among
nodes none of which fits. So the model's moments are interpolated: at noise level :math:`s`
(below) the mean :math:`\mu` and covariance :math:`\Sigma` of every node are computed
(:func:`node_moments`), and at any point of a grid ``refine`` times finer (in the grid
coordinates :math:`u`: log stiffness, logit restitution, the transforms of
:mod:`jaxclear.params`) and any :math:`\log s`, :math:`\mu` is the tensor-product cubic spline
through the nodes (:class:`scipy.interpolate.RegularGridInterpolator`, ``method="cubic"``; linear
where a coordinate has fewer than 4 nodes or a node failed) and :math:`\Sigma` the multilinear
interpolation of the nodes' (a convex combination of positive definite matrices, so positive
definite). The nodes' Monte-Carlo error is the likelihood's :math:`1/n_m` term.

The noise level
---------------
White noise of standard deviation :math:`s` (on the sensor's input scale) is added to the
model's filtered signal, the same draws :math:`\varepsilon` at every node (common random numbers:
the statistics are then smooth in :math:`s`), at :data:`NOISE_NODES` levels geometric between
:data:`NOISE_RANGE` times the record's RMS (divided by the gain). A record of 45 revolutions
fixes :math:`s` to about 1 % (the top frequency band is mostly noise), so :math:`s` is profiled:
at every point, :math:`\hat s = \arg\max_s \log \sum_g L(u, g, s)\,\pi(g)\,\Delta g` by a
golden-section search (30 steps: the bracket shrinks to 1e-6 of itself) in :math:`\log s` between
the levels next to the best one. A profile likelihood stands in for the marginal (flat in
:math:`\log s`) up to the curvature's factor :math:`\sqrt{2\pi}\,\mathrm{sd}(\log s)`, which
varies little over the posterior.
"""

from __future__ import annotations

import numpy as np

from .statistics import block_statistics, moments, quadratic_terms, statistic_weights, synthetic_loglik

#: Noise levels of the nodes: this many between NOISE_RANGE times the record's RMS.
NOISE_NODES = 17
NOISE_RANGE = (0.005, 0.5)
#: Golden-section steps of the noise profile.
PROFILE_STEPS = 30
_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def node_moments(signals, eps, levels, fs: float, kinds) -> tuple[np.ndarray, np.ndarray]:
    """``(mu (P, L, d), cov (P, L, d, d))`` of the statistics of each node's revolutions
    ``signals`` ``(P, n_m, n_b)`` [m/s^2] plus ``level * eps`` for every noise level ``(L,)``
    (``eps`` ``(n_m, n_b)``). A row of ``signals`` that is NaN (a failed node) gives NaN moments."""
    signals, levels = np.asarray(signals, dtype=float), np.asarray(levels, dtype=float)
    d = len(statistic_weights(kinds))
    mus, covs = [], []
    for f in signals:
        if not np.all(np.isfinite(f)):
            mus.append(np.full((len(levels), d), np.nan))
            covs.append(np.full((len(levels), d, d), np.nan))
            continue
        mu, cov = moments(block_statistics(f[None] + levels[:, None, None] * eps[None], fs, kinds))
        mus.append(mu)
        covs.append(cov)
    return np.asarray(mus), np.asarray(covs)


class Surrogate:
    """The interpolated moments (module docstring). ``axes``: the node coordinates of every grid
    dimension, the last one :math:`\\log s` where the noise is profiled; ``mu`` ``(*n, d)``,
    ``cov`` ``(*n, d, d)`` on those axes."""

    def __init__(self, axes, mu, cov):
        axes = [np.asarray(a, dtype=float) for a in axes]
        method = "cubic" if all(len(a) >= 4 for a in axes) and np.all(np.isfinite(mu)) else "linear"
        self.single = [len(a) == 1 for a in axes]
        keep = [a for a, s in zip(axes, self.single) if not s]
        squeeze = tuple(i for i, s in enumerate(self.single) if s)
        mu, cov = np.squeeze(mu, axis=squeeze), np.squeeze(cov, axis=squeeze)
        self.method = method
        if keep:
            # imported here: scipy.interpolate is a sixth of `import jaxclear`'s own time (issue 41)
            from scipy.interpolate import RegularGridInterpolator

            self.mu = RegularGridInterpolator(keep, mu, method=method, bounds_error=False, fill_value=np.nan)
            self.cov = RegularGridInterpolator(keep, cov, method="linear", bounds_error=False, fill_value=np.nan)
        else:  # one node: nothing to interpolate
            self.mu = lambda x: np.broadcast_to(mu, (len(x), *mu.shape))
            self.cov = lambda x: np.broadcast_to(cov, (len(x), *cov.shape))

    def __call__(self, x):
        """``(mu (Q, d), cov (Q, d, d))`` at the points ``x`` ``(Q, dims)``."""
        x = np.asarray(x, dtype=float)[:, [not s for s in self.single]]
        return self.mu(x), self.cov(x)


def _gain_marginal(surrogate, x, observed, weights, log_gains, log_gain_w, scale):
    """At points ``x`` ``(Q, dims)``: ``(log sum_g L pi(g) dg (Q,), loglik (Q, G), chi2 (Q, G))``."""
    from scipy.special import logsumexp

    mu, cov = surrogate(x)
    ll, chi2 = synthetic_loglik(quadratic_terms(observed, mu, cov, weights), log_gains, scale)
    with np.errstate(invalid="ignore"):
        m = logsumexp(ll + log_gain_w, axis=1)
    return np.where(np.isfinite(m), m, -np.inf), ll, chi2


def evaluate(surrogate: Surrogate, u, log_levels, observed, weights, log_gains, log_gain_w, scale):
    """The likelihood at the grid points ``u`` ``(Q, k)`` with the noise profiled over
    ``log_levels`` ``(L,)`` (a single level: fixed). Returns ``(loglik (Q, G), chi2 (Q, G),
    log s (Q,))``."""
    u = np.asarray(u, dtype=float)
    q = len(u)
    at = lambda ls: np.concatenate([u, ls[:, None]], axis=1)  # noqa: E731
    f = lambda ls: _gain_marginal(surrogate, at(ls), observed, weights, log_gains, log_gain_w, scale)[0]  # noqa: E731
    log_levels = np.asarray(log_levels, dtype=float)
    if len(log_levels) > 1:
        on_nodes = np.stack([f(np.full(q, ls)) for ls in log_levels], axis=1)
        best = np.argmax(on_nodes, axis=1)
        a = log_levels[np.maximum(best - 1, 0)]
        b = log_levels[np.minimum(best + 1, len(log_levels) - 1)]
        c1, c2 = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
        f1, f2 = f(c1), f(c2)
        for _ in range(PROFILE_STEPS):
            left = f1 >= f2  # the maximum lies in [a, c2]
            a, b = np.where(left, a, c1), np.where(left, c2, b)
            new = np.where(left, b - _GOLDEN * (b - a), a + _GOLDEN * (b - a))
            fn = f(new)
            c1, c2, f1, f2 = (np.where(left, new, c2), np.where(left, c1, new),
                              np.where(left, fn, f2), np.where(left, f1, fn))
        ls = 0.5 * (a + b)
    else:
        ls = np.full(q, log_levels[0])
    _, ll, chi2 = _gain_marginal(surrogate, at(ls), observed, weights, log_gains, log_gain_w, scale)
    return ll, chi2, ls
