"""One status family and one result protocol for every driver (issue 40, item 5).

Statuses: every run status is a member of ``jaxclear.RESULTS`` (a Lyapunov run's overflow
too), ``jaxclear.STATUS`` gives every message, one ``raise_for_status`` raises them, and the
old spellings still work with a DeprecationWarning.
"""

from __future__ import annotations

import importlib
import types
import warnings

import numpy as np
import pytest

import jaxclear as jc
from jaxclear.chaos import LyapunovError
from jaxclear.integrate._simulate import raise_for_status


# ---- the one status family ----------------------------------------------------------------


def test_results_is_the_one_status_family():
    """The codes a file may hold keep their meaning (members are only appended); the chaos
    overflow is a member; STATUS maps every member's code to its message."""
    names = list(jc.RESULTS._name_to_item)
    assert names[:12] == ["successful", "max_steps_reached", "nonfinite_state", "solver_failed", "assembly_failed",
                          "invalid_restitution", "invalid_stiffness", "invalid_clearance", "invalid_friction",
                          "invalid_mass", "invalid_parameter", "penetration_too_deep"]
    code = int(jc.RESULTS.tangent_overflow._value)
    assert code == 12 and jc.STATUS[code].startswith("the tangents overflowed within the shortest")
    assert sorted(jc.STATUS) == list(range(len(names)))


class _Result:
    """Any result with a status and a renormalisation interval (the one raise_for_status reads
    only ``status``)."""

    def __init__(self, status):
        self.status = np.asarray(status)
        self.interval = np.asarray(1.0)


def test_one_raise_for_status_for_every_result():
    s = jc.Settings(t_end=1.0, max_steps=77)
    raise_for_status(_Result(0), s)  # ok: nothing
    with pytest.raises(jc.SolverError, match=r"max_steps.*now 77"):
        raise_for_status(_Result(int(jc.RESULTS.max_steps_reached._value)), s)
    with pytest.raises(LyapunovError, match=r"tangents overflowed.*\(lyapunov\)"):
        raise_for_status(_Result(int(jc.RESULTS.tangent_overflow._value)), s, " (lyapunov)", error=LyapunovError)
    with pytest.raises(jc.ParameterError, match=r"restitution"):
        raise_for_status(_Result(int(jc.RESULTS.invalid_restitution._value)), s, error=LyapunovError)


def test_old_status_spellings_warn_and_still_work():
    with pytest.warns(DeprecationWarning, match=r"jaxclear.chaos.STATUS is deprecated"):
        old = jc.chaos.STATUS
    assert old is jc.STATUS
    from jaxclear.chaos import benettin

    with pytest.warns(DeprecationWarning, match=r"benettin.STATUS is deprecated"):
        assert benettin.STATUS is jc.STATUS
    lyapunov_module = importlib.import_module("jaxclear.chaos.lyapunov")  # the package's name is the function

    with pytest.warns(DeprecationWarning, match=r"raise_for_status is deprecated"):
        old_raise = lyapunov_module.raise_for_status
    with pytest.raises(LyapunovError, match=r"tangents overflowed"):
        old_raise(_Result(int(jc.RESULTS.tangent_overflow._value)), jc.Settings(t_end=1.0))
    import jaxclear.designing as designing

    with pytest.warns(DeprecationWarning, match=r"STATUSES is deprecated"):
        assert designing.STATUSES == designing.OUTCOMES == ("converged", "max_iter", "infeasible", "stopped")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "STATUS" not in jc.chaos.__all__ and "STATUSES" not in designing.__all__


# ---- one result protocol ------------------------------------------------------------------
#
# Tiny hand-made results (no simulation): each is an AbstractResult whose to_dict() is strict
# JSON, whose write(folder) writes the files it names (strict JSON among them) and returns their
# paths, whose summary() is text and whose plot() is a figure or the path it saved.


