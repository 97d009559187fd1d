r"""Uncertainty of the estimates at the optimum (all windows, all samples).

With the residual in physical units ``e = s_a r`` [m/s^2] (``N`` fitted samples) and its
Jacobian ``J_e = s_a J`` over the ``P`` unknowns (parameters and window states):

* noise variance ``sigma^2 = |e|^2 / (N - P)``;
* ``Cov(z) = sigma^2 (J_e^T J_e)^{-1}`` (Gauss-Newton approximation of the Fisher information
  for white Gaussian noise; e.g. Seber and Wild, *Nonlinear Regression*, 1989, section 2.1);
* ``std(theta_i) = |d theta_i / d z_i| std(z_i)`` (delta method).

This is honest only if the residual is white noise: the lag-1 autocorrelation of the residuals
is reported (about 0 for white noise, near 1 when the model cannot reproduce the data, e.g. a
different contact law) and a warning is given above :data:`AUTOCORRELATION_WARNING`.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from .parameters import dvalue_dz, transform, values_of

#: Lag-1 autocorrelation of the residuals above which the fit warns that the std are too small.
AUTOCORRELATION_WARNING = 0.3
#: ``|logit|`` beyond which a restitution-like parameter is reported at the edge of its range.
LOGIT_EDGE = 9.0


class Uncertainty(NamedTuple):
    """``estimates``/``std`` (name -> SI value), ``correlation`` ``(P, P)`` of the parameters,
    ``sigma`` [m/s^2], ``rms`` of the fitted residual [m/s^2], ``autocorrelation`` (lag 1),
    ``n_samples``, ``n_unknowns`` and the warnings."""

    estimates: dict
    std: dict
    correlation: list
    sigma: float
    rms: float
    autocorrelation: float
    n_samples: int
    n_unknowns: int
    warnings: list


def lag1_autocorrelation(res: np.ndarray) -> float:
    """Lag-1 autocorrelation of ``res`` ``(n,)``; NaN for fewer than 4 samples or a constant."""
    if res.size > 3 and np.std(res) > 0:
        return float(np.corrcoef(res[:-1], res[1:])[0, 1])
    return float("nan")


def estimate_uncertainty(r: np.ndarray, jac: np.ndarray, mask: np.ndarray, scale: float, theta: np.ndarray,
                         free: Sequence[str], mech=None) -> Uncertainty:
    """:class:`Uncertainty` from the normalised residual ``r`` ``(N_pad,)`` (0 where ``mask`` is
    0), its Jacobian ``(N_pad, P_all)`` (the first ``P = len(free)`` columns the parameters) and
    the data RMS ``scale`` [m/s^2] (module docstring); ``mech``: the fitted mechanism, whose own
    classes' names are known through it (:func:`~jaxclear.fitting.parameters.transform`)."""
    p = len(free)
    n_fit = int(mask.sum())
    n_unknown = jac.shape[1]
    res = r * scale
    sigma2 = float(res @ res) / max(n_fit - n_unknown, 1)
    jm = jac * scale
    warn = []
    try:
        cov = sigma2 * np.linalg.inv(jm.T @ jm)
    except np.linalg.LinAlgError:
        cov = np.full((n_unknown, n_unknown), np.nan)
        warn.append("J^T J is singular at the optimum: a free parameter is not identifiable from this record")
    std_z = np.sqrt(np.maximum(np.diag(cov)[:p], 0.0))
    estimates = dict(zip(free, values_of(free, theta, scale, mech)))
    std = {n: abs(dvalue_dz(n, theta[i], scale, mech)) * float(std_z[i]) for i, n in enumerate(free)}
    d = np.sqrt(np.maximum(np.diag(cov)[:p], 1e-300))
    corr = (cov[:p, :p] / np.outer(d, d)).tolist()
    res_fit = res[mask > 0]
    auto = lag1_autocorrelation(res_fit)
    if math.isfinite(auto) and auto > AUTOCORRELATION_WARNING:
        warn.append(
            f"the residuals are not white (lag-1 autocorrelation {auto:.2f} > {AUTOCORRELATION_WARNING}): the model "
            "does not reproduce the data to the noise level (another contact law, a wrong known parameter or a "
            "wrong sensor model?), so the std understate the true error"
        )
    for i, n in enumerate(free):
        if transform(n, mech) == "logit" and abs(float(theta[i])) > LOGIT_EDGE:
            warn.append(f"{n} = {estimates[n]:.6g} ran to the edge of its range: the model reaches no interior optimum "
                        "(wrong contact law or known parameter?)")
    return Uncertainty(estimates, std, corr, math.sqrt(sigma2), float(np.sqrt(np.mean(res_fit**2))), auto, n_fit,
                       n_unknown, warn)
