"""The scan of held values after a fit (jaxclear.fitting.scan; ``jc.fit(..., scan=NAME)``,
``jaxclear fit --scan``): its inputs, its decision rule, its report and its resume.

Its physics check is the acceptance record of the independent simulator that the plain fit
leaves in another basin (tests/test_lab_fit.py, slow; benchmarks/README "Records that begin
mid-run"): here the mechanics on a small record of jaxclear's own, where the truth is known.
"""

import jaxclear  # noqa: F401  (float64 first)

import json
import os

import numpy as np
import pytest

import jaxclear as jc
from jaxclear import fitting, params
from jaxclear.cli import main

SENSOR = jc.Accelerometer(20e3)


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """1.2 ms of the benchmark slider-crank from start-up at 200 kHz, 20 dB noise (the
    restitution 0.9, the stiffness the preset's)."""
    folder = tmp_path_factory.mktemp("scan")
    mech = jc.preset("flores-slider-crank")
    path = folder / "record.csv"
    jc.synthetic_record(mech, 1.2e-3, 200e3, SENSOR, snr_db=20, seed=7, path=path)
    return mech, str(path), folder


def test_scan_inputs_are_checked_before_any_fit(record, capsys):
    mech, path, _ = record
    with pytest.raises(jc.ParameterError, match="scan = 'clearance' is not a free parameter of this fit; valid: "
                       "stiffness, restitution"):
        jc.fit(path, mech, window=1e-3, scan="clearance", progress=False)
    with pytest.raises(jc.ParameterError, match="scan = 'sensor_gain': a sensor parameter cannot be scanned"):
        jc.fit(path, mech, free=["stiffness", "sensor_gain"], window=1e-3, scan="sensor_gain", progress=False)
    with pytest.raises(jc.ParameterError, match="scan = 'stiffness' is the only free parameter"):
        jc.fit(path, mech, free=["stiffness"], window=1e-3, scan="stiffness", progress=False)
    with pytest.raises(jc.ParameterError, match="give at least one finite value of 'restitution'"):
        jc.fit(path, mech, window=1e-3, scan={"restitution": [float("nan")]}, progress=False)
    with pytest.raises(jc.ParameterError, match="the held value 1.2 of 'restitution' is not allowed"):
        jc.fit(path, mech, window=1e-3, scan={"restitution": [0.8, 1.2]}, progress=False)
    with pytest.raises(jc.ParameterError, match="expected a free parameter's name or"):
        jc.fit(path, mech, window=1e-3, scan={"restitution": [0.8], "stiffness": [1e10]}, progress=False)
    assert main(["fit", path, "--out", str(record[2] / "cli-bad"), "--scan", "restitution=a,b", "--no-progress"]) == 2
    printed = capsys.readouterr()
    assert "--scan 'restitution=a,b': expected NAME or NAME=V1,V2,... with numbers" in printed.err
    assert "jaxclear fit:" not in printed.out  # refused before the fit starts


@pytest.mark.extended
def test_a_better_held_point_is_refitted_and_taken_and_the_scan_resumes(record):
    """A fit stopped before it converged (one Levenberg-Marquardt step on the whole window, ftol
    and xtol 0.5, from 1.3x the stiffness and restitution 0.75: its misfit stays near 0.24 of
    the data's mean square) scanned at the truth's 0.9: the held fit there follows the record better, so every unknown is
    fitted again from it and that result is taken; no scan point fits better than the result
    (every deviance >= 0 up to 1e-6 noise variances: the rule keeps the held point where the
    refit's last step climbs) and the restitution ends within 0.02 of the truth. Run again with
    the same ``out``, the fit, the held point and the decision are read back: no iteration is
    fitted again and the result is the same."""
    mech, path, folder = record
    k0 = float(params.get(mech, "stiffness"))
    out = folder / "taken"
    kw = dict(start={"stiffness": 1.3 * k0, "restitution": 0.75}, sensor=SENSOR, window=1e-3, starts=1,
              max_iter=1, horizons=[1.0], coarse=None, ftol=0.5, xtol=0.5, progress=False, out=out,
              scan={"restitution": [0.9]})
    res = jc.fit(path, mech, **kw)
    scan = res.settings["scan"]
    assert scan["name"] == "restitution" and scan["values"] == [0.9]
    assert scan["taken"] and scan["refit_from"] == 0.9
    assert res.loss <= scan["loss"][0] * (1 + 1e-12) and res.loss < 0.5 * scan["estimate_loss"]
    assert min(scan["deviance"]) >= -1e-6
    assert os.path.isfile(out / "scan-restitution-0.9" / fitting.CHECKPOINT_NAME)
    c = res.estimates["restitution"]
    assert abs(c - 0.9) < 0.02, res.estimates
    assert "restitution" in res.profiles  # the scanned name's profile is walked
    assert any("scan of restitution held" in line for line in res.profile_lines())
    # the seconds of each phase of this call: the stages, the scan and the profile, within the fit's wall time
    phases = res.settings["phase_s"]
    assert list(phases) == ["plan", "scan", "profile"] and min(phases.values()) >= 0.0
    assert sum(phases.values()) <= res.wall_time_s
    saved = json.loads((out / fitting.CHECKPOINT_NAME).read_text())["state"]["scan"]
    assert [p["kind"] for p in saved] == ["held", "decision"]
    seen = []
    again = jc.fit(path, mech, callback=seen.append, **kw)
    assert seen == [] and again.settings["resumed"]
    assert again.estimates == res.estimates and again.settings["scan"] == scan


