"""benchmarks/bench_first_result.py: its options, its bookkeeping, and one tiny entry end to end
(``jaxclear presets`` in one fresh process: no compilation, a few seconds). No timing is checked."""

import json

import pytest

import bench_first_result as bench  # benchmarks/ is on sys.path (conftest.py)


def test_options_and_entry_names():
    args = bench.parse_args([])
    assert args.entries == bench.ENTRIES and args.sizes == bench.SIZES and args.modes == ["cold", "warm"]
    assert args.timeout == 600 and args.json.endswith("first_result.json")
    quick = bench.parse_args(["--quick"])
    assert quick.entries == bench.QUICK["entries"] and quick.timeout == 240 and quick.json.endswith("_quick.json")
    args = bench.parse_args(["--entries", "fit,cli:simulate", "--sizes", "none", "--modes", "cold"])
    assert args.entries == ["api:fit", "cli:fit", "cli:simulate"] and args.sizes == [] and args.modes == ["cold"]
    assert bench.parse_args(["--entries", "presets"]).entries == ["cli:presets"]  # a command-line entry only
    for bad in (["--entries", "api:nope"], ["--sizes", "3x3"], ["--sizes", "ten"], ["--modes", "hot"]):
        with pytest.raises(SystemExit):
            bench.parse_args(bad)


def test_union_of_overlapping_spans_and_the_table_row():
    assert bench._union([(0, 2), (1, 3), (5, 6), (5.5, 5.7)]) == pytest.approx(4.0)
    assert bench._union([]) == 0
    row = {"entry": "api:simulate", "mode": "cold", "process_s": 7.0, "import_s": 1.7, "setup_s": 0.2, "status": "ok",
           "first": {"trace_s": 1.4, "lower_s": 0.2, "compile_s": 2.5, "other_s": 0.2, "wall_s": 4.3},
           "steady": {"wall_s": 0.004, "n_trace": 0}, "uncacheable": ["jit__simulate"]}
    line = bench._row(row)
    assert line.split()[:11] == ["api:simulate", "cold", "7.0", "1.7", "0.2", "1.4", "0.2", "2.5", "0.2", "4.3", "0.00"]
    assert "jit__simulate" in line
    assert bench._clean({"a": [float("nan"), 1.0], "b": float("inf")}) == {"a": [None, 1.0], "b": None}


def test_a_tiny_entry_in_fresh_processes(tmp_path):
    out = tmp_path / "first.json"
    result = bench.main(["--entries", "cli:presets", "--sizes", "none", "--timeout", "300", "--json", str(out)])
    rows = json.loads(out.read_text())["rows"]
    assert [(r["entry"], r["mode"], r["status"]) for r in rows] == [("cli:presets", "cold", "ok"),
                                                                      ("cli:presets", "warm", "ok")]
    assert rows[0]["import_s"] > 0 and rows[0]["process_s"] >= rows[0]["import_s"]
    assert rows[0]["first"]["n_compile"] == 0 and rows[0]["uncacheable"] == []  # listing presets compiles nothing
    assert "cli:presets" in result["table"] and result["machine"]["cpus"] >= 1
