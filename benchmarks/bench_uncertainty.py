"""Calibration and speed of the posterior (issue 31, points 2 and 6).

1. Calibration (``--records N``, default 30): N synthetic records of the benchmark slider-crank
   made by the engine at tight tolerance (rtol 1e-10) through an accelerometer whose true gain and
   bias differ per record (gain uniform in [0.8, 1.2], bias uniform in [-3000, 3000] m/s^2, noise
   at ``--snr-db`` with its own seed); for each: the least-squares fit, then the posterior of the
   ``--free`` parameters and the noise level (default priors). Table: per parameter, the share of
   records whose truth lies in the posterior's 90 % interval and in the Gauss-Newton 90 % interval
   (``estimate +- 1.645 std``), with the binomial 95 % interval of the share. Target: 80-97 %.
   ``--free stiffness,restitution`` calibrates the contact parameters instead (the true stiffness
   and restitution drawn per record too); that costs minutes per record on a laptop CPU.
2. Speed (``--speed``): effective samples per second (ArviZ bulk ESS of the slowest quantity over
   the sampling wall time, compilation excluded; NUTS's time includes its warm-up, the random
   walk's its burn-in, the first half of its draws) of NUTS and of a random-walk Metropolis baseline
   (Gaussian steps of 2.38 / sqrt(D) in the same Gauss-Newton-whitened coordinates, Roberts, Gelman
   and Gilks 1997) on the same log posterior: stiffness, restitution and the noise level from the
   benchmark record.
3. Tolerance runs per second (``--tolerance-speed``, ``--tolerance-runs 64``): a tolerance study
   against the serial loop on the same samples (:func:`tolerance_speed`).

Run from the repository root: ``PYTHONPATH=. python benchmarks/bench_uncertainty.py [--records 30]
[--free sensor_gain,sensor_bias] [--speed] [--tolerance-speed]``. Results: printed tables and
``benchmarks/results/uncertainty.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
import warnings

import jaxclear as jc  # noqa: I001  (float64 first)

import jax
import jax.numpy as jnp
import numpy as np

from jaxclear import params
from jaxclear._storage import atomic_write_json, locked_folder
from jaxclear.analysis.sensor import Accelerometer
from jaxclear.tolerance import wilson_interval

SENSOR = Accelerometer(20e3)


def _record(mech, truth: dict, seed: int, t_rec: float, rate: float, snr_db: float):
    sensor = Accelerometer(20e3, gain=truth.get("sensor_gain", 1.0), bias=truth.get("sensor_bias", 0.0))
    m = params.replace_many(mech, {k: v for k, v in truth.items() if not k.startswith("sensor_")})
    return jc.synthetic_record(m, t_rec, rate, sensor, snr_db=snr_db, seed=seed, rtol=1e-10, atol=1e-13)


_CALIBRATION_KEYS = ("free", "chains", "draws", "warmup", "chunk", "t_rec", "rate", "snr_db", "seed")


def _resumed_rows(args) -> list:
    """Records already done by an earlier run of the same calibration settings (``args.json``
    written after each record): a killed run resumes where it stopped."""
    if not getattr(args, "json", None):
        return []
    try:
        with open(args.json) as f:
            old = json.load(f)
    except (OSError, ValueError):
        return []
    same = all(old.get("settings", {}).get(k) == getattr(args, k) for k in _CALIBRATION_KEYS)
    return list(old.get("calibration", {}).get("records", [])) if same else []


def calibration(args, save=None) -> dict:
    """The coverage study; ``save(partial_result)`` is called after every record."""
    mech0 = jc.preset("flores-slider-crank")
    free = tuple(args.free.split(","))
    rng = np.random.default_rng(args.seed)
    rows = _resumed_rows(args)[: args.records]
    if rows:
        print(f"resuming after {len(rows)} records from {args.json}", flush=True)
    for i in range(args.records):
        truth = {"sensor_gain": rng.uniform(0.8, 1.2), "sensor_bias": rng.uniform(-3000, 3000)}
        if "stiffness" in free:
            truth["stiffness"] = float(params.get(mech0, "stiffness")) * rng.uniform(0.7, 1.4)
        if "restitution" in free:
            truth["restitution"] = rng.uniform(0.6, 0.95)
        if i < len(rows):  # done before the kill: the generator has advanced past its draws
            continue
        fixed_truth = {k: v for k, v in truth.items() if k not in free and not k.startswith("sensor_")}
        mech = params.replace_many(mech0, fixed_truth) if fixed_truth else mech0
        sensor = Accelerometer(20e3, gain=truth["sensor_gain"] if "sensor_gain" not in free else 1.0,
                               bias=truth["sensor_bias"] if "sensor_bias" not in free else 0.0)
        rec = _record(mech0, truth, 100 + i, args.t_rec, args.rate, args.snr_db)
        start = {n: (1.0 if n == "sensor_gain" else 0.0 if n == "sensor_bias" else
                     float(params.get(mech0, n)) if n != "restitution" else 0.8) for n in free}
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fr = jc.fit(rec, mech, free, start, sensor=sensor, window=args.t_rec, progress=False)
            post = jc.posterior(rec, mech, free, start, fit_result=fr, sensor=sensor, chains=args.chains,
                                draws=args.draws, warmup=args.warmup, chunk=args.chunk, seed=i, predictive_draws=0,
                                progress=False)
        sigma = float(rec.metadata["noise_sigma_m_s2"])
        row = {"record": i, "wall_s": time.perf_counter() - t0, "converged": post.converged,
               "divergences": post.divergences, "truth": {**{n: truth[n] for n in free}, "noise_sigma": sigma}}
        for n in (*free, "noise_sigma"):
            lo, hi = post.interval(n)
            row[n] = {"post": bool(lo <= row["truth"][n] <= hi)}
            if n != "noise_sigma":
                glo, ghi = post.interval(n, gauss_newton=True)
                row[n]["gn"] = bool(glo <= row["truth"][n] <= ghi)
        rows.append(row)
        print(f"record {i:2d}: {row['wall_s']:6.1f} s, {'converged' if post.converged else 'NOT CONVERGED'}, "
              + ", ".join(f"{n} {'in' if row[n]['post'] else 'OUT'}" for n in (*free, "noise_sigma")), flush=True)
        if save is not None:
            save({"complete": False, "records": rows})
    return _coverage_table(free, rows)


def _coverage_table(free, rows) -> dict:
    table = {}
    for n in (*free, "noise_sigma"):
        entry = {}
        for kind in ("post", "gn"):
            hits = [r[n][kind] for r in rows if kind in r[n]]
            if hits:
                k = int(sum(hits))
                entry[kind] = {"coverage": k / len(hits), "ci95": list(wilson_interval(k, len(hits))), "records": len(hits)}
        table[n] = entry
    print(f"\n90 % interval coverage over {len(rows)} records (target 80-97 %):")
    print(f"  {'parameter':<14} {'posterior':>22} {'Gauss-Newton':>22}")
    for n, e in table.items():
        cell = {k: f"{100 * v['coverage']:.0f} % [{100 * v['ci95'][0]:.0f}, {100 * v['ci95'][1]:.0f}]"
                for k, v in e.items()}
        print(f"  {n:<14} {cell.get('post', '-'):>22} {cell.get('gn', '-'):>22}")
    print(f"  not converged: {sum(not r['converged'] for r in rows)}, divergences: {sum(r['divergences'] for r in rows)}")
    return {"complete": True, "table": table, "records": rows}


def speed(args) -> dict:
    """NUTS vs random-walk Metropolis, ESS per second on the same log posterior."""
    import arviz as az

    from jaxclear.fitting.posterior import _chain_keys, _log_posterior, _starts
    from jaxclear.fitting.sampler import init_states, random_walk_chunk

    mech = jc.preset("flores-slider-crank")
    rec = _record(mech, {}, 7, args.t_rec, args.rate, args.snr_db)
    free = ("stiffness", "restitution")
    start = {"stiffness": float(params.get(mech, "stiffness")) * 1.3, "restitution": 0.8}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fr = jc.fit(rec, mech, free, start, sensor=SENSOR, window=args.t_rec, progress=False)
        # NUTS: the compilation is left out by timing a second call of the same draws
        kw = dict(fit_result=fr, sensor=SENSOR, chains=args.chains, warmup=args.warmup, chunk=args.chunk,
                  predictive_draws=0, progress=False)
        jc.posterior(rec, mech, free, start, draws=args.chunk, **kw)
        nuts = jc.posterior(rec, mech, free, start, draws=args.draws, **kw)
    ess_n = nuts.min_ess()
    common = dict(channels=None, sensor=SENSOR, rtol=1e-8, atol=1e-11, max_steps=200_000, align="time",
                  time_offset=0.0)
    lp, _ = _log_posterior(rec, mech, free, fr, {}, None, common)
    states = init_states(lp, jnp.asarray(_starts(lp, args.chains, 0)))
    d = int(lp.x0.shape[0])
    scale = 2.38 / math.sqrt(d)
    n_rw = args.draws * args.rw_factor
    random_walk_chunk(lp, states, _chain_keys(0, args.chains, 0), scale, args.chunk)  # compile
    t0 = time.perf_counter()
    st, (pos, acc) = random_walk_chunk(lp, states, _chain_keys(0, args.chains, 1), scale, n_rw)
    pos = np.asarray(pos)
    t_rw = time.perf_counter() - t0
    half = n_rw // 2  # the first half is the random walk's burn-in
    ess_rw = min(float(az.ess(pos[:, half:, j], method="bulk")) for j in range(d))
    out = {"nuts": {"draws_per_chain": args.draws, "chains": args.chains, "min_bulk_ess": ess_n,
                    "sampling_s": nuts.sampling_wall_s, "ess_per_s": ess_n / nuts.sampling_wall_s,
                    "gradient_evaluations": nuts.gradient_evaluations, "converged": nuts.converged},
           "random_walk": {"draws_per_chain": n_rw, "kept": n_rw - half, "chains": args.chains, "min_bulk_ess": ess_rw,
                           "sampling_s": t_rw, "ess_per_s": ess_rw / t_rw,
                           "acceptance": float(np.mean(np.asarray(acc)))}}
    print("\nESS/s (min bulk ESS over stiffness, restitution, log noise / sampling wall time):")
    for k, v in out.items():
        print(f"  {k:<12} ESS {v['min_bulk_ess']:8.1f} in {v['sampling_s']:7.1f} s: {v['ess_per_s']:.3g} /s")
    return out


def tolerance_speed(args) -> dict:
    """Runs per second of a tolerance study (``jc.tolerance_study``: each batch a list sweep,
    chunked, vmapped or mapped per device, written as it goes) against the plain serial loop a
    user would write (one jitted ``simulate`` of the clearance and of the ideal-joint mechanism per
    sample, then ``run_metrics``), on the same samples, settings and metrics: the inputs of
    ``examples/tolerance.toml`` (clearance, two link lengths, three masses), half a crank revolution
    of the benchmark at 400 samples per revolution, rtol 1e-6. First calls (with compilation) and
    steady state (a second study into a fresh folder, the program cached) reported separately."""
    import tempfile
    import tomllib

    import equinox as eqx

    from jaxclear.analysis.metrics import run_metrics
    from jaxclear.sweep.config import _applies
    from jaxclear.tolerance import inputs_from_dict, tolerance_study

    with open("examples/tolerance.toml", "rb") as f:
        inputs = inputs_from_dict(tomllib.load(f), "examples/tolerance.toml")
    mech, ideal = jc.preset("flores-slider-crank"), jc.preset("flores-slider-crank", ideal=True)
    run = dict(revolutions=0.5, samples_per_revolution=400)
    n = args.tolerance_runs
    timings, results = {}, []
    with tempfile.TemporaryDirectory() as d:
        for tag in ("first", "steady"):
            t0 = time.perf_counter()
            results.append(tolerance_study(inputs, mech, n=n, linearise=False, out=os.path.join(d, tag),
                                           progress=False, **run))
            timings[tag] = time.perf_counter() - t0
    res = results[-1]
    names, x = list(res.names), np.asarray(res.values)
    settings = jc.Settings(t_end=jnp.asarray(0.5 * jc.crank_period(mech)), n_out=201, throw=False)

    @eqx.filter_jit
    def one(m, im):
        sol, isol = jc.simulate(m, settings), jc.simulate(im, settings)
        return run_metrics(m, sol, isol.coordinate(im, "slider", "x", derivative=2))

    def sample(i):
        change = dict(zip(names, x[i]))
        return (params.replace_many(mech, change),
                params.replace_many(ideal, {k: v for k, v in change.items() if _applies(ideal, k)}))

    loop = {}
    t0 = time.perf_counter()
    jax.block_until_ready(one(*sample(0)))
    loop["first_call_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = [jax.tree_util.tree_map(np.asarray, one(*sample(i))) for i in range(len(x))]
    loop["steady_s"] = time.perf_counter() - t0
    peak = np.array([o["peak_contact_force_n"] for o in out])
    diff = float(np.max(np.abs(peak - res.metrics["peak_contact_force_n"]) / np.abs(peak)))
    table = {"runs": int(len(x)),
             "study_first_s": timings["first"], "study_steady_s": timings["steady"],
             "study_runs_per_s": len(x) / timings["steady"],
             "loop_first_call_s": loop["first_call_s"], "loop_steady_s": loop["steady_s"],
             "loop_runs_per_s": len(x) / loop["steady_s"],
             "speedup_steady": loop["steady_s"] / timings["steady"],
             "peak_force_max_rel_difference": diff, "devices": len(jax.devices())}
    print(f"\ntolerance study vs serial loop ({len(x)} runs of half a revolution, {len(jax.devices())} device(s)):")
    print(f"  study: {timings['first']:.1f} s first (with compilation), {timings['steady']:.1f} s steady: "
          f"{table['study_runs_per_s']:.1f} runs/s")
    print(f"  loop:  {loop['first_call_s']:.1f} s first call, {loop['steady_s']:.1f} s steady for all runs: "
          f"{table['loop_runs_per_s']:.1f} runs/s  (study {table['speedup_steady']:.2f}x the loop's rate)")
    print(f"  peak contact force, study against loop: largest relative difference {diff:.1e}")
    return table


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--records", type=int, default=30)
    p.add_argument("--free", default="sensor_gain,sensor_bias")
    p.add_argument("--chains", type=int, default=2)
    p.add_argument("--draws", type=int, default=300)
    p.add_argument("--warmup", type=int, default=200)
    p.add_argument("--chunk", type=int, default=100)
    p.add_argument("--t-rec", type=float, default=0.6e-3)
    p.add_argument("--rate", type=float, default=200e3)
    p.add_argument("--snr-db", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--speed", action="store_true")
    p.add_argument("--rw-factor", type=int, default=10, help="random-walk draws per NUTS draw")
    p.add_argument("--tolerance-speed", action="store_true",
                   help="runs per second of a tolerance study against the serial loop (issue 31, point 6)")
    p.add_argument("--tolerance-runs", type=int, default=64)
    p.add_argument("--json", default="benchmarks/results/uncertainty.json")
    args = p.parse_args()
    t0 = time.perf_counter()
    res = {"settings": vars(args), "machine": platform.platform(), "jax": jax.__version__,
           "device": str(jax.devices()[0])}
    if args.records:
        def save(partial):
            atomic_write_json(args.json, {**res, "calibration": partial}, indent=1, default=float)

        with locked_folder(os.path.dirname(args.json) or ".", "results folder"):
            res["calibration"] = calibration(args, save)
    if args.speed:
        res["speed"] = speed(args)
    if args.tolerance_speed:
        res["tolerance_speed"] = tolerance_speed(args)
    res["wall_s"] = time.perf_counter() - t0
    atomic_write_json(args.json, res, indent=1, default=float)
    print(f"wrote {args.json} ({res['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
