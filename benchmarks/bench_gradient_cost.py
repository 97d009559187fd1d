"""Cost of a derivative at equal accuracy: the sensitivities and the loop, each at its cheapest tolerance.

``bench_gradients.py`` compares the sensitivities at the DEFAULT settings with the loop's
derivative (``adjoint="forward"``: ``jax.jacfwd`` through diffrax's loop, steps sized for the
values) tightened until it is as accurate. The sensitivities at the default are often far more
accurate than the issue's 1e-3, so this script compares both methods at the same accuracy, each
at its own cheapest setting: per case, every setting of a ladder is timed in one process and
its worst error measured on the derivatives whose true value is settled (the references of
``bench_gradients.py --summary``: central differences of rtol 1e-10 runs where their plateau is
within 1e-3, the converged sensitivities where they decided the verdict); then, for an
accuracy target (1e-3, the issue's), the cheapest setting of each method within it.

Ladder: the sensitivities at rtol 1e-6 with ``derivative_tolerance`` 0.1 (the default) and 1,
at rtol 1e-5 with 0.1 and 1, at rtol 1e-4 with 1; the loop at rtol 1e-6 (its default) to 1e-10
by decades (atol = rtol 1e-3 throughout). Beside each time: the number of solver steps (the
sensitivity solve's own, accepted and rejected) and the time per step.

Needs the raw arrays of a ``bench_gradients.py`` run with ``--converged`` (``results/raw/``,
not committed). Cases: by default those where the tightened loop reached the sensitivities'
accuracy in ``results/gradients.json`` (its ``settled_accuracy``: in the others no loop
tolerance down to 1e-10 reaches 1e-3 at all); ``--cases all`` or ``--cases
lubricated:0:2,slider-crank:0:2`` (``case:friction:exponent``).

Usage: python benchmarks/bench_gradient_cost.py [--cases ...] [--repeats 3]
[--json benchmarks/results/gradient_cost.json]. Writes after each case; a second run skips the
cases already in the JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import bench_gradients as bg
import jaxclear as jc
from jaxclear._storage import atomic_write_json

#: (method, rtol, derivative_tolerance): the ladder, cheapest-looking first within each method
LADDER = (("sensitivities", 1e-4, 1.0), ("sensitivities", 1e-5, 1.0), ("sensitivities", 1e-5, 0.1),
          ("sensitivities", 1e-6, 1.0), ("sensitivities", 1e-6, 0.1),
          ("loop", 1e-6, None), ("loop", 1e-7, None), ("loop", 1e-8, None), ("loop", 1e-9, None), ("loop", 1e-10, None))
TARGET = 1e-3
RESULTS = Path(__file__).parent / "results"


def _label(method, rtol, f):
    return f"{method} rtol {rtol:g}" + (f" x{f:g}" if f is not None else "")


def _settings(case, method, rtol, f):
    tol = dict(rtol=rtol, atol=rtol * 1e-3, max_steps=4_000_000)
    if method == "loop":
        return jc.settings(case.t_end, n_out=case.n_out, adjoint="forward", **tol)
    return jc.settings(case.t_end, n_out=case.n_out, derivative_tolerance=f, **tol)


def references(raw, case, mech, record, x0):
    """The settled derivatives of a case (:func:`bench_gradients.settled_references`)."""
    blocks = bg._blocks(bg._function(case, mech, record, jc.settings(case.t_end, n_out=case.n_out)), x0)
    return bg.settled_references(raw, bg.per_parameter(raw, list(case.names), blocks), blocks, case.names)


def run_case(spec: str, repeats: int, raw_json: Path) -> dict:
    name, mu, n = spec.split(":")
    mu, n = float(mu), float(n)
    case = bg.CASES[name]
    mech, x0 = bg._nominal(case, mu, n)
    raw = dict(np.load(bg._raw_path(raw_json, name, mu, n)))
    record = bg._record(case, mech, x0)
    refs = references(raw, case, mech, record, x0)
    scale = raw["scale"]
    x = jnp.asarray(x0)
    value_fn = jax.jit(bg._flat(bg._function(case, mech, record, jc.settings(case.t_end, n_out=case.n_out), steps=True)))
    (_, value_steps), _, value_s = bg._timed(value_fn, x, repeats)
    row = dict(case=name, friction=mu, exponent=n, settled=len(refs), value_s=value_s,
               value_steps=int(value_steps), ladder=[])
    for method, rtol, f in LADDER:
        # the steps as the Jacobian's aux: its primal run (for the sensitivities, their own solve)
        fn = jax.jit(jax.jacfwd(bg._flat(bg._function(case, mech, record, _settings(case, method, rtol, f), steps=True)),
                                has_aux=True))
        (J, steps), compile_s, t = bg._timed(fn, x, repeats)
        worst, steps = bg.settled_error(J, refs, scale), int(steps)
        row["ladder"].append(dict(method=method, rtol=rtol, derivative_tolerance=f, worst=worst, s=t,
                                  compile_s=compile_s, steps=steps))
        print(f"  {_label(method, rtol, f):28s} worst {worst:8.1e}  {t / value_s:6.1f}x the value  "
              f"{steps:6d} steps  {t / steps * 1e6:6.1f} us/step", flush=True)
    row.update(equal_accuracy(row["ladder"]))
    return row


def equal_accuracy(ladder, target=TARGET) -> dict:
    """The cheapest setting of each method whose worst error is within ``target``, and the
    loop's time over the sensitivities' (None where a method has none)."""
    best = {}
    for method in ("sensitivities", "loop"):
        ok = [e for e in ladder if e["method"] == method and e["worst"] <= target]
        best[method] = min(ok, key=lambda e: e["s"]) if ok else None
    s, lp = best["sensitivities"], best["loop"]
    return dict(target=target, cheapest_sensitivities=s, cheapest_loop=lp,
                loop_over_sensitivities=(lp["s"] / s["s"]) if s and lp else None)


def _spec(row) -> str:
    """A results row's case as ``case:friction:exponent``."""
    return f"{row['case']}:{row['friction']:g}:{row['exponent']:g}"


