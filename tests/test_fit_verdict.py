"""Whether a fit's estimates are a result (jaxclear.fitting.verdict): each rule of ``assess`` on
hand-made estimates (no simulation), the physical stiffness range of the benchmark joint,
``FitResult.failures``/``ok`` in the result and fit.json, and ``jaxclear fit --strict`` (the
fit replaced by a failed result: no compilation)."""

import dataclasses
import json
import math

import jaxclear as jc
import pytest

from jaxclear.cli import main
from conftest import assert_strict_json
from jaxclear.contact.base import Material
from jaxclear.contact.hertz import cylindrical_stiffness
from jaxclear.fitting import FitResult, assess, stiffness_range, verdict

FREE = ("stiffness", "restitution")
GOOD = {"stiffness": 6.6e10, "restitution": 0.9}
GOOD_STD = {"stiffness": 1e8, "restitution": 1e-4}
START = {"stiffness": 2e10, "restitution": 0.6}
SETTINGS = {"mechanism": "flores-slider-crank", "law": "lankarani-nikravesh", "data_rms_m_s2": 500.0}


@pytest.fixture(scope="module")
def bench():
    return jc.preset("flores-slider-crank")


def _one(failures, *fragments):
    """The single failure, holding every fragment."""
    assert len(failures) == 1, failures
    assert all(f in failures[0] for f in fragments), failures[0]
    return failures[0]


def test_a_good_fit_passes(bench):
    assert assess(FREE, GOOD, GOOD_STD, start=START, mech=bench) == ()
    assert assess(FREE, GOOD, GOOD_STD) == ()  # without the mechanism and the start: the other rules


@pytest.mark.parametrize("value,edge", [(0.9995, "bound 1"), (1.0, "bound 1"), (5e-4, "bound 0")])
def test_restitution_at_a_bound_of_its_logit(value, edge):
    out = assess(("restitution",), {"restitution": value}, {"restitution": 1e-5})
    _one(out, "restitution = ", edge, "logit", "try more starts")
    assert assess(("restitution",), {"restitution": 0.99}, {"restitution": 1e-3}) == ()


def test_a_log_parameter_that_ran_from_its_start():
    """A factor 1e3 from the start: towards 0 or infinity; within it, nothing."""
    out = assess(("friction",), {"friction": 2e-6}, {"friction": 1e-7}, start={"friction": 0.01})
    _one(out, "friction = 2e-06", "a factor 5e+03 from its start 0.01", "towards 0")
    out = assess(("mass:slider",), {"mass:slider": 500.0}, {"mass:slider": 1.0}, start={"mass:slider": 0.14})
    _one(out, "mass:slider = 500 kg", "towards infinity", "units")
    assert assess(("mass:slider",), {"mass:slider": 100.0}, {"mass:slider": 1.0}, start={"mass:slider": 0.14}) == ()
    # a stiffness with a physical range is judged by the range, not by its distance from the start
    assert assess(("stiffness",), {"stiffness": 6.6e10}, {"stiffness": 1e8}, start={"stiffness": 1e7}) != ()
    assert assess(("stiffness",), {"stiffness": 6.6e10}, {"stiffness": 1e8}, start={"stiffness": 1e7},
                  mech=jc.preset("flores-slider-crank")) == ()


def test_outside_the_documented_range(bench):
    """A value that underflowed to the bound 0 of (0, inf); a clearance not below the bearing
    radius (with the mechanism)."""
    _one(assess(("mass:slider",), {"mass:slider": 0.0}, {"mass:slider": 0.0}), "outside its range (0, inf)")
    out = assess(("clearance",), {"clearance": 0.012}, {"clearance": 1e-5}, mech=bench)
    _one(out, "clearance = 0.012 m", "bearing radius")
    assert assess(("clearance",), {"clearance": 0.012}, {"clearance": 1e-5}) == ()  # no radius known


