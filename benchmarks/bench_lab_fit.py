"""Fits of records that begin mid-run: the acceptance of ``jc.fit(..., start_state="free")`` on
records made by the independent SciPy simulator (``lab_record.py``, no code shared with jaxclear).

Each record: the Flores benchmark slider-crank some revolutions after start-up
(``lab_record.CASES``: "acceptance", the first revolution from the 5th on whose journal is 80-97 %
in contact, or "one-impact", the 5th, 99 % in one contact), from a crank angle of 37 degrees, one
revolution (12 ms) at 50 kHz through a 10 kHz second-order accelerometer with gain 1.03, bias
0.5 m/s^2 and 20 dB noise; truths (stiffness factor, restitution) (0.8, 0.75), (1.25, 0.85),
(1.0, 0.9). The fit: free stiffness, restitution, sensor gain and bias, start values the preset's
(restitution 0.9), 4 windows of 2.99 ms, every window's start state unknown.

Targets: stiffness within 5 %, restitution within 0.02, every error within 3 reported std, under
5 minutes a record on 2 cores.

``python benchmarks/bench_lab_fit.py [--set acceptance] [--cases 0,1,2] [--windows 4] [--starts N] [--scan NAME|auto|none]
[--rtol R] [--json PATH]`` prints a table
and writes the JSON after every record (a killed run resumes: the records done are kept; the
output is locked while it runs).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import jaxclear as jc  # noqa: I001  (float64 first)
from jaxclear._storage import atomic_write_json, locked_folder
from jaxclear.fitting.problem import FREE_START_RTOL

import lab_record

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_JSON = os.path.join(HERE, "results", "lab_fit.json")
FREE = ["stiffness", "restitution", "sensor_gain", "sensor_bias"]


def fit_case(case: dict, windows: int, window: float, starts: int = 1, noise: bool = True, scan=None,
             rtol: float | None = None) -> dict:
    """One record (``make_record``'s arguments ``case``) made and fitted (``scan``: the fit's
    scan of held values, :mod:`jaxclear.fitting.scan`; ``rtol``: the model's tolerance, ``atol``
    a thousandth of it, None for the fit's default): the truth, the estimates, std, errors,
    verdict and times."""
    factor, c_r, seed = case["stiffness_factor"], case["c_r"], case["seed"]
    t0 = time.perf_counter()
    rec = lab_record.make_record(**case)
    made = time.perf_counter() - t0
    truth = rec["truth"]
    mech = jc.params.replace(jc.preset("flores-slider-crank"), "angle0", truth["start_angle"])
    data = {"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}
    t1 = time.perf_counter()
    res = jc.fit(data, mech, free=FREE, start={"restitution": 0.9}, sensor=jc.Accelerometer(10e3),
                 start_state="free", windows=windows, window=window, starts=starts, progress=False,
                 noise_sigma=truth["noise_std"] if noise else None, scan=scan,
                 settings=None if rtol is None else jc.settings(1.0, rtol=rtol, atol=1e-3 * rtol))
    wall = time.perf_counter() - t1
    k, c = res.estimates["stiffness"], res.estimates["restitution"]
    return {"stiffness_factor": factor, "c_r": c_r, "seed": seed, "revolutions_before": case["revolutions_before"],
            "true_stiffness": truth["stiffness"],
            "contact_fraction": truth["contact_fraction"], "impacts": truth["n_impacts"],
            "in_contact_at_start": truth["in_contact_at_start"], "estimates": res.estimates, "std": res.std,
            "stiffness_error": k / truth["stiffness"] - 1.0, "restitution_error": c - c_r,
            "stiffness_error_std": (k - truth["stiffness"]) / res.std["stiffness"],
            "restitution_error_std": (c - c_r) / res.std["restitution"], "ok": res.ok, "failures": list(res.failures),
            "loss": res.loss, "autocorrelation": res.residual_autocorrelation, "iterations": res.iterations,
            "fit_wall_s": wall, "phase_s": res.settings.get("phase_s", {}), "record_s": made, "way_in": res.settings.get("way_in", []), "starts": starts,
            "noise_sigma_given": truth["noise_std"] if noise else None, "residual_std": res.noise_sigma_m_s2,
            "stop_reason": res.stop_reason, "window_losses": list(res.window_losses),
            "window_onsets": res.window_onsets, "scan": scan, "scan_report": res.settings.get("scan"),
            "profiles": res.profiles, "rtol": rtol, "model_rtol": res.settings["rtol"]}


def model_rtol(record: dict) -> float:
    """The model's tolerance a record was fitted at (records written before ``model_rtol`` was
    kept, with the fit's default then, 1e-8)."""
    return record.get("model_rtol", record.get("rtol") or 1e-8)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--set", default="acceptance", choices=sorted(lab_record.CASES), help="the record set (default: acceptance)")
    p.add_argument("--cases", default="0,1,2", help="indices into the set (default: all three)")
    p.add_argument("--windows", type=int, default=4)
    p.add_argument("--window", type=float, default=2.99e-3)
    p.add_argument("--starts", type=int, default=1, help="starts of the parameters (default 1)")
    p.add_argument("--scan", default="auto", metavar="NAME|auto|none",
                   help="scan this free parameter after the fit (jc.fit's scan; default: auto, the fit's own rule: "
                   "the restitution where the fitted motion holds fewer than 4 onsets; none: no scan)")
    p.add_argument("--rtol", type=float, default=None,
                   help="the model's relative tolerance (atol a thousandth of it; default: the fit's for free "
                   "starts, 1e-7 with atol 1e-10)")
    p.add_argument("--no-noise", action="store_true",
                   help="do not give the fit the sensor's noise level (default: given, as a record at rest would)")
    p.add_argument("--json", default=DEFAULT_JSON)
    args = p.parse_args(argv)
    args.scan = None if args.scan == "none" else args.scan
    cases = [lab_record.CASES[args.set][int(i)] for i in args.cases.split(",")]
    rtol = args.rtol if args.rtol is not None else FREE_START_RTOL
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with locked_folder(os.path.dirname(os.path.abspath(args.json)), "benchmark results folder"):
        done = json.load(open(args.json))["records"] if os.path.isfile(args.json) else []
        for case in cases:
            if any(all(r.get(k) == v for k, v in case.items()) and r.get("starts", 1) == args.starts
                   and r.get("scan") == args.scan and model_rtol(r) == rtol for r in done):
                continue
            done.append(fit_case(case, args.windows, args.window, args.starts, not args.no_noise, args.scan, args.rtol))
            atomic_write_json(args.json, {"meta": {"date": time.strftime("%Y-%m-%d"), "windows": args.windows,
                                                   "window_s": args.window, "free": FREE, "scan": args.scan}, "records": done},
                              indent=1, sort_keys=False)
    print(f"{'K/K_H':>6} {'c_r':>5} {'revs':>4} {'contact':>8} {'K err %':>8} {'K err/std':>9} {'c_r err':>8} {'c_r err/std':>11} "
          f"{'gain':>6} {'ok':>5} {'iters':>5} {'fit s':>6} {'starts':>6}")
    for r in done:
        print(f"{r['stiffness_factor']:6.2f} {r['c_r']:5.2f} {r.get('revolutions_before', 5):4d} "
              f"{100 * r['contact_fraction']:7.1f}% "
              f"{100 * r['stiffness_error']:8.2f} {r['stiffness_error_std']:9.2f} {r['restitution_error']:8.3f} "
              f"{r['restitution_error_std']:11.2f} {r['estimates']['sensor_gain']:6.3f} {str(r['ok']):>5} "
              f"{r['iterations']:5d} {r['fit_wall_s']:6.0f} {r.get('starts', 1):6d}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
