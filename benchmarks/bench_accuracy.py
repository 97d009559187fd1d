#!/usr/bin/env python
"""Accuracy benchmark: work-precision of jaxclear against SciPy ``solve_ivp`` with event restarts.

The error measure is the relative RMS error of the slider acceleration over one crank revolution
of the Flores slider-crank (5000 rpm), on a uniform grid of ``--n-out`` samples,

    err = rms(a - a_ref) / rms(a_ref),

against a tight reference made once by the independent NumPy/SciPy model
(``benchmarks/scipy_reference.py``: DOP853, rtol 1e-10, atol 1e-13, the integration restarted at
every contact onset and separation) and cached in ``benchmarks/results/accuracy_ref_*.npz``.
The slider acceleration is the hardest output: every impact puts a spike into it, so the error
measures how well each impact (onset, approach speed, force pulse) is resolved.

Cases (``CASES``): the Flores law with c = 1 mm, c_r = 0.3, no friction (strong dissipation, so
the impact memory matters); Lankarani-Nikravesh with c = 0.5 mm, c_r = 0.9; Lankarani-Nikravesh
with c = 0.25 mm, c_r = 0.7 and Ambrosio friction mu = 0.1.

jaxclear runs Tsit5 (the default) at rtol 1e-5 ... 1e-9 and Dopri5 (the tableau of SciPy's RK45)
at 1e-5 ... 1e-7; SciPy RK45 at 1e-5 ... 1e-8; atol 1e-9 throughout.

Timed (wall clock, ``time.perf_counter``): jaxclear's first call at each setting (tracing + XLA
compilation + one run) and its steady-state time (best of ``--repeats`` calls), SciPy's
integration time (``scipy_reference.simulate``'s ``wall_s``, one run: nothing to compile). The machine
load (1-min load average) is recorded at the start and the end.

Run from the repository root::

    PYTHONPATH=. python benchmarks/bench_accuracy.py            # full table, PNG and JSON
    PYTHONPATH=. python benchmarks/bench_accuracy.py --quick    # one case, two tolerances
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jaxclear as jc  # noqa: E402
import scipy_reference as ref  # noqa: E402
from _timing import compile_and_steady  # noqa: E402

RESULTS_DIR = HERE / "results"

#: name -> (jaxclear preset options, SciPy reference parameters)
CASES = {
    "flores-c1mm-cr0.3": (
        dict(law="flores", clearance=1e-3, restitution=0.3, friction=0.0),
        dict(law="flores", R_J=0.009, c_r=0.3, mu=0.0),
    ),
    "ln-c0.5mm-cr0.9": (
        dict(law="lankarani-nikravesh", clearance=0.5e-3, restitution=0.9, friction=0.0),
        dict(law="lankarani-nikravesh", R_J=0.0095, c_r=0.9, mu=0.0),
    ),
    "ln-c0.25mm-cr0.7-mu0.1": (
        dict(law="lankarani-nikravesh", clearance=0.25e-3, restitution=0.7, friction=0.1),
        dict(law="lankarani-nikravesh", R_J=0.00975, c_r=0.7, mu=0.1),
    ),
}
REF_RTOL, REF_ATOL = 1e-10, 1e-13
ATOL = 1e-9


def rel_rms(a, a_ref) -> float:
    """Relative RMS error ``rms(a - a_ref) / rms(a_ref)`` [-]."""
    a, a_ref = np.asarray(a), np.asarray(a_ref)
    return float(np.sqrt(np.mean((a - a_ref) ** 2)) / np.sqrt(np.mean(a_ref**2)))


def reference(case: str, t_end: float, n_out: int, cache: bool = True) -> np.ndarray:
    """Slider acceleration of the tight SciPy reference (DOP853, event restarts) on the grid,
    cached in ``benchmarks/results``."""
    path = RESULTS_DIR / f"accuracy_ref_{case}_{t_end:.6g}s_{n_out}.npz"
    if cache and path.exists():
        return np.load(path)["slider_acc"]
    ts = np.linspace(0.0, t_end, n_out)
    r = ref.simulate(ref.params(**CASES[case][1]), t_end, ts=ts, rtol=REF_RTOL, atol=REF_ATOL, method="DOP853")
    if cache:
        RESULTS_DIR.mkdir(exist_ok=True)
        np.savez(path, t=ts, slider_acc=r["slider_acc"], rtol=REF_RTOL, atol=REF_ATOL, n_impacts=r["n_impacts"])
    return r["slider_acc"]


def run_jaxclear(case: str, solver: str, rtol: float, t_end: float, n_out: int, repeats: int, **kw) -> dict:
    mech = jc.preset("flores-slider-crank", **CASES[case][0])
    s = jc.settings(t_end, n_out=n_out, rtol=rtol, atol=ATOL, solver=solver, **kw)
    sol, first, steady = compile_and_steady(mech, s, repeats, steady=min)
    acc = np.asarray(sol.coordinate(mech, "slider", "x", 2))
    return dict(code="jaxclear", solver=solver, rtol=rtol, acc=acc, steady_s=steady, compile_s=first - steady,
                steps=int(sol.num_steps), rejected=int(sol.num_rejected_steps))


def run_scipy(case: str, method: str, rtol: float, t_end: float, n_out: int, repeats: int) -> dict:
    p = ref.params(**CASES[case][1])
    ts = np.linspace(0.0, t_end, n_out)
    runs = [ref.simulate(p, t_end, ts=ts, rtol=rtol, atol=ATOL, method=method) for _ in range(repeats)]
    return dict(code="scipy", solver=method, rtol=rtol, acc=runs[0]["slider_acc"],
                steady_s=min(r["wall_s"] for r in runs), compile_s=0.0, steps=None, rejected=None,
                nfev=runs[0]["nfev"])


def speedups(rows: list[dict]) -> list[dict]:
    """For every SciPy row: the fastest jaxclear row (steady state) at least as accurate."""
    out = []
    for r in (r for r in rows if r["code"] == "scipy"):
        better = [j for j in rows if j["code"] == "jaxclear" and j["case"] == r["case"] and j["error"] <= r["error"]]
        if not better:
            out.append(dict(case=r["case"], scipy=f"{r['solver']} {r['rtol']:g}", scipy_error=r["error"], jaxclear=None,
                            speedup=None))
            continue
        b = min(better, key=lambda j: j["steady_s"])
        out.append(dict(case=r["case"], scipy=f"{r['solver']} {r['rtol']:g}", scipy_error=r["error"],
                        jaxclear=f"{b['solver']} {b['rtol']:g}", jaxclear_error=b["error"],
                        speedup=r["steady_s"] / b["steady_s"]))
    return out


def front(rows: list[dict]) -> list[dict]:
    """The work-precision front of some runs: sorted by time, each more accurate than every
    faster one."""
    out = []
    for r in sorted(rows, key=lambda r: r["steady_s"]):
        if not out or r["error"] < out[-1]["error"]:
            out.append(r)
    return out


def interpolated_speedups(rows: list[dict]) -> list[dict]:
    """For every SciPy row: jaxclear's time at the SciPy run's error, interpolated on jaxclear's
    work-precision front (log time linear in log error between the two front runs that bracket
    it; the fastest front run's time where the SciPy error is larger than its error, so never
    extrapolated to faster), and SciPy's time over it. None where no jaxclear run is as accurate."""
    out = []
    for r in (r for r in rows if r["code"] == "scipy"):
        fr = front([j for j in rows if j["code"] == "jaxclear" and j["case"] == r["case"]])
        t = None
        if fr and r["error"] >= fr[0]["error"]:
            t = fr[0]["steady_s"]
        for a, b in zip(fr, fr[1:]):
            if a["error"] > r["error"] >= b["error"]:
                w = math.log(a["error"] / r["error"]) / math.log(a["error"] / b["error"])
                t = math.exp((1 - w) * math.log(a["steady_s"]) + w * math.log(b["steady_s"]))
        out.append(dict(case=r["case"], scipy=f"{r['solver']} {r['rtol']:g}", scipy_error=r["error"],
                        jaxclear_s=t, speedup=None if t is None else r["steady_s"] / t))
    return out