def test_stiffness_range_of_the_benchmark(bench, monkeypatch):
    """The range holds the preset's nominal stiffness (steel, 6.61e10) and excludes 1.8e14; it is
    the law's own formula at the extreme materials. Its floor is a 1 GPa polymer pair: 3.0e8, so
    1.2e9 (E* about 2 GPa, a polymer joint) lies inside, and outside with a 5 GPa floor."""
    low, high, unit, what = stiffness_range(bench)
    nominal = float(jc.params.get(bench, "stiffness"))
    assert low < nominal < high and not low <= 1.8e14 <= high and not low <= 1.2e8 <= high
    assert unit == "N/m^1.5" and "bearing radius 10 mm" in what and "journal radius 9.5 mm" in what
    soft, hard = Material(1e9, 0.2).compliance, Material(1000e9, 0.45).compliance
    assert math.isclose(low, float(cylindrical_stiffness(0.01, 0.0095, soft, soft)), rel_tol=1e-12)
    assert math.isclose(high, float(cylindrical_stiffness(0.01, 0.0095, hard, hard)), rel_tol=1e-12)
    assert low <= 1.2e9 <= high
    monkeypatch.setattr(verdict, "YOUNG_MIN", 5e9)
    assert not stiffness_range(bench)[0] <= 1.2e9


@pytest.mark.parametrize("value", [1.8e14, 1e8])
def test_stiffness_outside_the_physical_range(bench, value):
    out = assess(("stiffness",), {"stiffness": value}, {"stiffness": value / 100}, mech=bench)
    _one(out, f"stiffness = {value:.6g} N/m^1.5", "outside the physical range 3.03e+08 to 3.64e+11 N/m^1.5",
         "clearance joint 0", "more starts", "shorter window", "window start states", "sensor gain", "units")


def test_stiffness_range_follows_the_fitted_geometry_and_the_law(bench):
    """A free clearance moves the range (K grows as the clearance shrinks); a law without a
    formula from materials (Kelvin-Voigt) or another exponent has none."""
    wide = assess(("stiffness", "clearance"), {"stiffness": 1e12, "clearance": 5e-4},
                  {"stiffness": 1e9, "clearance": 1e-6}, mech=bench)
    _one(wide, "physical range 3.03e+08 to 3.64e+11")
    assert assess(("stiffness", "clearance"), {"stiffness": 1e12, "clearance": 1e-5},
                  {"stiffness": 1e9, "clearance": 1e-8}, mech=bench) == ()
    assert stiffness_range(jc.preset("flores-slider-crank", law="kelvin-voigt")) is None
    assert stiffness_range(jc.params.replace(bench, "exponent", 1.0)) is None
    assert stiffness_range(jc.preset("slider-crank-guide-clearance")) is None  # no radii


@pytest.mark.parametrize("gain", [0.009, 0.4, 2.5])
def test_sensor_gain_far_from_one(gain):
    out = assess(("stiffness", "sensor_gain"), {"stiffness": 6.6e10, "sensor_gain": gain},
                 {"stiffness": 1e8, "sensor_gain": 1e-3}, start={"stiffness": 6e10, "sensor_gain": 1.0})
    _one(out, f"sensor_gain = {gain:g}", "outside [0.5, 2]", "units")


def test_sensor_gain_near_one_passes():
    assert assess(("sensor_gain",), {"sensor_gain": 1.3}, {"sensor_gain": 1e-3}) == ()


def test_std_larger_than_the_estimate_or_not_finite():
    out = assess(FREE, GOOD, {"stiffness": 6.6e14, "restitution": 1e-4})
    _one(out, "stiffness = 6.6e+10", "standard deviation 6.6e+14", "1e+04 times the estimate", "free fewer")
    _one(assess(FREE, GOOD, {"stiffness": 1e8, "restitution": math.nan}), "restitution", "not finite")
    # a bias may be smaller than its std (it is not a positive quantity), but not without one
    assert assess(("sensor_bias",), {"sensor_bias": 0.01}, {"sensor_bias": 0.5}) == ()
    _one(assess(("sensor_bias",), {"sensor_bias": 0.01}, {"sensor_bias": math.inf}), "not finite")


def test_a_diverged_estimate():
    _one(assess(("stiffness",), {"stiffness": math.inf}, {"stiffness": math.nan}), "not finite", "diverged")