def test_a_held_fit_keeps_the_fit_s_unknowns_and_compiled_programs(record):
    """A scan point is the fit's own problem with the scanned parameter held
    (``FitProblem.holding``): the same unknowns, every stage that moves the parameters holds it
    (its Jacobian column exactly zero, the other columns those of the fit at the same values),
    every start of the parameters keeps it at the held value, the checkpoint's key tells the two
    apart; and its evaluation runs the fit's compiled program (no trace), where a problem without
    the name among its free parameters would compile its programs again."""
    from jaxclear.fitting.problem import ATOL, RTOL, build_problem
    from jaxclear.fitting.run import fresh_state, stage_evaluation

    mech, path, _ = record
    settings = dict(max_iter=3, ftol=1e-8, xtol=1e-8, rtol=RTOL, atol=ATOL, max_steps=None, align="time",
                    time_offset=0.0, optimizer="lm")  # the fit's model: its program is the other tests' here
    args = (SENSOR, 1e-3, 1, (0.5, 1.0), None, 3, settings)
    fit = build_problem(path, mech, ["stiffness", "restitution"], {"restitution": 0.8}, *args)
    held = build_problem(path, mech, ["stiffness", "restitution"], {"restitution": 0.8}, *args).holding("restitution")
    assert held.free == fit.free and len(held.stages) == len(fit.stages)
    assert all(s.held == ((1,) if s.theta else ()) for s in held.stages)
    assert [z[1] for z in held.z_starts] == [fit.z0[1]] * 3 and fit.z_starts[1][1] != fit.z0[1]
    assert held.checkpoint_key() != fit.checkpoint_key()
    stage = fit.stages[-1]
    r, jac, _ = stage_evaluation(fit, fresh_state(fit), stage)
    traced = []
    with jc.integrate.on_trace(traced.append):
        r_held, jac_held, _ = stage_evaluation(held, fresh_state(held), held.stages[-1])
    assert traced == []
    np.testing.assert_array_equal(r_held, r)
    assert np.all(jac_held[:, 1] == 0.0) and np.any(jac[:, 1] != 0.0)
    np.testing.assert_array_equal(jac_held[:, 0], jac[:, 0])


def test_a_scan_that_finds_nothing_better_keeps_the_fit(record):
    """A converged fit scanned at its default values (the estimate's logit +- 0.5: two held
    fits, 0.85 and 0.94 for an estimate of 0.90) keeps its estimate; the held points lie above
    it by hundreds of noise variances (a 1 ms record of 200 samples fixes the restitution to
    +-0.002)."""
    mech, path, folder = record
    out = folder / "kept"
    code = main(["fit", path, "--out", str(out), "--window", "1e-3", "--sensor-cutoff-hz", "20000",
                 "--start", "restitution=0.85", "--scan", "restitution", "--no-progress", "--no-plots"])
    assert code == 0
    d = json.loads((out / "fit.json").read_text())
    scan = d["settings"]["scan"]
    assert not scan["taken"] and len(scan["values"]) == 2
    est = d["estimates"]["restitution"]
    lo, hi = scan["values"]
    assert lo < est < hi
    np.testing.assert_allclose(np.log(np.array([lo, hi]) / (1 - np.array([lo, hi]))),
                               np.log(est / (1 - est)) + np.array([-0.5, 0.5]), atol=1e-9)
    assert min(scan["deviance"]) > 10.0


