#!/usr/bin/env python
"""Dense output: the cost of output samples on the benchmark slider-crank.

One crank revolution of ``jc.preset("flores-slider-crank")`` (the same solver steps for every
grid), steady-state time of ``jc.simulate`` with ``--coarse`` and ``--fine`` output samples; the
difference divided by the extra samples is the cost per sample. Also split: the output
post-processing (accelerations, reactions and contact outputs at every sample) timed alone.
Both wall time and process CPU time are reported (CPU time is less sensitive to other
processes on a shared machine).

    PYTHONPATH=. python benchmarks/bench_output.py        # table + benchmarks/results/output.json
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import sys
import time
from pathlib import Path

import jax

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

import jaxclear as jc  # noqa: E402
from jaxclear.integrate._compile import jit  # noqa: E402
from jaxclear.integrate._runs import revolution_settings  # noqa: E402
from jaxclear.integrate._solve import _postprocess  # noqa: E402
from jaxclear.integrate._state import State  # noqa: E402


def measure(fns: dict, repeats: int) -> dict:
    """Median wall and CPU time of each ``fns[key]()``, the calls interleaved (round after
    round over all keys: on this machine the first-measured of several variants timed one
    after another came out slowest, up to 2x)."""
    for fn in fns.values():
        jax.block_until_ready(fn())
    wall = {k: [] for k in fns}
    cpu = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            jax.block_until_ready(fn())
            wall[k].append(time.perf_counter() - t0)
            cpu[k].append(time.process_time() - c0)
    return {k: (statistics.median(wall[k]), statistics.median(cpu[k])) for k in fns}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--coarse", type=int, default=241, help="samples of the coarse grid (default 241)")
    ap.add_argument("--fine", type=int, default=24001, help="samples of the fine grid (default 24001)")
    ap.add_argument("--repeats", type=int, default=15, help="timed rounds, median (default 15)")
    ap.add_argument("--json", default=str(HERE / "results" / "output.json"), help="JSON output file")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    mech = jc.preset("flores-slider-crank")
    post = jit(lambda m, s, ts, v: _postprocess(m, s, ts, v, jax.vmap(lambda x: State.unpack(x, m))(v)))
    runs, posts, steps = {}, {}, {}
    for sampling in ("loop", "block"):
        for n in (args.coarse, args.fine):
            s = revolution_settings(mech, 1.0, n_out=n, sampling=sampling)
            sol = jc.simulate(mech, s)
            steps[(sampling, n)] = int(sol.num_steps)
            runs[(sampling, n)] = (lambda s=s: jc.simulate(mech, s))
            if sampling == "loop":
                packed = jax.vmap(lambda q, qd, e: State(q, qd, e).pack())(sol.q, sol.qdot, sol.element_states)
                posts[n] = (lambda s=s, ts=sol.ts, v=packed: post(mech, s, ts, v))
    timed = measure({**runs, **{("post", n): f for n, f in posts.items()}}, args.repeats)
    extra = args.fine - args.coarse
    lines = [f"{'':<52}{'wall':>10}{'cpu':>10}{'us/step':>10}", "-" * 82]
    res = {}
    for sampling in ("loop", "block"):
        for n in (args.coarse, args.fine):
            w, c = timed[(sampling, n)]
            st = steps[(sampling, n)]
            lines.append(f"{f'sampling={sampling!r}, {n} samples ({st} steps)':<52}{w * 1e3:>8.1f}ms{c * 1e3:>8.1f}ms"
                         f"{w / st * 1e6:>10.1f}")
            res[f"{sampling}_{n}"] = {"steps": st, "simulate_wall_s": w, "simulate_cpu_s": c}
        a, b = res[f"{sampling}_{args.coarse}"], res[f"{sampling}_{args.fine}"]
        d = b["simulate_wall_s"] - a["simulate_wall_s"]
        per_step = b["simulate_wall_s"] / b["steps"] / (a["simulate_wall_s"] / a["steps"]) - 1
        lines.append(f"  fine grid adds {d / a['simulate_wall_s']:.0%} to the run ({d / extra * 1e6:.2f} us per extra "
                     f"sample; per step {per_step:+.0%}, the step counts differing)")
    base = res[f"loop_{args.coarse}"]["simulate_wall_s"]
    d = res[f"block_{args.fine}"]["simulate_wall_s"] - base
    lines.append(f"sampling='block' with {args.fine} samples against the default ('loop') with {args.coarse}: "
                 f"{d / base:+.0%} ({d / extra * 1e6:.2f} us per extra sample)")
    res["block_fine_over_default_coarse"] = d / base
    for n in (args.coarse, args.fine):
        w, c = timed[("post", n)]
        lines.append(f"{f'  output post-processing alone, {n} samples':<52}{w * 1e3:>8.1f}ms{c * 1e3:>8.1f}ms")
        res[f"postprocess_{n}"] = {"wall_s": w, "cpu_s": c}
    load1 = os.getloadavg()[0]
    lines.append(f"load average (1 min) at start / end: {load0:.2f} / {load1:.2f} on {os.cpu_count()} CPUs")
    text = "\n".join(lines)
    print(text)
    out = {"benchmark": "output", "results": res, "load_average": [load0, load1],
           "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), "table": text}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
