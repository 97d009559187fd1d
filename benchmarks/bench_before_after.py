#!/usr/bin/env python
"""Before and after: the engine's steady-state time and the sweep's throughput of two commits,
measured in one run on one machine, interleaved (issue 40: "unchanged", shown, not assumed).

Each commit is checked out into a ``git worktree`` of a temporary folder (removed at the end).
Every measurement runs in a fresh Python process whose ``PYTHONPATH`` is that worktree, so each
imports its own ``jaxclear`` (the child checks ``jaxclear.__file__``), with its own empty
``JAXCLEAR_CACHE_DIR`` (a new folder for every child: no version reads the other's programs, nor
its own from an earlier round, so every first call compiles cold). The rounds alternate: engine
before, engine after, sweep before, sweep after, then again, ``--rounds`` times, so that a drift
of the machine's load shows as a spread over the rounds rather than as a difference.

Only public names that both versions have are used:

* **engine**: ``jc.simulate(jc.preset("flores-slider-crank"), jc.settings(t_end, n_out=N))``
  (Settings' defaults: Tsit5, rtol 1e-6, atol 1e-9; 5000 rpm, ``--revolutions`` crank
  revolutions). First call = tracing + compilation + one run; then ``--warmup`` calls discarded,
  then the median (and minimum) of ``--repeats`` calls, each ``jax.block_until_ready``-ed;
  compile = first - steady median. Then the same program (``t_end`` is an array leaf: no new
  compilation) over ``--short-revolutions``: its steady time is mostly the fixed cost of a call
  (checks, dispatch, status), which the long run's time hides.
* **sweep**: ``jaxclear.sweep.run_sweep(SweepConfig(list={clearance, restitution}, ...))`` with
  ``ideal_reference=False``, ``chunk_size=--chunk``, one device, no progress bar, solver and
  tolerances left at the defaults (the same in both: Tsit5, 1e-6, 1e-9, 200 000 steps; the after
  version deprecated ``SweepConfig(solver=, rtol=, ...)``, so none is given). The first sweep
  (compilation + runs + files) goes to one folder, then ``--sweep-repeats`` sweeps of the same
  configuration into fresh folders (the compiled chunk function reused in the process:
  ``sweep.TRACES`` is recorded); throughput = runs / median wall time of those, files included
  (``runs.csv``, chunk files, ``manifest.json``, ``results.nc``): what a user's sweep does.

Agreement: the engine run's final slider position and step count, and every numeric column of
the sweep's ``runs.csv`` that both versions write, before against after (largest relative
difference).

Run from the repository root (about 2 minutes on 2 shared cores with the defaults; the README's
run, 5 rounds with 128 sweep runs, took 3 minutes)::

    python benchmarks/bench_before_after.py                      # parent of the first issue-40 commit vs HEAD
    python benchmarks/bench_before_after.py --rounds 5 --sweep-runs 128 --chunk 16 --repeats 30
    python benchmarks/bench_before_after.py --before cb7ace5~1 --after cb7ace5 --kinds engine

It prints a table and writes ``benchmarks/results/before_after.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: 1f4f1a4 (2026-11-29 06:41, "force elements: bodies() once on AbstractConnector"): the parent of
#: ccff543, the first commit of issue 40's spine ("one JSON writer and one TOML reader (issue 40,
#: item 5)"); the Settings of strategies, lane runner, parameter registry, result protocol and
#: checkpoint protocol all came after it.
DEFAULT_BEFORE = "1f4f1a4"
PRESET = "flores-slider-crank"
RPM = 5000.0
KINDS = ("engine", "sweep", "fit")

#: (key in a child's record, label, unit, scale): the rows of the table, in order
ROWS = (
    ("engine", "import_s", "engine: import jax + jaxclear", "s", 1.0),
    ("engine", "first_s", "engine: first call (trace + compile + run)", "s", 1.0),
    ("engine", "compile_s", "engine: compile (first - steady)", "s", 1.0),
    ("engine", "steady_median_s", "engine: steady, median", "ms", 1e3),
    ("engine", "steady_min_s", "engine: steady, min", "ms", 1e3),
    ("engine", "short_first_s", "engine: short run, first call (same program)", "s", 1.0),
    ("engine", "short_median_s", "engine: short run, steady median", "ms", 1e3),
    ("sweep", "first_s", "sweep: first run_sweep (compile + runs + files)", "s", 1.0),
    ("sweep", "steady_median_s", "sweep: steady run_sweep, median", "s", 1.0),
    ("sweep", "runs_per_s", "sweep: throughput, steady", "runs/s", 1.0),
    ("fit", "first_s", "fit: the README's fit, first (compile included)", "s", 1.0),
    ("fit", "iterations", "fit: iterations", "", 1.0),
)


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--before", default=DEFAULT_BEFORE, help=f"the commit before (default {DEFAULT_BEFORE})")
    p.add_argument("--after", default="HEAD", help="the commit after (default HEAD)")
    p.add_argument("--rounds", type=int, default=3, help="rounds of before/after (>= 2; default 3)")
    p.add_argument("--revolutions", type=float, default=3.0, help="engine: crank revolutions (default 3)")
    p.add_argument("--n-out", type=int, default=1001, help="engine: output samples (default 1001)")
    p.add_argument("--short-revolutions", type=float, default=0.2,
                   help="engine: revolutions of the short run, the fixed cost of a call (default 0.2)")
    p.add_argument("--warmup", type=int, default=2, help="engine: calls discarded after the first (default 2)")
    p.add_argument("--repeats", type=int, default=30, help="engine: timed steady calls (default 30)")
    p.add_argument("--sweep-runs", type=int, default=64, help="sweep: runs (default 64)")
    p.add_argument("--sweep-revolutions", type=float, default=1.0, help="sweep: revolutions per run (default 1)")
    p.add_argument("--samples", type=int, default=200, help="sweep: samples per revolution (default 200)")
    p.add_argument("--chunk", type=int, default=16, help="sweep: runs per chunk (default 16)")
    p.add_argument("--sweep-repeats", type=int, default=3, help="sweep: timed steady sweeps (default 3)")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds a child may take (default 600)")
    p.add_argument("--kinds", default="engine,sweep", help="what to measure, among engine, sweep and fit (default engine,sweep)")
    p.add_argument("--json", default=str(HERE / "results" / "before_after.json"), help="JSON output ('' for none)")
    p.add_argument("--keep", action="store_true", help="keep the temporary folder (worktrees, caches, sweeps)")
    p.add_argument("--child", choices=KINDS, help=argparse.SUPPRESS)
    p.add_argument("--child-out", help=argparse.SUPPRESS)
    p.add_argument("--child-dir", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    kinds = tuple(k.strip() for k in args.kinds.split(",") if k.strip())
    bad = [k for k in kinds if k not in KINDS]
    if bad or not kinds:
        p.error(f"--kinds: {','.join(bad) or 'nothing'}; choose among {','.join(KINDS)}")
    args.kinds = kinds
    if args.child is None and args.rounds < 2:
        p.error("--rounds must be at least 2 (a spread needs two rounds)")
    if args.repeats < 1 or args.sweep_repeats < 1 or args.sweep_runs < 1 or args.chunk < 1:
        p.error("--repeats, --sweep-repeats, --sweep-runs and --chunk must be at least 1")
    return args


# ----------------------------------------------------------------------------------------------
# the children (each in its own process, importing the worktree's jaxclear)
# ----------------------------------------------------------------------------------------------
def sweep_values(n: int):
    """``n`` (clearance [m], restitution) pairs over 0.25-1.0 mm x 0.5-0.95, fixed seed."""
    import numpy as np

    rng = np.random.default_rng(20261121)
    return rng.uniform(0.25e-3, 1.0e-3, n).tolist(), rng.uniform(0.5, 0.95, n).tolist()


def _imported(t0: float) -> tuple:
    import jax

    import jaxclear as jc

    tree = os.environ.get("PYTHONPATH", "").split(os.pathsep)[0]
    where = os.path.realpath(jc.__file__)
    if not tree or not where.startswith(os.path.realpath(tree) + os.sep):
        raise RuntimeError(f"jaxclear imported from {where}, not from the worktree {tree!r}")
    # recorded relative to the worktree (checked above): no temporary path of this machine in the JSON
    return jax, jc, time.perf_counter() - t0, os.path.relpath(where, os.path.realpath(tree))


def _timed_calls(jax, jc, mech, s, args):
    """``(first solution, first call [s], the steady calls [s])``: one call, ``args.warmup``
    discarded, ``args.repeats`` timed, each ``jax.block_until_ready``-ed."""
    t = time.perf_counter()
    sol = jax.block_until_ready(jc.simulate(mech, s))
    first = time.perf_counter() - t
    for _ in range(args.warmup):
        jax.block_until_ready(jc.simulate(mech, s))
    times = []
    for _ in range(args.repeats):
        t = time.perf_counter()
        jax.block_until_ready(jc.simulate(mech, s))
        times.append(time.perf_counter() - t)
    return sol, first, times


def child_engine(args) -> dict:
    t0 = time.perf_counter()
    jax, jc, import_s, where = _imported(t0)
    import numpy as np

    mech = jc.preset(PRESET)
    s = jc.settings(args.revolutions * 60.0 / RPM, n_out=args.n_out)
    sol, first, times = _timed_calls(jax, jc, mech, s, args)
    # the same program (t_end is an array leaf) over a short run: the fixed cost of a call
    short = jc.settings(args.short_revolutions * 60.0 / RPM, n_out=args.n_out)
    sol_short, short_first, short_times = _timed_calls(jax, jc, mech, short, args)
    names = [getattr(b, "name", "") for b in mech.bodies]
    i = names.index("slider") if "slider" in names else len(names) - 1
    q = np.asarray(sol.q)
    steady = statistics.median(times)
    return {"jaxclear": where, "import_s": import_s, "first_s": first, "compile_s": first - steady,
            "steady_median_s": steady, "steady_min_s": min(times), "steady_s": times,
            "short_first_s": short_first, "short_median_s": statistics.median(short_times),
            "short_s": short_times, "short_steps": int(sol_short.num_steps),
            "status": int(sol.status), "steps": int(sol.num_steps), "slider_body": names[i],
            "slider_x_final": float(q[-1, 3 * i]), "q_final": q[-1].tolist()}


def _read_csv(path: Path) -> dict:
    """Numeric columns of a ``runs.csv`` as lists of floats (a column with text is left out)."""
    import csv

    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    cols = {}
    for key in rows[0] if rows else ():
        try:
            cols[key] = [float(r[key]) if r[key] not in ("", None) else float("nan") for r in rows]
        except ValueError:
            continue
    return cols


def child_sweep(args) -> dict:
    t0 = time.perf_counter()
    jax, jc, import_s, where = _imported(t0)
    from jaxclear import sweep

    work = Path(args.child_dir)
    clearance, restitution = sweep_values(args.sweep_runs)
    t = time.perf_counter()
    cfg = sweep.SweepConfig(list={"clearance": clearance, "restitution": restitution}, preset=PRESET,
                            revolutions=args.sweep_revolutions, samples_per_revolution=args.samples,
                            ideal_reference=False, chunk_size=args.chunk, devices=1, progress=False,
                            out=str(work / "sweep-0"))
    config_s = time.perf_counter() - t
    t = time.perf_counter()
    sweep.run_sweep(cfg, out=str(work / "sweep-0"))
    first = time.perf_counter() - t
    traces_first = int(sweep.TRACES.value)
    walls = []
    for k in range(args.sweep_repeats):
        t = time.perf_counter()
        sweep.run_sweep(cfg, out=str(work / f"sweep-{k + 1}"))
        walls.append(time.perf_counter() - t)
    steady = statistics.median(walls)
    return {"jaxclear": where, "import_s": import_s, "config_s": config_s, "first_s": first,
            "steady_median_s": steady, "steady_s": walls, "runs": args.sweep_runs,
            "runs_per_s": args.sweep_runs / steady, "traces_after_first": traces_first,
            "traces_after_all": int(sweep.TRACES.value), "columns": _read_csv(work / "sweep-0" / "runs.csv")}


def child_fit(args) -> dict:
    """The fit of the README (both commits have it): a record of the benchmark from start-up,
    3.2 ms at 200 kHz through a 20 kHz accelerometer with 20 dB noise (``jc.synthetic_record``,
    seed 0), stiffness and restitution from 2e11 and 0.6; its estimates, std and iterations."""
    t0 = time.perf_counter()
    jax, jc, import_s, where = _imported(t0)
    work = Path(args.child_dir)
    mech = jc.preset(PRESET)
    jc.synthetic_record(mech, 3.2e-3, 200e3, jc.Accelerometer(20e3), path=str(work / "data.csv"))
    t = time.perf_counter()
    res = jc.fit(str(work / "data.csv"), mech, free=["stiffness", "restitution"],
                 start={"stiffness": 2e11, "restitution": 0.6}, sensor=jc.Accelerometer(cutoff_hz=20e3),
                 progress=False)
    first = time.perf_counter() - t
    return {"jaxclear": where, "import_s": import_s, "first_s": first, "iterations": int(res.iterations),
            "estimates": {k: float(v) for k, v in res.estimates.items()},
            "std": {k: float(v) for k, v in res.std.items()}, "loss": float(res.loss)}


def child_main(args) -> int:
    record = {"engine": child_engine, "sweep": child_sweep, "fit": child_fit}[args.child](args)
    Path(args.child_out).write_text(json.dumps(record))
    return 0


# ----------------------------------------------------------------------------------------------
# the parent: worktrees, interleaved children, table
# ----------------------------------------------------------------------------------------------
def git(*argv: str, cwd=ROOT) -> str:
    return subprocess.run(["git", *argv], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def describe(rev: str) -> dict:
    sha = git("rev-parse", "--verify", f"{rev}^{{commit}}")
    return {"rev": rev, "sha": sha, "date": git("show", "-s", "--format=%cI", sha),
            "subject": git("show", "-s", "--format=%s", sha)[:160]}


def load_average():
    try:
        return list(os.getloadavg())
    except OSError:  # pragma: no cover
        return None


def child_argv(args, kind: str, out: Path, work: Path) -> list[str]:
    argv = [sys.executable, str(Path(__file__).resolve()), "--child", kind, "--child-out", str(out),
            "--child-dir", str(work), "--revolutions", repr(args.revolutions), "--n-out", str(args.n_out),
            "--short-revolutions", repr(args.short_revolutions), "--warmup", str(args.warmup), "--repeats", str(args.repeats), "--sweep-runs", str(args.sweep_runs),
            "--sweep-revolutions", repr(args.sweep_revolutions), "--samples", str(args.samples),
            "--chunk", str(args.chunk), "--sweep-repeats", str(args.sweep_repeats)]
    return argv


def run_child(args, kind: str, label: str, tree: Path, tmp: Path, rnd: int) -> dict:
    tag = f"{kind}-{label}-{rnd}"
    work = tmp / tag
    (work / "cache").mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(tree), JAXCLEAR_CACHE_DIR=str(work / "cache"))
    out = work / "record.json"
    load = load_average()
    t = time.perf_counter()
    proc = subprocess.run(child_argv(args, kind, out, work), env=env, cwd=work, capture_output=True, text=True,
                          timeout=args.timeout)
    wall = time.perf_counter() - t
    if proc.returncode != 0 or not out.exists():
        raise RuntimeError(f"{tag} failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}")
    record = json.loads(out.read_text())
    record.update(kind=kind, version=label, round=rnd, process_s=wall, load_before=load)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return record


def spread(xs: list) -> float | None:
    """(max - min) / median of a quantity over the rounds, or None under two values."""
    xs = [x for x in xs if x is not None]
    if len(xs) < 2:
        return None
    m = statistics.median(xs)
    return (max(xs) - min(xs)) / m if m else None


def summarize(records: list[dict]) -> list[dict]:
    """One row per quantity of :data:`ROWS` measured: medians over the rounds, after/before and
    each version's spread."""
    rows = []
    for kind, key, label, unit, scale in ROWS:
        vals = {v: [r[key] * scale for r in records if r["kind"] == kind and r["version"] == v] for v in ("before", "after")}
        if not vals["before"] or not vals["after"]:
            continue
        b, a = statistics.median(vals["before"]), statistics.median(vals["after"])
        rows.append({"kind": kind, "key": key, "quantity": label, "unit": unit, "before": b, "after": a,
                     "ratio": a / b if b else None, "before_rounds": vals["before"], "after_rounds": vals["after"],
                     "spread_before": spread(vals["before"]), "spread_after": spread(vals["after"])})
    return rows


