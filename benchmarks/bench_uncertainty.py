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
   the sampling wall time, compilation excluded, warm-up included) of ``jc.posterior``'s two
   samplers, NUTS and the random walk (``--rw-factor`` times the draws, warm-up and chunk), on the
   same log posterior: stiffness, restitution and the noise level from the benchmark record of
   ``--t-rec`` (engine-made).
3. Samplers at the fit's own window (``--samplers``, issue 39 point 6): records made by the
   independent simulator (``lab_record.py``, the truths of ``bench_profile.py``: start state known,
   one default window of 3 ms, 200 kHz, 20 kHz sensor, 20 dB) are fitted at the default window
   and their posterior sampled by each method of ``--methods`` (``NAME:SAMPLER:DEPTH:TARGET``)
   with ``--chains``, ``--warmup``, ``--draws``; per method and record: the first call's extra
   time (compilation: one chunk's call minus that chunk at the steady rate), the sampling wall
   time, the slowest quantity's bulk ESS and ESS/s, the largest R-hat, divergences, gradient
   evaluations, and whether the 90 % interval holds the truth. ``--max-seconds`` stops a method
   after the chunk that passes it (the row then says how far it came).
4. Tolerance runs per second (``--tolerance-speed``, ``--tolerance-runs 64``): a tolerance study
   against the serial loop on the same samples (:func:`tolerance_speed`).

Run from the repository root: ``PYTHONPATH=. python benchmarks/bench_uncertainty.py [--records 30]
[--free sensor_gain,sensor_bias] [--speed] [--tolerance-speed]``. Results: printed tables and
``benchmarks/results/uncertainty.json``.
"""

from __future__ import annotations

import argparse
import json
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


_CALIBRATION_KEYS = ("free", "chains", "draws", "warmup", "chunk", "t_rec", "rate", "snr_db", "seed", "sampler")


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
    same = all(old.get("settings", {}).get(k) == getattr(args, k, None) for k in _CALIBRATION_KEYS)
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
                                sampler=getattr(args, "sampler", "nuts"), progress=False)
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
    """NUTS vs random-walk Metropolis through ``jc.posterior`` on the same log posterior: per
    sampler the first call of one chunk (compilation), then warm-up and draws; ESS/s over the
    sampling wall time (warm-up included)."""
    mech = jc.preset("flores-slider-crank")
    rec = _record(mech, {}, 7, args.t_rec, args.rate, args.snr_db)
    free = ("stiffness", "restitution")
    start = {"stiffness": float(params.get(mech, "stiffness")) * 1.3, "restitution": 0.8}
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fr = jc.fit(rec, mech, free, start, sensor=SENSOR, window=args.t_rec, progress=False)
        for sampler, factor in (("nuts", 1), ("random-walk", args.rw_factor)):
            kw = dict(fit_result=fr, sensor=SENSOR, chains=args.chains, chunk=args.chunk * factor, sampler=sampler,
                      predictive_draws=0, progress=False)
            t0 = time.perf_counter()
            first = jc.posterior(rec, mech, free, start, draws=args.chunk * factor, warmup=0, **kw)
            first_s = time.perf_counter() - t0
            post = jc.posterior(rec, mech, free, start, draws=args.draws * factor, warmup=args.warmup * factor, **kw)
            chunks = (args.draws + args.warmup) / args.chunk
            out[sampler] = {"draws_per_chain": args.draws * factor, "warmup": args.warmup * factor,
                            "chains": args.chains, "min_bulk_ess": post.min_ess(), "sampling_s": post.sampling_wall_s,
                            "ess_per_s": post.min_ess() / post.sampling_wall_s, "first_call_s": first_s,
                            "compile_s": max(first.sampling_wall_s - post.sampling_wall_s / chunks, 0.0),
                            "max_rhat": max(v["r_hat"] for v in post.statistics.values()),
                            "gradient_evaluations": post.gradient_evaluations, "converged": post.converged,
                            "acceptance": float(np.mean(post.stats["acceptance_rate"]))}
    print(f"\nESS/s at {args.t_rec * 1e3:g} ms (min bulk ESS over stiffness, restitution, noise / sampling wall time):")
    for k, v in out.items():
        print(f"  {k:<12} ESS {v['min_bulk_ess']:8.1f} in {v['sampling_s']:7.1f} s: {v['ess_per_s']:.3g} /s; "
              f"compile {v['compile_s']:.0f} s, R-hat {v['max_rhat']:.3f}")
    return out


def _lab_case(index: int) -> dict:
    """``bench_profile.py``'s record ``index`` (its truths, seed 100) and its data."""
    import sys

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import bench_profile
    import lab_record

    case = bench_profile.truths(index + 1, 100)[index]
    rec = lab_record.make_record(**case, revolutions_before=0, start_angle_deg=0.0, duration=3e-3, fs=200e3,
                                 cutoff_hz=20e3, order=2, gain=1.0, bias=0.0, snr_db=20.0)
    truth = {"stiffness": rec["truth"]["stiffness"], "restitution": case["c_r"], "noise_sigma": rec["truth"]["noise_std"]}
    return {"data": {"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}, "truth": truth, "case": case}


def _method(spec: str) -> dict:
    name, sampler, depth, target = spec.split(":")
    return dict(name=name, sampler=sampler, max_tree_depth=int(depth), target_accept=float(target) if target else None)


def samplers(args, save=None, rows=()) -> dict:
    """The samplers on the same records at the default window (module docstring, item 3)."""
    import shutil
    import signal
    import tempfile

    mech = jc.preset("flores-slider-crank")
    free = ("stiffness", "restitution")
    methods = [_method(m) for m in args.methods.split(",")]
    rows = list(rows)  # done by an earlier run of the same settings
    done = {(r["record"], r["method"]) for r in rows}
    for index in (int(i) for i in args.lab_records.split(",")):
        if all((index, m["name"]) in done for m in methods):
            continue
        case = _lab_case(index)
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fr = jc.fit(case["data"], mech, list(free), sensor=SENSOR, progress=False)
        fit_s = time.perf_counter() - t0
        print(f"record {index}: fit {fit_s:.0f} s, window {fr.window_length_s * 1e3:.3f} ms, {fr.estimates}", flush=True)
        for m in methods:
            if (index, m["name"]) in done:
                continue
            kw = dict(fit_result=fr, sensor=SENSOR, chains=args.chains, chunk=args.chunk, sampler=m["sampler"],
                      max_tree_depth=m["max_tree_depth"], target_accept=m["target_accept"], seed=index,
                      predictive_draws=0, progress=False)
            folder = tempfile.mkdtemp(prefix="bench_samplers_")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t1 = time.perf_counter()
                first = jc.posterior(case["data"], mech, free, draws=args.chunk, warmup=0, **kw)
                first_s = time.perf_counter() - t1
                stopped = False

                def stop(*_):
                    raise KeyboardInterrupt

                old = signal.signal(signal.SIGALRM, stop)
                signal.alarm(int(args.max_seconds)) if args.max_seconds else None
                t1 = time.perf_counter()
                try:
                    post = jc.posterior(case["data"], mech, free, draws=args.draws, warmup=args.warmup, out=folder,
                                        **kw)
                except KeyboardInterrupt:
                    stopped, post = True, None
                finally:
                    signal.alarm(0)
                    signal.signal(signal.SIGALRM, old)
                wall = time.perf_counter() - t1
            per_draw = first.sampling_wall_s  # one chunk, compilation included
            row = {"record": index, "method": m["name"], **m, "chains": args.chains, "warmup": args.warmup,
                   "draws": args.draws, "fit_s": fit_s, "truth": case["truth"], "first_chunk_s": per_draw,
                   "first_call_s": first_s, "stopped": stopped, "wall_s": wall}
            if post is not None:
                steady_chunk = post.sampling_wall_s / ((args.warmup + args.draws) / args.chunk)
                row.update(compile_s=max(per_draw - steady_chunk, 0.0), sampling_s=post.sampling_wall_s,
                           min_ess_bulk=post.min_ess(), ess_per_s=post.min_ess() / post.sampling_wall_s,
                           max_rhat=max(v["r_hat"] for v in post.statistics.values()), converged=post.converged,
                           divergences=post.divergences, warmup_divergences=post.warmup_divergences,
                           gradient_evaluations=post.gradient_evaluations, step_size=post.step_size,
                           acceptance=float(np.mean(post.stats["acceptance_rate"])),
                           mean_tree_depth=float(np.mean(post.stats["tree_depth"])),
                           at_depth_cap=float(np.mean(post.stats["tree_depth"] >= m["max_tree_depth"])))
                for n in (*free, "noise_sigma"):
                    lo, hi = post.interval(n)
                    row[n] = {"interval": [lo, hi], "covers": bool(lo <= case["truth"][n] <= hi),
                              "median": post.statistics[n]["q50"], "sd": post.statistics[n]["sd"]}
                    if n != "noise_sigma":
                        glo, ghi = post.interval(n, gauss_newton=True)
                        row[n]["gn_covers"] = bool(glo <= case["truth"][n] <= ghi)
            else:  # how far it came: the checkpoint's draws, their diagnostics, the step sizes
                ck = dict(np.load(os.path.join(folder, "posterior_checkpoint.npz")))
                row.update(warm_chunks_done=int(ck["warm_done"]), draws_done=int(ck["x"].shape[1]),
                           sampling_s=float(ck["wall_s"]), step_size=np.exp(ck["log_step_size_avg"]).tolist(),
                           warmup_divergences=int(ck["warmup_divergences"].sum()))
                if ck["x"].shape[1] >= 4:
                    row.update(_partial_diagnostics(ck, m["max_tree_depth"]))
            shutil.rmtree(folder, ignore_errors=True)
            rows.append(row)
            _print_sampler_row(row)
            if save is not None:
                save({"complete": False, "rows": rows})
    return {"complete": True, "rows": rows}


def _partial_diagnostics(ck: dict, depth: int) -> dict:
    """A stopped run's diagnostics from its checkpoint's draws (ArviZ's bulk ESS and R-hat are
    rank-based: the unconstrained draws give the values' own)."""
    from jaxclear.fitting.posterior_result import _summaries

    x = ck["x"]
    summary = _summaries({f"x{j}": x[..., j] for j in range(x.shape[-1])})
    out = {"min_ess_bulk": min(v["ess_bulk"] for v in summary.values()),
           "max_rhat": max(v["r_hat"] for v in summary.values()), "divergences": int(ck["diverging"].sum()),
           "gradient_evaluations": int(ck["n_steps"].sum()), "acceptance": float(ck["acceptance_rate"].mean()),
           "mean_tree_depth": float(ck["tree_depth"].mean()), "at_depth_cap": float(np.mean(ck["tree_depth"] >= depth))}
    out["ess_per_s"] = out["min_ess_bulk"] / float(ck["wall_s"])
    return out


def _print_sampler_row(r: dict):
    if r["stopped"]:
        print(f"  {r['method']:<10} record {r['record']}: STOPPED after {r['sampling_s']:.0f} s: "
              f"{r['warm_chunks_done']} warm-up chunks, {r['draws_done']} draws; step {r['step_size']}, "
              + (f"ESS {r['min_ess_bulk']:.0f}, R-hat {r['max_rhat']:.3f}, div {r['divergences']}+"
                 f"{r['warmup_divergences']}, acc {r['acceptance']:.2f}, depth {r['mean_tree_depth']:.1f} "
                 f"({100 * r['at_depth_cap']:.0f} % capped)" if "max_rhat" in r else ""), flush=True)
        return
    cov = " ".join(f"{n[:5]} {'in' if r[n]['covers'] else 'OUT'}" for n in ("stiffness", "restitution", "noise_sigma"))
    print(f"  {r['method']:<10} record {r['record']}: compile {r['compile_s']:5.0f} s, sampling {r['sampling_s']:6.0f} s, "
          f"ESS {r['min_ess_bulk']:6.0f}, ESS/s {r['ess_per_s']:6.3f}, R-hat {r['max_rhat']:.3f}, div "
          f"{r['divergences']}+{r['warmup_divergences']}, grads {r['gradient_evaluations']}, acc {r['acceptance']:.2f}, "
          f"depth {r['mean_tree_depth']:.1f} ({100 * r['at_depth_cap']:.0f} % capped), {cov}", flush=True)


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
    p.add_argument("--sampler", default="nuts", choices=("nuts", "random-walk"),
                   help="calibration: the posterior's sampler (default nuts, what the documented calibration used; "
                   "the random walk wants about 10x the draws)")
    p.add_argument("--speed", action="store_true")
    p.add_argument("--rw-factor", type=int, default=10, help="random-walk draws per NUTS draw")
    p.add_argument("--tolerance-speed", action="store_true",
                   help="runs per second of a tolerance study against the serial loop (issue 31, point 6)")
    p.add_argument("--tolerance-runs", type=int, default=64)
    p.add_argument("--samplers", action="store_true",
                   help="the samplers on independent-simulator records at the default window (issue 39, point 6)")
    p.add_argument("--lab-records", default="0,1,2,18", help="--samplers: bench_profile.py's records (0-based)")
    p.add_argument("--methods", default="nuts8:nuts:8:,nuts5:nuts:5:0.9,rw:random-walk:8:",
                   help="--samplers: NAME:SAMPLER:MAX_TREE_DEPTH:TARGET_ACCEPT (empty: the sampler's default), ...")
    p.add_argument("--max-seconds", type=float, default=0, help="--samplers: stop a method after this long (0: never)")
    p.add_argument("--json", default="benchmarks/results/uncertainty.json")
    args = p.parse_args()
    t0 = time.perf_counter()
    res = {"settings": vars(args), "machine": platform.platform(), "jax": jax.__version__,
           "device": str(jax.devices()[0])}
    if args.records:
        def save(partial):
            atomic_write_json(args.json, {**res, "calibration": partial}, indent=1)

        with locked_folder(os.path.dirname(args.json) or ".", "results folder"):
            res["calibration"] = calibration(args, save)
    if args.samplers:
        rows = []
        try:
            with open(args.json) as f:
                old = json.load(f)
            keep = ("chains", "warmup", "draws", "chunk", "max_seconds")
            if all(old["settings"].get(k) == getattr(args, k) for k in keep):
                rows = old.get("samplers", {}).get("rows", [])
        except (OSError, ValueError, KeyError):
            pass

        def save_samplers(partial):
            atomic_write_json(args.json, {**res, "samplers": partial}, indent=1)

        res["samplers"] = samplers(args, save_samplers, rows)
    if args.speed:
        res["speed"] = speed(args)
    if args.tolerance_speed:
        res["tolerance_speed"] = tolerance_speed(args)
    res["wall_s"] = time.perf_counter() - t0
    atomic_write_json(args.json, res, indent=1)
    print(f"wrote {args.json} ({res['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
