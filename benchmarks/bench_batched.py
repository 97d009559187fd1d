"""Batched against solo runs: what ``jax.jit(jax.vmap(simulate))`` promises (docs/errors.md,
"Batched runs").

Three cases over a quarter crank revolution at rtol 1e-6 / atol 1e-9, 101 output samples: the
benchmark slider-crank with LuGre friction (mu = 0.1), the benchmark with Lankarani-Nikravesh at
c_r = 0.9 and no friction, and the pin-in-slot slider-crank preset. For each:

1. lanes coupled? A member is run in a batch of 4 identical members and in a batch of 4 whose
   other members have other restitutions and clearances (their steps are rejected and split at
   other times): its outputs are compared bit for bit. The same for the last member of a batch
   of 5 (on CPU, the lane left over when XLA groups float64 lanes by 4).
2. rounding? One vector-field evaluation at a state in contact, alone and batched.
3. equal error? Every run (solo ``jax.jit(simulate)``, batches of 1, 4, 5) against a reference at
   rtol 1e-10 / atol 1e-13: the largest normal-force and slider-acceleration errors, at rtol 1e-6
   and 1e-8.

Usage: python benchmarks/bench_batched.py [--cases lugre,ln,pinslot] [--json PATH]
(about 10 minutes per case on 2 shared cores, most of it compilation).
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxclear as jc
from jaxclear import params
from jaxclear.integrate._dynamics import flat_vector_field
from jaxclear.integrate._state import State

#: Neighbours of the member in the mixed batches: (restitution, clearance [m]).
OTHERS = [(0.7, 0.4e-3), (0.5, 0.3e-3), (0.95, 0.45e-3), (0.8, 0.35e-3)]


def case_mechanism(case: str):
    if case == "lugre":
        m = jc.preset("flores-slider-crank")
        return eqx.tree_at(lambda m: m.clearance_joints[0].friction, m, jc.Friction(0.1, model="lugre"))
    if case == "ln":
        return jc.preset("flores-slider-crank", restitution=0.9)
    if case == "pinslot":
        return jc.preset("slider-crank-pin-slot")
    raise ValueError(case)


def run_case(case: str) -> dict:
    mech = case_mechanism(case)
    t_end = 0.25 * 60.0 / float(params.get(mech, "speed_rpm"))
    slider = 3 * mech.body_index(mech.role("slider"))

    def member(p, s):
        m = params.replace_many(mech, {"restitution": p[0], "clearance": p[1]})
        sol = jc.simulate(m, s)
        return dict(steps=sol.num_steps, rejected=sol.num_rejected_steps, fn=sol.normal_force[:, 0], q=sol.q,
                    acc=sol.qddot[:, slider])

    p0 = jnp.asarray([float(params.get(mech, "restitution")), float(params.get(mech, "clearance"))])
    others = jnp.asarray(OTHERS)
    out: dict = {"case": case, "t_end_s": t_end}

    def lane(res, k):
        return {key: np.asarray(v)[k] for key, v in res.items()}

    def same(a, b):
        return all(np.array_equal(a[k], b[k]) for k in ("fn", "q", "acc"))

    s = jc.settings(t_end, n_out=101, throw=False)
    batched = jax.jit(jax.vmap(lambda p: member(p, s)))
    four_same, four_mixed = batched(jnp.stack([p0] * 4)), batched(jnp.concatenate([p0[None], others[:3]]))
    five_same, five_mixed = batched(jnp.stack([p0] * 5)), batched(jnp.concatenate([others[:4], p0[None]]))
    out["lanes_independent"] = bool(same(lane(four_same, 0), lane(four_mixed, 0))
                                    and same(lane(five_same, 4), lane(five_mixed, 4)))
    out["batch_of_5_lanes_equal"] = [bool(same(lane(five_same, 0), lane(five_same, k))) for k in range(5)]

    # one vector-field evaluation at the first output sample in contact
    sol = jax.jit(lambda m: jc.simulate(m, s))(mech)
    k = int(np.argmax(np.asarray(sol.penetration[:, 0]) > 0))
    v = State(sol.q[k], sol.qdot[k], jax.tree_util.tree_map(lambda a: a[k], sol.element_states)).pack()
    args = (mech, s.baumgarte)
    a = np.asarray(jax.jit(lambda t, y: flat_vector_field(t, y, args))(sol.ts[k], v))
    b = np.asarray(jax.jit(jax.vmap(lambda t, y: flat_vector_field(t, y, args)))(sol.ts[k][None], v[None]))[0]
    scale = np.maximum(np.abs(a), np.finfo(float).tiny)
    big = np.abs(a) > 1e-6 * np.abs(a).max()  # entries that are not cancellation residue
    out["vector_field"] = {"sample": k, "entries": len(a), "differ": int(np.count_nonzero(a != b)),
                           "max_relative": float(np.max(np.abs(a - b)[big] / scale[big]))}

    ref_s = jc.settings(t_end, n_out=101, throw=False, rtol=1e-10, atol=1e-13, max_steps=2_000_000)
    ref = jax.jit(lambda p: member(p, ref_s))(p0)
    out["reference_steps"] = int(ref["steps"])
    out["peak_normal_force_n"] = float(np.max(ref["fn"]))
    out["runs"] = []
    for rtol, atol in ((1e-6, 1e-9), (1e-8, 1e-11)):
        s = jc.settings(t_end, n_out=101, throw=False, rtol=rtol, atol=atol)
        runs = {"solo": lane({k_: v_[None] for k_, v_ in jax.jit(lambda p: member(p, s))(p0).items()}, 0)}
        vm = jax.jit(jax.vmap(lambda p: member(p, s)))
        for size, k_ in ((1, 0), (4, 0), (5, 4)):
            runs[f"vmap B={size} lane {k_}"] = lane(vm(jnp.stack([p0] * size)), k_)
        for name, r in runs.items():
            out["runs"].append({"rtol": rtol, "run": name, "steps": int(r["steps"]), "rejected": int(r["rejected"]),
                                "normal_force_error_max_n": float(np.max(np.abs(r["fn"] - ref["fn"]))),
                                "slider_acc_error_rms_m_s2": float(np.sqrt(np.mean((r["acc"] - ref["acc"]) ** 2)))})
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="lugre,ln,pinslot")
    parser.add_argument("--json", default=str(Path(__file__).parent / "results" / "batched.json"))
    args = parser.parse_args()
    results = {"machine": platform.processor() or platform.machine(), "jax": jax.__version__, "cases": []}
    for case in args.cases.split(","):
        r = run_case(case)
        results["cases"].append(r)
        vf = r["vector_field"]
        print(f"\n{case}: lanes independent (bit for bit with other neighbours): {r['lanes_independent']}; "
              f"batch of 5, lanes equal to lane 0: {r['batch_of_5_lanes_equal']}")
        print(f"  one vector-field evaluation in contact: {vf['differ']} of {vf['entries']} entries differ, "
              f"at most {vf['max_relative']:.2g} relative")
        print(f"  reference: {r['reference_steps']} steps, peak normal force {r['peak_normal_force_n']:.6g} N")
        print(f"  {'rtol':>6} {'run':>16} {'steps':>6} {'rejected':>8} {'max |F_N error| [N]':>20} "
              f"{'RMS slider acc error [m/s^2]':>29}")
        for row in r["runs"]:
            print(f"  {row['rtol']:>6g} {row['run']:>16} {row['steps']:>6} {row['rejected']:>8} "
                  f"{row['normal_force_error_max_n']:>20.3g} {row['slider_acc_error_rms_m_s2']:>29.3g}")
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
