"""Where the test suite's time goes: tracing, lowering and XLA's compilation per test.

A pytest plugin and its summary. The plugin listens to JAX's monitoring events (the durations JAX
reports for each trace, lowering and backend compilation, with the function's name) and writes, per
pytest process (each xdist worker), ``OUT/suite-time-<worker>.json``: for every test its wall time
from setup to teardown and the seconds of each event, and the seconds per traced or compiled
function. The summary reads those files and prints the totals, the functions that cost most and the
tests that cost most, and writes ``OUT/suite_time.json``.

The plugin also notes each program of jaxclear's store by its key and the ``repr`` of its
arguments' non-array part (the static fields of the mechanism and the settings: what makes two
runs two programs), and the summary counts the distinct programs and how many would remain if
a field's value did not enter them (:data:`IGNORED_FIELDS`: the tolerances, the sample count):
which levers would share programs between tests.

    PYTHONPATH=benchmarks SUITE_TIME_OUT=/tmp/st python -m pytest -n 2 -p suite_time tests/test_engine.py
    python benchmarks/suite_time.py /tmp/st

Compare two commits only in the same time window (one right after the other): a shared 2-core
machine's speed drifts by up to 1.6x within hours (benchmarks/README, "Repeated pieces traced once").
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import time
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_first_result import EVENTS as _SPLIT  # noqa: E402  (the one table of JAX's event names)

#: JAX's monitoring events kept (trace, lower, compile), by the last part of their name.
EVENTS = tuple(name.rsplit("/", 1)[-1] for name in _SPLIT.values())

#: Groups of static fields whose values the summary leaves out in turn, to count the programs
#: that differ only in them.
IGNORED_FIELDS = (("rtol", "atol"), ("n_out",), ("rtol", "atol", "n_out"))

_current = {"test": "<collection>"}
_programs: dict = {}
_tests: dict = collections.defaultdict(lambda: collections.defaultdict(float))
_functions: dict = collections.defaultdict(lambda: collections.defaultdict(float))


def _listener(event: str, duration: float, **kwargs) -> None:
    key = event.rsplit("/", 1)[-1]
    if key not in EVENTS:
        return
    _tests[_current["test"]][key] += duration
    _functions[str(kwargs.get("fun_name"))][key] += duration
    _functions[str(kwargs.get("fun_name"))][key + "_count"] += 1


def _note_programs() -> None:
    """Wrap the store's key function (a measurement's monkeypatch: the store has no hook for it)
    so that every keyed program's non-array arguments are noted by key."""
    from jaxclear.integrate import _programs as store

    keyed = store.program_key

    def noting(name, args):
        found = keyed(name, args)
        if found is not None and found[0] not in _programs:
            _programs[found[0]] = {"name": name.split(":")[0], "static": repr(store._split(args)[2]),
                                   "test": _current["test"]}
        return found

    store.program_key = noting


def pytest_configure(config) -> None:
    from jax import monitoring

    monitoring.register_event_duration_secs_listener(_listener)
    _note_programs()


def pytest_runtest_setup(item) -> None:
    _current["test"] = item.nodeid
    _tests[item.nodeid]["start"] = time.perf_counter()


def pytest_runtest_teardown(item, nextitem) -> None:
    record = _tests[item.nodeid]
    record["wall"] = time.perf_counter() - record.pop("start", time.perf_counter())


def pytest_sessionfinish(session) -> None:
    out = Path(os.environ.get("SUITE_TIME_OUT", "suite-time"))
    out.mkdir(parents=True, exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    if worker == "main" and not _tests:
        return  # xdist's controlling process runs no test
    (out / f"suite-time-{worker}.json").write_text(json.dumps({"tests": _tests, "functions": _functions,
                                                                    "programs": _programs}))


def program_counts(programs: dict) -> dict:
    """The distinct programs noted, and how many remain with each group of
    :data:`IGNORED_FIELDS` left out of their static arguments."""
    counts = {"distinct": len(programs)}
    for fields in IGNORED_FIELDS:
        shapes = set()
        for record in programs.values():
            text = record["static"]
            for field in fields:
                text = re.sub(rf"\b{field}=[^,)\n]*", f"{field}=*", text)
            shapes.add((record["name"], text))
        counts["without " + ", ".join(fields)] = len(shapes)
    return counts


def summarize(folder: Path, top: int = 20) -> dict:
    """Totals, the costliest functions and tests over every ``suite-time-*.json`` in ``folder``."""
    totals, functions, tests, programs = collections.Counter(), collections.Counter(), {}, {}
    for path in sorted(folder.glob("suite-time-*.json")):
        data = json.loads(path.read_text())
        for name, record in data["tests"].items():
            tests[name] = record
            totals["wall"] += record.get("wall", 0.0)
            for key in EVENTS:
                totals[key] += record.get(key, 0.0)
        programs.update(data.get("programs", {}))
        for name, record in data["functions"].items():
            for key in EVENTS:
                if record.get(key):
                    functions[(name, key)] += record[key]
    slowest = sorted(tests.items(), key=lambda kv: -kv[1].get("wall", 0.0))[:top]
    return {"totals_s": dict(totals), "tests": len(tests),
            "functions": [{"function": f, "event": e, "seconds": s} for (f, e), s in functions.most_common(top)],
            "programs": program_counts(programs),
            "slowest": [{"test": n, **{k: r.get(k, 0.0) for k in ("wall", *EVENTS)}} for n, r in slowest]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="the plugin's SUITE_TIME_OUT folder")
    parser.add_argument("--top", type=int, default=20, help="functions and tests listed (default 20)")
    args = parser.parse_args(argv)
    summary = summarize(args.folder, args.top)
    t = summary["totals_s"]
    print(f"{summary['tests']} tests, {t.get('wall', 0):.1f} s of tests (workers' time together): "
          f"trace {t.get(EVENTS[0], 0):.1f} s, lower {t.get(EVENTS[1], 0):.1f} s, XLA compile {t.get(EVENTS[2], 0):.1f} s")
    print("programs of the store: " + ", ".join(f"{k} {v}" for k, v in summary["programs"].items()))
    print(f"\n{'seconds':>8}  {'event':30}  function")
    for row in summary["functions"]:
        print(f"{row['seconds']:8.1f}  {row['event']:30}  {row['function']}")
    print(f"\n{'wall':>7} {'trace':>7} {'lower':>7} {'compile':>7}  test")
    for row in summary["slowest"]:
        print(f"{row['wall']:7.1f} {row[EVENTS[0]]:7.1f} {row[EVENTS[1]]:7.1f} {row[EVENTS[2]]:7.1f}  {row['test']}")
    (args.folder / "suite_time.json").write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
