"""Cost of each force element relative to the dry revolute clearance joint.

Every mechanism is the Flores benchmark slider-crank at the same crank speed (default 5000 rpm)
with one element kind in it: the dry revolute clearance joint in the rod-slider joint (the
reference), the lubricated joint there (0.4 Pa s), the pin-in-slot joint there with l = 0 (the
same dynamics as the dry joint: isolates the cost of the element) and with l = 1 mm, the
translational clearance joint in the slider's guide (0.1 mm, all revolute joints ideal), and the
three kinds together (lubricated crank-rod joint, dry rod-slider joint, guide clearance).
Each run: N crank revolutions at rtol 1e-6 / atol 1e-9, compiled once, then timed as the median
of R repeats. Reported: compile time, steady time per simulation, solver steps, time per step,
the time of one evaluation of the vector field (2000 evaluations in one compiled loop near the start state:
the element's cost without its effect on the step count), and the ratios to the dry joint per
simulation, per step and per evaluation (elements change the dynamics and so the step count).

Usage: python benchmarks/bench_joints.py [--revolutions 1] [--repeats 3] [--speed-rpm 5000] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import jax

import jaxclear as jc
from _timing import compile_and_steady
from jaxclear.integrate._assembly import initial_state
from jaxclear.integrate._dynamics import flat_vector_field


def mechanisms(rpm: float):
    dry = jc.preset("flores-slider-crank", speed_rpm=rpm)
    joint = dry.clearance_joints[0]

    def with_elements(base, elements, name, joints=None):
        return jc.Mechanism(base.bodies, base.joints if joints is None else joints, base.drivers, elements,
                            gravity=base.gravity, ground_points=base.ground_points, roles=dict(base.roles), name=name)

    slot0 = jc.PinSlotJoint(joint.bearing_body, joint.bearing_point, joint.journal_body, joint.journal_point,
                            joint.bearing_radius, joint.journal_radius, slot_length=0.0, length=joint.length,
                            law=joint.law, friction=joint.friction)
    guide = jc.preset("slider-crank-guide-clearance", speed_rpm=rpm)
    crank_rod = jc.LubricatedJoint("rod", "A", "crank", "A", 0.010, 0.0095, viscosity=0.4, name="crank-rod")
    keep = [j for j in guide.joints if not (isinstance(j, jc.Revolute) and {j.body_i, j.body_j} != {jc.GROUND, "crank"})]
    return [
        ("dry revolute (reference)", dry),
        ("lubricated, 0.4 Pa s", jc.preset("flores-slider-crank", speed_rpm=rpm, viscosity=0.4)),
        ("pin-in-slot, l = 0", with_elements(dry, [slot0], "slot0")),
        ("pin-in-slot, l = 1 mm", jc.preset("slider-crank-pin-slot", speed_rpm=rpm)),
        ("translational (guide)", guide),
        ("all three kinds", with_elements(guide, [crank_rod, joint, *guide.clearance_joints], "mixed", keep)),
    ]


def rhs_time(mech, s, calls=2000):
    """Seconds per vector-field evaluation: ``calls`` evaluations inside one compiled loop (each
    at a slightly different state, so none is hoisted), median of 5 timings."""
    y0 = initial_state(mech, s).pack()
    args = (mech, s.baumgarte)
    t = jax.numpy.asarray(0.0)

    @jax.jit
    def many(y):
        return jax.lax.fori_loop(0, calls, lambda i, acc: acc + jax.numpy.sum(flat_vector_field(t, y + 1e-20 * i, args)), 0.0)

    jax.block_until_ready(many(y0))
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        jax.block_until_ready(many(y0))
        times.append((time.perf_counter() - t0) / calls)
    return statistics.median(times)


def run(revolutions: float, repeats: int, rpm: float):
    rows = []
    for name, mech in mechanisms(rpm):
        # throw=False: a run outside a law's validity is recorded by its status, not aborted
        s = jc.settings(revolutions * jc.crank_period(mech), n_out=201, throw=False)
        sol, first, steady = compile_and_steady(mech, s, repeats)
        steps = int(sol.num_steps)
        rows.append(dict(element=name, compile_s=first - steady, steady_s=steady, steps=steps,
                         us_per_step=steady / steps * 1e6, us_per_rhs=rhs_time(mech, s) * 1e6,
                         impacts=[int(x) for x in sol.impacts], status=int(sol.status)))
        print(f"  {name:<26s} {steady:7.3f} s", flush=True)
    ref = rows[0]
    for r in rows:
        r["ratio_per_simulation"] = r["steady_s"] / ref["steady_s"]
        r["ratio_per_step"] = r["us_per_step"] / ref["us_per_step"]
        r["ratio_per_rhs"] = r["us_per_rhs"] / ref["us_per_rhs"]
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--revolutions", type=float, default=1.0, help="crank revolutions per run (default 1)")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats after compilation (default 3)")
    ap.add_argument("--speed-rpm", type=float, default=5000.0, help="crank speed of every mechanism (default 5000)")
    ap.add_argument("--json", default="benchmarks/results/joints.json", help="where to write the JSON results")
    args = ap.parse_args(argv)
    rows = run(args.revolutions, args.repeats, args.speed_rpm)
    head = (f"{'element':<26s} {'compile s':>9s} {'steady s':>9s} {'steps':>6s} {'us/step':>8s} {'us/rhs':>7s} "
            f"{'x/sim':>6s} {'x/step':>6s} {'x/rhs':>6s}")
    print()
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['element']:<26s} {r['compile_s']:9.2f} {r['steady_s']:9.3f} {r['steps']:6d} {r['us_per_step']:8.1f} "
              f"{r['us_per_rhs']:7.1f} {r['ratio_per_simulation']:6.2f} {r['ratio_per_step']:6.2f} {r['ratio_per_rhs']:6.2f}")
    out = {
        "benchmark": "force elements on the Flores slider-crank, relative to the dry revolute clearance joint",
        "revolutions": args.revolutions, "repeats": args.repeats, "speed_rpm": args.speed_rpm,
        "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(), "jax": jax.__version__,
                    "device": str(jax.devices()[0])},
        "rows": rows,
    }
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
