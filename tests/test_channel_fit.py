"""Fits through named channels with ``jc.fit`` (record columns mapped to channels).

* The four-bar with the clearance at the rocker pivot, fitted from the rocker's angular
  acceleration alone, on a record made by another solver configuration (Dormand-Prince 5(4) at
  rtol 1e-10 against the model's Tsitouras 5(4) at rtol 1e-6) plus 2 % noise: the truth is what
  the record was simulated with, not an output of the fitted model.
* Oil viscosity of the lubricated journal (short-bearing film) from the slider acceleration.
* A slider-crank whose slider runs in a guide with clearance (four corner contacts), with two
  back-to-back windows: the second window's start state is the translational element's own
  (lateral offset, tilt and their rates), and the fit runs through.
"""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import jaxclear as jc
from jaxclear import params
from jaxclear.analysis.sensor import Accelerometer
from jaxclear.cli import main

ROOT = Path(__file__).resolve().parents[1]
ROCKER = "body:rocker:phi:acc"


def _rocker_record(mech, window, n, seed=0):
    """The rocker channel by dopri5 at rtol 1e-10 plus white noise of 2 % of its std (SNR 34 dB)."""
    sol = jc.simulate(mech, jc.settings(window, n_out=n, solver="dopri5", rtol=1e-10, atol=1e-13))
    clean = np.asarray(jc.channel(mech, sol, ROCKER))
    noisy = clean + 0.02 * np.std(clean) * np.random.default_rng(seed).standard_normal(clean.shape)
    return {"time_s": np.asarray(sol.ts), "rocker_acc_rad_s2": noisy}


@pytest.mark.slow  # compilation-dominated: 14 min wall on a shared, loaded 2-core machine
def test_four_bar_fit_from_rocker_channel(tmp_path):
    """Stiffness 2x and restitution 0.7 at the start; 5 ms from the known start through the first
    impact (2.95 ms) and its contact; one window, the velocity stage then the acceleration over
    the whole window (``horizons=(1,)``). Recovers K within 5 % and c_r within 0.02 (measured:
    -0.34 % and 0.8972, 7 iterations). The
    fit reports the column's channel and its fitted samples."""
    mech = jc.load_mechanism(ROOT / "examples" / "four-bar-rocker-pivot.toml")
    k0 = float(params.get(mech, "stiffness"))
    window = 0.005
    rec = _rocker_record(mech, window, 501)
    kw = dict(start={"stiffness": 2 * k0, "restitution": 0.7}, channels={"rocker_acc_rad_s2": ROCKER},
              sensor=Accelerometer(oversample=1), window=window, horizons=(1.0,), rtol=1e-6, atol=1e-9,
              progress=False)
    res = jc.fit(rec, mech, **kw)
    assert abs(res.estimates["stiffness"] / k0 - 1) < 0.05, res.estimates
    assert abs(res.estimates["restitution"] - 0.9) < 0.02, res.estimates
    assert res.settings["channels"] == {"rocker_acc_rad_s2": {"channel": ROCKER, "weight": 1.0,
                                                             "sensor": "no low-pass, gain 1, bias 0 m/s^2"}}
    assert set(res.series) == {"rocker_acc_rad_s2"}
    np.testing.assert_array_equal(res.series["rocker_acc_rad_s2"]["fitted"], res.fitted)


def test_channel_targets_are_checked(tmp_path, capsys):
    """Bad channel targets are errors naming the column, channel or weight, before any
    compilation (API, CSV record with any columns, TOML form, CLI)."""
    mech = jc.load_mechanism(ROOT / "examples" / "four-bar-rocker-pivot.toml")
    rec = _rocker_record(mech, 0.003, 301)
    path = tmp_path / "rec.csv"
    jc.io.write_table_csv(path, {**rec, "unused": np.zeros_like(rec["time_s"])})
    toml = tmp_path / "channels.toml"
    toml.write_text(f'[channels.rocker_acc_rad_s2]\nchannel = "{ROCKER}"\nweight = 2.0\n')
    with pytest.raises(jc.ParameterError, match="unknown body 'rockr'"):
        jc.fit(str(path), mech, channels={"rocker_acc_rad_s2": "body:rockr:phi:acc"}, window=0.003)
    with pytest.raises(jc.ParameterError, match="missing required column"):
        jc.fit(str(path), mech, channels={"nope": ROCKER}, window=0.003)
    with pytest.raises(jc.ParameterError, match="every weight is 0"):
        jc.fit(str(path), mech, channels={"rocker_acc_rad_s2": {"channel": ROCKER, "weight": 0.0}}, window=0.003)
    assert jc.fitting.read_channels_toml(toml) == {"rocker_acc_rad_s2": {"channel": ROCKER, "weight": 2.0}}
    code = main(["fit", str(path), "--preset", "four-bar", "--channels", str(toml), "--weight", "other=1",
                 "--out", str(tmp_path / "out"), "--no-progress"])
    assert code != 0 and "'other' is not a fitted column" in capsys.readouterr().err


