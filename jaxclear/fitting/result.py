"""The result of a fit (:class:`FitResult`, an :class:`~jaxclear.AbstractResult`) and its files
(``fit.json``, ``fit.png``)."""

from __future__ import annotations

import math
import os
from dataclasses import InitVar, dataclass, field

import numpy as np

from .._results import AbstractResult, deprecated
from .._storage import atomic_write_json, jsonable
from ..model import Mechanism
from ..plot import plot_fit, plot_profiles
from .verdict import assess, fallback_mechanism


@dataclass
class FitResult(AbstractResult):
    """What :func:`fit` found (:meth:`to_dict`, :meth:`write`, :meth:`summary`, :meth:`plot`:
    the protocol of every driver's result, :class:`~jaxclear.AbstractResult`).

    Attributes:
        estimates, std, start: parameter name -> value (SI; std by the delta method,
            :mod:`jaxclear.fitting`, or from the profile likelihood for the names in
            ``profiles``), and the start of the best run.
        profiles: name -> its profile likelihood (``fit(profile=...)``;
            :func:`jaxclear.fitting.profile.summarize`: ``values``, ``deviance``, the 90 %
            ``interval``, ``std``, ``std_gauss_newton``, ``better``, ``open``); ``{}`` without.
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
        t, measured, fitted, initial: the fitted samples of the first fitted column for the plot
            (times in simulation time, ``initial`` = the model at the start values), per window
            stacked; ``window_starts`` [s].
        series: every fitted column -> ``{"measured", "fitted", "initial"}`` (same samples as ``t``).
        window_losses, window_samples, window_onsets: per window its normalised misfit, its
            fitted samples (the verdict's window rule reads both) and the contact onsets of the
            fitted motion inside it, counted by the contacts' memories (None: not known; an
            entry None: the window's run failed there). With every window's start free only
            these onsets' approach speeds are set by the motion: the impacts that hold the
            restitution.
        free, fixed, settings, warnings: inputs and remarks, written to ``fit.json``;
            ``settings["phase_s"]``: the seconds of this call's phases, ``plan`` (the stages,
            compilation included), ``scan`` and ``profile`` where they ran (a resumed fit: since
            the resume; the automatic refit: the refit's own).
        failures: why the estimates are not a result (one sentence each: the parameter, its
            value, the rule broken and what to try; :func:`jaxclear.fitting.verdict.assess`),
            ``()`` for a fit that passed; computed when the result is made unless given.
        ok: True when ``failures`` is empty (a property).

    ``mech`` (init only): the fitted mechanism, whose joint geometry and laws give the physical
    range of a fitted stiffness; without it the preset named ``settings["mechanism"]``, rebuilt
    with the reported law and clearance, stands in (:func:`~jaxclear.fitting.verdict.fallback_mechanism`),
    and a mechanism that is no preset's gets no stiffness-range check.
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
    window_samples: list = field(default_factory=list)
    window_onsets: list | None = None
    evaluations: int = 0
    series: dict = field(default_factory=dict)
    profiles: dict = field(default_factory=dict)
    failures: tuple | None = None
    mech: InitVar[Mechanism | None] = None

    def __post_init__(self, mech: Mechanism | None):
        """Assess the estimates once (:func:`~jaxclear.fitting.verdict.assess`) unless
        ``failures`` was given."""
        if self.failures is None:
            if mech is None:
                mech = fallback_mechanism(self.settings, self.fixed)
            self.failures = assess(self.free, self.estimates, self.std, start=self.start, mech=mech,
                                   history=self.history, scale=float(self.settings.get("data_rms_m_s2", 1.0)),
                                   autocorrelation=self.residual_autocorrelation, loss=self.loss,
                                   stop_reason=self.stop_reason,
                                   free_start=self.settings.get("start_state") == "free", profiles=self.profiles,
                                   noise=(self.noise_sigma_m_s2, self.settings.get("noise_sigma_given_m_s2"),
                                          self.n_samples - self.n_unknowns),
                                   windows=self._window_noise())
        self.failures = tuple(self.failures)

    def _window_noise(self) -> tuple | None:
        """Per window its residual std [record units] and degrees of freedom (its fitted samples
        times the record's ``(N - P) / N``; the std over those, as the record's own
        ``noise_sigma_m_s2``), for the verdict's window rule; None without them."""
        if not self.window_samples or len(self.window_samples) != len(self.window_losses) or not self.n_samples:
            return None
        scale = float(self.settings.get("data_rms_m_s2", 1.0))
        share = max(self.n_samples - self.n_unknowns, 1) / self.n_samples
        return ([math.sqrt(max(loss, 0.0) / share) * scale for loss in self.window_losses],
                [n * share for n in self.window_samples])

    @property
    def ok(self) -> bool:
        """Whether the estimates passed every check (no ``failures``)."""
        return not self.failures

    def format_failures(self) -> str:
        """``FAILED: ...`` with one ``  - reason`` line per failure; '' for a fit that passed."""
        if self.ok:
            return ""
        lines = [f"FAILED: the fit's estimates are not a result ({len(self.failures)} reason"
                 f"{'s' if len(self.failures) > 1 else ''}; fit.json has \"ok\": false):"]
        return "\n".join(lines + [f"  - {reason}" for reason in self.failures])

    def summary(self) -> str:
        """The outcome as text: a failed fit's reasons first, then the loss, the estimates with
        their start values and std [SI], the profiles, the contact onsets per window (several
        windows) and the warnings."""
        lines = [self.format_failures()] if not self.ok else []
        lines.append(f"{'FAILED' if not self.ok else 'ok'}: {self.iterations} iterations ({self.stop_reason or '-'}); "
                     f"loss {self.loss:.4g}, residual lag-1 autocorrelation {self.residual_autocorrelation:.2f}")
        width = max([len(n) for n in self.estimates] + [len("parameter")])
        lines.append(f"  {'parameter':<{width}}  {'start':>12}  {'estimate':>12}  {'std':>10}")
        for name, value in self.estimates.items():
            lines.append(f"  {name:<{width}}  {self.start.get(name, float('nan')):>12.6g}  {value:>12.6g}  "
                         f"{self.std.get(name, float('nan')):>10.3g}")
        lines += self.profile_lines()
        if self.window_onsets is not None and len(self.window_onsets) > 1:
            lines.append(f"  contact onsets of the fitted motion per window: "
                         f"{', '.join('-' if n is None else str(int(n)) for n in self.window_onsets)} "
                         f"({int(sum(n for n in self.window_onsets if n is not None))} in all)")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def profile_lines(self) -> list[str]:
        """One line per profiled parameter: its 90 % interval ("open" on a side the record does
        not bound), the Gauss-Newton std beside it and the points walked; and one for a scan of
        held values (:mod:`jaxclear.fitting.scan`)."""
        lines = []
        for name, p in self.profiles.items():
            lo, hi = (f"{v:.6g}" if v is not None else "open" for v in p["interval"])
            lines.append(f"  profile likelihood of {name}: 90 % interval [{lo}, {hi}] (Gauss-Newton std "
                         f"{p['std_gauss_newton']:.3g}; {len(p['values']) - 1} points)")
        scan = self.settings.get("scan")
        if scan:
            held = ", ".join(f"{v:.6g} (misfit {m:.5g}, deviance {d:+.3g})"
                             for v, m, d in zip(scan["values"], scan["loss"], scan["deviance"]))
            lines.append(f"  scan of {scan['name']} held (starts searched anew): {held}; "
                         + (f"the result is the refit from {scan['refit_from']:.6g} (the fit before it: misfit "
                            f"{scan['estimate_loss']:.5g})" if scan["taken"] else "the fit before the scan stands"))
        return lines

    def to_dict(self) -> dict:
        """The content of ``fit.json`` (JSON-ready: NaN as None): ``ok`` and ``failures`` first,
        then the estimates."""
        return jsonable({
            "ok": self.ok,
            "failures": list(self.failures),
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
            "window_samples": self.window_samples,
            "window_onsets": self.window_onsets,
            "window_states": self.window_states,
            "profiles": self.profiles,
            "settings": self.settings,
            "warnings": self.warnings,
            "loss_definition": "mean over the fitted samples of ((model - measured) / rms(measured))^2",
            "std_definition": ("Gauss-Newton: sigma^2 (J^T J)^-1 in the transformed parameters, delta method back; "
                               "for the names in profiles, the longer half of the profile likelihood's 90 % interval "
                               "over 1.645"),
        })

    def to_dataframe(self):
        """The estimates as a :class:`pandas.DataFrame`: one row per free parameter (index
        ``parameter``) with columns ``estimate``, ``std``, ``start`` (SI units) and the
        correlation with every free parameter; ``df.attrs`` holds the loss, iterations,
        evaluations, noise and residual statistics."""
        import pandas as pd  # deferred like the sweep's labelled results: pandas loads on use

        names = list(self.free)
        rows = {
            "estimate": [self.estimates.get(n, np.nan) for n in names],
            "std": [self.std.get(n, np.nan) for n in names],
            "start": [self.start.get(n, np.nan) for n in names],
        }
        corr = np.asarray(self.correlation, dtype=float) if len(self.correlation) else np.full((len(names),) * 2, np.nan)
        for j, n in enumerate(names):
            rows[f"corr_{n}"] = list(corr[:, j])
        df = pd.DataFrame(rows, index=pd.Index(names, name="parameter"))
        df.attrs.update(loss=self.loss, iterations=self.iterations, evaluations=self.evaluations,
                        noise_sigma_m_s2=self.noise_sigma_m_s2, residual_rms_m_s2=self.residual_rms_m_s2,
                        residual_lag1_autocorrelation=self.residual_autocorrelation, converged=self.converged,
                        ok=self.ok, failures=list(self.failures))
        return df

    def signals_frame(self):
        """The fitted samples as a :class:`pandas.DataFrame` with columns ``time_s``
        (simulation time), ``measured``, ``fitted`` and ``initial`` [m/s^2] (empty when the fit
        kept no samples)."""
        import pandas as pd

        cols = {"time_s": self.t, "measured": self.measured, "fitted": self.fitted, "initial": self.initial}
        return pd.DataFrame({k: np.ravel(v) for k, v in cols.items() if v is not None})

    def write(self, folder, *, plots: bool = True) -> list[str]:
        """``fit.json`` (:meth:`to_dict`, keys in their order) and, with ``plots``, ``fit.png``
        (:meth:`plot`) and, with profiles, ``profiles.png`` (:meth:`plot_profiles`) in
        ``folder``; returns their paths."""
        folder = os.fspath(folder)
        os.makedirs(folder, exist_ok=True)
        paths = [atomic_write_json(os.path.join(folder, "fit.json"), self.to_dict(), sort_keys=False)]
        if plots:
            paths.append(self.plot(os.path.join(folder, "fit.png")))
            if self.profiles:
                paths.append(self.plot_profiles(os.path.join(folder, "profiles.png")))
        return paths

    def write_json(self, path) -> str:
        """Deprecated: :meth:`write` (``fit.json`` in a folder). Writes :meth:`to_dict` to ``path``."""
        deprecated("FitResult.write_json(path)", "FitResult.write(folder), which writes fit.json (and fit.png)")
        return atomic_write_json(path, self.to_dict(), sort_keys=False)

    def plot_profiles(self, path=None):
        """The profile likelihoods (:func:`jaxclear.plot.plot_profiles`; ``fit(profile=...)``):
        the figure, or ``path`` once saved there."""
        if not self.profiles:
            raise ValueError("this fit has no profile likelihood: fit(..., profile=True) (--profile all)")
        fig = plot_profiles(path, self)
        return fig if path is None else os.fspath(path)

    def plot(self, path=None):
        """The fit plot (:func:`jaxclear.plot.plot_fit`): the figure, or ``path`` once saved there
        (a :class:`matplotlib.figure.Figure` outside pyplot: nothing to close)."""
        fig = plot_fit(path, self)
        return fig if path is None else os.fspath(path)