def plot(rows: list[dict], cases: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(cases), figsize=(5.2 * len(cases), 4.4), squeeze=False)
    styles = {"tsit5": ("C0", "o"), "dopri8": ("C1", "s"), "dopri5": ("C2", "^"), "RK45": ("C3", "D"),
              "DOP853": ("C4", "v")}
    for ax, case in zip(axes[0], cases):
        groups = sorted({(r["code"], r["solver"]) for r in rows if r["case"] == case})
        for code, solver in groups:
            rr = sorted((r for r in rows if r["case"] == case and r["code"] == code and r["solver"] == solver),
                        key=lambda r: r["rtol"])
            color, marker = styles.get(solver, ("k", "x"))
            ax.loglog([r["steady_s"] for r in rr], [r["error"] for r in rr], marker=marker, color=color,
                      ls="-" if code == "jaxclear" else "--", label=f"{code} {solver}")
            for r in rr:
                ax.annotate(f"{r['rtol']:.0e}", (r["steady_s"], r["error"]), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_title(case, fontsize=10)
        ax.set_xlabel("wall time per run, steady state [s]")
        ax.set_ylabel("relative RMS error of slider acceleration [-]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("work-precision: one revolution at 5000 rpm (labels: rtol)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one case, two tolerances, a short run")
    ap.add_argument("--t-end", type=float, default=None, help="simulated time [s] (default one revolution)")
    ap.add_argument("--n-out", type=int, default=None, help="output samples (default 2001; quick 201)")
    ap.add_argument("--repeats", type=int, default=None, help="timed jaxclear repeats (default 2; quick 1)")
    ap.add_argument("--no-dopri5", action="store_true", help="Tsit5 only (fewer compilations)")
    ap.add_argument("--rtols", type=str, default=None, help="jaxclear rtols, comma-separated (overrides the mode's)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default benchmarks/results)")
    ap.add_argument("--no-cache", action="store_true", help="recompute the reference, do not store it")
    a = ap.parse_args(argv)
    period = 60.0 / 5000.0
    if a.quick:
        cases, solvers, rtols, scipy_rtols = ["flores-c1mm-cr0.3"], ["tsit5"], [1e-5, 1e-6], [1e-5]
        t_end, n_out, repeats = a.t_end or period / 4, a.n_out or 201, a.repeats or 1
    else:
        cases, solvers = list(CASES), ["tsit5"] + ([] if a.no_dopri5 else ["dopri5"])
        # half decades for jaxclear (each setting compiles): the fastest setting that reaches an
        # error is then found to within a factor of about 3 in rtol
        rtols = [1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9]
        scipy_rtols = [1e-5, 1e-6, 1e-7, 1e-8]
        t_end, n_out, repeats = a.t_end or period, a.n_out or 2001, a.repeats or 2
    if a.rtols:
        rtols = [float(x) for x in a.rtols.split(",")]
    out_dir = a.out or RESULTS_DIR
    out_dir.mkdir(parents=True, exist_ok=True)
    load_start = os.getloadavg()
    rows: list[dict] = []
    result: dict = {}
    for case in cases:
        t0 = time.perf_counter()
        a_ref = reference(case, t_end, n_out, cache=not a.no_cache)
        print(f"[{case}] reference ready ({time.perf_counter() - t0:.1f} s)", flush=True)
        # dopri5 (the tableau of SciPy's RK45) at the looser tolerances only: each setting compiles
        settings = [(sv, rt) for sv in solvers for rt in rtols if sv == "tsit5" or rt >= 1e-7]
        for sv, rt in settings:
            rows.append(_scored(run_jaxclear(case, sv, rt, t_end, n_out, repeats), case, a_ref))
        for rt in scipy_rtols:
            rows.append(_scored(run_scipy(case, "RK45", rt, t_end, n_out, 1), case, a_ref))
        # written after every case, so that an interrupted run leaves what it measured
        result = _write(rows, cases[: cases.index(case) + 1], a, t_end, n_out, load_start, out_dir)
    return result


def _scored(r: dict, case: str, a_ref) -> dict:
    r["case"] = case
    r["error"] = rel_rms(r.pop("acc"), a_ref)
    print(f"  {r['code']} {r['solver']} rtol {r['rtol']:g}: error {r['error']:.3e}, {r['steady_s']:.4f} s "
          f"(compile {r['compile_s']:.1f} s)", flush=True)
    return r


def _write(rows, cases, a, t_end, n_out, load_start, out_dir) -> dict:
    load_end = os.getloadavg()
    ups = speedups(rows)
    lines = [f"work-precision, slider acceleration over t_end = {t_end:.6g} s, {n_out} samples; atol {ATOL:g}; "
             f"reference SciPy DOP853 rtol {REF_RTOL:g} with event restarts",
             f"{'case':24s} {'code':9s} {'solver':7s} {'rtol':>7s} {'rel. error':>11s} {'steady [s]':>11s} "
             f"{'compile [s]':>11s} {'steps':>7s} {'rej.':>6s}"]
    for r in rows:
        steps = "" if r["steps"] is None else str(r["steps"])
        rej = "" if r["rejected"] is None else str(r["rejected"])
        lines.append(f"{r['case']:24s} {r['code']:9s} {r['solver']:7s} {r['rtol']:7.0e} {r['error']:11.3e} "
                     f"{r['steady_s']:11.4f} {r['compile_s']:11.2f} {steps:>7s} {rej:>6s}")
    lines.append("fastest jaxclear setting at least as accurate as each SciPy run (steady state):")
    for u in ups:
        if u["speedup"] is None:
            lines.append(f"  {u['case']:24s} SciPy {u['scipy']:12s} err {u['scipy_error']:.2e}: no jaxclear run as accurate")
        else:
            lines.append(f"  {u['case']:24s} SciPy {u['scipy']:12s} err {u['scipy_error']:.2e} -> jaxclear "
                         f"{u['jaxclear']:14s} err {u['jaxclear_error']:.2e}: {u['speedup']:.1f}x faster")
    inter = interpolated_speedups(rows)
    lines.append("jaxclear's time at each SciPy run's error, interpolated on jaxclear's work-precision front:")
    for u in inter:
        got = "no jaxclear run as accurate" if u["speedup"] is None else \
            f"jaxclear {u['jaxclear_s']:.4f} s: {u['speedup']:.1f}x faster"
        lines.append(f"  {u['case']:24s} SciPy {u['scipy']:12s} err {u['scipy_error']:.2e}: {got}")
    lines.append(f"load average (1 min) start / end: {load_start[0]:.2f} / {load_end[0]:.2f} on {os.cpu_count()} CPUs")
    print("\n".join(lines))
    name = "accuracy_quick" if a.quick else "accuracy"
    png = out_dir / f"{name}.png"
    plot(rows, cases, png)
    result = dict(date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                  t_end=t_end, n_out=n_out, atol=ATOL, reference=dict(method="DOP853", rtol=REF_RTOL, atol=REF_ATOL),
                  cases={c: dict(jaxclear=CASES[c][0], scipy=CASES[c][1]) for c in cases}, rows=rows, speedups=ups,
                  interpolated_speedups=inter,
                  load_average_start=load_start, load_average_end=load_end, cpus=os.cpu_count(),
                  versions=dict(jax=jax.__version__, jaxclear=jc.__version__), png=png.name, table=lines)
    (out_dir / f"{name}.json").write_text(json.dumps(result, indent=1, default=float))
    print(f"wrote {out_dir / (name + '.json')} and {png}", flush=True)
    return result


if __name__ == "__main__":
    main()
