"""Deprecated: the hand-written NumPy Levenberg-Marquardt as an optax transformation
(``jaxclear.levenberg_marquardt``), kept only so that existing code keeps working. The fit uses
:class:`optimistix.LevenbergMarquardt` (:mod:`jaxclear.fitting.solver`)."""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax


class LMState(NamedTuple):
    """State of :func:`levenberg_marquardt`: the damping ``mu`` and the factor ``nu`` by which it
    grows after a rejected step (Nielsen)."""

    damping: jax.Array
    nu: jax.Array


class LevenbergMarquardt(optax.GradientTransformationExtraArgs):
    """The optax transformation returned by :func:`levenberg_marquardt` (a marker subclass;
    deprecated). :func:`jaxclear.fitting.make_optimizer` reads it as the fit's optimistix
    Levenberg-Marquardt."""

    _jaxclear_legacy_lm = True


def levenberg_marquardt(damping: float = 1e-3, max_tries: int = 12, max_damping: float = 1e10,
                        extrapolate: int = 3, max_step: float = 1.5) -> LevenbergMarquardt:
    r"""Levenberg-Marquardt as an optax transformation. **Deprecated**: the fit now runs
    :class:`optimistix.LevenbergMarquardt` (its default, ``optimizer=None`` or
    ``"levenberg-marquardt"``); for a least-squares problem of your own use
    ``optimistix.least_squares(fn, optimistix.LevenbergMarquardt(rtol, atol), y0)``.

    Kept with its exact meaning for existing code (calling it warns with a DeprecationWarning):
    this is still the NumPy Levenberg-Marquardt that calls ``value_fn`` from Python. Passed as
    ``jaxclear.fit(..., optimizer=levenberg_marquardt())`` it selects the fit's optimistix
    Levenberg-Marquardt (its own damping settings are then not used).

    ``update(grad, state, params, *, jacobian, residual, value_fn)`` returns the step
    :math:`-(J^TJ + \mu\,\mathrm{diag}(J^TJ))^{-1} J^T r` for the smallest damping ``mu`` (tried
    from the state's, growing by ``nu``, ``nu`` doubling) whose trial point lowers
    ``value_fn(params + step)`` (``0.5 |r|^2``); the damping then shrinks by Nielsen's factor
    ``max(1/3, 1 - (2 rho - 1)^3)`` (``rho``: actual over predicted decrease). An accepted step is
    then doubled up to ``extrapolate`` times while the value keeps decreasing: in the curved
    valleys of impact-timing misfits the Gauss-Newton step is much shorter than the way to the
    minimum (on the benchmark this halves the iterations from a 3x stiffness error). No step
    (extended or not) exceeds ``max_step`` in any coordinate (a trust region in the transformed
    parameters: 1.5 is a factor 4.5 in a log parameter), so a parameter the data do not yet
    constrain cannot run off. If no step within
    ``max_tries`` (or below ``max_damping``) decreases the value, the update is zero and the
    damping is left above ``max_damping``, which the fit reads as convergence/stall.
    The step is computed in NumPy and ``value_fn`` is called from Python: do not ``jit`` it.
    """

    warnings.warn(
        "jaxclear.levenberg_marquardt is deprecated: jaxclear.fit uses optimistix.LevenbergMarquardt by default "
        "(optimizer=None); for your own least-squares problems use optimistix.least_squares with "
        "optimistix.LevenbergMarquardt",
        DeprecationWarning,
        stacklevel=2,
    )

    def init(params_):
        return LMState(jnp.asarray(damping, dtype=float), jnp.asarray(2.0))

    def update(updates, state, params_=None, *, jacobian=None, residual=None, value_fn=None, **_):
        if jacobian is None or residual is None or value_fn is None or params_ is None:
            raise ValueError("levenberg_marquardt needs params and the extra arguments jacobian, residual, value_fn")
        J = np.asarray(jacobian, dtype=float)
        r = np.asarray(residual, dtype=float)
        z = np.asarray(params_, dtype=float)
        jtj = J.T @ J
        g = J.T @ r
        value0 = 0.5 * float(r @ r)
        diag = np.maximum(np.diag(jtj), 1e-12 * max(float(np.max(np.diag(jtj))), 1e-300))
        mu, nu = float(state.damping), float(state.nu)
        for _ in range(max_tries):
            if mu > max_damping:
                break
            try:
                step = -np.linalg.solve(jtj + mu * np.diag(diag), g)
            except np.linalg.LinAlgError:
                mu, nu = mu * nu, 2.0 * nu
                continue
            if not np.all(np.isfinite(step)):
                mu, nu = mu * nu, 2.0 * nu
                continue
            largest = float(np.max(np.abs(step))) if step.size else 0.0
            if largest > max_step:
                step = step * (max_step / largest)
            value = float(value_fn(jnp.asarray(z + step)))
            predicted = -(g @ step + 0.5 * step @ jtj @ step)
            if math.isfinite(value) and value < value0 and predicted > 0:
                rho = (value0 - value) / predicted
                mu = mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                # along a curved valley the Gauss-Newton step is short: extend it while that helps
                best = step
                for _ in range(extrapolate):
                    trial = 2.0 * best
                    if float(np.max(np.abs(trial))) > max_step:
                        break
                    v = float(value_fn(jnp.asarray(z + trial)))
                    if not (math.isfinite(v) and v < value):
                        break
                    best, value = trial, v
                if best is not step:
                    value_fn(jnp.asarray(z + best))  # leave the accepted point last (evaluation cache)
                return jnp.asarray(best), LMState(jnp.asarray(max(mu, 1e-12)), jnp.asarray(2.0))
            mu, nu = mu * nu, 2.0 * nu
        return jnp.zeros_like(jnp.asarray(z)), LMState(jnp.asarray(max(mu, 2 * max_damping)), jnp.asarray(nu))

    opt = LevenbergMarquardt(init, update)
    return opt
