"""The result of a fit (:class:`FitResult`) and its JSON form (``fit.json``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import io
from ..plot import plot_fit


@dataclass
class FitResult:
    """What :func:`fit` found.

    Attributes:
        estimates, std, start: parameter name -> value (SI; std by the delta method,
            :mod:`jaxclear.fitting`), and the start of the best run.
        loss: mean square of the normalised residual over the fitted samples (see :mod:`jaxclear.fitting`).
        iterations: optimiser iterations over all stages and starts (Levenberg-Marquardt: accepted
            steps, plus the last update of a stage that finds no decreasing step).
        evaluations: solver steps, each one evaluation of the model and its Jacobian (accepted
            and rejected trial points and each stage's start).
        wall_time_s: wall time of the fit [s] (including compilation; summed over resumed runs).
        correlation: correlation matrix of the free parameters (list of lists, ``free`` order).
        noise_sigma_m_s2: residual standard deviation sigma [m/s^2]; residual_rms_m_s2: RMS.
        residual_autocorrelation: lag-1 autocorrelation of the residuals (about 0 when white).
        converged: whether the last stage stopped on a tolerance (not on ``max_iter``).
        history: one record per iteration (stage, loss, values).
        t, measured, fitted, initial: the fitted samples for the plot (times in simulation time,
            ``initial`` = the model at the start values), per window stacked; ``window_starts`` [s].
        free, fixed, settings, warnings: inputs and remarks, written to ``fit.json``.
    """

    estimates: dict
    std: dict
    loss: float
    iterations: int
    wall_time_s: float
    start: dict = field(default_factory=dict)
    correlation: list = field(default_factory=list)
    noise_sigma_m_s2: float = float("nan")
    residual_rms_m_s2: float = float("nan")
    residual_autocorrelation: float = float("nan")
    n_samples: int = 0
    n_unknowns: int = 0
    converged: bool = False
    stop_reason: str = ""
    history: list = field(default_factory=list)
    t: np.ndarray | None = None
    measured: np.ndarray | None = None
    fitted: np.ndarray | None = None
    initial: np.ndarray | None = None
    window_starts: list = field(default_factory=list)
    window_length_s: float = 0.0
    free: tuple = ()
    fixed: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    window_states: list = field(default_factory=list)
    window_losses: list = field(default_factory=list)
    evaluations: int = 0

    def to_dict(self) -> dict:
        """The content of ``fit.json``."""
        return {
            "estimates": self.estimates,
            "std": self.std,
            "loss": self.loss,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "wall_time_s": self.wall_time_s,
            "start": self.start,
            "fixed": self.fixed,
            "correlation": {"names": list(self.free), "matrix": self.correlation},
            "noise_sigma_m_s2": self.noise_sigma_m_s2,
            "residual_rms_m_s2": self.residual_rms_m_s2,
            "residual_lag1_autocorrelation": self.residual_autocorrelation,
            "n_samples": self.n_samples,
            "n_unknowns": self.n_unknowns,
            "converged": self.converged,
            "stop_reason": self.stop_reason,
            "window_starts_s": self.window_starts,
            "window_length_s": self.window_length_s,
            "window_losses": self.window_losses,
            "window_states": self.window_states,
            "settings": self.settings,
            "warnings": self.warnings,
            "loss_definition": "mean over the fitted samples of ((model - measured) / rms(measured))^2",
            "std_definition": "Gauss-Newton: sigma^2 (J^T J)^-1 in the transformed parameters, delta method back",
        }

    def write_json(self, path) -> str:
        return io.write_json(path, self.to_dict())

    def plot(self, path=None):
        """The fit plot (:func:`jaxclear.plot.plot_fit`)."""
        return plot_fit(path, self)