def test_viscosity_fit_on_the_lubricated_joint():
    """The lubricated benchmark (short-bearing film, 0.4 Pa s) from a start 2x off in viscosity:
    1 ms of slider acceleration at 200 kHz (20 dB noise, made at rtol 1e-10), one window;
    the film force is proportional to the viscosity away from contact, so the fit recovers it
    within 5 %."""
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    rec = jc.synthetic_record(mech, 1.0e-3, 200e3, snr_db=20, seed=3)
    res = jc.fit(rec, mech, free=("viscosity",), start={"viscosity": 0.8}, window=1.0e-3, horizons=(1.0,),
                 coarse=None, sensor=Accelerometer(oversample=2), rtol=1e-7, atol=1e-10, progress=False)
    assert abs(res.estimates["viscosity"] / 0.4 - 1) < 0.05, res.estimates


@pytest.mark.slow  # 370 s on 2 shared cores (two 3 ms windows, forward-mode Jacobians through the corner impacts)
def test_translational_clearance_fit_runs_with_windows(tmp_path):
    """slider-crank-guide-clearance through jc.fit with two windows (the second window's start
    state in the translational element's layout), a handful of iterations: runs, finite
    estimates, window states of 4 numbers (lateral offset, tilt and their rates), and the
    restitution moves from the start 0.8 towards the 0.9 the record was simulated with.

    The slider, centred at the start, first reaches a guide face at 2.6 ms and then bounces at
    4.5 and 5.8 ms: each 3 ms window holds impacts, so the restitution is seen in both (a 0.5 ms
    window holds none: zero sensitivity, and the fit cannot start). 50 kHz keeps 150 samples a
    window."""
    mech = jc.preset("slider-crank-guide-clearance")
    el = mech.clearance_joints[0]
    sol = jc.simulate(mech, jc.settings(1e-6, n_out=2))  # the assembled start
    np.testing.assert_allclose(np.asarray(el.start_state(mech, sol.q[0], sol.qdot[0])),
                               np.concatenate([el.initial_offset, el.initial_velocity]), atol=1e-9)
    rec = jc.synthetic_record(mech, 6e-3, 50e3, snr_db=30, seed=1)
    res = jc.fit(rec, mech, free=("restitution",), start={"restitution": 0.8}, window=3e-3, windows=2,
                 horizons=(1.0,), coarse=None, sensor=Accelerometer(oversample=2), max_iter=3, rtol=1e-6,
                 atol=1e-9, progress=False)
    assert np.isfinite(res.estimates["restitution"]) and np.isfinite(res.loss)
    assert len(res.window_states) == 1 and len(res.window_states[0]) == 4
    assert abs(res.estimates["restitution"] - 0.9) < 0.1  # closer to the truth than the start (0.855 seen)


def test_cli_fit_mechanism_file_errors_name_the_file(tmp_path, capsys):
    """`jaxclear fit --mechanism FILE.toml`: a missing file is an error naming it (no compilation)."""
    pd.DataFrame({"time_s": [0.0, 1e-3], "rocker_acc_rad_s2": [0.0, 1.0]}).to_csv(tmp_path / "r.csv", index=False)
    code = main(["fit", str(tmp_path / "r.csv"), "--mechanism", str(tmp_path / "nope.toml"),
                 "--channel", f"rocker_acc_rad_s2={ROCKER}", "--out", str(tmp_path / "o")])
    assert code in (1, 2) and "nope.toml" in capsys.readouterr().err
