#!/usr/bin/env python
"""Time to first result: every entry point in fresh processes, with empty and with warm caches,
split into import, tracing, lowering, XLA compilation and the rest (supersedes bench_startup.py).

Each measurement is a new Python process (``subprocess``; this parent imports neither jax nor
jaxclear). Caches: every entry gets its own fresh temporary folder; the ``cold`` process finds
it empty, the ``warm`` process is the same entry again in the same folder. Nothing in the user's
home is read or written: ``XDG_CACHE_HOME`` and ``JAXCLEAR_CACHE_DIR`` point into the temporary
folder, ``JAX_COMPILATION_CACHE_DIR`` and ``JAX_PERSISTENT_CACHE_*`` are removed, and matplotlib's
font cache (``MPLCONFIGDIR``) is a temporary one filled once before the first measurement.

* ``api:NAME``: the Python API. The child points JAX's persistent compilation cache at the folder
  (``jax.config.update("jax_compilation_cache_dir", ...)``, JAX's other cache options at their
  defaults: what a Python user had to do before jaxclear kept its caches by default), with
  ``JAXCLEAR_CACHE_DIR=off``. ``--api-programs`` also enables jaxclear's store of traced programs
  there, as the command line does (``jaxclear.integrate.programs``). ``--api-default`` configures
  nothing in the child: ``JAXCLEAR_CACHE_DIR`` is the folder, and ``import jaxclear`` enables both
  caches there (``jaxclear/integrate/caches.py``, since issue 41 item 3; a source tree without it runs
  without caches). The entry is set up (mechanism, record: ``setup``), called once (``first``)
  and once more (``steady``: the run alone, if nothing is traced again).
* ``cli:NAME``: ``jaxclear.cli.main(argv)`` in the child (``JAXCLEAR_CACHE_DIR`` = the folder: the
  XLA cache and the traced-program store, ``jaxclear/cli/cache.py``), then ``os._exit``, as ``jaxclear``.
* ``api:convergence``: the preset's run at the four tolerances of :data:`CONVERGENCE_RTOLS`
  one after the other (a user's convergence check): one program where the tolerances are inputs.
* ``size:NxK``: ``jc.simulate`` (2 ms) of an open chain of N bars (a driven crank and N-1
  hanging links at 2000 rpm), K of its N-1 inner pin joints clearance joints, cold only.

The first call is split with JAX's monitoring events (jax 0.10:
``/jax/core/compile/jaxpr_trace_duration``, ``.../jaxpr_to_mlir_module_duration``,
``.../backend_compile_duration``, the last including a persistent-cache read): ``trace``,
``lower``, ``compile`` are the summed durations (threads may overlap), ``other`` is the first
call's wall minus the union of those spans (the run, eager Python work, output writing, and the
tracing under a transformation that is not jitted, e.g. ``jax.jacfwd(f)(x)``: JAX reports only
top-level traces). The JSON adds the programs behind each, cache hits and writes, and the programs
JAX would not write to its cache because they hold host callbacks (``uncacheable``).

    PYTHONPATH=. python benchmarks/bench_first_result.py --quick     # ~3 min
    PYTHONPATH=. python benchmarks/bench_first_result.py             # everything (~1 h on 2 cores)
    PYTHONPATH=. python benchmarks/bench_first_result.py --entries api:fit,cli:fit --sizes 10x1,10x9

Table on stdout, JSON (NaN as null) in benchmarks/results/first_result.json (``--quick``: _quick).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import importlib.util
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SRC = [ROOT]  # the source tree whose jaxclear the children import (--source)
T_END = 2e-3  # [s] every simulation of the preset
NAMES3 = ("stiffness", "restitution", "clearance")
EVENTS = {"trace": "/jax/core/compile/jaxpr_trace_duration", "lower": "/jax/core/compile/jaxpr_to_mlir_module_duration",
          "compile": "/jax/core/compile/backend_compile_duration"}
RECORD = dict(t_end=1.2e-3, rate=200e3, cutoff=20e3, seed=7)  # the small fit of tests/test_fit.py
FIT_CLI = ["--window", "1e-3", "--sensor-cutoff-hz", "20000", "--start", "stiffness={k2}", "--start",
           "restitution=0.75", "--starts", "1", "--max-iter", "3", "--no-progress", "--out", "{out}"]
CLI = {
    "presets": ["presets"],
    "simulate": ["simulate", "--preset", "flores-slider-crank", "--t-end", str(T_END), "--out", "{out}"],
    "sweep": ["sweep", "{dir}/sweep.toml", "--out", "{out}", "--no-progress"],
    "fit": ["fit", "{rec}", *FIT_CLI],
    "design": ["design", "--preset", "four-bar", "--vary", "centroid_x:rocker=-0.05:0.05", "--vary",
               "centroid_x:coupler=-0.05:0.05", "--objective", "rms-deviation", "--revolutions", "0.5",
               "--max-iter", "1", "--no-progress", "--out", "{out}"],
    "chaos": ["chaos", "--revolutions", "2", "--transient", "0", "--discard", "0", "--per-revolution", "4",
              "--count", "1", "--out", "{out}"],
    "tolerance": ["tolerance", "{dir}/tolerance.toml", "--out", "{out}", "--no-progress"],
    "posterior": ["fit", "{rec}", *FIT_CLI, "--posterior", "--chains", "1", "--draws", "10", "--warmup", "10",
                  "--chunk", "10"],
    "wear": ["wear", "--preset", "flores-slider-crank", "--revolutions", "0.25", "--updates", "1", "--no-progress",
             "--out", "{out}"],
}
API = ("simulate", "jacfwd", "sensitivities", "fit", "sweep", "design", "chaos", "tolerance", "posterior", "wear",
       "convergence")
#: The tolerances of the ``convergence`` entry: the same run at each (a user's convergence check).
CONVERGENCE_RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)
ENTRIES = [f"api:{n}" for n in API] + [f"cli:{n}" for n in CLI]
SIZES = ["2x1", "5x1", "5x4", "10x1", "10x9", "20x1", "20x10", "50x1", "50x10"]
QUICK = dict(entries=["api:simulate", "api:jacfwd", "cli:simulate"], sizes=["2x1", "5x4"], timeout=240)
SWEEP_TOML = ('[mechanism]\npreset = "flores-slider-crank"\n[grid]\nclearance = [0.25e-3, 0.5e-3]\n'
              "restitution = [0.6, 0.9]\n[run]\nrevolutions = 0.5\nsamples_per_revolution = 200\n")


# ----------------------------------------------------------------------------------------------
# child side: runs in the fresh process (imports jax and jaxclear)
# ----------------------------------------------------------------------------------------------

def _chain(n: int, k: int, speed_rpm: float = 2000.0):
    """An open chain of ``n`` bars 0.1 m / 0.2 kg along +x: bar 0 a crank driven about the ground
    point O, bar i pinned to bar i-1; ``k`` of the ``n - 1`` inner pins (evenly spread, from the
    tip) are clearance joints (bearing 10 mm, c = 0.5 mm, LN law, c_r 0.9, no friction)."""
    import jaxclear as jc

    L, m = 0.1, 0.2
    bodies = [jc.Body(f"b{i}", m, m * L * L / 12, {"A": (-L / 2, 0.0), "B": (L / 2, 0.0)}, ((i + 0.5) * L, 0.0, 0.0))
              for i in range(n)]
    loose = {n - 1 - round(j * (n - 1) / k) for j in range(k)}
    assert len(loose) == k and 1 <= min(loose), (n, k, loose)
    joints, clear = [jc.Revolute(jc.GROUND, "O", "b0", "A")], []
    for i in range(1, n):
        if i in loose:
            clear.append(jc.ClearanceJoint(f"b{i - 1}", "B", f"b{i}", "A", bearing_radius=0.01, journal_radius=0.0095,
                                           law=jc.make_law("lankarani-nikravesh", restitution=0.9), name=f"c{i}"))
        else:
            joints.append(jc.Revolute(f"b{i - 1}", "B", f"b{i}", "A"))
    drivers = [jc.AngleDriver("b0", speed_rpm * 2 * math.pi / 60)]
    return jc.Mechanism(bodies, joints, drivers, clear, ground_points={"O": (0.0, 0.0)}, name=f"chain-{n}x{k}")


def _api_entry(name: str, spec: dict):
    """``call(out_folder)`` running the API entry ``name`` once (everything before it is setup)."""
    import jax
    import jax.numpy as jnp

    import jaxclear as jc
    from jaxclear import params

    mech = jc.preset("flores-slider-crank")
    s = jc.settings(T_END)
    period = float(jc.crank_period(mech))
    k0 = float(params.get(mech, "stiffness"))
    fit_kw = dict(start={"stiffness": 2 * k0, "restitution": 0.75}, sensor=jc.Accelerometer(RECORD["cutoff"]),
                  window=1e-3, starts=1, max_iter=3, progress=False)
    if name == "simulate":
        return lambda out: jc.simulate(mech, s)
    if name == "convergence":  # the same run at four tolerances, atol = rtol * 1 mm
        return lambda out: [jc.simulate(mech, jc.settings(T_END, rtol=r, atol=r * 1e-3)) for r in CONVERGENCE_RTOLS]
    if name == "jacfwd":  # d(slider x at 2 ms)/d(stiffness); q = (x, y, phi) of crank, rod, slider
        return lambda out: jax.jacfwd(lambda k: jc.simulate(params.replace(mech, "stiffness", k), s).q[-1, 6])(
            jnp.asarray(k0))
    if name == "sensitivities":
        return lambda out: jc.sensitivities(mech, s=s, names=NAMES3)
    if name in ("fit", "posterior"):
        if name == "fit":
            return lambda out: jc.fit(spec["record"], mech, **fit_kw)
        return lambda out: jc.posterior(spec["record"], mech, out=out, chains=1, draws=10, warmup=10, chunk=10,
                                        predictive_draws=0, **fit_kw)
    if name == "sweep":
        grid = {"clearance": [0.25e-3, 0.5e-3], "restitution": [0.6, 0.9]}
        return lambda out: jc.run_sweep(jc.SweepConfig(grid=grid, revolutions=0.5, samples_per_revolution=200,
                                                       progress=False), out=out)
    if name == "design":  # docs/getting-started.md, "Design", one iteration
        variables = {"mass:coupler": (0.25, 0.75), "mass:rocker": (0.2, 0.6), "centroid_x:rocker": (-0.05, 0.05)}
        return lambda out: jc.design(jc.preset("four-bar"), variables, "peak-force", constraints=["total-mass"],
                                     revolutions=0.5, out=out, max_iter=1, progress=False)
    if name == "chaos":
        s2 = jc.settings(2 * period, throw=False)
        return lambda out: jc.lyapunov(mech, s2, interval=period / 4, count=1, samples=4, keep=False)
    if name == "tolerance":
        import tomllib

        with open(Path(jc.__file__).resolve().parents[1] / "examples" / "tolerance.toml", "rb") as f:
            inputs = jc.inputs_from_dict(tomllib.load(f), "examples/tolerance.toml")
        return lambda out: jc.tolerance_study(inputs, mech, n=8, out=out, progress=False, revolutions=0.25,
                                              samples_per_revolution=400)
    if name == "wear":  # the hybrid law at body-fixed points, as jaxclear wear's defaults
        ws, mech = jc.settings(0.25 * period), jc.preset("flores-slider-crank", law="hybrid",
                                                          law_options={"placement": "fixed"})
        return lambda out: jc.wear(mech, ws, jc.WearOptions(coefficient=1e-15, updates=1), out, progress=False)
    raise ValueError(f"unknown API entry {name!r}")


def _union(spans) -> float:
    """Total length of the union of ``(start, end)`` intervals."""
    total, end = 0.0, -math.inf
    for a, b in sorted(spans):
        if b > end:
            total += b - max(a, end)
            end = b
    return total


def _phase(spans, durations, counts, t0: float, t1: float) -> dict:
    """Breakdown of the wall-clock window ``[t0, t1]`` (``time.time()``) from the events in it."""
    inside = [(e, a, b) for e, a, b in spans if t0 <= a <= t1]
    out = {"wall_s": t1 - t0}
    for key, event in EVENTS.items():
        mine = [d for e, d, a, _ in durations if e == event and t0 <= a <= t1]
        out[f"{key}_s"], out[f"n_{key}"] = sum(mine), len(mine)
        top = {}
        for e, d, a, fun in durations:
            if e == event and t0 <= a <= t1:
                top[fun] = top.get(fun, 0.0) + d
        out[f"top_{key}"] = sorted(top.items(), key=lambda kv: -kv[1])[:4]
    out["other_s"] = max(out["wall_s"] - _union([(a, b) for _, a, b in inside]), 0.0)
    hits = [a for e, a in counts if e.endswith("cache_hits") and t0 <= a <= t1]
    misses = [a for e, a in counts if e.endswith("cache_misses") and t0 <= a <= t1]
    out["cache_hits"], out["cache_misses"] = len(hits), len(misses)
    return out


def child(spec: dict) -> None:
    """Run one measurement described by ``spec`` and write its result to ``spec["result"]`` (also
    after the import and the setup, so that a killed process still says how far it got)."""
    t_start = time.time()
    res = {"status": "running", "stage": "import"}

    def save():
        Path(spec["result"]).write_text(json.dumps(res))

    import jax
    from jax import monitoring

    spans, durations, counts = [], [], []
    monitoring.register_event_time_span_listener(lambda e, a, b, **kw: spans.append((e, a, b)))
    monitoring.register_event_duration_secs_listener(
        lambda e, d, **kw: durations.append((e, d, time.time() - d, str(kw.get("fun_name", "?")))))
    monitoring.register_event_listener(lambda e, **kw: counts.append((e, time.time())))
    import logging  # JAX says at DEBUG level which programs it does not write to its cache, and why

    log = logging.getLogger("jax._src.compiler")
    log.setLevel(logging.DEBUG), setattr(log, "propagate", False)
    log.addHandler(logging.Handler())
    log.handlers[-1].emit = lambda r: "host callbacks" in r.getMessage() and res["uncacheable"].append(r.args[0])
    res["uncacheable"] = []  # programs with host callbacks: never written to the persistent cache
    kind = spec["kind"]
    if kind == "cli":
        import jaxclear.cli as cli
    else:
        import jaxclear as jc
    res["import_s"] = time.time() - t_start  # jax, jaxclear (the command line: its modules too)
    res["jaxclear"] = os.path.dirname(sys.modules["jaxclear"].__file__)
    res["stage"] = "setup"
    save()
    if kind == "record":
        mech = jc.preset("flores-slider-crank")
        jc.synthetic_record(mech, RECORD["t_end"], RECORD["rate"], jc.Accelerometer(RECORD["cutoff"]), snr_db=20,
                            seed=RECORD["seed"], path=spec["record"])
        res.update(status="ok", stiffness=float(jc.params.get(mech, "stiffness")))
        return save()
    if kind == "cli":
        t0 = time.time()
        code = cli.main(spec["argv"])
        t1 = time.time()
        res.update(status="ok" if code == 0 else f"exit {code}", setup_s=0.0, first=_phase(spans, durations,
                                                                                          counts, t0, t1))
        save()
        sys.stdout.flush(), sys.stderr.flush()
        os._exit(0)
    if spec.get("cache") and not spec.get("default"):
        jax.config.update("jax_compilation_cache_dir", spec["cache"])
        if spec.get("programs"):
            from jaxclear.integrate import _programs as programs

            programs.enable(Path(spec["cache"]) / "programs")
    if kind == "api" and spec["name"] == "posterior" and importlib.util.find_spec("blackjax") is None:
        res.update(status="skipped", note="the [uncertainty] extra (blackjax) is not installed")
        return save()
    t0 = time.time()
    call = _chain_call(spec) if kind == "size" else _api_entry(spec["name"], spec)
    t1 = time.time()
    res.update(setup_s=t1 - t0, setup=_phase(spans, durations, counts, t0, t1), stage="first")
    save()
    blocked = lambda x: [leaf.block_until_ready() for leaf in jax.tree_util.tree_leaves(x)  # noqa: E731
                         if hasattr(leaf, "block_until_ready")]
    out = blocked(call(os.path.join(spec["dir"], "first")))
    t2 = time.time()
    res.update(first=_phase(spans, durations, counts, t1, t2), stage="steady")
    save()
    if spec.get("steady", True):
        blocked(call(os.path.join(spec["dir"], "second")))
        res["steady"] = _phase(spans, durations, counts, t2, time.time())
    if kind == "size":  # after the timed calls: these eager operations compile programs of their own
        sol = call.solution
        res.update(run_status=int(sol.status), steps=int(sol.num_steps), contact=float(sol.normal_force.max()) > 0,
                   n_coordinates=int(sol.q.shape[-1]), n_constraints=int(sol.reactions.shape[-1]))
    del out
    res.update(status="ok", stage="done")
    save()


def _chain_call(spec):
    import jaxclear as jc

    mech = _chain(spec["bodies"], spec["clearance"])
    s = jc.settings(T_END, max_steps=200_000, throw=False)

    def call(out):
        call.solution = jc.simulate(mech, s)
        return call.solution

    return call


# ----------------------------------------------------------------------------------------------
# parent side: plain Python, no jax
# ----------------------------------------------------------------------------------------------

def _sources_digest() -> str:
    h = hashlib.sha256()
    for p in sorted((SRC[0] / "jaxclear").rglob("*.py")):
        h.update(str(p.relative_to(SRC[0])).encode() + p.read_bytes())
    return h.hexdigest()[:16]


def _env(tmp: Path, cache: str | None) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("JAX_COMPILATION_CACHE", "JAX_PERSISTENT_CACHE", "JAXCLEAR_CACHE"))}
    env.update(PYTHONPATH=str(SRC[0]) + os.pathsep + os.environ.get("PYTHONPATH", ""), XDG_CACHE_HOME=str(tmp / "xdg"),
               MPLCONFIGDIR=str(tmp / "mpl"), JAXCLEAR_CACHE_DIR=cache or "off", PYTHONUNBUFFERED="1")
    return env


def run_child(spec: dict, tmp: Path, timeout: float) -> dict:
    """One fresh process for ``spec``; its result with the process's wall time (``process_s``)."""
    spec = dict(spec, result=str(tmp / f"result-{time.monotonic_ns()}.json"))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", json.dumps(spec)]
    t = time.perf_counter()
    by_env = spec["kind"] == "cli" or spec.get("default")  # the folder through JAXCLEAR_CACHE_DIR
    proc = subprocess.Popen(cmd, cwd=SRC[0], env=_env(tmp, spec.get("cache") if by_env else None),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        err, timed_out = proc.communicate(timeout=timeout)[1], False
    except subprocess.TimeoutExpired:
        proc.kill()  # the child we started, by its handle
        err, timed_out = proc.communicate()[1], True
    wall = time.perf_counter() - t
    try:
        res = json.loads(Path(spec["result"]).read_text())
    except (OSError, ValueError):
        res = {"status": "error"}
    res["process_s"] = wall
    if timed_out:
        res.update(status="timeout", note=f"killed after {timeout:.0f} s in stage {res.get('stage')}")
    elif res.get("status") != "ok" and res.get("status") != "skipped":
        res.setdefault("note", (err or "").strip().splitlines()[-1:] or ["no output"])
        res["status"] = res["status"] if res["status"] != "running" else f"error (exit {proc.returncode})"
        res["stderr_tail"] = (err or "")[-1500:]
    return res


def measure(label: str, spec: dict, modes, tmp: Path, timeout: float, opts) -> list[dict]:
    """Cold (fresh folder) then warm (same folder) processes of one entry; rows."""
    base = tmp / label.replace(":", "-")
    rows, digest = [], None
    for mode in modes:
        folder = base / "cache"
        digest_now = _sources_digest()
        full = dict(spec, dir=str(base / f"out-{mode}"), cache=None if mode == "off" else str(folder),
                    programs=opts.api_programs, default=opts.api_default, steady=not opts.no_steady)
        if "argv" in spec:
            full["argv"] = [a.replace("{out}", full["dir"]) for a in spec["argv"]]
        res = run_child(full, tmp, timeout)
        res.update(entry=label, mode=mode, sources=digest_now)
        if mode == "warm" and digest not in (None, digest_now):
            res["note"] = "jaxclear's sources changed between the cold and the warm process"
        digest = digest_now
        if folder.exists():
            files = [p for p in folder.rglob("*") if p.is_file()]
            res["cache_files"], res["cache_bytes"] = len(files), sum(p.stat().st_size for p in files)
        rows.append(res)
        print(_row(res), flush=True)
        if res["status"] in ("timeout", "skipped") or res["status"].startswith("error"):
            break  # a warm run after a failed cold one says nothing
    return rows


def _f(x, width=8, digits=1):
    return f"{x:>{width}.{digits}f}" if isinstance(x, (int, float)) and math.isfinite(x) else f"{'-':>{width}}"


HEADER = (f"{'entry':<18}{'cache':<6}{'process':>8}{'import':>8}{'setup':>8}{'trace':>8}{'lower':>8}{'compile':>8}"
          f"{'other':>8}{'first':>8}{'steady':>8}  note")


def _row(r: dict) -> str:
    first, steady = r.get("first") or {}, r.get("steady") or {}
    note = r.get("note") or ("" if r.get("status") == "ok" else r.get("status", ""))
    if isinstance(note, list):
        note = " ".join(note)
    if r.get("uncacheable"):
        note = f"not cacheable (host callbacks): {', '.join(sorted(set(r['uncacheable'])))}. " + note
    if steady.get("n_trace"):
        note = f"2nd call traced {steady['n_trace']}x, compiled {steady['n_compile']}x. " + note
    if "steps" in r:
        note = f"n={r['n_coordinates']} m={r['n_constraints']} {r['steps']} steps{' contact' if r['contact'] else ''}" \
               f"{'' if r['run_status'] == 0 else ' status ' + str(r['run_status'])}. " + note
    cells = [r.get("process_s"), r.get("import_s"), r.get("setup_s")] + [first.get(f"{k}_s") for k in EVENTS]
    cells = "".join(_f(x) for x in cells + [first.get("other_s"), first.get("wall_s")])
    return f"{r['entry']:<18}{r['mode']:<6}{cells}{_f(steady.get('wall_s'), digits=2)}  {note[:110]}".rstrip()


def _clean(x):  # NaN and inf as null
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return None if isinstance(x, float) and not math.isfinite(x) else x


def _machine() -> dict:
    model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                  if line.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").exists() else ""
    return {"platform": platform.platform(), "cpu": model, "cpus": os.cpu_count(), "python": platform.python_version(),
            "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
            **{p: version(p) for p in ("jax", "jaxlib", "diffrax", "equinox")}}


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help=f"small set: {', '.join(QUICK['entries'])}; sizes {', '.join(QUICK['sizes'])} (~3 min)")
    ap.add_argument("--entries", help="comma-separated api:NAME / cli:NAME / NAME (both) or 'none' (default: all)")
    ap.add_argument("--sizes", help=f"comma-separated NxK (bodies x clearance joints), 'none' (default {','.join(SIZES)})")
    ap.add_argument("--modes", default="cold,warm", help="cache states in order: cold, warm, off (default cold,warm)")
    ap.add_argument("--timeout", type=float, help="seconds per process (default 600, --quick 240)")
    ap.add_argument("--api-programs", action="store_true",
                    help="API processes also keep traced programs (jaxclear.integrate.programs), as the CLI does")
    ap.add_argument("--api-default", action="store_true",
                    help="API processes configure nothing: JAXCLEAR_CACHE_DIR is the folder, and jaxclear's default "
                    "caches (jaxclear/integrate/caches.py) are measured")
    ap.add_argument("--no-steady", action="store_true", help="skip the second call of API entries")
    ap.add_argument("--json", help="output (default benchmarks/results/first_result.json; --quick: _quick)")
    ap.add_argument("--source", type=Path, default=ROOT, help="source tree whose jaxclear is measured, e.g. "
                    "'git archive HEAD | tar -x -C DIR' while others edit the checkout (default: this checkout)")
    ap.add_argument("--list", action="store_true", help="list the entries and exit")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    pick = lambda text, default: default if text is None else [] if text == "none" else text.split(",")  # noqa: E731
    names = pick(args.entries, QUICK["entries"] if args.quick else ENTRIES)
    args.entries = [e for n in names for e in ([n] if ":" in n else [f"api:{n}", f"cli:{n}"]) if e in ENTRIES]
    unknown = [n for n in names if n not in ENTRIES and not {f"api:{n}", f"cli:{n}"} & set(ENTRIES)]
    if unknown:
        ap.error(f"--entries: unknown {unknown}; entries: {', '.join(ENTRIES)}")
    args.sizes = pick(args.sizes, QUICK["sizes"] if args.quick else SIZES)
    for size in args.sizes:
        n, _, k = size.partition("x")
        if not (n.isdigit() and k.isdigit() and 1 <= int(k) <= int(n) - 1):
            ap.error(f"--sizes: {size!r} is not NxK with 1 <= K <= N - 1")
    args.modes = args.modes.split(",")
    if not set(args.modes) <= {"cold", "warm", "off"}:
        ap.error(f"--modes: {args.modes} (allowed: cold, warm, off)")
    args.timeout = args.timeout or (QUICK["timeout"] if args.quick else 600.0)
    args.json = args.json or str(HERE / "results" / f"first_result{'_quick' if args.quick else ''}.json")
    return args