def _reached(raw_json: Path) -> list[str]:
    rows = json.loads(raw_json.read_text())["rows"]
    return [_spec(r) for r in rows if (r.get("settled_accuracy") or {}).get("loop")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="reached", help="'reached' (default), 'all' or case:friction:exponent,...")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--gradients-json", default=str(RESULTS / "gradients.json"),
                    help="the bench_gradients.py results whose raw arrays hold the references")
    ap.add_argument("--json", default=str(RESULTS / "gradient_cost.json"))
    args = ap.parse_args(argv)
    raw_json, path = Path(args.gradients_json), Path(args.json)
    if args.cases == "reached":
        specs = _reached(raw_json)
    elif args.cases == "all":
        specs = [_spec(r) for r in json.loads(raw_json.read_text())["rows"]]
    else:
        specs = args.cases.split(",")
    done = {_spec(r): r for r in (json.loads(path.read_text())["rows"] if path.exists() else [])}
    meta = dict(machine=platform.processor() or platform.machine(), cores=os.cpu_count(), jax=jax.__version__,
                date=time.strftime("%Y-%m-%d"), target=TARGET)
    for spec in specs:
        if spec not in done:
            print(spec, flush=True)
            done[spec] = run_case(spec, args.repeats, raw_json)
            atomic_write_json(path, dict(meta=meta, rows=list(done.values())), indent=1, sort_keys=False)
    print(f"\n{'case':14s} {'mu':>4s} {'n':>4s}  {'cheapest sensitivities (1e-3)':34s} {'cheapest loop (1e-3)':30s} loop/sens.")
    for r in done.values():
        s, lp = r["cheapest_sensitivities"], r["cheapest_loop"]
        fmt = lambda e: (f"{_label(e['method'], e['rtol'], e['derivative_tolerance'])}: {e['s'] / r['value_s']:.1f}x"  # noqa: E731
                         if e else "none")
        ratio = r["loop_over_sensitivities"]
        print(f"{r['case']:14s} {r['friction']:4g} {r['exponent']:4g}  {fmt(s):34s} {fmt(lp):30s} "
              + (f"{ratio:.2f}" if ratio else "-"))


if __name__ == "__main__":
    main()
