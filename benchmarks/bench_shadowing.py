"""Shadowing derivatives of the benchmark slider-crank's steady running (issue 44):
``jc.steady_derivatives`` (NILSS on the engine's tangents) against the slopes of long-time averages
that ``benchmarks/bench_steady_averages.py`` measured (the truth: regressions over 10 values x 2000
revolutions, ``benchmarks/results/steady_averages.json``).

Objectives (``--objective``): ``rms_dev``, the mean square of the slider's acceleration minus the
ideal joint's (closed form, ``bench_steady_averages.slider_crank_exact``), reported as the RMS and
its derivative d RMS = d<J> / (2 RMS); ``peak_force``, the mean over revolutions of each
revolution's largest sampled normal force in the clearance joint [N]
(``statistic="revolution_peak"``, the force read from the joint's memory: the objective's sixth
parameter), on the regression's grid of 100 samples a revolution by default (4 segments x 25
samples). For each run the table gives the derivative, its standard error from
``--blocks`` batch means, the blocks' range, the homogeneous tangents' growth rates and the time.
``--floor`` sets the clearance joint's impact-velocity floor [m/s] (the Lankarani-Nikravesh
damping divides by the approach speed, floored there: 1e-4 in the preset) to see whether the tails
come from contacts entered at small approach speeds.

``python benchmarks/bench_shadowing.py [--objective rms_dev|peak_force] [--revolutions 100,400]
[--n-unstable 2] [--samples 32] [--segments 16] [--floor F] [--json PATH]``: prints a table and
writes the JSON after every run (a killed run resumes with the runs done; the output is locked
while it runs). A run's ``rms`` (the RMS objectives) or ``average`` (the peak force) is the
objective's value.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
import warnings

import jaxclear as jc  # noqa: I001  (float64 first)
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from bench_steady_averages import PRESET, slider_crank_exact
from jaxclear._storage import atomic_write_json, locked_folder

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_JSON = os.path.join(HERE, "results", "shadowing.json")
TRUTH_JSON = os.path.join(HERE, "results", "steady_averages.json")
NAMES = ("restitution", "speed_rpm", "clearance")


def mechanism(floor: float | None):
    mech = jc.preset(PRESET)
    if floor is not None:
        mech = eqx.tree_at(lambda m: m.clearance_joints[0].impact_velocity_floor, mech, float(floor))
    return mech


def deviation_squared(mech):
    """J = (slider acceleration - the ideal joint's)^2 [m^2/s^4] at (t, q, qdot, qddot, mech)."""
    i = 3 * mech.body_index("slider")

    def objective(t, q, qdot, qddot, m):
        omega, angle0 = jc.params.get(m, "speed"), jc.params.get(m, "angle0")
        return (qddot[i] - slider_crank_exact(angle0 + omega * t, omega, xp=jnp)[2]) ** 2

    return objective


def normal_force(mech):
    """J = the clearance joint's normal contact force [N] at (t, q, qdot, qddot, mech, states): the
    joint's own force law on its memory (the approach speed its damping reads)."""

    def objective(t, q, qdot, qddot, m, states):
        return m.clearance_joints[0].forces(m, t, q, qdot, states[0])[2].normal_force

    return objective


#: Per objective: the traced objective's builder, steady_derivatives' statistic, whether the
#: result is reported as an RMS (d RMS = d<J> / (2 RMS)), its default segments x samples, and
#: what the reported value is.
OBJECTIVES = {"rms_dev": (deviation_squared, "mean", True, (16, 32),
                          "RMS of the slider's acceleration minus the ideal joint's [m/s^2]"),
              "peak_force": (normal_force, "revolution_peak", False, (4, 25),
                             "mean over revolutions of the largest sampled normal force [N]")}


def truth(objective: str = "rms_dev") -> dict:
    """The regressions' slopes of ``objective`` with their 95 % intervals, by parameter."""
    if not os.path.exists(TRUTH_JSON):
        return {}
    with open(TRUTH_JSON, encoding="utf-8") as f:
        studies = json.load(f)["studies"]
    out = {}
    for s in studies:
        fit = (s.get("fits_single") if s.get("multistable") else None) or s["fits"]
        if objective in fit:
            out[s["parameter"]] = {"slope": fit[objective]["slope"], "slope_95": fit[objective]["slope_95"]}
    return out


def run(revolutions: int, n_unstable: int, samples: int, segments: int, blocks: int, floor,
        objective: str = "rms_dev") -> dict:
    mech = mechanism(floor)
    build, statistic, as_rms, *_ = OBJECTIVES[objective]
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", jc.chaos.ShadowingWarning)
        r = jc.steady_derivatives(mech, list(NAMES), build(mech), revolutions=revolutions,
                                  transient_revolutions=20, n_unstable=n_unstable, samples_per_segment=samples,
                                  segments_per_revolution=segments, blocks=blocks, statistic=statistic)
    seconds = time.perf_counter() - t0
    value = math.sqrt(float(r.average)) if as_rms else float(r.average)
    scale = 1.0 / (2.0 * value) if as_rms else 1.0  # d<J> -> d RMS for the RMS objectives
    blocks_ = np.asarray(r.member_derivatives) * scale
    return {"objective": objective, "revolutions": revolutions, "n_unstable": n_unstable, "samples": samples,
            "segments": segments, "blocks": blocks, "floor": floor, "seconds": seconds, ("rms" if as_rms else "average"): value,
            "exponents": [float(x) for x in np.asarray(r.exponents)[0]],
            "derivative": {n: float(d) * scale for n, d in zip(NAMES, np.asarray(r.derivative))},
            "error": {n: float(e) * scale for n, e in zip(NAMES, np.asarray(r.derivative_error))},
            "block_derivatives": {n: blocks_[:, k].tolist() for k, n in enumerate(NAMES)},
            "warned": bool(caught), "steps": int(np.sum(np.asarray(r.steps)))}


def key(r: dict) -> tuple:
    return (r.get("objective", "rms_dev"), r["revolutions"], r["n_unstable"], r["samples"], r["segments"],
            r["blocks"], r["floor"])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--revolutions", default="100,400", help="comma-separated: one run each")
    p.add_argument("--n-unstable", type=int, default=2, help="homogeneous tangents (the benchmark has two positive "
                   "exponents at the preset's floor)")
    p.add_argument("--objective", choices=sorted(OBJECTIVES), default="rms_dev")
    p.add_argument("--samples", type=int, default=None, help="samples a segment (rms_dev 32, peak_force 25)")
    p.add_argument("--segments", type=int, default=None, help="segments a revolution (rms_dev 16, peak_force 4)")
    p.add_argument("--blocks", type=int, default=8)
    p.add_argument("--floor", type=float, default=None, help="impact-velocity floor [m/s] (preset: 1e-4)")
    p.add_argument("--json", default=DEFAULT_JSON)
    a = p.parse_args(argv)
    segments, samples = OBJECTIVES[a.objective][3]  # the objective's defaults
    a.segments = segments if a.segments is None else a.segments
    a.samples = samples if a.samples is None else a.samples
    path = os.path.abspath(a.json)
    with locked_folder(os.path.dirname(path)):
        runs = []
        if os.path.exists(path):
            with open(path, encoding="utf-8") as f:
                runs = json.load(f).get("runs", [])
        meta = {"date": time.strftime("%Y-%m-%d"), "preset": PRESET, "cpus": os.cpu_count(), "names": list(NAMES),
                "objectives": {k: v[4] for k, v in OBJECTIVES.items()},
                "command": "python benchmarks/bench_shadowing.py"}
        for revolutions in (int(x) for x in a.revolutions.split(",")):
            want = (a.objective, revolutions, a.n_unstable, a.samples, a.segments, a.blocks, a.floor)
            if any(key(r) == want for r in runs):
                continue
            print(f"{revolutions} revolutions, n_unstable {a.n_unstable} ...", flush=True)
            runs.append(run(revolutions, a.n_unstable, a.samples, a.segments, a.blocks, a.floor, a.objective))
            atomic_write_json(path, {"meta": meta, "truth": {k: truth(k) for k in OBJECTIVES}, "runs": runs})
    known = {k: truth(k) for k in OBJECTIVES}
    print(f"\n{'objective':10s} {'parameter':12s} {'revs':>5s} {'n_u':>3s} {'floor':>7s} {'NILSS d':>12s} "
          f"{'+- (blocks)':>10s} {'blocks from':>11s} {'to':>10s} {'regression [95 %]':>30s} {'exponents':>16s} {'s':>6s}")
    for r in runs:
        for n in NAMES:
            b = r["block_derivatives"][n]
            t = known[r.get("objective", "rms_dev")].get(n)
            ref = f"{t['slope']:.4g} [{t['slope_95'][0]:.3g}, {t['slope_95'][1]:.3g}]" if t else "-"
            print(f"{r.get('objective', 'rms_dev'):10s} {n:12s} {r['revolutions']:5d} {r['n_unstable']:3d} "
                  f"{str(r['floor'] or '1e-4'):>7s} {r['derivative'][n]:12.4g} {r['error'][n]:10.2g} {min(b):11.3g} {max(b):10.3g} {ref:>30s} "
                  f"{', '.join(f'{x:.0f}' for x in r['exponents']):>16s} {r['seconds']:6.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