def _history(*starts):
    """History records of the start stages: (loss, stiffness, restitution) per start, two records each."""
    n = len(starts)
    out = []
    for j, (loss, k, c) in enumerate(starts):
        stage = f"start {j + 1}/{n}, window 1, velocity, horizon 0.25"
        out += [{"stage": stage, "iteration": 2 * j + 1, "loss": 10 * loss,
                 "values": {"stiffness": 1e10, "restitution": 0.5}},
                {"stage": stage, "iteration": 2 * j + 2, "loss": loss, "values": {"stiffness": k, "restitution": c}}]
    out.append({"stage": "window 1, acceleration, horizon 1", "iteration": 99, "loss": 0.001,
                "values": {"stiffness": 6.6e10, "restitution": 0.9}})
    return out


def test_estimates_that_change_with_the_start():
    """Two starts equally good (losses within 1 %) but 2e11 against 6.6e10 (130 std): failed;
    a start with a clearly worse loss, or differences within 10 % of the estimate, are not."""
    history = _history((0.0100, 6.6e10, 0.90), (0.0101, 2.0e11, 0.90), (0.05, 3e9, 0.3))
    std = {"stiffness": 1e9, "restitution": 1e-3}
    out = assess(FREE, GOOD, std, history=history)
    _one(out, "estimates change with the start", "stiffness = 6.6e+10 from start 1", "2e+11 from start 2",
         "134 std apart", "more starts")
    assert assess(FREE, GOOD, std, history=_history((0.0100, 6.6e10, 0.9), (0.0200, 2e11, 0.9))) == ()
    close = _history((0.0100, 6.6e10, 0.900), (0.0100, 6.9e10, 0.905))  # 30 and 50 std, but 4.4 % and 0.05
    assert assess(FREE, GOOD, {"stiffness": 1e8, "restitution": 1e-4}, history=close) == ()  # in logit: one minimum
    assert assess(FREE, GOOD, std, history=_history((0.01, 6.6e10, 0.9))) == ()  # one start


def _result(**kw):
    base = dict(estimates=dict(GOOD), std=dict(GOOD_STD), loss=0.01, iterations=7, wall_time_s=2.0, start=dict(START),
                free=FREE, settings=dict(SETTINGS), fixed={"clearance": 5e-4}, stop_reason="ftol")
    base.update(kw)
    return FitResult(**base)


def test_fit_result_carries_the_verdict(tmp_path, bench):
    good = _result()
    assert good.ok and good.failures == () and good.format_failures() == ""
    assert not good.summary().startswith("FAILED")
    bad = _result(estimates={"stiffness": 1.8e14, "restitution": 0.9})  # the preset's geometry from the settings
    assert not bad.ok and "physical range" in bad.failures[0]
    assert bad.summary().startswith("FAILED") and bad.failures[0] in bad.summary()
    d = bad.to_dict()
    assert list(d)[:2] == ["ok", "failures"] and d["ok"] is False and d["failures"] == list(bad.failures)
    written = json.loads(open(bad.write(tmp_path, plots=False)[0], encoding="utf-8").read())
    assert written["ok"] is False and written["failures"] == list(bad.failures)
    assert bad.to_dataframe().attrs["ok"] is False
    # the mechanism itself when given; a mechanism that is no preset's gets no range check
    with_mech = _result(estimates={"stiffness": 1.8e14, "restitution": 0.9}, settings={"mechanism": "my-rig"},
                        mech=bench)
    assert not with_mech.ok and "mech" not in {f.name for f in dataclasses.fields(FitResult)}  # init only
    assert _result(estimates={"stiffness": 1.8e14, "restitution": 0.9}, start={"stiffness": 1e12, "restitution": 0.6},
                   settings={"mechanism": "my-rig"}).ok
    assert _result(failures=["given"]).failures == ("given",)  # given failures are kept


def _failed_result():
    return _result(estimates={"stiffness": 1.8e14, "restitution": 0.9}, std={"stiffness": 1e12, "restitution": 1e-3})