@pytest.mark.slow  # about 40 s: a held fit and the stiffness's profile
def test_a_finished_fit_scanned_for_another_name_runs_the_new_scan(record):
    """The converged fit of :func:`test_a_scan_that_finds_nothing_better_keeps_the_fit`, then the
    same call scanned for the stiffness (held at 7e10, 5 % above the estimate) with the same
    ``out``: the fit and the restitution's scan are read back, the new scan runs and replaces the
    old one in the report."""
    mech, path, folder = record
    out = folder / "renamed"
    args = ["fit", path, "--out", str(out), "--window", "1e-3", "--sensor-cutoff-hz", "20000", "--start",
            "restitution=0.85", "--no-progress", "--no-plots"]
    assert main(args + ["--scan", "restitution"]) == 0
    est = json.loads((out / "fit.json").read_text())["estimates"]["restitution"]
    assert main(args + ["--scan", "stiffness=7e10"]) == 0
    d = json.loads((out / "fit.json").read_text())
    assert d["settings"]["scan"]["name"] == "stiffness" and d["settings"]["scan"]["values"] == [7e10]
    assert d["settings"]["resumed"] and d["estimates"]["restitution"] == est


def test_a_free_start_fit_with_few_onsets_names_the_scan():
    """The hint of :func:`jaxclear.fitting.scan.few_onsets`: a record that begins mid-run whose
    fitted motion holds fewer than 4 onsets (acceptance record 1's 1, 1, 1, 0) with the
    restitution free and no scan run; none with 4 or more (record 2), with a known start, with
    the restitution held, or after a scan."""
    from jaxclear.fitting.scan import FEW_ONSETS, few_onsets

    assert FEW_ONSETS == 4
    free = ("stiffness", "restitution", "sensor_gain", "sensor_bias")
    text = few_onsets(free, True, False, [1, 1, 1, 0])
    assert "seen through 3 contact onset(s) of the fitted motion (per window: 1, 1, 1, 0)" in text
    assert "scan='restitution' (--scan restitution)" in text
    assert "per window: 1, -, 0" in few_onsets(free, True, False, [1, None, 0])
    assert few_onsets(free, True, False, [1, 2, 1, 0]) == ""
    assert few_onsets(free, False, False, [1, 1, 1, 0]) == ""
    assert few_onsets(("stiffness", "sensor_gain"), True, False, [1, 1, 1, 0]) == ""
    assert few_onsets(free, True, True, [1, 1, 1, 0]) == ""
    assert few_onsets(free, True, False, [None, None]) == ""


def test_the_automatic_scan_runs_where_the_fitted_motion_holds_few_onsets(monkeypatch):
    """``scan="auto"`` (the default, ``--scan auto``): the restitution, for a record that begins
    mid-run with the restitution and another parameter free, nothing
    elsewhere (as ``scan="restitution"`` is checked); it runs where the fitted motion holds fewer than 4 onsets (acceptance record 1's
    1, 1, 1, 0, the evaluation replaced by those counts here), not with 4 or more (record 2's 1,
    0, 0, 4), and a scan begun before is continued. ``--scan none`` is no scan."""
    from types import SimpleNamespace

    from jaxclear.cli.fit import _scan
    from jaxclear.fitting import scan as scan_module

    free = ("stiffness", "restitution", "sensor_gain", "sensor_bias")
    assert scan_module.auto_scan(free, True) == ("restitution", None)
    assert scan_module.auto_scan(free, False) == ()
    assert scan_module.auto_scan(("stiffness", "sensor_gain"), True) == ()
    assert scan_module.auto_scan(("restitution",), True) == ()  # holding it would leave nothing to fit
    problem = SimpleNamespace(free=free, anywhere=True)
    state = SimpleNamespace(scan=(), theta=[0.0] * 4, states=[[0.0]], guesses=())
    for onsets, expected in (([1, 1, 1, 0], "fewer than 4"), ([1, 0, 0, 4], "")):
        evals = [(None, None, None, None, float(n)) for n in onsets]
        monkeypatch.setattr(scan_module, "evaluate_all", lambda *args, evals=evals: evals)
        why = scan_module.auto_reason(problem, state)
        assert (expected in why) if expected else why == ""
    assert scan_module.auto_reason(problem, SimpleNamespace(scan=({"kind": "held"},))) == "automatic, resumed"
    assert _scan("none") is None and _scan("auto") == "auto" and _scan("restitution") == "restitution"