def main(argv=None) -> dict | None:
    args = parse_args(argv)
    SRC[0] = args.source.resolve()
    if args.child:
        return child(json.loads(args.child))
    if args.list:
        print("\n".join(ENTRIES + [f"size:{s}" for s in SIZES]))
        return None
    load0 = os.getloadavg()[0]
    result = {"benchmark": "first_result", "command": " ".join(["python", "benchmarks/bench_first_result.py",
                                                                 *(argv if argv is not None else sys.argv[1:])]),
              "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "machine": _machine(), "modes": args.modes, "timeout_s": args.timeout, "t_end_s": T_END,
              "api_programs": args.api_programs, "api_default": args.api_default, "source": str(SRC[0]), "sources": _sources_digest(), "rows": []}
    rows = result["rows"]

    def write():
        result["load_average"] = [load0, os.getloadavg()[0]]
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(_clean(result), indent=1) + "\n")

    print(HEADER, flush=True)
    with tempfile.TemporaryDirectory(prefix="jaxclear-first-") as t:
        tmp = Path(t)
        (tmp / "sweep.toml").write_text(SWEEP_TOML)
        tol = (SRC[0] / "examples" / "tolerance.toml").read_text()
        tol = tol.replace("n = 64 ", "n = 8 ").replace("sobol_n = 16", "sobol_n = 0").replace(
            "revolutions = 0.5", "revolutions = 0.25")
        (tmp / "tolerance.toml").write_text(tol)
        # matplotlib's font cache, once, outside the measurements
        subprocess.run([sys.executable, "-c", "import matplotlib.font_manager"], env=_env(tmp, None), check=False)
        fill = {"dir": str(tmp), "rec": str(tmp / "record.csv"), "k2": "nan"}
        if any(e.endswith(("fit", "posterior")) for e in args.entries):
            r = run_child({"kind": "record", "record": fill["rec"], "dir": str(tmp)}, tmp, args.timeout)
            result["record_prep"] = r
            fill["k2"] = repr(2 * r.get("stiffness", math.nan))
        for entry in args.entries:
            surface, name = entry.split(":")
            if surface == "api":
                spec = {"kind": "api", "name": name, "record": fill["rec"]}
            else:
                spec = {"kind": "cli", "name": name, "argv": [a.format(out="{out}", **fill) for a in CLI[name]]}
            rows += measure(entry, spec, args.modes, tmp, args.timeout, args)
            write()
        for size in args.sizes:
            n, k = map(int, size.split("x"))
            rows += measure(f"size:{size}", {"kind": "size", "bodies": n, "clearance": k}, ["cold"], tmp, args.timeout,
                            args)
            write()
    result["table"] = "\n".join([HEADER] + [_row(r) for r in rows])
    print(f"\nload average (1 min) start / end: {load0:.2f} / {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; "
          f"wrote {args.json}")
    write()
    return result


if __name__ == "__main__":
    main()
