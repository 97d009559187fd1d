r"""The log posterior density the sampler explores (:mod:`jaxclear.fitting.posterior`).

The likelihood is the fit's own residual model (:meth:`~jaxclear.fitting.WindowModel.residual`,
every fitted channel through its sensor model, window 0 from the known start, all its samples):
with ``r`` the normalised residual (``sqrt(w_j) (y_j - d_j) / s_j`` at the ``n`` fitted
samples, :mod:`.window`), the noise is white Gaussian with one standard deviation
:math:`\sigma_r` in those units (channel ``j``: :math:`\sigma_j = \sigma_r s_j / \sqrt{w_j}`,
the fit's weighting read as a noise model), so

:math:`\log L(z, \sigma_r) = -n \log \sigma_r - |r(z)|^2 / (2 \sigma_r^2) - (n/2) \log 2\pi`.

The noise level is reported in the units of the first fitted column,
:math:`\sigma = \sigma_r s_0 / \sqrt{w_0}` [m/s^2 for the slider acceleration]. The sampled
position is ``x = (z_1 .. z_P, log sigma_r)`` (``z``: the fit's unconstrained coordinates), and
the log posterior adds the priors of the values with the change of variables
(:mod:`.priors`). A run that fails (status not 0) or a value that is not finite has log density
``-inf`` (the sampler rejects it and counts a divergence).

Whitening: the sampler works in ``u`` with ``x = x_0 + L u``, ``x_0`` the least-squares optimum
and ``L L^T`` the Gauss-Newton covariance (:func:`gauss_newton_covariance`), i.e. the
Gauss-Newton covariance is the sampler's (inverse) mass matrix and the scale of its first step.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .parameters import from_z
from .window import WindowInput, WindowModel

_LOG_2PI = math.log(2.0 * math.pi)


class LogPosterior(eqx.Module):
    """``log p(x | data)`` up to a constant, in the whitened coordinate ``u`` (module docstring).

    Fields: the window model and input, the start state of window 0 (unconstrained), the
    priors of the free parameters (``free`` order) and of the noise, ``x0`` ``(D,)``, ``chol``
    ``(D, D)`` the whitening, ``noise_log`` the fixed ``log sigma_r`` (used when
    ``fixed_noise``), ``n`` the fitted residual entries, ``sigma_unit`` ``s_0 / sqrt(w_0)``."""

    model: WindowModel
    win: WindowInput
    state0: jax.Array
    priors: tuple
    noise_prior: eqx.Module
    x0: jax.Array
    chol: jax.Array
    noise_log: jax.Array
    n: jax.Array
    sigma_unit: jax.Array
    fixed_noise: bool = eqx.field(static=True)

    @property
    def n_free(self) -> int:
        return len(self.model.free)

    def position(self, u):
        """``x = x0 + L u``."""
        return self.x0 + self.chol @ u

    def log_sigma_r(self, x):
        return self.noise_log if self.fixed_noise else x[self.n_free]

    def log_prior(self, x):
        """Sum of the priors' log densities of the values, with ``log |d value / d z|``."""
        lp = jnp.asarray(0.0)
        scale = self.model.bias_scale
        for i, (name, prior) in enumerate(zip(self.model.free, self.priors)):
            value = from_z(name, x[i], scale, self.model.mech)
            dv = jax.grad(lambda zz, name=name: from_z(name, zz, scale, self.model.mech))(x[i])
            lp = lp + prior.logpdf(value) + jnp.log(jnp.abs(dv))
        if not self.fixed_noise:
            sigma = self.sigma_unit * jnp.exp(x[self.n_free])
            lp = lp + self.noise_prior.logpdf(sigma) + jnp.log(sigma)
        return lp

    def log_likelihood(self, x):
        """``log L`` (module docstring) and the run's status."""
        r, (_, extra) = self.model.residual(x[: self.n_free], self.state0, self.win)
        s = self.log_sigma_r(x)
        ll = -self.n * s - 0.5 * jnp.sum(r**2) * jnp.exp(-2.0 * s) - 0.5 * self.n * _LOG_2PI
        return ll, extra[3]

    def log_density_x(self, x):
        ll, status = self.log_likelihood(x)
        lp = ll + self.log_prior(x)
        return jnp.where((status == 0) & jnp.isfinite(lp), lp, -jnp.inf)

    def __call__(self, u):
        """The log density in ``u`` (the Jacobian of ``x = x0 + L u`` is a constant, left out)."""
        return self.log_density_x(self.position(u))


def fitted_entries(win: WindowInput, weights) -> float:
    """Residual entries that carry data: the fitted samples of every channel of non-zero weight."""
    return float(np.sum(np.asarray(win.mask))) * int(np.count_nonzero(np.asarray(weights) > 0))


def gauss_newton_covariance(r: np.ndarray, jac: np.ndarray, n: float, fixed_noise_r: float | None):
    r"""Covariance of ``x`` at the optimum, ``(D, D)``: ``sigma_r^2 (J^T J)^{-1}`` for the
    parameters (``r``, ``jac``: the normalised residual and its Jacobian over ``z``) and, unless
    the noise is fixed, ``1 / (2 n)`` for ``log sigma_r`` (the Fisher information of a log
    standard deviation from ``n`` Gaussian samples); ``sigma_r`` is ``|r| / sqrt(n - P)``, or
    the fixed value. Returns ``(cov, sigma_r)``; ``cov`` is ``None`` when ``J^T J`` is singular."""
    p = jac.shape[1]
    sigma_r = fixed_noise_r if fixed_noise_r is not None else math.sqrt(float(r @ r) / max(n - p, 1.0))
    jtj = jac.T @ jac
    try:
        cov_z = sigma_r**2 * np.linalg.inv(jtj)
        np.linalg.cholesky(cov_z)
    except np.linalg.LinAlgError:
        return None, sigma_r
    if fixed_noise_r is not None:
        return cov_z, sigma_r
    cov = np.zeros((p + 1, p + 1))
    cov[:p, :p] = cov_z
    cov[p, p] = 1.0 / (2.0 * n)
    return cov, sigma_r
