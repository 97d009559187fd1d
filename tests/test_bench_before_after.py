"""benchmarks/bench_before_after.py: its options and its bookkeeping (summary rows, table,
agreement) on hand-made records; nothing is checked out, compiled or timed here."""

import math

import pytest

import bench_before_after as bench  # benchmarks/ is on sys.path (conftest.py)


def test_options():
    a = bench.parse_args([])
    assert a.before == bench.DEFAULT_BEFORE and a.after == "HEAD" and a.rounds >= 2
    assert a.kinds == ("engine", "sweep") and a.child is None
    assert bench.parse_args(["--kinds", "sweep"]).kinds == ("sweep",)
    for bad in (["--rounds", "1"], ["--kinds", "engine,nope"], ["--repeats", "0"]):
        with pytest.raises(SystemExit):
            bench.parse_args(bad)


def _record(kind, version, rnd, scale):
    if kind == "engine":
        return {"kind": kind, "version": version, "round": rnd, "import_s": 2.0, "first_s": 5.0 * scale,
                "compile_s": 4.98 * scale, "steady_median_s": 0.02 * scale, "steady_min_s": 0.018 * scale,
                "short_first_s": 0.1, "short_median_s": 0.003 * scale,
                "slider_x_final": 0.25 * scale, "q_final": [0.1, 0.25 * scale], "steps": 3362, "status": 0}
    if kind == "fit":
        return {"kind": kind, "version": version, "round": rnd, "first_s": 20.0 * scale, "iterations": 7,
                "estimates": {"stiffness": 4e10 * scale, "restitution": 0.9}, "std": {"stiffness": 1e8, "restitution": 1e-3},
                "loss": 1.0}
    return {"kind": kind, "version": version, "round": rnd, "first_s": 9.0, "steady_median_s": 0.5 * scale,
            "runs_per_s": 64 / (0.5 * scale), "columns": {"impacts": [1.0, 2.0], "max_force": [3.0, 4.0 * scale],
                                                          "nan_col": [math.nan, math.nan]}}


def test_summary_table_and_agreement():
    recs = [_record(k, v, r, s) for r, (sb, sa) in enumerate([(1.0, 1.1), (1.2, 1.1)])
            for k in ("engine", "sweep", "fit") for v, s in (("before", sb), ("after", sa))]
    rows = bench.summarize(recs)
    steady = next(r for r in rows if r["kind"] == "engine" and r["key"] == "steady_median_s")
    assert steady["before"] == pytest.approx(22.0) and steady["after"] == pytest.approx(22.0)  # ms, medians
    assert steady["ratio"] == pytest.approx(1.0) and steady["spread_before"] == pytest.approx(4 / 22)
    assert steady["spread_after"] == pytest.approx(0.0)
    table = bench.format_table(rows)
    assert table.splitlines()[0].startswith("| quantity |") and "engine: steady, median" in table
    assert len(table.splitlines()) == 2 + len(bench.ROWS)
    agree = bench.agreement(recs)  # round 0: before scale 1.0, after 1.1
    assert agree["engine"]["slider_x_rel_diff"] == pytest.approx(0.1 / 1.1)
    assert agree["sweep"]["worst_column"] == "max_force" and agree["sweep"]["columns_compared"] == 3
    assert agree["sweep"]["per_column"]["nan_col"] == 0.0 and agree["sweep"]["per_column"]["impacts"] == 0.0
    assert agree["fit"]["iterations"] == [7, 7] and agree["fit"]["estimates_max_rel_diff"] == pytest.approx(0.1 / 1.1)
    assert agree["fit"]["std_max_rel_diff"] == 0.0
