#!/usr/bin/env python
"""Command-line startup: wall time of ``jaxclear simulate`` in fresh processes, with a fresh
(cold) and a filled (warm) persistent compilation cache, and with the cache off.

Each run is a new Python process (``python -m jaxclear simulate ...``) on the benchmark preset
(``flores-slider-crank``, ``--revolutions`` 1 by default, plots included, so the ideal-joint run
for the slider-acceleration overlay is part of it). The cache folder is a fresh temporary folder
(``JAXCLEAR_CACHE_DIR``); nothing in the user's cache is read or written. Also timed: ``import
jaxclear`` alone and ``jaxclear presets`` (no compilation).

    PYTHONPATH=. python benchmarks/bench_startup.py            # table + benchmarks/results/startup.json
    PYTHONPATH=. python benchmarks/bench_startup.py --repeats 3

The machine's load average is printed and stored: on a shared machine every number grows with it.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def timed(cmd, env):
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--revolutions", type=float, default=1.0, help="crank revolutions (default 1)")
    ap.add_argument("--repeats", type=int, default=1, help="warm-cache runs (default 1)")
    ap.add_argument("--json", default=str(HERE / "results" / "startup.json"), help="JSON output file")
    args = ap.parse_args(argv)

    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    py = sys.executable
    rows = []
    with tempfile.TemporaryDirectory(prefix="jaxclear-startup-") as tmp:
        out = os.path.join(tmp, "out")
        sim = [py, "-m", "jaxclear", "simulate", "--preset", "flores-slider-crank",
               "--revolutions", str(args.revolutions), "--out", out]
        load0 = os.getloadavg()[0]
        rows.append(("import jaxclear", timed([py, "-c", "import jaxclear"], env)))
        rows.append(("jaxclear presets", timed([py, "-m", "jaxclear", "presets"], env)))
        off = dict(env, JAXCLEAR_CACHE_DIR="off")
        rows.append(("simulate, cache off", timed(sim, off)))
        on = dict(env, JAXCLEAR_CACHE_DIR=os.path.join(tmp, "cache"))
        rows.append(("simulate, cold cache (fresh folder)", timed(sim, on)))
        for i in range(args.repeats):
            rows.append((f"simulate, warm cache (run {i + 1})", timed(sim, on)))
        entries = sorted(Path(tmp, "cache").glob("*-cache"))
        size = sum(p.stat().st_size for p in entries)
        load1 = os.getloadavg()[0]

    lines = [f"{'fresh process':<40}{'wall [s]':>10}", "-" * 50]
    lines += [f"{name:<40}{wall:>10.2f}" for name, wall in rows]
    lines += ["", f"cache entries written: {len(entries)} ({size / 1e6:.1f} MB)",
              f"load average (1 min) at start / end: {load0:.2f} / {load1:.2f} on {os.cpu_count()} CPUs"]
    text = "\n".join(lines)
    print(text)
    result = {
        "benchmark": "startup", "revolutions": args.revolutions, "rows": dict(rows),
        "cache_entries": len(entries), "cache_bytes": size, "load_average": [load0, load1],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()},
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), "table": text,
    }
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
