"""The command line, the summary metrics, and the file formats (CSV/JSON out, measurements in)."""

import jaxclear  # noqa: F401  (switches on float64 first)

import csv
import json
import math
import re
import warnings

import numpy as np
import pytest

import jaxclear as jc
from jaxclear import io
from jaxclear.analysis import metrics
from jaxclear.integrate import _runs as runs
from jaxclear.integrate._state import element_states
from jaxclear.cli import build_parser, main
from jaxclear.cli.common import mechanism_overrides
from conftest import assert_strict_json, strict_json
from jaxclear import ParameterError

HEADER = [
    "time_s", "crank_angle_rad", "slider_pos_m", "slider_vel_m_s", "slider_acc_m_s2",
    "ecc_x_m", "ecc_y_m", "penetration_m", "contact_force_n", "friction_force_n",
]


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """One short default run (a quarter crank revolution at 5000 rpm, with plots)."""
    out = tmp_path_factory.mktemp("sim")
    code = main(["simulate", "--revolutions", "0.25", "--no-progress", "--out", str(out)])
    return code, out


def test_simulate_writes_files(simulated):
    code, out = simulated
    assert code == 0
    for name in ("timeseries.csv", "timeseries.nc", "summary.json", "slider_acceleration.png", "orbit.png",
                 "contact_force.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    for name in ("slider_acceleration.png", "orbit.png", "contact_force.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert assert_strict_json(out) == ["summary.json"]


def test_timeseries_csv(simulated):
    _, out = simulated
    with open(out / "timeseries.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == HEADER
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (501, len(HEADER))  # 2000 samples per revolution + 1
    assert np.all(np.isfinite(data))
    assert data[0, 0] == 0.0 and math.isclose(data[-1, 0], 0.25 * 60 / 5000, rel_tol=1e-9)
    assert np.all(np.diff(data[:, 0]) > 0)
    # crank driven at 5000 rpm from 0
    assert np.allclose(data[:, 1], 5000 * 2 * math.pi / 60 * data[:, 0], atol=1e-9)
    assert np.max(data[:, HEADER.index("contact_force_n")]) > 0


def test_timeseries_netcdf_beside_the_csv(simulated):
    """timeseries.nc holds the CSV's columns (equal to the CSV's 12 digits), on the coordinate
    time [s], each with its unit, and the run's settings as global attributes."""
    xr = pytest.importorskip("xarray")
    _, out = simulated
    data = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)
    with xr.open_dataset(out / "timeseries.nc", engine="scipy") as ds:
        np.testing.assert_allclose(ds["time"].values, data[:, 0], rtol=1e-11, atol=0)
        assert ds["time"].attrs["units"] == "s"
        for i, name in enumerate(HEADER[1:], start=1):
            np.testing.assert_allclose(ds[name].values, data[:, i], rtol=1e-11, atol=1e-300)
        units = {n: ds[n].attrs["units"] for n in HEADER[1:]}
        assert units["slider_acc_m_s2"] == "m/s^2" and units["contact_force_n"] == "N" and units["ecc_x_m"] == "m"
        a = ds.attrs
        assert a["mechanism"] == "flores-slider-crank" and a["preset"] == "flores-slider-crank"
        assert a["solver"] == "tsit5" and a["rtol"] == 1e-6 and a["n_out"] == 501 and a["status"] == 0
        assert a["source"].startswith("jaxclear") and a["ideal"] == 0


def test_timeseries_dataset_of_channel_columns():
    """A channel column "NAME [UNIT]" becomes the variable NAME with separators as "_", its
    channel name as long name; None and tables as attributes become text."""
    t = np.linspace(0.0, 1.0, 3)
    ds = io.timeseries_dataset({"time_s": t, "body:rocker:phi:acc [rad/s^2]": t**2},
                               {"mechanism_file": None, "law_options": {"a": 1}, "gravity": (0.0, -9.81)})
    v = ds["body_rocker_phi_acc"]
    assert v.attrs == {"units": "rad/s^2", "long_name": "body:rocker:phi:acc"}
    assert ds.attrs["mechanism_file"] == "none" and ds.attrs["law_options"] == '{"a": 1}'
    np.testing.assert_array_equal(ds.attrs["gravity"], [0.0, -9.81])


def test_summary(simulated):
    _, out = simulated
    s = json.loads((out / "summary.json").read_text())
    for key in metrics.SUMMARY_KEYS:
        assert key in s, key
    numeric = [
        "t_end_s", "peak_contact_force_n", "peak_friction_force_n", "max_penetration_m", "peak_slider_acc_m_s2",
        "max_constraint_drift", "fraction_free_flight", "fraction_impact", "fraction_continuous_contact",
        "energy_dissipated_j", "wall_time_s",
    ]
    for key in numeric:
        assert isinstance(s[key], (int, float)) and math.isfinite(s[key]), (key, s[key])
    assert s["status"] == 0 and s["status_message"] == "ok"
    assert s["impacts"] >= 1 and s["impacts_per_joint"] == [s["impacts"]]
    assert s["peak_contact_force_n"] > 0 and s["max_penetration_m"] > 0
    assert s["energy_dissipated_j"] > 0  # c_r = 0.9 < 1 dissipates
    fractions = s["fraction_free_flight"] + s["fraction_impact"] + s["fraction_continuous_contact"]
    assert math.isclose(fractions, 1.0, rel_tol=1e-12)
    assert s["num_steps"] == s["num_accepted_steps"] + s["num_rejected_steps"]
    assert s["wall_time_s"] > 0
    # the clearance joint raises the slider's peak acceleration above the ideal joint's
    assert s["peak_slider_acc_m_s2"] > s["ideal_peak_slider_acc_m_s2"] > 0


@pytest.mark.parametrize(
    "args, name",
    [
        (["--clearance", "-1"], "clearance"),
        (["--restitution", "1.5"], "restitution"),
        (["--preset", "nope"], "preset"),
        (["--model", "nope"], "contact law"),
        (["--solver", "nope"], "solver"),
        (["--rtol", "2"], "rtol"),
        (["--revolutions", "0"], "--revolutions"),
        (["--t-end", "-1"], "--t-end"),
        (["--friction", "-0.1"], "friction"),
    ],
)
def test_bad_input_exits_2(args, name, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", *args, "--no-progress", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and name in err
    assert "Traceback" not in err
    assert not out.exists()  # nothing written on bad input


def test_usage_errors_exit_2(capsys):
    assert main(["simulate", "--clearance", "abc"]) == 2
    assert "--clearance" in capsys.readouterr().err
    assert main(["no-such-command"]) == 2
    assert main([]) == 2


@pytest.mark.parametrize("value", ["-0.5e-3", "-5E+2", "-1e3", "-.5", "-2", "-inf"])
def test_negative_numbers_are_values_in_any_notation(value, capsys):
    """A negative number after a flag is its value (argparse alone reads ``-0.5e-3`` as a flag and
    says "expected one argument"): the flag's range check names it, in every command's parser."""
    for command in (["simulate"], ["fit", "rec.csv"], ["wear"], ["animate"]):
        assert main([*command, "--clearance", value]) == 2
        err = capsys.readouterr().err
        assert f"argument --clearance: {value} is outside the allowed range (0, inf)" in err, err
    args = build_parser().parse_args(["fit", "rec.csv", "--sensor-bias", "-0.5e-3", "--speed-rpm", "-3E3"])
    assert args.sensor_bias == -0.5e-3 and args.speed_rpm == -3000.0
    assert main(["simulate", "-x"]) == 2  # a dash and a letter is still an (unknown) option
    assert "unrecognized arguments: -x" in capsys.readouterr().err


def test_help(capsys):
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    assert "simulate" in text and "presets" in text
    assert main(["simulate", "--help"]) == 0
    text = capsys.readouterr().out
    for option, unit in [("--clearance", "[m]"), ("--speed-rpm", "[rev/min]"), ("--t-end", "[s]"),
                         ("--rtol", "1e-6"), ("--atol", "1e-9"), ("--revolutions", "default: 3"),
                         ("--out", "./jaxclear-out"), ("--model", "lankarani-nikravesh")]:
        assert option in text and unit in text, option


def _stated_defaults():
    """(command, option, argparse default, the default its help states) of every option of
    every command whose help ends with "(default: ...)"."""
    import argparse
    import re

    from jaxclear.cli.common import Formatter

    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    for name, sub in commands.items():
        for action in sub._actions:
            m = re.search(r"\(default: ([^)]*)\)\s*$", Formatter(sub.prog)._expand_help(action) if action.help else "")
            if m:
                yield name, action.option_strings, action.default, m.group(1)


def test_help_states_the_defaults_the_parser_uses():
    """Every option's help says the default the parser applies (``jaxclear wear --help`` said
    lankarani-nikravesh and arc while wear runs the hybrid law at fixed points)."""
    wrong = []
    for command, option, default, stated in _stated_defaults():
        if default is None or isinstance(default, bool) or default == []:
            continue  # no value: the help says what the command does then
        same = stated == str(default) or stated.split(" ")[0] == str(default)
        try:
            same = same or float(stated.split(" ")[0]) == float(default)
        except ValueError:
            pass
        if not same:
            wrong.append(f"{command} {option}: default {default!r}, help says {stated!r}")
    assert not wrong, wrong
    stated = {(c, o[0]): s for c, o, _, s in _stated_defaults() if o}
    assert stated["wear", "--model"] == "hybrid" and stated["wear", "--placement"] == "fixed"
    assert stated["simulate", "--model"] == "lankarani-nikravesh" and stated["simulate", "--placement"] == "arc"


def test_hybrid_options_name_their_flags(tmp_path, capsys):
    """Hybrid-model options without --model hybrid: the message names the flags given."""
    out = tmp_path / "out"
    assert main(["simulate", "--elements", "3", "--gauss-points", "2", "--no-progress", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --elements, --gauss-points apply only to --model hybrid"), err
    assert not out.exists()
    # the parser accepts what the hybrid law accepts (>= 1) and maps the flags to its options
    args = build_parser().parse_args(["simulate", "--model", "hybrid", "--elements", "1", "--gauss-points", "1"])
    assert mechanism_overrides(args)["law_options"] == {"n_elements": 1, "n_gauss": 1}
    assert main(["simulate", "--model", "hybrid", "--elements", "0"]) == 2
    assert "--elements" in capsys.readouterr().err


def test_values_from_the_user_are_written_without_float_noise():
    """3 revolutions at 5000 rpm: t_end = 0.036000000000000004 s and back 3.0000000000000004
    revolutions; summary.json's inputs say 0.036 and 3 (as_typed: 15 significant digits, the
    float64's decimal precision); a swept linear range holds the typed decimals, and runs.csv
    writes t_end_s the same way."""
    from jaxclear._numbers import as_typed
    from jaxclear.cli.simulate import inputs
    from jaxclear.sweep.store import _fmt
    from jaxclear.sweep.values import _range

    mech = jc.preset("flores-slider-crank")
    t_end = float(runs.revolution_settings(mech, 3.0).t_end)
    revolutions = runs.revolutions_of(mech, t_end)
    assert (t_end, revolutions) == (0.036000000000000004, 3.0000000000000004)  # the noise itself
    args = build_parser().parse_args(["simulate", "--revolutions", "3"])
    got = inputs(args, None, {}, t_end, revolutions, 6001)
    assert got["t_end_s"] == 0.036 and got["revolutions"] == 3.0 and json.dumps(got).count("000000") == 0
    assert _range("r", {"start": 0.1, "stop": 0.9, "num": 9}).tolist() == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
    assert _range("k", {"start": 1e6, "stop": 1e9, "num": 4, "spacing": "log"}).tolist() == [1e6, 1e7, 1e8, 1e9]
    assert _fmt("t_end_s", t_end) == "0.036" and _fmt("peak_contact_force_n", 0.1 + 0.2) == repr(0.1 + 0.2)
    # the helper: 15 digits exactly, computed digits beyond them dropped (< 5e-16 relative), others untouched
    rng = np.random.default_rng(0)
    for x in rng.uniform(-1e3, 1e3, 200) * 10.0 ** rng.integers(-12, 12, 200):
        typed = float(f"{x:.15g}")
        assert as_typed(typed) == typed and as_typed(typed * (1 + 2.2e-16)) == typed
        assert abs(as_typed(x) / x - 1) < 5e-15
    assert as_typed(None) is None and as_typed(7) == 7 and math.isnan(as_typed(float("nan")))
    assert as_typed(np.int64(5)) == 5 and isinstance(as_typed(np.int64(5)), int)
    assert as_typed([0.1 + 0.2, None]) == [0.3, None] and as_typed(np.array([[0.1 + 0.2]])).tolist() == [[0.3]]


def test_revolution_settings():
    """Revolutions -> t_end and samples (2000 per revolution + 1, at least 101); t_end instead."""
    mech = jc.preset("flores-slider-crank")  # 5000 rpm: one revolution in 12 ms
    period = 60.0 / 5000.0
    s = runs.revolution_settings(mech, 0.25, solver="bosh3", rtol=1e-5)
    assert math.isclose(float(s.t_end), 0.25 * period, rel_tol=1e-14) and s.n_out == 501
    assert s.solver == jc.SOLVERS["bosh3"]() and s.rtol == 1e-5  # the named solver, as an instance
    assert runs.revolution_settings(mech).n_out == 6001  # 3 revolutions by default
    assert runs.revolution_settings(mech, 0.01).n_out == 101  # at least 100 + 1
    s = runs.revolution_settings(mech, t_end=0.5 * period)  # t_end wins over revolutions
    assert float(s.t_end) == 0.5 * period and s.n_out == 1001
    assert runs.revolution_settings(mech, 2.0, n_out=7).n_out == 7
    assert math.isclose(runs.revolutions_of(mech, 3 * period), 3.0, rel_tol=1e-14)
    assert runs.revolutions_of(jc.preset("flores-slider-crank", speed_rpm=0.0), 1.0) is None
    assert runs.revolution_settings(jc.preset("flores-slider-crank", speed_rpm=0.0), t_end=1.0).n_out == 2001
    with pytest.raises(ParameterError, match="revolutions"):
        runs.revolution_settings(mech, 0.0)
    with pytest.raises(ParameterError, match="t_end"):
        runs.revolution_settings(mech, t_end=-1.0)


def test_presets_command(capsys):
    """Every preset with its whole summary as plain text: no reST role, literal or emphasis
    marks (the docstrings' ``:func:`flores_slider_crank``` is the preset's name)."""
    assert main(["presets"]) == 0
    text = capsys.readouterr().out
    for name in jc.preset_names():
        assert name in text
    assert not re.search(r":[a-z]+:`|``|`", text), text
    assert "of 'flores-slider-crank' whose" in " ".join(text.split()) and "..." not in text


def test_plain_text_of_rest():
    from jaxclear.cli.common import plain_text

    rst = ("See :func:`~jaxclear.presets.flores_slider_crank` and :class:`jaxclear.PinSlotJoint`, "
           ":math:`F = K\\delta^n`, ``law=\"hybrid\"``,\n   *emphasis* and **strong**; 2 * 3 * 4 stays.")
    assert plain_text(rst, {"flores_slider_crank": "'flores-slider-crank'"}) == (
        "See 'flores-slider-crank' and PinSlotJoint, F = K\\delta^n, law=\"hybrid\", emphasis and strong; "
        "2 * 3 * 4 stays.")


# --------------------------------------------------------------------------------------
# metrics and io without the command line
# --------------------------------------------------------------------------------------


def _fake_solution(mech, n=5):
    """A Solution with the right shapes for a mechanism (values arbitrary but finite)."""
    k = len(mech.clearance_joints)
    nq = mech.n_coordinates
    t = np.linspace(0.0, 1e-3, n)
    z = np.zeros((n, k))
    from jaxclear.elements import ContactMemory

    # memory at t = 0 is the initial one (no onsets, no work); 5 onsets and 1 J dissipated by the first step
    onsets = np.concatenate([z[:1], np.full((n - 1, k), 5.0)])
    mem = ContactMemory(z, np.full((n, k), -1e9), onsets, -onsets / 5.0, z, z)
    return jc.Solution(
        ts=t, q=np.tile(np.arange(nq, dtype=float), (n, 1)), qdot=np.zeros((n, nq)),
        qddot=np.outer(np.sin(np.arange(n)), np.ones(nq)), reactions=np.zeros((n, mech.n_constraints)),
        drift=np.full(n, 1e-9), ecc=np.zeros((n, k, 2)), penetration=z - 1e-4, normal_force=z,
        friction_force=z, mode=np.zeros((n, k), int),
        element_states=element_states(mech, mem),
        num_steps=np.asarray(7),
        num_accepted_steps=np.asarray(5), num_rejected_steps=np.asarray(2), status=np.asarray(0),
    )


def test_summary_ideal_mechanism_is_json():
    mech = jc.preset("flores-slider-crank", ideal=True)
    s = metrics.summary(mech, _fake_solution(mech))
    assert list(s) == list(metrics.SUMMARY_KEYS)
    assert s["impacts"] is None and s["peak_contact_force_n"] is None and s["fraction_impact"] is None
    assert s["peak_slider_acc_m_s2"] == pytest.approx(np.max(np.abs(np.sin(np.arange(5)))))
    json.dumps(s)


def test_summary_no_contact():
    mech = jc.preset("four-bar")
    s = metrics.summary(mech, _fake_solution(mech), wall_time_s=1.5)
    assert s["peak_slider_acc_m_s2"] is None  # no slider
    assert s["max_penetration_m"] == 0.0  # gap everywhere
    assert s["impacts"] == 5 and s["energy_dissipated_j"] == 1.0 and s["fraction_free_flight"] == 1.0
    assert s["wall_time_s"] == 1.5
    json.dumps(s)


def test_csv_columns_depend_on_roles():
    assert io.timeseries_columns(jc.preset("flores-slider-crank")) == HEADER
    assert io.timeseries_columns(jc.preset("flores-slider-crank", ideal=True)) == HEADER[:5]
    assert io.timeseries_columns(jc.preset("four-bar")) == ["time_s", "crank_angle_rad"] + HEADER[5:]


def test_write_timeseries_matches_columns(tmp_path):
    mech = jc.preset("four-bar")
    io.write_timeseries_csv(tmp_path / "t.csv", mech, _fake_solution(mech))
    with open(tmp_path / "t.csv") as f:
        assert f.readline().strip().split(",") == io.timeseries_columns(mech)


def test_write_json_nonfinite(tmp_path):
    """NaN and infinities of every kind (float, NumPy and JAX scalars and arrays) are written as
    null: strict JSON, not the bare NaN of Python's json module."""
    import jax.numpy as jnp

    io.write_json(tmp_path / "a.json", {"a": float("nan"), "b": np.arange(3), "c": np.float64(2.5),
                                        "d": -math.inf, "e": np.float32("inf"), "f": jnp.asarray([1.0, jnp.nan]),
                                        "g": jnp.float64(jnp.inf), "h": (np.int64(2), np.bool_(True))})
    assert strict_json((tmp_path / "a.json").read_text()) == {
        "a": None, "b": [0, 1, 2], "c": 2.5, "d": None, "e": None, "f": [1.0, None], "g": None, "h": [2, True]}


# --------------------------------------------------------------------------------------
# read_measurements (the measured-data format of docs/theory/fit.md)
# --------------------------------------------------------------------------------------


def _write(tmp_path, text, name="m.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_read_measurements_good(tmp_path):
    path = _write(
        tmp_path,
        "# rig: flores-2011\n# speed_rpm = 200\n# a free comment\n"
        "time_s,slider_acc_m_s2,crank_angle_rad,slider_pos_m\n"
        "0.0,1.5,0.0,0.35\n0.001,-2.0,0.02,0.349\n\n0.002,3e1,0.04,0.348\n",
    )
    m = io.read_measurements(path)
    assert len(m) == 3
    np.testing.assert_array_equal(m.time_s, [0.0, 0.001, 0.002])
    np.testing.assert_array_equal(m.slider_acc_m_s2, [1.5, -2.0, 30.0])
    np.testing.assert_array_equal(m.crank_angle_rad, [0.0, 0.02, 0.04])
    assert m.slider_vel_m_s is None
    assert m.metadata["rig"] == "flores-2011" and m.metadata["speed_rpm"] == "200"
    assert m.metadata["comments"] == ["a free comment"]
    assert m.columns == ["time_s", "slider_acc_m_s2", "crank_angle_rad", "slider_pos_m"]


def test_read_measurements_minimal_and_unknown_column(tmp_path):
    path = _write(tmp_path, "slider_acc_m_s2, temperature_c ,time_s\n1,20,0\n2,21,0.5\n")
    with pytest.warns(UserWarning, match="temperature_c"):
        m = io.read_measurements(path)
    np.testing.assert_array_equal(m.time_s, [0.0, 0.5])
    np.testing.assert_array_equal(m.slider_acc_m_s2, [1.0, 2.0])
    assert m.crank_angle_rad is None and m.metadata == {}


@pytest.mark.parametrize(
    "text, fragments",
    [
        ("# meta\ntime_s,slider_pos_m\n0,1\n1,2\n", ["line 2", "slider_acc_m_s2"]),
        ("time_s,slider_acc_m_s2\n0,1\n0.1,abc\n", ["line 3", "'slider_acc_m_s2'", "abc"]),
        ("time_s,slider_acc_m_s2\n0,1\nx,2\n", ["line 3", "'time_s'", "non-numeric"]),
        ("time_s,slider_acc_m_s2\n0,1\n0.1,\n", ["line 3", "'slider_acc_m_s2'"]),
        ("time_s,slider_acc_m_s2\n0,1\nnan,2\n", ["line 3", "'time_s'", "non-finite"]),
        ("time_s,slider_acc_m_s2\n0,1\n0.1,inf\n", ["line 3", "'slider_acc_m_s2'", "non-finite"]),
        ("#c\ntime_s,slider_acc_m_s2\n0,1\n0.2,2\n0.1,3\n", ["line 5", "'time_s'", "increasing"]),
        ("time_s,slider_acc_m_s2\n0,1\n0,2\n", ["line 3", "'time_s'", "increasing"]),
        ("time_s,slider_acc_m_s2\n0,1\n0.1,2,3\n", ["line 3", "3 fields"]),
        ("time_s,slider_acc_m_s2,time_s\n0,1,0\n", ["line 1", "twice"]),
        ("# only comments\n", ["no header"]),
        ("time_s,slider_acc_m_s2\n0,1\n", ["at least 2"]),
    ],
)
def test_read_measurements_bad(tmp_path, text, fragments):
    path = _write(tmp_path, text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError) as info:
            io.read_measurements(path)
    msg = str(info.value)
    assert str(path) in msg
    for fragment in fragments:
        assert fragment in msg, (fragment, msg)


def test_read_measurements_missing_file(tmp_path):
    with pytest.raises(ParameterError, match="cannot read"):
        io.read_measurements(tmp_path / "absent.csv")
