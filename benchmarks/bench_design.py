"""Optimal design through impacts against the field's gradient-free method.

A Varedi-type study (Varedi, Daniali, Dardel and Fathi, Mechanism and Machine Theory 86, 2015:
particle swarm over the links' mass distribution) on the benchmark slider-crank with its
clearance joint: vary the rod's mass distribution (``centroid_x:rod``, ``centroid_y:rod``,
``mass:rod`` within +-50 %) within their ranges and minimise the RMS deviation of the slider acceleration
from the ideal joint over a run. Side by side, from the same starts:

* **gradient**: ``jc.design`` (L-BFGS-B on the unit cube, gradients from the error-controlled
  sensitivities through the impacts);
* **CMA-ES**: ``cma`` (Hansen's maintained implementation), bounds on the unit cube, sigma0 0.25;
* **DE**: ``scipy.optimize.differential_evolution`` (best1bin, no polishing), its population
  seeded with the start.

Compute is counted in simulations: an objective evaluation is one simulation (with
``--ensemble K``: K runs of 1/K of the horizon, the same simulated time, counted as one) (the ideal-joint
reference is a kinematic analysis, far cheaper, counted in neither); a gradient evaluation is
counted at its measured cost in simulations (steady-state wall time of a gradient evaluation over
that of a value evaluation, both compiled, in the same process). Wall times exclude compilation
(every program is compiled by a warm-up before the timed runs).

Outputs: a table on stdout, ``--json`` (default benchmarks/results/design.json) and ``--png``
(default benchmarks/results/design.png: best objective against simulations).

Usage: python benchmarks/bench_design.py [--revolutions 0.25] [--samples 400] [--starts 2]
[--budget 60] [--json ...] [--png ...]. The defaults are small settings (a quarter revolution,
~10 minutes on 2 shared cores); the issue's full study (a revolution or an ensemble, masses
within +-50 % with the total mass fixed, the four-bar too) is larger than that.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize as so
from matplotlib.figure import Figure

import jaxclear as jc
from jaxclear import designing

#: The rod's mass distribution: its centroid along and across its axis, and its mass within +-50 %.
#: (The crank's is left out: the crank is driven at constant speed, so its mass distribution
#: changes the driving torque only, not the motion: its derivative is 0 to rounding.)
CASES = {
    "slider-crank": ("flores-slider-crank", {"centroid_x:rod": (-0.05, 0.05), "centroid_y:rod": (-0.02, 0.02),
                                             "mass:rod": (0.105, 0.315)}),
    # the four-bar (500 rpm, clearance between coupler and rocker): the rocker's angular acceleration
    "four-bar": ("four-bar", {"centroid_x:coupler": (-0.05, 0.05), "centroid_x:rocker": (-0.05, 0.05),
                              "mass:rocker": (0.2, 0.6)}),
}
VARIABLES = CASES["slider-crank"][1]


class Counter:
    """The objective at unit coordinates, one simulation per call, with its best-so-far trace."""

    def __init__(self, problem):
        self.problem, self.trace, self.wall = problem, [], 0.0

    def __call__(self, u) -> float:
        t0 = time.perf_counter()
        values, _ = designing.evaluate(self.problem, jnp.asarray(np.clip(u, 0.0, 1.0), dtype=float))
        self.wall += time.perf_counter() - t0
        f = float(values[0])
        f = f if np.isfinite(f) else 1e12
        best = min(f, self.trace[-1][1]) if self.trace else f
        self.trace.append((len(self.trace) + 1, best))
        return f


def run_gradient(mech, kw, u0, problem) -> dict:
    variables = designing.check_variables(mech, VARIABLES)
    start = {v.name: v.from_unit(u) for v, u in zip(variables, u0)}
    t0 = time.perf_counter()
    res = jc.design(mech, VARIABLES, "rms-deviation", start=start, **kw)
    wall = time.perf_counter() - t0
    cost = res.gradient_cost
    # simulations so far at each iteration: values at 1 each, gradients at their measured cost; the
    # objective of the plain runs (as the gradient-free methods see it), not of the sensitivity solve
    trace = [((h["evaluations"] - h["gradients"]) + cost * h["gradients"], h["objective"]) for h in res.history]
    sims = res.evaluations["values"] + cost * res.evaluations["gradients"]
    u_opt = [v.to_unit(res.design[v.name]) for v in variables]
    final = float(designing.evaluate(problem, jnp.asarray(u_opt, dtype=float))[0][0])
    trace.append((sims, final))
    best = [min(f for _, f in trace[: i + 1]) for i in range(len(trace))]
    return {"best": best[-1], "start_objective": res.objective["start"], "optimum_sensitivity_solve":
            res.objective["optimum"], "simulations": float(sims), "wall_s": wall, "gradient_cost": cost,
            "status": res.status, "design": res.design, "trace": [(s, b) for (s, _), b in zip(trace, best)],
            "evaluations": res.evaluations}


def noise(problem, u0, steps=(1e-12, 1e-10, 1e-8, 1e-6)) -> dict:
    """The objective's relative change when every coordinate moves by ``step`` of its range: a smooth
    objective changes in proportion to the step, a rugged (numerically chaotic) one by a constant."""
    f0 = float(designing.evaluate(problem, jnp.asarray(u0, dtype=float))[0][0])
    out = {}
    for h in steps:
        f = float(designing.evaluate(problem, jnp.asarray(np.asarray(u0) + h, dtype=float))[0][0])
        out[repr(h)] = (f - f0) / f0
    return out


def run_cma(problem, u0, budget: int, seed: int) -> dict:
    import cma

    f = Counter(problem)
    t0 = time.perf_counter()
    es = cma.CMAEvolutionStrategy(list(u0), 0.25, {"bounds": [0.0, 1.0], "maxfevals": budget, "seed": seed,
                                                   "verbose": -9})
    es.optimize(f)
    return {"best": float(es.result.fbest), "simulations": len(f.trace), "wall_s": time.perf_counter() - t0,
            "trace": f.trace, "design_u": list(map(float, es.result.xbest))}


def run_de(problem, u0, budget: int, seed: int) -> dict:
    f = Counter(problem)
    p = len(u0)
    popsize = 5  # members = popsize * p; generations from the budget
    t0 = time.perf_counter()
    res = so.differential_evolution(f, [(0.0, 1.0)] * p, x0=np.asarray(u0), popsize=popsize,
                                    maxiter=max(budget // (popsize * p) - 1, 1), polish=False, seed=seed, tol=0.0)
    return {"best": float(res.fun), "simulations": len(f.trace), "wall_s": time.perf_counter() - t0,
            "trace": f.trace, "design_u": list(map(float, res.x))}


def first_within(trace, target: float, rel: float = 0.01):
    """Simulations at which the best-so-far first comes within ``rel`` of ``target`` (None: never)."""
    for s, b in trace:
        if b <= target * (1 + rel):
            return s
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), default="slider-crank")
    ap.add_argument("--revolutions", type=float, default=0.25)
    ap.add_argument("--samples", type=int, default=400, help="samples per revolution")
    ap.add_argument("--starts", type=int, default=2)
    ap.add_argument("--budget", type=int, default=60, help="simulations of each gradient-free run")
    ap.add_argument("--max-iter", type=int, default=15)
    ap.add_argument("--ensemble", type=int, default=1,
                    help="periodic starts per evaluation, each run --revolutions / ENSEMBLE long (default 1)")
    ap.add_argument("--json", default="benchmarks/results/design.json")
    ap.add_argument("--png", default="benchmarks/results/design.png")
    args = ap.parse_args()
    global VARIABLES
    preset, VARIABLES = CASES[args.case]
    mech = jc.preset(preset)
    ensemble = designing.Ensemble(starts=args.ensemble)
    run_revolutions = args.revolutions / args.ensemble
    kw = dict(revolutions=run_revolutions, samples_per_revolution=args.samples, max_iter=args.max_iter,
              ensemble=ensemble, check_chaos=False, report_sensitivity=False, plots=False, progress=False)
    rng = np.random.default_rng(0)
    starts = [np.full(len(VARIABLES), 0.5)] + [rng.uniform(0.1, 0.9, len(VARIABLES)) for _ in range(args.starts - 1)]
    variables = designing.check_variables(mech, VARIABLES)
    problem = designing.problem.build_problem(mech, variables, designing.objective("rms-deviation"), (),
                                              (designing.OperatingPoint(),), ensemble, run_revolutions,
                                              args.samples, jc.Settings(t_end=1.0))
    t0 = time.perf_counter()
    warm = jc.design(mech, VARIABLES, "rms-deviation", **dict(kw, max_iter=1))  # compiles value and gradient
    compile_s = time.perf_counter() - t0
    nominal = warm.objective["start"]
    rugged = noise(problem, starts[0])
    print("relative change of the objective when the design moves by h of each range, at the first start:",
          {h: f"{v:+.2e}" for h, v in rugged.items()}, flush=True)
    rows = []
    for i, u0 in enumerate(starts):
        g = run_gradient(mech, kw, u0, problem)
        c = run_cma(problem, u0, args.budget, seed=i + 1)
        d = run_de(problem, u0, args.budget, seed=i + 1)
        target = min(c["best"], d["best"])
        row = {"start": list(map(float, u0)), "target_gradient_free": target, "gradient": g, "cma": c, "de": d,
               "gradient_simulations_to_target": first_within(g["trace"], target),
               "cma_simulations_to_target": first_within(c["trace"], target),
               "de_simulations_to_target": first_within(d["trace"], target)}
        rows.append(row)
        print(f"{args.case} start {i} u0={np.round(u0, 3).tolist()}: gradient best {g['best']:.6g} in {g['simulations']:.1f} "
              f"simulation-equivalents ({g['wall_s']:.1f} s, gradient cost {g['gradient_cost']:.2f} sims, "
              f"{g['status']}); CMA-ES best {c['best']:.6g} in {c['simulations']} ({c['wall_s']:.1f} s); DE best "
              f"{d['best']:.6g} in {d['simulations']} ({d['wall_s']:.1f} s); gradient reaches 1 % of the best "
              f"gradient-free at {row['gradient_simulations_to_target']}", flush=True)
    out = {"case": f"{preset}, rms-deviation of the output link's acceleration", "variables": VARIABLES,
           "revolutions": args.revolutions, "ensemble": args.ensemble, "samples_per_revolution": args.samples, "budget": args.budget,
           "nominal_objective": nominal, "objective_noise": rugged, "compile_s": compile_s, "rows": rows, "machine": platform.platform(),
           "jax_backend": jax.default_backend()}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=1, default=float))
    fig = Figure(figsize=(7.5, 4.5))
    ax = fig.subplots()
    for i, row in enumerate(rows):
        for key, color, label in (("gradient", "C0", "gradient (L-BFGS-B)"), ("cma", "C1", "CMA-ES"),
                                  ("de", "C2", "differential evolution")):
            tr = np.asarray(row[key]["trace"], dtype=float)
            ax.plot(tr[:, 0], tr[:, 1], color=color, ls="-" if i == 0 else "--", marker="o" if key == "gradient" else None,
                    ms=3, label=f"{label}, start {i}")
    ax.axhline(nominal, color="gray", lw=0.8, ls=":", label="nominal design")
    ax.set_xlabel("simulations (a gradient at its measured cost)")
    ax.set_ylabel("best RMS deviation of the output's acceleration")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{preset}, {args.revolutions:g} revolution ({args.ensemble} run(s) per evaluation): "
                 f"{', '.join(VARIABLES)}", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(f"nominal objective {nominal:.6g}; written {args.json}, {args.png}")


if __name__ == "__main__":
    main()