def _fit_result():
    from jaxclear import FitResult

    t = np.linspace(0.0, 0.01, 50)
    return FitResult(estimates={"stiffness": 1e10}, std={"stiffness": float("nan")}, loss=0.01, iterations=3,
                     wall_time_s=1.0, start={"stiffness": 2e10}, free=("stiffness",), t=t, measured=np.sin(t),
                     fitted=np.sin(t) + 1e-3, initial=np.sin(t) + 1e-2, noise_sigma_m_s2=1e-3, failures=())


def _posterior_result():
    from jaxclear.fitting.posterior_result import PosteriorResult, _summaries

    a = np.random.default_rng(0).standard_normal((2, 50))
    stats = {"lp": -a ** 2, "diverging": np.zeros_like(a), "acceptance_rate": np.full_like(a, 0.8),
             "n_steps": np.full_like(a, 3.0), "tree_depth": np.full_like(a, 2.0)}
    return PosteriorResult(free=("stiffness",), samples={"stiffness": a}, stats=stats, statistics=_summaries(
        {"stiffness": a}), divergences=0, warmup_divergences=0, converged=True, warnings=[], priors={}, settings={})


def _design_result():
    from jaxclear import DesignResult

    return DesignResult(status="converged", message="ok", design={"mass:slider": 0.2}, start={"mass:slider": 0.3},
                        objective={"name": "rms", "description": "RMS deviation", "unit": "m/s^2", "start": 2.0,
                                   "optimum": 1.0, "improvement": 0.5},
                        constraints=[], gradient={"mass:slider": float("nan")}, gradient_norm=1e-6, sensitivity={},
                        iterations=2, evaluations={"values": 3, "gradients": 3, "replayed": 0}, runs=6,
                        gradient_cost=1.5, wall_time_s=1.0,
                        history=[{"iteration": 0, "objective": 2.0, "violation": 0.0, "gradient_norm": 1.0,
                                  "design": {"mass:slider": 0.3}, "evaluations": 1, "gradients": 1, "runs": 2,
                                  "wall_s": 0.5}], chaos=None, settings={})


def _tolerance_result():
    from jaxclear import ToleranceResult

    x = np.random.default_rng(1).normal(size=(20, 1))
    y = {"peak_contact_force_n": 1e4 * (1 + 0.1 * x[:, 0])}
    stats = {m: {"mean": float(v.mean()), "sd": float(v.std()), "q05": float(np.quantile(v, 0.05)),
                 "q50": float(np.median(v)), "q95": float(np.quantile(v, 0.95)), "failed_runs": 0}
             for m, v in y.items()}
    return ToleranceResult(["clearance"], x, y, stats, linearised={"peak_contact_force_n": {
        "mean": 1e4, "sd": 1e3, "outside_range": False}}, exceedance={"peak_contact_force_n": {
            "limit": 1.1e4, "probability": 0.15, "ci95": [0.05, 0.36]}}, warnings=["an example warning"])


def _chaos_report():
    import jax.numpy as jnp

    from jaxclear.chaos import ChannelReport, ChaosReport, LyapunovResult

    k = 6
    running = np.stack([np.linspace(5.0, 4.0, k), np.linspace(-1.0, -3.0, k)], axis=1)
    lyap = LyapunovResult(exponents=jnp.asarray(running[-1]), running=jnp.asarray(running),
                          times=jnp.linspace(0.1, 0.6, k), log_growth=jnp.zeros((k, 2)), interval=jnp.asarray(0.1),
                          spread=jnp.asarray([0.5, 1.0]), stderr=jnp.asarray([0.1, float("nan")]),
                          status=jnp.asarray(0), run_status=jnp.asarray(0), t_end=jnp.asarray(0.6),
                          ts=jnp.zeros((0,)), packed=jnp.zeros((0, 4)), renormalisations=jnp.ones(k),
                          num_steps=jnp.asarray(100))
    f = np.linspace(0.0, 100.0, 20)
    channel = ChannelReport("body:slider:x:vel", "m/s", np.sin(np.arange(10.0)), 0, float("nan"), "too few samples",
                            4, f, 1.0 + f)
    return ChaosReport("test", lyap, [channel])


