"""``jaxclear chaos``: bad input exits 2 with one line and no traceback (fast); a small run of the
benchmark slider-crank writes its tables and figures (slow: the tangent run compiles in minutes)."""

from __future__ import annotations

import csv
import json
import math

import pytest

import jaxclear  # noqa: F401  (switches on float64 first)
from jaxclear.cli import main
from conftest import assert_strict_json


@pytest.mark.parametrize("args, message", [
    (["--channel", "joint:7:ecc_x"], r"output channel 'joint:7:ecc_x': '7' is no clearance joint"),
    (["--revolutions", "3", "--transient", "1"],
     r"too short for a converged estimate: \(--revolutions 3 - --transient 1\) x --per-revolution 1 = 2 "
     r"interval\(s\), less --discard 4, leaves -2 counted renormalisation interval\(s\), outside the allowed range "
     r"\[4, inf\); raise --revolutions to 9 or more, or --per-revolution$"),
    (["--t-end", "0.036", "--transient", "0", "--discard", "0"],  # 3 revolutions at 5000 rpm
     r"\(--t-end 0.036 s = 3 revolutions - --transient 0\) .* leaves 3 counted .*raise --t-end to 0.048 s "
     r"\(4 revolutions\) or more"),
    (["--revolutions", "3"], r"--transient = 4 revolution\(s\) is outside the allowed range \[0, 3\) \(the run, "
                             r"--revolutions\); raise --revolutions or lower --transient$"),
    (["--per-revolution", "0"], r"--per-revolution: 0 is outside the allowed range \[1, inf\)"),
    (["--count", "5"], r"--count = 5 exponents is outside the allowed range \[1, 4\]"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    import re

    assert main(["chaos", *args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and re.search(message, err[0]), err
    assert "Traceback" not in err[0]
    assert not (tmp_path / "out").exists()  # checked before anything ran


def test_defaults_leave_the_zero_one_test_enough_samples():
    """The defaults pass every check (a converged estimate needs 4 counted intervals) and leave
    the 0-1 test its 100 samples at 2 a revolution: (60 - 4) x 2 = 112 (no compilation here)."""
    from jaxclear.chaos.signals import ZERO_ONE_MIN_SAMPLES
    from jaxclear.cli import build_parser
    from jaxclear.cli.chaos import check_run
    from jaxclear.cli.simulate import load, settings_from

    args = build_parser().parse_args(["chaos"])
    assert (args.revolutions, args.transient, args.discard, args.per_revolution) == (60, 4, 4, 1)
    mech, _, _ = load(args)
    assert check_run(args, mech, settings_from(args, mech)) == 0
    assert (args.revolutions - args.transient) * 2 >= ZERO_ONE_MIN_SAMPLES
    short = build_parser().parse_args(["chaos", "--revolutions", "40"])
    assert check_run(short, mech, settings_from(short, mech)) == 54  # the 0-1 test would need 4 + 50


@pytest.mark.slow  # 37 s cold, 13 s with the compilation cache, on 2 loaded cores
def test_default_run_writes_the_spectrum_and_runs_the_zero_one_test(tmp_path, capsys):
    """``jaxclear chaos`` with its defaults: 56 revolutions with all four tangents (before the
    memory's records were dropped at renormalisation, their tangents overflowed after ~43
    one-revolution intervals), every exponent finite, the 0-1 test run on every channel."""
    out = tmp_path / "out"
    assert main(["chaos", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == 0 and summary["intervals_counted"] == 52
    assert all(math.isfinite(v) for v in summary["exponents"]) and summary["sum"] < 0
    for name, c in summary["channels"].items():
        assert 0.0 <= c["zero_one_K"] <= 1.0 and c["zero_one_on"] == "2 samples a revolution", name
    assert "0-1 test not run" not in capsys.readouterr().out


@pytest.mark.slow
def test_chaos_writes_tables_and_figures(tmp_path, capsys):
    """8 revolutions of the benchmark slider-crank at 5000 rpm (1 transient, 1 discarded): all
    four exponents finite, their sum negative (a dissipative contact), every file written."""
    out = tmp_path / "out"
    assert main(["chaos", "--revolutions", "8", "--transient", "1", "--discard", "1", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == 0 and len(summary["exponents"]) == 4 and summary["sum"] < 0
    assert assert_strict_json(out) == ["summary.json"]
    rows = list(csv.DictReader((out / "exponents.csv").open()))
    assert [int(r["index"]) for r in rows] == [1, 2, 3, 4]
    channels = list(csv.DictReader((out / "channels.csv").open()))
    assert [c["channel"] for c in channels] == ["body:slider:x:vel", "joint:0:ecc_x"]
    for name in ("running.csv", "running.png", "spectrum.png", "poincare.png"):
        assert (out / name).stat().st_size > 0
    assert "lambda_1" in capsys.readouterr().out
