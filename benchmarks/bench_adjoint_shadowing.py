"""Tangent against adjoint shadowing as the parameters grow (issue 44): ``jaxclear.shadowing.nilss``
(one tangent per parameter) and ``jaxclear.shadowing.nilsas`` (n_u + 1 adjoints, whatever the
parameters) on Lorenz 63 (sigma 10, rho 28, beta 8/3) with ``p`` parameters: constant forcings
``B s`` added to the vector field at ``s = 0``, ``B`` (3 x p) the identity in its first three columns
and standard normal numbers after, objective ``z``.

For each ``p`` and method: the first call (compilation and run, in this process) and the steady
state (the best of ``--repeats`` further calls) [s], the solver's accepted steps, and the
derivatives: the first three (the unit forcings of x, y and z) with their standard errors, the
largest difference between the two methods in combined standard errors over all ``p``, and, for
NILSAS, how far its derivative is from ``B^T`` times its own three unit forcings' (the adjoint is the
same for every ``p``: zero up to rounding). A finite-difference estimate needs a regression of
long-time averages per parameter: its cost for one parameter is measured once (7 values x 8
members x 500 time units, the regression of tests/test_shadowing.py) and multiplied by ``p``.

``python benchmarks/bench_adjoint_shadowing.py [--parameters 3,12,48,192] [--segments 400]
[--repeats 2] [--json PATH]``: prints a table and writes the JSON after every run (a killed run
resumes with the runs done; the output folder is locked while it runs).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import jaxclear  # noqa: F401  (float64 first)
import jax
import jax.numpy as jnp
import numpy as np

from jaxclear._storage import atomic_write_json, locked_folder
from jaxclear.shadowing import nilsas, nilss

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_JSON = os.path.join(HERE, "results", "adjoint_shadowing.json")
U0 = jnp.array([1.0, 1.0, 25.0])
METHODS = {"NILSS": nilss, "NILSAS": nilsas}


def weights(p: int) -> np.ndarray:
    """``B`` (3, p): the unit forcings of x, y, z first, then random columns (seed 0)."""
    rng = np.random.default_rng(0)
    return np.concatenate([np.eye(3), rng.normal(size=(3, p - 3))], axis=1)


def forced_lorenz(B):
    B = jnp.asarray(B)

    def f(u, s):
        x, y, z = u
        return jnp.stack([10.0 * (y - x), x * (28.0 - z) - y, x * y - 8.0 / 3.0 * z]) + B @ s

    return f


def height(u, s):
    return u[2]


def run(method: str, p: int, segments: int, repeats: int) -> dict:
    f, s = forced_lorenz(weights(p)), jnp.zeros(p)
    options = dict(n_unstable=1, segment_time=0.25, segments=segments, members=4, transient=20.0, rtol=1e-7,
                   atol=1e-7, discard=8)
    t0 = time.perf_counter()
    r = METHODS[method](f, U0, s, height, **options)
    first = time.perf_counter() - t0
    steady = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        METHODS[method](f, U0, s, height, **options)
        steady.append(time.perf_counter() - t0)
    return {"method": method, "p": p, "segments": segments, "first_s": first, "steady_s": min(steady),
            "steps": int(np.sum(np.asarray(r.steps))), "derivative": np.asarray(r.derivative).tolist(),
            "error": np.asarray(r.derivative_error).tolist(),
            "member_derivatives": np.asarray(r.member_derivatives).tolist(), "average": float(r.average)}


def regression_seconds() -> float:
    """One parameter's regression of long-time averages (tests/test_shadowing.py's, compiled first)."""
    sys.path.insert(0, os.path.join(HERE, "..", "tests"))
    from test_shadowing import regression_slope

    rhos = np.linspace(25.0, 31.0, 7)
    regression_slope(rhos)  # compile
    t0 = time.perf_counter()
    regression_slope(rhos)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("--parameters", default="3,12,48,192", help="comma-separated counts p (each >= 3)")
    a.add_argument("--segments", type=int, default=400, help="segments of 0.25 time units a member (4 members)")
    a.add_argument("--repeats", type=int, default=2, help="further calls timed for the steady state")
    a.add_argument("--json", default=DEFAULT_JSON)
    args = a.parse_args(argv)
    counts = [int(x) for x in args.parameters.split(",")]
    if min(counts) < 3:
        a.error(f"--parameters must each be >= 3 (the unit forcings of x, y, z), got {args.parameters}")
    path = os.path.abspath(args.json)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with locked_folder(os.path.dirname(path)):
        data = {"runs": []}
        if os.path.exists(path):
            with open(path, encoding="utf-8") as fh:
                data = json.load(fh)
        data["meta"] = {"date": time.strftime("%Y-%m-%d"), "cpus": os.cpu_count(), "jax": jax.__version__,
                        "command": "python benchmarks/bench_adjoint_shadowing.py " + " ".join(argv or sys.argv[1:])}
        if "regression_s" not in data:
            data["regression_s"] = regression_seconds()
            atomic_write_json(path, data)
        for p in counts:
            for method in METHODS:
                if any(r["method"] == method and r["p"] == p and r["segments"] == args.segments for r in data["runs"]):
                    continue
                print(f"{method} with {p} parameters ...", flush=True)
                data["runs"].append(run(method, p, args.segments, args.repeats))
                atomic_write_json(path, data)
    print(f"\nLorenz 63, 4 members x {args.segments} segments of 0.25; a regression of averages: "
          f"{data['regression_s']:.1f} s a parameter\n")
    print(f"{'p':>4s} {'method':7s} {'first [s]':>9s} {'steady [s]':>10s} {'steps':>8s} {'d<z>/dF_x':>18s} "
          f"{'d<z>/dF_y':>18s} {'d<z>/dF_z':>18s} {'max |diff| / se':>15s} {'B^T check':>10s} {'regression [s]':>14s}")
    for p in counts:
        rows = {r["method"]: r for r in data["runs"] if r["p"] == p and r["segments"] == args.segments}
        for method, r in rows.items():
            other = rows.get("NILSS" if method == "NILSAS" else "NILSAS")
            diff = "-"
            if other:
                d, e = np.asarray(r["derivative"]), np.asarray(r["error"])
                do, eo = np.asarray(other["derivative"]), np.asarray(other["error"])
                diff = f"{np.max(np.abs(d - do) / np.hypot(e, eo)):.2f}"
            check = "-"
            if method == "NILSAS":
                m = np.asarray(r["member_derivatives"])
                want = m[:, :3] @ weights(p)
                check = f"{np.max(np.abs(m - want)) / np.max(np.abs(want)):.1e}"
            cells = " ".join(f"{r['derivative'][k]:9.4f} +- {r['error'][k]:.4f}" for k in range(3))
            print(f"{p:4d} {method:7s} {r['first_s']:9.1f} {r['steady_s']:10.2f} {r['steps']:8d} {cells} "
                  f"{diff:>15s} {check:>10s} {p * data['regression_s']:14.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