def _sweep_result(tmp_path):
    from jaxclear import SweepResult

    xs, ys = np.array([1e-4, 2e-4]), np.array([0.5, 0.9])
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    n = X.size
    table = {"run": np.arange(n), "clearance": X.ravel(), "restitution": Y.ravel(),
             "peak_contact_force_n": np.array([1e4, np.nan, 2e4, 3e4]), "status": np.array([0, 1, 0, 0]),
             "status_message": np.array(["", jc.STATUS[1], "", ""], dtype=object)}
    poincare = np.random.default_rng(2).normal(scale=1e-5, size=(n, 3, 1, 4))
    return SweepResult(str(tmp_path), table, ("clearance", "restitution"), poincare,
                       {"clearance": xs, "restitution": ys}, "grid", manifest={"n_runs": n})


def _statistics_fit_result():
    from jaxclear import StatisticsFitResult

    grid = {"stiffness": np.geomspace(1e10, 1e11, 9)}
    marg = np.array([0.0, 0.1, 0.3, 0.4, 0.2, 0, 0, 0, 0])
    return StatisticsFitResult(
        free=("stiffness",), estimates={"stiffness": 2.5e10}, map={"stiffness": 2.4e10}, std={"stiffness": 5e9},
        intervals={"stiffness": (1.5e10, 3.6e10)}, grid=grid, nodes=grid, posterior=marg,
        log_likelihood=np.full(9, -np.inf), marginals={"stiffness": marg}, noise={"estimate": 1.0, "profiled": False},
        noise_profile=np.zeros(9), statistics=["a"] * 3, observed=np.zeros(3), model_mean=np.zeros(3), chi2=2.0,
        record_revolutions=3, model_revolutions=40)


def _wear_history():
    from jaxclear import WearHistory
    from jaxclear.wearing import node_angles

    angles = node_angles(36)
    depth = np.stack([1e-7 * (1 + np.cos(angles)), 2.5e-7 * (1 + np.cos(angles))])
    return WearHistory(jc.preset("flores-slider-crank"), angles, depth, volume=np.array([1e-12, 1.5e-12]),
                       service_time=np.array([0.5, 1.0]), peak_force=np.array([2e3, 1.9e3]),
                       max_penetration=np.array([2e-6, 1.9e-6]), cycles_per_update=1e3, clearance=1e-4)


RESULTS = {"fit": (_fit_result, {"fit.json", "fit.png"}),
           "statistics fit": (_statistics_fit_result, {"statistics_fit.json", "statistics_fit.png"}),
           "posterior": (_posterior_result, {"posterior.nc", "posterior.json", "posterior_summary.csv",
                                             "posterior_pair.png"}),
           "design": (_design_result, {"design_history.csv", "design.json"}),
           "tolerance": (_tolerance_result, {"tolerance.json", "tolerance_runs.csv", "tolerance.png"}),
           "chaos": (_chaos_report, {"exponents.csv", "running.csv", "channels.csv", "summary.json", "running.png",
                                     "spectrum.png", "poincare.png"}),
           "sweep": (_sweep_result, {"results.nc", "heatmap_peak_contact_force_n.png", "poincare.png"}),
           "wear": (_wear_history, {"wear.json", "updates.csv", "profile_0000.csv", "profile_0001.csv",
                                    "profile.png"})}