@pytest.mark.parametrize("strict", [True, False])
def test_cli_strict_exits_3_after_writing_fit_json(tmp_path, capsys, monkeypatch, strict):
    """``jaxclear fit --strict`` on a failed fit: fit.json written (ok false, the reasons), FAILED
    and the reasons printed first, exit status 3; without --strict the same printout and 0."""
    import jaxclear.cli.fit as cli_fit

    seen = {}

    def fake_fit(data, mech, free, start, **kwargs):
        seen.update(data=data, free=list(free))
        return _failed_result()

    monkeypatch.setattr(cli_fit, "fit", fake_fit)
    out = tmp_path / "out"
    args = ["fit", "rec.csv", "--out", str(out), "--no-plots", "--no-progress"] + (["--strict"] if strict else [])
    code = main(args)
    text = capsys.readouterr().out
    assert code == (3 if strict else 0) and seen == {"data": "rec.csv", "free": ["stiffness", "restitution"]}
    d = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    assert d["ok"] is False and "physical range" in d["failures"][0] and assert_strict_json(out) == ["fit.json"]
    body = text.split("\n", 1)[1]  # after the command's first line (what is fitted)
    assert body.startswith("FAILED") and d["failures"][0] in body
    assert ("exit status 3" in text) == strict


def test_cli_help_documents_strict(capsys):
    assert main(["fit", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "--strict" in help_text and "exit with status 3" in help_text and "3 with --strict" in help_text


def test_a_free_start_fit_that_stopped_on_max_iter_fails():
    """Every window's start free and the last stage on ``max_iter``: not an optimum, a failure;
    the same stop of a fit from a known start stays a warning (``FitResult.warnings``)."""
    out = assess(FREE, GOOD, GOOD_STD, stop_reason="max_iter", free_start=True)
    _one(out, "max_iter", "every window's start free", "--max-iter")
    assert assess(FREE, GOOD, GOOD_STD, stop_reason="max_iter") == ()
    assert assess(FREE, GOOD, GOOD_STD, stop_reason="relative loss decrease 1e-7 < ftol 1e-06", free_start=True) == ()


def test_a_free_start_fit_needs_a_whiter_residual():
    """Lag-1 autocorrelation 0.30 and a misfit twice the noise (a fit of a record that begins
    mid-run with the restitution 108 std off): passed with a known start (rule at 0.5), a failure
    with every start free (rule at 0.2)."""
    assert assess(FREE, GOOD, GOOD_STD, autocorrelation=0.2993, loss=0.019) == ()
    _one(assess(FREE, GOOD, GOOD_STD, autocorrelation=0.2993, loss=0.019, free_start=True),
         "the residual is not noise", "0.30 > 0.2")
    assert assess(FREE, GOOD, GOOD_STD, autocorrelation=0.003, loss=0.0103, free_start=True) == ()


def _profile(interval=(0.89, 0.91), better=None, open_=()):
    return {"values": [0.88, 0.9, 0.92], "deviance": [4.0, 0.0, 4.0], "interval": list(interval), "level": 0.9,
            "std": 0.01 / 1.645 if None not in interval else math.inf, "std_gauss_newton": 1e-4, "better": better,
            "open": list(open_)}


def test_a_closed_profile_passes_and_an_open_or_better_one_fails():
    """A closed profile without a better point passes; an open side fails the parameter (and the
    std rules then judge the Gauss-Newton std, not the infinite profile std: one failure, not
    two); a point that fits better than the estimate fails the fit with the value to start from."""
    closed = _profile()
    assert assess(FREE, GOOD, {**GOOD_STD, "restitution": closed["std"]}, profiles={"restitution": closed}) == ()
    opened = _profile((0.89, None), open_=["the deviance stays below 2.71 out to restitution = 0.9994"])
    _one(assess(FREE, GOOD, {**GOOD_STD, "restitution": math.inf}, profiles={"restitution": opened}),
         "restitution = 0.9", "profile likelihood does not close", "stays below 2.71", "does not determine it")
    better = _profile(better={"value": 0.75, "deviance": -12.0})
    _one(assess(FREE, GOOD, {**GOOD_STD, "restitution": better["std"]}, profiles={"restitution": better}),
         "found a better fit at 0.75", "12 noise variances below", "local minimum", "--start restitution=0.75")


def test_a_residual_above_the_given_noise_fails():
    """With the sensor's noise given (a record at rest), dof s^2 / sigma^2 is chi-square with dof
    degrees of freedom for a model that follows the record: z = (s^2/sigma^2 - 1) / sqrt(2/dof).
    1.12 times the noise over 539 dof is z = 4.2 (the record of the independent simulator whose
    fit passed every other rule with the stiffness 11.8 % low): a failure; 1.05 times is z = 1.7:
    none; a residual below the noise is none either (it says nothing about a misfit); without
    a given noise no test."""
    out = assess(FREE, GOOD, GOOD_STD, noise=(1.12 * 1000.0, 1000.0, 539))
    _one(out, "1.12 times the sensor's noise 1000", "4.2 chi-square std over 539", "does not follow the record")
    assert assess(FREE, GOOD, GOOD_STD, noise=(1.05 * 1000.0, 1000.0, 539)) == ()
    assert assess(FREE, GOOD, GOOD_STD, noise=(0.8 * 1000.0, 1000.0, 539)) == ()
    assert assess(FREE, GOOD, GOOD_STD, noise=(2000.0, None, 539)) == ()



def test_a_window_above_the_given_noise_fails_though_the_record_passes():
    """The same chi-square test window by window (several windows, the noise given): a start in
    another basin leaves its misfit in its own window. Four windows of 135 dof, one at 1.33 times
    the noise (z = (1.77 - 1) / sqrt(2/135) = 6.3; the record as a whole 1.09 times, z = 2.2 over
    540: it passes): a failure naming window 1 alone; all at 1.05 times (z = 0.9 each): none;
    one window: only the record's test; no noise given: none."""
    ok = (1.05 * 1000.0, 1000.0, 540)
    out = assess(FREE, GOOD, GOOD_STD, noise=ok, windows=([1330.0, 1000.0, 990.0, 1010.0], [135.0] * 4))
    _one(out, "window 1 (1.33 times, 6.3 chi-square std over 135", "does not follow this window",
         "start was probably not found")
    assert assess(FREE, GOOD, GOOD_STD, noise=ok, windows=([1050.0] * 4, [135.0] * 4)) == ()
    assert assess(FREE, GOOD, GOOD_STD, noise=ok, windows=([1330.0], [540.0])) == ()
    assert assess(FREE, GOOD, GOOD_STD, noise=(1050.0, None, 540), windows=([2000.0, 1000.0], [270.0] * 2)) == ()
    two = assess(FREE, GOOD, GOOD_STD, noise=ok, windows=([1330.0, 1000.0, 1500.0, 1010.0], [135.0] * 4))
    _one(two, "windows 1 (1.33 times", "; 3 (1.5 times", "does not follow these windows")

def test_noise_sigma_is_checked():
    import numpy as np

    meas = jc.Measurements(time_s=np.arange(100) * 1e-5, slider_acc_m_s2=np.ones(100))
    mech = jc.preset("flores-slider-crank")
    for bad in (-1.0, 0.0, math.nan, "1"):
        with pytest.raises(jc.ParameterError, match="noise_sigma = .* must be a finite number > 0"):
            jc.fit(meas, mech, window=5e-4, noise_sigma=bad)


def test_a_stage_stops_where_a_step_gains_less_than_a_tenth_of_a_noise_variance():
    """jaxclear.fitting.run.statistically_converged: with N - P = 2400 degrees of freedom and a
    sum of squares of 24 (s^2 = 0.01), an accepted step lowering it by 0.0005 (0.05 noise
    variances) ends the stage; by 0.005 (0.5) it does not; nor does a rejected step, the first
    step of a stage (no loss before it), or a step that raised the loss."""
    from jaxclear.fitting.run import DEVIANCE_TOL, statistically_converged

    assert DEVIANCE_TOL == 0.1
    reason = statistically_converged(24.0005, 24.0, 2400.0, True)
    assert "0.05 noise variances" in reason and "statistically converged" in reason
    assert statistically_converged(24.005, 24.0, 2400.0, True) == ""
    assert statistically_converged(24.0005, 24.0, 2400.0, False) == ""
    assert statistically_converged(float("nan"), 24.0, 2400.0, True) == ""
    assert statistically_converged(23.9, 24.0, 2400.0, True) == ""


def test_the_contact_onsets_per_window_are_reported():
    """``FitResult.window_onsets`` (the impacts the fitted motion has in each window) is in the
    summary (several windows) and in ``to_dict``; a result that does not know them says nothing."""
    res = _result(window_onsets=[1, 1, 1, 0])
    assert res.ok
    assert "contact onsets of the fitted motion per window: 1, 1, 1, 0 (3 in all)" in res.summary()
    assert res.to_dict()["window_onsets"] == [1, 1, 1, 0]
    assert "contact onsets" not in _result().summary() and _result().to_dict()["window_onsets"] is None