def _num(x) -> str:
    if x is None:
        return "-"
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:.0f}"


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def format_table(rows: list[dict]) -> str:
    """A Markdown table: quantity, before, after, after/before, spread of each over the rounds."""
    lines = ["| quantity | unit | before | after | after / before | spread before | spread after |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        ratio = "-" if r["ratio"] is None else f"{r['ratio']:.3f}"
        lines.append(f"| {r['quantity']} | {r['unit']} | {_num(r['before'])} | {_num(r['after'])} | {ratio} | "
                     f"{_pct(r['spread_before'])} | {_pct(r['spread_after'])} |")
    return "\n".join(lines)


def _rel(a: float, b: float) -> float:
    import math

    if math.isnan(a) and math.isnan(b):
        return 0.0
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def agreement(records: list[dict]) -> dict:
    """Before against after: the engine's final slider position, steps and status; the sweep's
    common numeric columns of runs.csv (largest relative difference, worst column named)."""
    out = {}
    first = {}  # each version's first round
    for r in sorted(records, key=lambda r: r["round"]):
        first.setdefault((r["kind"], r["version"]), r)
    eb, ea = first.get(("engine", "before")), first.get(("engine", "after"))
    if eb and ea:
        q = max(_rel(x, y) for x, y in zip(eb["q_final"], ea["q_final"]))
        out["engine"] = {"slider_x_before": eb["slider_x_final"], "slider_x_after": ea["slider_x_final"],
                         "slider_x_rel_diff": _rel(eb["slider_x_final"], ea["slider_x_final"]),
                         "q_final_max_rel_diff": q, "steps": [eb["steps"], ea["steps"]],
                         "status": [eb["status"], ea["status"]]}
    sb, sa = first.get(("sweep", "before")), first.get(("sweep", "after"))
    if sb and sa:
        common = sorted(set(sb["columns"]) & set(sa["columns"]))
        diffs = {c: max((_rel(x, y) for x, y in zip(sb["columns"][c], sa["columns"][c])), default=0.0) for c in common}
        worst = max(diffs, key=diffs.get) if diffs else None
        out["sweep"] = {"columns_compared": len(common), "max_rel_diff": diffs.get(worst, 0.0) if worst else None,
                        "worst_column": worst, "per_column": diffs,
                        "only_before": sorted(set(sb["columns"]) - set(sa["columns"])),
                        "only_after": sorted(set(sa["columns"]) - set(sb["columns"]))}
    fb, fa = first.get(("fit", "before")), first.get(("fit", "after"))
    if fb and fa:
        out["fit"] = {"iterations": [fb["iterations"], fa["iterations"]],
                      "estimates_before": fb["estimates"], "estimates_after": fa["estimates"],
                      "estimates_max_rel_diff": max(_rel(fb["estimates"][k], fa["estimates"][k]) for k in fb["estimates"]),
                      "std_max_rel_diff": max(_rel(fb["std"][k], fa["std"][k]) for k in fb["std"]),
                      "loss": [fb["loss"], fa["loss"]]}
    return out


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.child:
        return child_main(args)
    revs = {"before": describe(args.before), "after": describe(args.after)}
    started = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    load_start = load_average()
    print(f"before {revs['before']['sha'][:10]} {revs['before']['subject'][:70]}")
    print(f"after  {revs['after']['sha'][:10]} {revs['after']['subject'][:70]}")
    print(f"load average at start: {load_start}")
    tmp = Path(tempfile.mkdtemp(prefix="jaxclear-before-after-"))
    trees = {}
    records = []
    t_all = time.perf_counter()
    try:
        for label in ("before", "after"):
            trees[label] = tmp / f"tree-{label}"
            git("worktree", "add", "--detach", str(trees[label]), revs[label]["sha"])
        for rnd in range(args.rounds):
            for kind in args.kinds:
                for label in ("before", "after"):
                    rec = run_child(args, kind, label, trees[label], tmp, rnd)
                    records.append(rec)
                    main_key = {"engine": "steady_median_s", "sweep": "runs_per_s", "fit": "iterations"}[kind]
                    print(f"round {rnd} {kind:6s} {label:6s} first {rec['first_s']:7.2f} s  "
                          f"{main_key} {rec[main_key]:.4g}  (process {rec['process_s']:.1f} s, load {rec['load_before'][0]:.2f})",
                          flush=True)
    finally:
        for label, tree in trees.items():
            try:
                git("worktree", "remove", "--force", str(tree))
            except subprocess.CalledProcessError as err:  # pragma: no cover
                print(f"could not remove the worktree {tree}: {err.stderr}", file=sys.stderr)
        try:
            git("worktree", "prune")
        except subprocess.CalledProcessError:  # pragma: no cover
            pass
        if args.keep:
            print(f"kept: {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    load_end = load_average()
    rows = summarize(records)
    agree = agreement(records)
    table = format_table(rows)
    print()
    print(table)
    print()
    if "engine" in agree:
        e = agree["engine"]
        print(f"engine agreement: final slider x {e['slider_x_before']:.12g} vs {e['slider_x_after']:.12g} m "
              f"(rel diff {e['slider_x_rel_diff']:.2e}); all final coordinates {e['q_final_max_rel_diff']:.2e}; "
              f"steps {e['steps'][0]} vs {e['steps'][1]}; status {e['status']}")
    if "sweep" in agree:
        s = agree["sweep"]
        print(f"sweep agreement: {s['columns_compared']} runs.csv columns, largest rel diff "
              f"{s['max_rel_diff']:.2e} ({s['worst_column']}); only before: {s['only_before']}; only after: {s['only_after']}")
    if "fit" in agree:
        f = agree["fit"]
        print(f"fit agreement: iterations {f['iterations'][0]} vs {f['iterations'][1]}; estimates largest rel diff "
              f"{f['estimates_max_rel_diff']:.2e}, std {f['std_max_rel_diff']:.2e}; after: {f['estimates_after']}")
    print(f"load average at end: {load_end}; total {time.perf_counter() - t_all:.0f} s")
    if args.json:
        for r in records:
            r.pop("columns", None)
        result = {"benchmark": "before/after: engine steady state and sweep throughput", "started_utc": started,
                  "revisions": revs, "config": {k: v for k, v in vars(args).items() if not k.startswith("child")},
                  "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                              "python": platform.python_version(), "XLA_FLAGS": os.environ.get("XLA_FLAGS")},
                  "load_average_start": load_start, "load_average_end": load_end, "rows": rows,
                  "agreement": agree, "records": records, "table": table}
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
