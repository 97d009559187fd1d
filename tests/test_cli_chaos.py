"""``jaxclear chaos``: bad input exits 2 with one line and no traceback (fast); a small run of the
benchmark slider-crank writes its tables and figures (slow: the tangent run compiles in minutes)."""

from __future__ import annotations

import csv
import json

import pytest

import jaxclear  # noqa: F401  (switches on float64 first)
from jaxclear.cli import main


@pytest.mark.parametrize("args, message", [
    (["--channel", "joint:7:ecc_x"], r"output channel 'joint:7:ecc_x': '7' is no clearance joint"),
    (["--revolutions", "3", "--transient", "1"], r"too short for a converged estimate"),
    (["--per-revolution", "0"], r"--per-revolution: 0 is outside the allowed range \[1, inf\)"),
    (["--count", "5"], r"count = 5 exponents is outside the allowed range \[1, 4\]"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    import re

    assert main(["chaos", *args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and re.search(message, err[0]), err
    assert "Traceback" not in err[0]


@pytest.mark.slow
def test_chaos_writes_tables_and_figures(tmp_path, capsys):
    """8 revolutions of the benchmark slider-crank at 5000 rpm (1 transient, 1 discarded): all
    four exponents finite, their sum negative (a dissipative contact), every file written."""
    out = tmp_path / "out"
    assert main(["chaos", "--revolutions", "8", "--transient", "1", "--discard", "1", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == 0 and len(summary["exponents"]) == 4 and summary["sum"] < 0
    rows = list(csv.DictReader((out / "exponents.csv").open()))
    assert [int(r["index"]) for r in rows] == [1, 2, 3, 4]
    channels = list(csv.DictReader((out / "channels.csv").open()))
    assert [c["channel"] for c in channels] == ["body:slider:x:vel", "joint:0:ecc_x"]
    for name in ("running.csv", "running.png", "spectrum.png", "poincare.png"):
        assert (out / name).stat().st_size > 0
    assert "lambda_1" in capsys.readouterr().out
