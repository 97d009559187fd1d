"""Cost of every contact law on the benchmark run, relative to Lankarani-Nikravesh.

For each law: the Flores slider-crank (c = 0.5 mm, 5000 rpm, c_r = 0.9, Ambrosio friction
mu = 0) over N crank revolutions at rtol 1e-6 / atol 1e-9, compiled once, then timed as the
median of R repeats. Reported: compile time (first call minus steady state), steady-state time
per simulation, solver steps, time per step, and the ratios to LN per simulation and per step
(laws change the contact dynamics and so the number of steps; the per-step ratio isolates the
cost of evaluating the law). Hybrid variants: ``arc`` (2 x 4 Gauss points on the contact arc)
and ``fixed`` with 720 points (360 elements x 2) over the whole pin; the default hybrid (h = c)
is ~70x stiffer than LN's cylindrical K and so needs more steps, hence an extra row with the layer
thickness matched to LN's stiffness at 10 um (same contact dynamics scale, isolates the cost).
The friction rows run LN with mu = 0.1 and each friction model; their ratios are to the LN +
Ambrosio (mu = 0.1) row.

Usage: python benchmarks/bench_laws.py [--revolutions 1] [--repeats 3] [--subset all|new] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import equinox as eqx
import jax

import jaxclear as jc
from _timing import compile_and_steady

VARIANTS = [
    ("lankarani-nikravesh", {}),
    ("hertz", {}),
    ("hunt-crossley", {}),
    ("herbert-mcwhannell", {}),
    ("lee-wang", {}),
    ("gonthier", {}),
    ("qin-lu", {}),
    ("flores", {}),
    ("kelvin-voigt", {"stiffness": 1e8}),
    ("liu", {}),
    ("bai-zhao", {}),
    ("hybrid", {"law_options": {"placement": "arc"}}),
    ("hybrid", {"law_options": {"placement": "arc", "thickness": "matched"}}),
    ("hybrid", {"law_options": {"placement": "fixed", "n_elements": 360, "n_gauss": 2}}),
    ("hu-guo", {}),
    ("carvalho-martins", {}),
    ("impact", {"law_options": {"max_damping": 1e4, "damping_depth": 1e-5}}),
    ("johnson", {}),
    ("radzimovsky", {}),
    ("goldsmith", {}),
    ("dubowsky-freudenstein", {}),
    ("esdu-78035", {}),
    ("pereira", {}),
    ("persson", {}),
    # friction laws on LN (mu = 0.1, static 0.15 where the law has one); the first is the
    # reference for these rows (the benchmark's own friction is Ambrosio with mu = 0)
    ("lankarani-nikravesh", {"friction_law": ("ambrosio", {})}),
    ("lankarani-nikravesh", {"friction_law": ("smooth", {})}),
    ("lankarani-nikravesh", {"friction_law": ("viscous", {"viscous": 0.5})}),
    ("lankarani-nikravesh", {"friction_law": ("stribeck", {"static": 0.15, "viscous": 0.5})}),
    ("lankarani-nikravesh", {"friction_law": ("threlfall", {})}),
    ("lankarani-nikravesh", {"friction_law": ("brown-mcphee", {"static": 0.15})}),
    ("lankarani-nikravesh", {"friction_law": ("dahl", {})}),
    ("lankarani-nikravesh", {"friction_law": ("lugre", {"static": 0.15, "bristle_damping": 1e-2})}),
]

#: the rows added with the laws of Pereira et al., the step-damped impact force and the friction
#: laws (``--subset new``), plus the LN reference row
NEW_FROM = 14


def label(name, opts):
    if "friction_law" in opts:
        return f"LN + {opts['friction_law'][0]} friction"
    lo = opts.get("law_options", {})
    if name == "hybrid":
        n = lo.get("n_elements", 2) * lo.get("n_gauss", 4)
        h = ", h matched to LN" if lo.get("thickness") == "matched" else ""
        return f"hybrid-{lo.get('placement', 'arc')} ({n} pts{h})"
    return name


def ln_matched_thickness():
    """Layer thickness giving the hybrid LN's force at 10 um (see contact.hybrid.matched_thickness)."""
    from jaxclear.contact.hybrid import matched_thickness

    joint = jc.preset("flores-slider-crank").clearance_joints[0]
    k = joint.law.stiffness_value(joint.bearing_radius, joint.journal_radius)
    return float(matched_thickness(jc.HybridLaw(), joint.bearing_radius, joint.journal_radius, joint.length, k))


def run(revolutions: float, repeats: int, subset: str = "all"):
    rows = []
    variants = VARIANTS if subset == "all" else VARIANTS[:1] + VARIANTS[NEW_FROM:]
    for name, opts in variants:
        name_label = label(name, opts)
        if opts.get("law_options", {}).get("thickness") == "matched":
            opts = {"law_options": {**opts["law_options"], "thickness": ln_matched_thickness()}}
        friction = opts.get("friction_law")
        opts = {k: v for k, v in opts.items() if k != "friction_law"}
        mech = jc.preset("flores-slider-crank", law=name, **opts)
        if friction is not None:
            model, kwargs = friction
            mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction, mech, jc.Friction(0.1, model, **kwargs))
        s = jc.settings(revolutions * jc.crank_period(mech), n_out=201, throw=False)  # a failed run is a row with its status
        sol, first, steady = compile_and_steady(mech, s, repeats)
        steps = int(sol.num_steps)
        rows.append(dict(law=name_label, compile_s=first - steady, steady_s=steady, steps=steps,
                         us_per_step=steady / steps * 1e6, impacts=int(sol.impacts[0]),
                         peak_force_n=float(sol.peak_force[0]), status=int(sol.status)))
        print(f"  {rows[-1]['law']:<28s} {steady:7.3f} s", flush=True)
    ln = rows[0]
    friction_ref = next((r for r in rows if r["law"] == "LN + ambrosio friction"), ln)
    for r in rows:
        ref = friction_ref if r["law"].startswith("LN + ") else ln
        r["ratio_per_simulation"] = r["steady_s"] / ref["steady_s"]
        r["ratio_per_step"] = r["us_per_step"] / ref["us_per_step"]
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--revolutions", type=float, default=1.0, help="crank revolutions per run (default 1)")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats after compilation (default 3)")
    ap.add_argument("--json", default="benchmarks/results/laws.json", help="where to write the JSON results")
    ap.add_argument("--subset", choices=("all", "new"), default="all",
                    help="all rows, or LN and the rows of the newer laws and friction models (default all)")
    args = ap.parse_args(argv)
    rows = run(args.revolutions, args.repeats, args.subset)
    head = f"{'law':<28s} {'compile s':>9s} {'steady s':>9s} {'steps':>6s} {'us/step':>8s} {'x LN/sim':>8s} {'x LN/step':>9s} {'impacts':>7s} {'peak F N':>10s}"
    print()
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['law']:<28s} {r['compile_s']:9.2f} {r['steady_s']:9.3f} {r['steps']:6d} {r['us_per_step']:8.1f} "
              f"{r['ratio_per_simulation']:8.2f} {r['ratio_per_step']:9.2f} {r['impacts']:7d} {r['peak_force_n']:10.3g}")
    out = {
        "benchmark": "contact laws on the Flores slider-crank",
        "revolutions": args.revolutions,
        "repeats": args.repeats,
        "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(), "jax": jax.__version__,
                    "device": str(jax.devices()[0])},
        "rows": rows,
    }
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