@pytest.mark.parametrize("kind", sorted(RESULTS))
def test_every_result_has_the_four_methods(kind, tmp_path):
    from conftest import assert_strict_json, strict_json

    from jaxclear._storage import json_text

    make, files = RESULTS[kind]
    res = make(tmp_path / "own") if kind == "sweep" else make()
    assert isinstance(res, jc.AbstractResult)
    d = res.to_dict()
    assert isinstance(d, dict) and strict_json(json_text(d))
    assert json_text(d) == json_text(strict_json(json_text(d)))  # already JSON values: NaN is None
    text = res.summary()
    assert isinstance(text, str) and text.strip()
    paths = res.write(tmp_path / "out")
    assert all(isinstance(p, str) and p.startswith(str(tmp_path / "out")) for p in paths)
    assert files <= {p.rsplit("/", 1)[-1] for p in paths}, paths
    assert all((tmp_path / "out" / p.rsplit("/", 1)[-1]).is_file() for p in paths)
    assert_strict_json(tmp_path / "out")
    without = res.write(tmp_path / "no-plots", plots=False)
    assert not [p for p in without if p.endswith(".png")]
    if kind == "design":  # the figure needs the comparison runs (design(plots=True)); its own test draws it
        with pytest.raises(ValueError, match="no comparison runs"):
            res.plot()
        return
    from matplotlib.figure import Figure

    assert isinstance(res.plot(), Figure)
    saved = res.plot(tmp_path / "main.png")
    assert saved == str(tmp_path / "main.png") and (tmp_path / "main.png").read_bytes()[:4] == b"\x89PNG"


def test_the_results_of_every_driver_are_listed():
    """Every result class jaxclear exports is an AbstractResult and has a case above."""
    from jaxclear.chaos import ChaosReport

    classes = {jc.FitResult, jc.StatisticsFitResult, jc.PosteriorResult, jc.DesignResult, jc.ToleranceResult,
               jc.SweepResult, ChaosReport, jc.WearHistory}
    assert all(issubclass(c, jc.AbstractResult) for c in classes) and len(RESULTS) == len(classes)


def test_old_result_spellings_warn_and_still_work(tmp_path):
    fit = _fit_result()
    with pytest.warns(DeprecationWarning, match=r"FitResult.write_json\(path\) is deprecated"):
        path = fit.write_json(tmp_path / "f.json")
    assert strict_json_file(path) == fit.to_dict()
    design = _design_result()
    with pytest.warns(DeprecationWarning, match=r"DesignResult.to_json\(\) is deprecated"):
        assert design.to_json() == design.to_dict()
    with pytest.warns(DeprecationWarning, match=r"DesignResult.write_json\(path\) is deprecated"):
        design.write_json(tmp_path / "d.json")
    post = _posterior_result()
    with pytest.warns(DeprecationWarning, match=r"format_summary\(\) is deprecated"):
        assert post.format_summary() == post.summary()
    with pytest.warns(DeprecationWarning, match=r"PosteriorResult.summary as a table is deprecated"):
        assert post.summary["stiffness"] == post.statistics["stiffness"]
    tol = _tolerance_result()
    with pytest.warns(DeprecationWarning, match=r"ToleranceResult.summary as a table is deprecated"):
        assert dict(tol.summary.items()) == tol.statistics
    stats = _statistics_fit_result()
    with pytest.warns(DeprecationWarning, match=r"StatisticsFitResult.write\(path.json\) is deprecated"):
        assert strict_json_file(stats.write(str(tmp_path / "s.json"))) == stats.to_dict()
    report = _chaos_report()
    with pytest.warns(DeprecationWarning, match=r"unpacking characterise"):
        lyap, channels = report
    assert lyap is report.lyapunov and channels is report.channels
    from jaxclear.chaos import write_report

    with pytest.warns(DeprecationWarning, match=r"write_report.* is deprecated"):
        summary = write_report(str(tmp_path / "chaos"), types.SimpleNamespace(name="test"), lyap, channels)
    assert summary["exponents"] == report.to_dict()["exponents"] and (tmp_path / "chaos" / "summary.json").is_file()


def strict_json_file(path):
    from conftest import strict_json

    with open(path, encoding="utf-8") as f:
        return strict_json(f.read())
