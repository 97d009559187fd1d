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
import inspect
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
from jaxclear.integrate.compile import jit  # noqa: E402
from jaxclear.integrate.runs import revolution_settings  # noqa: E402
from jaxclear.integrate.simulate import _postprocess  # noqa: E402
from jaxclear.integrate.state import State  # noqa: E402


def measure(fn, repeats):
    jax.block_until_ready(fn())
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        jax.block_until_ready(fn())
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--coarse", type=int, default=241, help="samples of the coarse grid (default 241)")
    ap.add_argument("--fine", type=int, default=24001, help="samples of the fine grid (default 24001)")
    ap.add_argument("--repeats", type=int, default=7, help="timed repeats, median (default 7)")
    ap.add_argument("--json", default=str(HERE / "results" / "output.json"), help="JSON output file")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    mech = jc.preset("flores-slider-crank")
    def unpacked(m, v):
        return jax.vmap(lambda x: State.unpack(x, m))(v)
    if len(inspect.signature(_postprocess).parameters) == 4:  # before 2026-11-24: (mech, s, ts, ys)
        post = jit(lambda m, s, ts, v: _postprocess(m, s, ts, unpacked(m, v)))
    else:
        post = jit(lambda m, s, ts, v: _postprocess(m, s, ts, v, unpacked(m, v)))
    rows, res = [], {}
    for n in (args.coarse, args.fine):
        s = revolution_settings(mech, 1.0, n_out=n)
        sol = jc.simulate(mech, s)
        packed = jax.vmap(lambda q, qd, e: State(q, qd, e).pack())(sol.q, sol.qdot, sol.element_states)
        run = measure(lambda: jc.simulate(mech, s), args.repeats)
        pp = measure(lambda: post(mech, s, sol.ts, packed), args.repeats)
        res[n] = {"steps": int(sol.num_steps), "simulate_wall_s": run[0], "simulate_cpu_s": run[1],
                  "postprocess_wall_s": pp[0], "postprocess_cpu_s": pp[1]}
    c, f = res[args.coarse], res[args.fine]
    extra = args.fine - args.coarse
    lines = [f"{'':<44}{'wall':>12}{'cpu':>12}", "-" * 68]
    for n in (args.coarse, args.fine):
        r = res[n]
        label = f"jc.simulate, {n} samples ({r['steps']} steps)"
        lines.append(f"{label:<44}"
                     f"{r['simulate_wall_s'] * 1e3:>10.1f}ms{r['simulate_cpu_s'] * 1e3:>10.1f}ms")
        lines.append(f"{'  of which output post-processing':<44}"
                     f"{r['postprocess_wall_s'] * 1e3:>10.1f}ms{r['postprocess_cpu_s'] * 1e3:>10.1f}ms")
    for key, label in (("wall", "wall"), ("cpu", "cpu")):
        d = f[f"simulate_{key}_s"] - c[f"simulate_{key}_s"]
        lines.append(f"per extra sample ({label}): {d / extra * 1e6:.2f} us; fine grid adds "
                     f"{d / c[f'simulate_{key}_s']:.0%} to the run")
    load1 = os.getloadavg()[0]
    lines.append(f"load average (1 min) at start / end: {load0:.2f} / {load1:.2f} on {os.cpu_count()} CPUs")
    text = "\n".join(lines)
    print(text)
    out = {"benchmark": "output", "results": {str(k): v for k, v in res.items()}, "load_average": [load0, load1],
           "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), "table": text}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
