#!/usr/bin/env python
"""Sweep throughput: simulations per second against the batch size.

The same ``--runs`` simulations of the Flores benchmark (``jc.preset("flores-slider-crank")``,
5000 rpm, Lankarani-Nikravesh, ``--revolutions`` crank revolutions, Tsit5 at rtol 1e-6 and
atol 1e-9, ``--samples`` output samples per revolution, clearance 0.25 to 1.0 mm and
restitution 0.5 to 0.95 drawn from a fixed grid) are computed

* by the sweep's compiled chunk function (``jaxclear.sweep._run_chunk``: the per-run function
  mapped over a device's rows inside ``jax.shard_map``) in chunks of each ``--batch-sizes``
  value, on one device, in each of the ``--modes``: ``auto`` (what a sweep does: on CPU with
  single-kernel loops the runs of a device one after another, ``jax.lax.map``) and ``vmap``
  (side by side, ``Plan(side_by_side=True)``);
* by a serial Python loop over the *same* per-run function (``jaxclear.sweep.run_outputs``,
  unbatched, jitted once with ``equinox.filter_jit``), one call per run; this is the baseline of
  the "vs serial" column and of the issue's target. The sweep integrates with diffrax's
  ``while_loop`` over the Runge-Kutta stages (``Settings(stages="loop")``), the faster form
  under ``vmap``;
* by the same serial loop with the stages unrolled (``stages="unrolled"``), reported alongside;
* by the plain SciPy implementation (``benchmarks/scipy_reference.py``, RK45, same tolerances,
  same output grid) for the first ``--scipy-runs`` runs;
* (``--two-devices``) in a child process with two host CPU devices forced
  (``XLA_FLAGS=--xla_force_host_platform_device_count=2``): the chunk function sharded over both
  devices against the same chunks on one device, with ``--two-devices-samples`` output samples
  per revolution (default: ``--samples``). The compiled chunk calls no LAPACK kernel, so the
  jaxlib 0.10 thread-pool deadlock of batched LAPACK calls, which once forced few samples and
  small per-device batches here, cannot occur.

Every jaxclear row runs the per-run metrics too (no ideal-joint reference run, so that the work
equals SciPy's: one clearance simulation per run). Throughput = runs / wall time of the whole
set after compilation; compile = first chunk call - the mean chunk time. A vmapped batch runs
until its slowest member is done (the others idle, masked), so the table also gives the lane
efficiency of the vmap rows: total solver steps / (sum over chunks of batch size x the chunk's
largest step count).

Run from the repository root (about 3 to 5 minutes on 2 cores)::

    PYTHONPATH=. python benchmarks/bench_sweep.py
    PYTHONPATH=. python benchmarks/bench_sweep.py --batch-sizes 1,4,16 --runs 16 --scipy-runs 2

Timings on a shared machine are noisy: the script records the load average at start and end.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (str(ROOT), str(HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)


def _grid(n: int) -> np.ndarray:
    """``n`` (clearance, restitution) pairs spread over 0.25-1.0 mm x 0.5-0.95 (deterministic)."""
    rng = np.random.default_rng(20261121)
    c = rng.uniform(0.25e-3, 1.0e-3, n)
    r = rng.uniform(0.5, 0.95, n)
    return np.stack([c, r], axis=-1)


def _config(args, values, chunk, devices=1):
    from jaxclear import sweep

    return sweep.SweepConfig(list={"clearance": values[:, 0].tolist(), "restitution": values[:, 1].tolist()},
                             revolutions=args.revolutions, samples_per_revolution=args.samples, solver="tsit5",
                             rtol=1e-6, atol=1e-9, ideal_reference=False, chunk_size=chunk, devices=devices,
                             progress=False, out=os.devnull)


def _plan(cfg, mesh):
    from jaxclear import sweep

    return sweep.make_plan(cfg, mesh, trajectories=False, ideal=False)


def time_batched(args, values, batch: int, devices: int = 1, mode: str = "auto") -> dict:
    """All runs in chunks of ``batch`` through the sweep's chunk function (padded last chunk);
    ``mode`` ``"vmap"``: side by side on each device, ``"auto"``: as a sweep chooses."""
    import dataclasses

    import jax

    from jaxclear import sweep

    cfg = _config(args, values, batch, devices)
    mesh = sweep.make_mesh(devices)
    plan = _plan(cfg, mesh)
    if mode == "vmap":
        plan = dataclasses.replace(plan, side_by_side=True)
    side = not sweep.batch.one_by_one(plan)
    n = len(values)
    chunks = []
    for lo in range(0, n, batch):
        rows = values[lo:lo + batch]
        chunks.append(np.concatenate([rows, np.repeat(rows[-1:], batch - len(rows), axis=0)]))
    t = time.perf_counter()
    jax.block_until_ready(sweep._run_chunk(sweep._put(chunks[0], mesh), cfg.base_mechanism, None, plan))
    first = time.perf_counter() - t
    steps, lane_slots, status = [], 0, []
    t = time.perf_counter()
    for k, chunk in enumerate(chunks):
        out = sweep._fetch(sweep._run_chunk(sweep._put(chunk, mesh), cfg.base_mechanism, None, plan))
        real = min(batch, n - k * batch)
        steps.extend(out["num_steps"][:real].tolist())
        status.extend(out["status"][:real].tolist())
        lane_slots += batch * int(np.max(out["num_steps"]))
    wall = time.perf_counter() - t
    kind = "vmap chunks" if side else "chunks, one after another"
    return {"method": f"{kind}, {devices} device{'s' if devices > 1 else ''}",
            "batch": batch, "devices": devices, "runs": n, "first_call_s": first,
            "compile_s": max(first - wall / len(chunks), 0.0), "wall_s": wall, "sims_per_s": n / wall,
            "steps_total": int(sum(steps)), "steps_max": int(max(steps)), "lane_efficiency": sum(steps) / lane_slots if side else None,
            "failed": int(sum(1 for s in status if s != 0))}


def time_serial(args, values, stages="loop") -> dict:
    """A Python loop over the unbatched per-run function, jitted once. ``stages="loop"`` is the
    sweep's own per-run function; ``"unrolled"`` the same with the Runge-Kutta stages unrolled,
    which is what ``jc.simulate`` does by default for a single run (the fastest serial path)."""
    import dataclasses

    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from jaxclear import sweep
    from jaxclear.sweep import batch

    cfg = _config(args, values, 1)
    plan = _plan(cfg, None)
    original = batch._settings
    if stages != "loop":
        batch._settings = lambda plan, m: dataclasses.replace(original(plan, m), stages=stages)
    try:
        # a fresh function object per call: jit caches compilations by function, and the
        # stages setting is read inside it
        f = eqx.filter_jit(lambda *a: sweep.run_outputs(*a))
        mech = cfg.base_mechanism
        t = time.perf_counter()
        jax.block_until_ready(f(plan, mech, None, jnp.asarray(values[0])))
        first = time.perf_counter() - t
        steps, status = [], []
        t = time.perf_counter()
        for row in values:
            out = jax.block_until_ready(f(plan, mech, None, jnp.asarray(row)))
            steps.append(int(out["num_steps"]))
            status.append(int(out["status"]))
        wall = time.perf_counter() - t
    finally:
        batch._settings = original
    n = len(values)
    method = ("serial loop (same function, jitted, unbatched)" if stages == "loop"
              else "serial loop, unrolled stages")
    return {"method": method, "batch": 1, "devices": 1, "runs": n,
            "first_call_s": first, "compile_s": max(first - wall / n, 0.0), "wall_s": wall, "sims_per_s": n / wall,
            "steps_total": int(sum(steps)), "steps_max": int(max(steps)), "lane_efficiency": 1.0,
            "failed": int(sum(1 for s in status if s != 0))}


def time_scipy(args, values) -> dict:
    """The SciPy reference (RK45), one run after another, same t_end and output grid."""
    import scipy_reference as ref

    n = len(values)
    t_end = args.revolutions * 60.0 / 5000.0
    ts = np.linspace(0.0, t_end, int(round(args.revolutions * args.samples)) + 1)
    t = time.perf_counter()
    nfev = 0
    for c, r in values:
        p = ref.params(R_J=0.010 - c, c_r=r)
        out = ref.simulate(p, t_end, ts=ts, rtol=1e-6, atol=1e-9, method="RK45")
        nfev += int(out["nfev"])
    wall = time.perf_counter() - t
    return {"method": "SciPy solve_ivp RK45 (scipy_reference.py), serial", "batch": 1, "devices": 1, "runs": n,
            "first_call_s": None, "compile_s": 0.0, "wall_s": wall, "sims_per_s": n / wall, "steps_total": None,
            "steps_max": None, "lane_efficiency": None, "failed": 0, "rhs_evaluations": nfev}


def machine_info() -> dict:
    import jax

    cpu = None
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), None)
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {"date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "platform": platform.platform(), "cpu_model": cpu, "cpus_usable": usable,
            "python": platform.python_version(), "jax": jax.__version__, "backend": jax.default_backend(),
            "devices": [str(d) for d in jax.devices()], "XLA_FLAGS": os.environ.get("XLA_FLAGS")}


def table(rows: list[dict], serial_rate: float) -> str:
    head = (f"{'method':<52} {'batch':>5} {'dev':>3} {'compile s':>9} {'wall s':>8} {'sims/s':>7} "
            f"{'vs serial':>9} {'steps max':>9} {'steps tot':>9} {'us/step':>7} {'lane eff':>8}")
    lines = [head, "-" * len(head)]
    for r in rows:
        def f(v, spec):
            return "-" if v is None else format(v, spec)
        ratio = "        -" if r.get("child") else f"{r['sims_per_s'] / serial_rate:8.2f}x"
        lines.append(f"{r['method'][:52]:<52} {r['batch']:>5} {r['devices']:>3} {f(r['compile_s'], '9.1f')} "
                     f"{r['wall_s']:8.2f} {r['sims_per_s']:7.2f} {ratio} "
                     f"{f(r['steps_max'], '9d')} {f(r.get('steps_total'), '9d')} "
                     f"{f(1e6 * r['wall_s'] / r['steps_total'] if r.get('steps_total') else None, '7.1f')} "
                     f"{f(r['lane_efficiency'], '8.2f')}")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=32, help="simulations per method (default 32)")
    p.add_argument("--revolutions", type=float, default=1.0, help="crank revolutions per run (default 1)")
    p.add_argument("--samples", type=int, default=200, help="output samples per revolution (default 200)")
    p.add_argument("--batch-sizes", default="1,2,4,8,16,32", help="chunk sizes, comma-separated (default 1,2,4,8,16,32)")
    p.add_argument("--scipy-runs", type=int, default=4, help="runs of the SciPy reference (default 4; 0 skips)")
    p.add_argument("--two-devices", default="4,8,16",
                   help="chunk sizes sharded over 2 forced host devices in a child process ('' skips; default 4,8,16)")
    p.add_argument("--two-devices-samples", type=int, default=None,
                   help="output samples per revolution in the two-device rows (default: --samples)")
    p.add_argument("--modes", default="auto,vmap",
                   help="chunk modes, comma-separated: auto (what a sweep does), vmap (runs side by side); default both")
    p.add_argument("--json", default=str(HERE / "results" / "sweep.json"), help="where the JSON results go")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    values = _grid(args.runs)
    sizes = [int(s) for s in args.batch_sizes.split(",") if s]
    modes = [m for m in args.modes.split(",") if m]
    if not modes or set(modes) - {"auto", "vmap"}:
        p.error(f"--modes: a comma-separated list of auto and vmap, got {args.modes!r}")

    if args.child:  # two forced host devices: sharded rows and the same chunks on one device
        rows = []
        for mode in modes:
            for b in sizes:
                for devices in (1, 2):
                    rows.append(time_batched(args, values, b, devices=devices, mode=mode))
                    rows[-1]["method"] += f" ({args.samples}/rev)"
                    rows[-1]["mode"] = mode
        print(json.dumps(rows))
        return 0

    import jax  # noqa: F401  (after argument parsing: --help stays fast)

    import jaxclear  # noqa: F401

    load_start = os.getloadavg()
    t0 = time.perf_counter()
    rows = []
    print(f"serial loop of {args.runs} runs...", file=sys.stderr, flush=True)
    serial = time_serial(args, values)
    rows.append(serial)
    print(f"serial loop of {args.runs} runs, unrolled stages...", file=sys.stderr, flush=True)
    serial_unrolled = time_serial(args, values, stages="unrolled")
    rows.append(serial_unrolled)
    for mode in modes:
        for b in sizes:
            print(f"chunks of {b}, mode {mode}...", file=sys.stderr, flush=True)
            rows.append(dict(time_batched(args, values, b, mode=mode), mode=mode))
    if args.two_devices:
        print(f"two host devices, chunks of {args.two_devices} (child process)...", file=sys.stderr, flush=True)
        env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2",
                   PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        cmd = [sys.executable, __file__, "--child", "--runs", str(args.runs), "--revolutions", str(args.revolutions),
               "--samples", str(args.two_devices_samples or args.samples), "--batch-sizes", args.two_devices,
               "--modes", args.modes]
        done = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if done.returncode == 0:
            child_rows = json.loads(done.stdout.strip().splitlines()[-1])
            for r in child_rows:
                r["child"] = True
            rows.extend(child_rows)
        else:
            print(done.stderr[-2000:], file=sys.stderr)
    if args.scipy_runs:
        print(f"SciPy reference, {args.scipy_runs} runs...", file=sys.stderr, flush=True)
        rows.append(time_scipy(args, values[: args.scipy_runs]))
    load_end = os.getloadavg()
    info = machine_info()
    single = [r for r in rows if r.get("mode") and r["devices"] == 1 and not r.get("child")]
    best = max(single, key=lambda r: r["sims_per_s"])
    best_mode = {m: max((r for r in single if r["mode"] == m), key=lambda r: r["sims_per_s"]) for m in modes}
    title = (f"sweep throughput: flores-slider-crank, {args.revolutions:g} revolution(s) per run at 5000 rpm, "
             f"tsit5 rtol 1e-6 atol 1e-9, {int(round(args.revolutions * args.samples)) + 1} samples, "
             f"{args.runs} runs (clearance 0.25-1 mm x c_r 0.5-0.95)")
    text = [title, "=" * len(title), table(rows, serial["sims_per_s"]), "",
            f"best single-device chunks: {best['sims_per_s'] / serial['sims_per_s']:.2f}x the serial loop "
            f"({best['method']}, batch {best['batch']}); target >= 2x: "
            f"{'met' if best['sims_per_s'] >= 2 * serial['sims_per_s'] else 'NOT met'}",
            "best per mode, one device: " + ", ".join(
                f"{m} {r['sims_per_s']:.0f} sims/s (batch {r['batch']})" for m, r in best_mode.items()),
            f"against the fastest serial path (unrolled stages): "
            f"{best['sims_per_s'] / serial_unrolled['sims_per_s']:.2f}x",
            "per solver step (wall / total steps; insensitive to which runs happen to take many steps): "
            f"batch {best['batch']} {1e6 * best['wall_s'] / best['steps_total']:.1f} us, serial "
            f"{1e6 * serial['wall_s'] / serial['steps_total']:.1f} us, serial unrolled "
            f"{1e6 * serial_unrolled['wall_s'] / serial_unrolled['steps_total']:.1f} us",
            f"load average (1 min) at start / end: {load_start[0]:.2f} / {load_end[0]:.2f} "
            f"({info['cpus_usable']} usable CPUs; other processes share them: timings are noisy)",
            f"machine: {info['platform']}, {info['cpu_model']}, jax {info['jax']} on {info['devices']}; "
            f"{info['date_utc']}; whole script {time.perf_counter() - t0:.0f} s"]
    pairs = [(a, b) for a, b in zip(rows, rows[1:]) if a.get("child") and b.get("child") and a["devices"] == 1
             and b["devices"] == 2 and a["batch"] == b["batch"] and a["mode"] == b["mode"]]
    if pairs:
        text.insert(4, "two devices / one device (same chunks, child process): " + ", ".join(
            f"{a['mode']} batch {a['batch']}: {b['sims_per_s'] / a['sims_per_s']:.2f}x" for a, b in pairs))
    print("\n".join(text))
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"config": vars(args), "rows": rows, "machine": info, "load_average_start": load_start,
                   "load_average_end": load_end, "table": "\n".join(text)}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
