"""Honest uncertainty at the fit's own window (issue "Fits on real records", point 6).

Records made by the independent NumPy/SciPy simulator (``benchmarks/lab_record.py``: no jax, no
jaxclear) of the Flores benchmark slider-crank from start-up (crank angle 0, journal centred: the
start state known), one default fit window long (a quarter revolution, 3 ms at 5000 rpm), through
a second-order 20 kHz low-pass sampled at 200 kHz with 20 dB noise; the truths drawn per record
(stiffness 0.7-1.4 times the Hertz value, restitution 0.6-0.95; ``numpy.random.default_rng(seed)``).
Each record is fitted (stiffness and restitution free, start 1.0 and 0.9) with
``profile=True``; the table shows, per parameter, whether the truth lies in the Gauss-Newton
90 % interval (estimate +- 1.645 std) and in the profile likelihood's 90 % interval, with the
share over the records and its binomial 95 % interval (Wilson). Target: 80-97 %.

Run from the repository root: ``python benchmarks/bench_profile.py [--records 8] [--json PATH]``.
The JSON is written after every record; a killed run resumes from it (same settings).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings

import jaxclear as jc  # noqa: I001  (float64 first)
import numpy as np

from jaxclear._storage import atomic_write_json, locked_folder
from jaxclear.tolerance import wilson_interval

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lab_record  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_JSON = os.path.join(HERE, "results", "profile.json")
FREE = ("stiffness", "restitution")


def truths(n: int, seed: int) -> list[dict]:
    """``n`` records' truths: stiffness factor in [0.7, 1.4], restitution in [0.6, 0.95]."""
    rng = np.random.default_rng(seed)
    return [dict(stiffness_factor=float(rng.uniform(0.7, 1.4)), c_r=float(rng.uniform(0.6, 0.95)), seed=seed + 1 + i)
            for i in range(n)]


def fit_record(case: dict, duration: float) -> dict:
    """One record made and fitted with its profiles: truth, estimates, both intervals, times."""
    rec = lab_record.make_record(**case, revolutions_before=0, start_angle_deg=0.0, duration=duration, fs=200e3,
                                 cutoff_hz=20e3, order=2, gain=1.0, bias=0.0, snr_db=20.0)
    truth = {"stiffness": rec["truth"]["stiffness"], "restitution": case["c_r"]}
    data = {"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = jc.fit(data, jc.preset("flores-slider-crank"), free=list(FREE), sensor=jc.Accelerometer(20e3),
                     progress=False, profile=True)
    wall = time.perf_counter() - t
    fit_s = res.wall_time_s
    row = {**case, "truth": truth, "estimates": res.estimates, "std": res.std, "ok": res.ok,
           "failures": list(res.failures), "iterations": res.iterations, "wall_s": wall, "fit_and_profile_s": fit_s,
           "autocorrelation": res.residual_autocorrelation, "loss": res.loss, "window_s": res.window_length_s}
    for name in FREE:
        p = res.profiles[name]
        est, sd_gn, tru = res.estimates[name], p["std_gauss_newton"], truth[name]
        lo, hi = p["interval"]
        row[name] = {"gauss_newton_interval": [est - 1.645 * sd_gn, est + 1.645 * sd_gn],
                     "profile_interval": [lo, hi], "error_in_gn_std": (est - tru) / sd_gn,
                     "in_gauss_newton": bool(abs(est - tru) <= 1.645 * sd_gn),
                     "in_profile": bool(lo is not None and hi is not None and lo <= tru <= hi),
                     "profile_points": len(p["values"]) - 1, "better": p["better"], "open": p["open"]}
    return row


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--records", type=int, default=8)
    p.add_argument("--seed", type=int, default=100)
    p.add_argument("--duration", type=float, default=3e-3, help="record length [s] (default 3 ms: one default window)")
    p.add_argument("--json", default=DEFAULT_JSON)
    args = p.parse_args(argv)
    folder = os.path.dirname(os.path.abspath(args.json))
    os.makedirs(folder, exist_ok=True)
    meta = {"records": args.records, "seed": args.seed, "duration_s": args.duration, "free": list(FREE)}
    with locked_folder(folder, "benchmark results folder"):
        done = []
        if os.path.isfile(args.json):
            saved = json.load(open(args.json))
            done = saved["rows"] if {k: saved["meta"].get(k) for k in meta} == meta else []
        for case in truths(args.records, args.seed)[len(done):]:
            done.append(fit_record(case, args.duration))
            atomic_write_json(args.json, {"meta": {**meta, "date": time.strftime("%Y-%m-%d")}, "rows": done},
                              indent=1, sort_keys=False)
            r = done[-1]
            print(f"record {len(done)}/{args.records}: K {r['stiffness']['error_in_gn_std']:+.2f} GN std, "
                  f"c_r {r['restitution']['error_in_gn_std']:+.2f} GN std, {r['wall_s']:.0f} s", flush=True)
    print(f"{'K/K_H':>6} {'c_r':>5} {'K err %':>8} {'K/GN std':>8} {'K in GN':>7} {'K in prof':>9} {'c_r err':>8} "
          f"{'c_r/GN std':>10} {'c_r in GN':>9} {'c_r in prof':>11} {'s':>5}")
    for r in done:
        k, c = r["stiffness"], r["restitution"]
        print(f"{r['stiffness_factor']:6.2f} {r['c_r']:5.2f} "
              f"{100 * (r['estimates']['stiffness'] / r['truth']['stiffness'] - 1):8.2f} {k['error_in_gn_std']:8.2f} "
              f"{str(k['in_gauss_newton']):>7} {str(k['in_profile']):>9} "
              f"{r['estimates']['restitution'] - r['c_r']:8.4f} {c['error_in_gn_std']:10.2f} "
              f"{str(c['in_gauss_newton']):>9} {str(c['in_profile']):>11} {r['wall_s']:5.0f}")
    for name in FREE:
        for kind in ("in_gauss_newton", "in_profile"):
            hits = sum(r[name][kind] for r in done)
            lo, hi = wilson_interval(hits, len(done))
            print(f"{name} {kind.replace('in_', '')}: {hits}/{len(done)} cover the truth "
                  f"({100 * hits / max(len(done), 1):.0f} %, 95 % interval {100 * lo:.0f}-{100 * hi:.0f} %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
