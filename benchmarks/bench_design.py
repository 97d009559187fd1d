"""Optimal design through impacts against the field's gradient-free method.

A Varedi-type study (Varedi, Daniali, Dardel and Fathi, Mechanism and Machine Theory 86, 2015:
particle swarm over the links' mass distribution) on the benchmark slider-crank with its
clearance joint: vary the links' mass distribution (``centroid_x:rod``, ``centroid_y:rod``, the
rod's and the crank's masses within +-50 % with their total fixed, see :data:`CASES`) and
minimise the RMS deviation of the slider acceleration from the ideal joint over a run. Side by
side, from the same starts:

* **gradient**: ``jc.design`` (L-BFGS-B on the unit cube, SLSQP with the total-mass equality;
  gradients from the error-controlled sensitivities through the impacts);
* **CMA-ES**: ``cma`` (Hansen's maintained implementation), bounds on the unit cube, sigma0 0.25;
* **DE**: ``scipy.optimize.differential_evolution`` (best1bin, no polishing), its population
  seeded with the start.

Compute is counted in simulations: an objective evaluation is one simulation (with
``--ensemble K``: K runs of 1/K of the horizon, the same simulated time, counted as one) (the ideal-joint
reference is a kinematic analysis, far cheaper, counted in neither); a gradient evaluation is
counted at its measured cost in simulations (steady-state wall time of a gradient evaluation over
that of a value evaluation, both compiled, in the same process). Wall times exclude compilation
(every program is compiled by a warm-up before the timed runs).

**Steady operation** (``--steady REVS``, issue 44): the objective is the RMS deviation averaged
over ``REVS`` revolutions of steady running after ``--transient`` (``jc.design(...,
steady=SteadyOperation(...))``), the gradient method's gradients by least-squares shadowing
(``jc.steady_derivatives``), the gradient-free methods on the same average; each method's best
design is then judged by a long average (``--check-revolutions``), since the short average's
noise picked it.

Outputs: a table on stdout, ``--json`` (default benchmarks/results/design.json, with
``_four_bar`` for ``--case four-bar`` and ``_ensemble`` for ``--ensemble K``) and ``--png`` (the
same name: best objective against simulations).

Usage: python benchmarks/bench_design.py [--case slider-crank|four-bar] [--revolutions 0.25]
[--samples 400] [--starts 2] [--budget 60] [--max-iter 15] [--ensemble 1] [--steady REVS [--transient 20]
[--n-unstable 2] [--check-revolutions 400]] [--json ...] [--png ...].
The defaults are small settings (a quarter revolution); the runs recorded in benchmarks/README.md
("Optimal design") give their command lines, each under ~10 minutes on 2 shared cores.
"""

from __future__ import annotations

import argparse
import dataclasses
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
from jaxclear._extras import require_extra
from jaxclear.designing.steady import SteadyEvaluation

#: Each case: the preset, its design variables with their ranges, and the masses held to a fixed
#: total. The slider-crank (Varedi et al.'s study): the rod's centroid along and across its axis,
#: the rod's and the crank's masses within +-50 %, the sum of the crank's and the rod's masses fixed
#: at its nominal 0.51 kg (``TotalMass`` of jaxclear.designing.constraints, an equality for the
#: gradient method). The crank is driven at constant speed, so its mass distribution changes the
#: driving torque only, not the motion (its derivative is 0 to rounding): its mass follows the rod's
#: through the total. The gradient-free methods search the other variables and set the follower
#: to total - rod (the rod's whole range keeps the crank's within its own: 0.195..0.405 kg).
CASES = {
    "slider-crank": ("flores-slider-crank", {"centroid_x:rod": (-0.05, 0.05), "centroid_y:rod": (-0.02, 0.02),
                                             "mass:rod": (0.105, 0.315), "mass:crank": (0.15, 0.45)},
                     {"bodies": ("crank", "rod"), "follower": "mass:crank", "leader": "mass:rod"}),
    # the four-bar (500 rpm, clearance between coupler and rocker): the rocker's angular acceleration
    "four-bar": ("four-bar", {"centroid_x:coupler": (-0.05, 0.05), "centroid_x:rocker": (-0.05, 0.05),
                              "mass:rocker": (0.2, 0.6)}, None),
}
VARIABLES = CASES["slider-crank"][1]


class Space:
    """The gradient-free methods' coordinates (the unit cube of the variables but the follower)
    and the full unit coordinates of the design (the follower's mass the total minus the leader's)."""

    def __init__(self, mech, variables, total):
        self.variables = designing.check_variables(mech, variables)
        self.total = total
        names = [v.name for v in self.variables]
        self.free = [i for i, n in enumerate(names) if total is None or n != total["follower"]]
        if total is not None:
            self.follower, self.leader = names.index(total["follower"]), names.index(total["leader"])
            self.mass = float(sum(mech.body(b).mass for b in total["bodies"]))

    def constraints(self):
        if self.total is None:
            return []
        return [designing.TotalMass(tuple(self.total["bodies"]), self.mass)]

    def full_of(self, design: dict) -> np.ndarray:
        """The full unit coordinates of a design given by its values."""
        return np.asarray([v.to_unit(design[v.name]) for v in self.variables])

    def full(self, w) -> np.ndarray:
        u = np.full(len(self.variables), 0.5)
        u[self.free] = np.clip(np.asarray(w, dtype=float), 0.0, 1.0)
        if self.total is not None:
            leader = self.variables[self.leader].from_unit(u[self.leader])
            u[self.follower] = self.variables[self.follower].to_unit(self.mass - leader)
        return u


def evaluator(problem, steady=None):
    """``u -> (values, statuses)``: the problem's runs, or with ``steady`` (a
    :class:`jaxclear.designing.SteadyOperation`) the average over steady operation that ``jc.design(...,
    steady=...)`` minimises."""
    if steady is None:
        return lambda u: designing.evaluate(problem, u)
    return SteadyEvaluation(problem, steady).value


class Counter:
    """The objective at unit coordinates, one simulation per call, with its best-so-far trace."""

    def __init__(self, problem, space, steady=None):
        self.problem, self.space, self.trace, self.wall = problem, space, [], 0.0
        self.evaluate = evaluator(problem, steady)

    def __call__(self, w) -> float:
        t0 = time.perf_counter()
        values, _ = self.evaluate(jnp.asarray(self.space.full(w), dtype=float))
        self.wall += time.perf_counter() - t0
        f = float(values[0])
        f = f if np.isfinite(f) else 1e12
        best = min(f, self.trace[-1][1]) if self.trace else f
        self.trace.append((len(self.trace) + 1, best))
        return f


def run_gradient(mech, kw, u0, problem, space, steady=None) -> dict:
    variables = space.variables
    start = {v.name: float(v.from_unit(u)) for v, u in zip(variables, u0)}
    t0 = time.perf_counter()
    res = jc.design(mech, VARIABLES, "rms-deviation", space.constraints(), start=start, **kw)
    wall = time.perf_counter() - t0
    cost = res.gradient_cost
    # simulations so far at each iteration: values at 1 each, gradients at their measured cost; the
    # objective of the plain runs (as the gradient-free methods see it), not of the sensitivity solve
    trace = [((h["evaluations"] - h["gradients"]) + cost * h["gradients"], h["objective"]) for h in res.history]
    sims = res.evaluations["values"] + cost * res.evaluations["gradients"]
    u_opt = [v.to_unit(res.design[v.name]) for v in variables]
    final = float(evaluator(problem, steady)(jnp.asarray(u_opt, dtype=float))[0][0])
    trace.append((sims, final))
    best = [min(f for _, f in trace[: i + 1]) for i in range(len(trace))]
    return {"best": best[-1], "start_objective": res.objective["start"], "optimum_sensitivity_solve":
            res.objective["optimum"], "simulations": float(sims), "wall_s": wall, "gradient_cost": cost,
            "status": res.status, "design": res.design, "trace": [(s, b) for (s, _), b in zip(trace, best)],
            "evaluations": res.evaluations, "constraints": res.constraints,
            "shadowing": None if steady is None else dict(
                {k: v for k, v in res.chaos["steady"].items() if k != "reports"},
                start=res.chaos["steady"]["reports"][0] if res.chaos["steady"]["reports"] else None)}


def noise(problem, space, w0, steps=(1e-12, 1e-10, 1e-8, 1e-6), steady=None) -> dict:
    """The objective's relative change when every free coordinate moves by ``step`` of its range: a
    smooth objective changes in proportion to the step, a rugged (numerically chaotic) one by a constant."""
    evaluate = evaluator(problem, steady)
    f0 = float(evaluate(jnp.asarray(space.full(w0), dtype=float))[0][0])
    out = {}
    for h in steps:
        f = float(evaluate(jnp.asarray(space.full(np.asarray(w0) + h), dtype=float))[0][0])
        out[repr(h)] = (f - f0) / f0
    return out


def run_cma(problem, space, w0, budget: int, seed: int, steady=None) -> dict:
    import cma

    f = Counter(problem, space, steady)
    t0 = time.perf_counter()
    es = cma.CMAEvolutionStrategy(list(w0), 0.25, {"bounds": [0.0, 1.0], "maxfevals": budget, "seed": seed,
                                                   "verbose": -9})
    es.optimize(f)
    return {"best": float(es.result.fbest), "simulations": len(f.trace), "wall_s": time.perf_counter() - t0,
            "trace": f.trace, "design": design_of(space, es.result.xbest)}


def run_de(problem, space, w0, budget: int, seed: int, steady=None) -> dict:
    f = Counter(problem, space, steady)
    p = len(w0)
    popsize = 5  # members = popsize * p; generations from the budget
    t0 = time.perf_counter()
    res = so.differential_evolution(f, [(0.0, 1.0)] * p, x0=np.asarray(w0), popsize=popsize,
                                    maxiter=max(budget // (popsize * p) - 1, 1), polish=False, seed=seed, tol=0.0)
    return {"best": float(res.fun), "simulations": len(f.trace), "wall_s": time.perf_counter() - t0,
            "trace": f.trace, "design": design_of(space, res.x)}


def design_of(space, w) -> dict:
    """The design (values, the follower's included) at the gradient-free coordinates ``w``."""
    return {v.name: float(v.from_unit(u)) for v, u in zip(space.variables, space.full(w))}


#: Step (fraction of a range) of the long averages' central differences at the start (``--steady``):
#: large enough for the slope to stand above the long average's noise where the average moves
#: by tens of percents over the range.
SLOPE_STEP = 0.1


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
    ap.add_argument("--steady", type=int, default=0,
                    help="design on steady operation: revolutions averaged after --transient (0: off, the default)")
    ap.add_argument("--transient", type=int, default=20, help="revolutions left out first (--steady)")
    ap.add_argument("--n-unstable", type=int, default=2, help="homogeneous tangents of the shadowing (--steady)")
    ap.add_argument("--check-revolutions", type=int, default=400,
                    help="revolutions of the long average that judges each method's best design (--steady)")
    ap.add_argument("--json", default=None, help="default benchmarks/results/design[_four_bar][_ensemble|_steady].json")
    ap.add_argument("--png", default=None, help="default: the JSON's name with .png")
    args = ap.parse_args()
    require_extra("bench", "benchmarks/bench_design.py (CMA-ES)")  # before any run
    stem = "benchmarks/results/design" + ("_four_bar" if args.case == "four-bar" else "") + (
        "_ensemble" if args.ensemble > 1 else "") + ("_steady" if args.steady else "")
    args.json = args.json or stem + ".json"
    args.png = args.png or (args.json[: -len(".json")] + ".png" if args.json.endswith(".json") else stem + ".png")
    global VARIABLES
    preset, VARIABLES, total = CASES[args.case]
    mech = jc.preset(preset)
    space = Space(mech, VARIABLES, total)
    ensemble = designing.Ensemble(starts=args.ensemble)
    run_revolutions = args.revolutions / args.ensemble
    steady = designing.SteadyOperation(revolutions=args.steady, transient_revolutions=args.transient,
                              n_unstable=args.n_unstable) if args.steady else None
    kw = dict(revolutions=run_revolutions, samples_per_revolution=args.samples, max_iter=args.max_iter,
              ensemble=None if steady else ensemble, check_chaos=bool(steady), report_sensitivity=False, plots=False,
              progress=False, steady=steady)
    rng = np.random.default_rng(0)
    nfree = len(space.free)
    # the nominal design (the middle of every range), then seeded starts; the follower from the total
    starts = [np.full(nfree, 0.5)] + [rng.uniform(0.1, 0.9, nfree) for _ in range(args.starts - 1)]
    variables = space.variables
    problem = designing.problem.build_problem(mech, variables, designing.objective("rms-deviation"), (),
                                              (designing.OperatingPoint(),), ensemble, run_revolutions,
                                              args.samples, jc.Settings(t_end=1.0))
    t0 = time.perf_counter()
    warm = jc.design(mech, VARIABLES, "rms-deviation", space.constraints(), **dict(kw, max_iter=1))  # compiles
    compile_s = time.perf_counter() - t0
    nominal = warm.objective["start"]
    rugged = noise(problem, space, starts[0], steady=steady)
    print("relative change of the objective when the design moves by h of each range, at the first start:",
          {h: f"{v:+.2e}" for h, v in rugged.items()}, flush=True)
    rows = []
    for i, w0 in enumerate(starts):
        u0 = space.full(w0)
        g = run_gradient(mech, kw, u0, problem, space, steady)
        c = run_cma(problem, space, w0, args.budget, seed=i + 1, steady=steady)
        d = run_de(problem, space, w0, args.budget, seed=i + 1, steady=steady)
        target = min(c["best"], d["best"])
        row = {"start": design_of(space, w0), "target_gradient_free": target, "gradient": g, "cma": c, "de": d,
               "gradient_simulations_to_target": first_within(g["trace"], target),
               "cma_simulations_to_target": first_within(c["trace"], target),
               "de_simulations_to_target": first_within(d["trace"], target)}
        if steady:  # each best design judged again by a long average (the short one's noise picked them)
            long = evaluator(problem, dataclasses.replace(steady, revolutions=args.check_revolutions))
            row["check"] = {k: float(long(jnp.asarray(space.full_of(row[k]["design"]), dtype=float))[0][0])
                            for k in ("gradient", "cma", "de")}
            best = min(row["check"]["cma"], row["check"]["de"])
            row["check"]["gradient_above_best_gradient_free"] = row["check"]["gradient"] / best - 1.0
            row["check"]["nominal"] = float(long(jnp.asarray(space.full(np.full(nfree, 0.5)), dtype=float))[0][0])
            # the long average's slope at the start along each free coordinate (the follower
            # following), by central differences over +-SLOPE_STEP of its range: what the start's
            # shadowing gradient (row["gradient"]["shadowing"]["start"], over all four coordinates)
            # should have pointed along
            row["check"]["slope_step"] = SLOPE_STEP
            row["check"]["slopes"] = {}
            for j in range(nfree):
                e = np.zeros(nfree)
                e[j] = SLOPE_STEP
                up, down = (float(long(jnp.asarray(space.full(np.asarray(w0) + sgn * e), dtype=float))[0][0])
                            for sgn in (1, -1))
                row["check"]["slopes"][variables[space.free[j]].name] = (up - down) / (2 * SLOPE_STEP)
            print(f"  long averages ({args.check_revolutions} revolutions): {row['check']}", flush=True)
        rows.append(row)
        print(f"{args.case} start {i} u0={np.round(u0, 3).tolist()}: gradient best {g['best']:.6g} in {g['simulations']:.1f} "
              f"simulation-equivalents ({g['wall_s']:.1f} s, gradient cost {g['gradient_cost']:.2f} sims, "
              f"{g['status']}); CMA-ES best {c['best']:.6g} in {c['simulations']} ({c['wall_s']:.1f} s); DE best "
              f"{d['best']:.6g} in {d['simulations']} ({d['wall_s']:.1f} s); gradient reaches 1 % of the best "
              f"gradient-free at {row['gradient_simulations_to_target']}", flush=True)
    out = {"case": f"{preset}, rms-deviation of the output link's acceleration", "variables": VARIABLES,
           "steady": None if steady is None else dict(dataclasses.asdict(steady),
                                                       check_revolutions=args.check_revolutions),
           "total_mass": None if total is None else {"bodies": list(total["bodies"]), "kg": space.mass,
                                                     "follower": total["follower"], "leader": total["leader"]},
           "revolutions": args.revolutions, "ensemble": args.ensemble, "samples_per_revolution": args.samples, "budget": args.budget,
           "nominal_objective": nominal, "objective_noise": rugged, "compile_s": compile_s, "rows": rows, "machine": platform.platform(),
           "jax_backend": jax.default_backend()}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=1, default=float))
    fig = Figure(figsize=(7.5, 4.5))
    ax = fig.subplots()
    for i, row in enumerate(rows):
        method = "SLSQP" if space.constraints() else "L-BFGS-B"
        for key, color, label in (("gradient", "C0", f"gradient ({method})"), ("cma", "C1", "CMA-ES"),
                                  ("de", "C2", "differential evolution")):
            tr = np.asarray(row[key]["trace"], dtype=float)
            ax.plot(tr[:, 0], tr[:, 1], color=color, ls="-" if i == 0 else "--", marker="o" if key == "gradient" else None,
                    ms=3, label=f"{label}, start {i}")
    ax.axhline(nominal, color="gray", lw=0.8, ls=":", label="nominal design")
    ax.set_xlabel("simulations (a gradient at its measured cost)")
    ax.set_ylabel(f"best RMS deviation of the output's acceleration [{warm.objective['unit']}]")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    runs = (f"{args.revolutions:g} revolution per evaluation as an ensemble of {args.ensemble} periodic starts of "
            f"{run_revolutions:g} revolution" if args.ensemble > 1 else f"one run of {args.revolutions:g} revolution "
            "per evaluation")
    if steady:
        runs = (f"steady operation: {args.steady} revolutions averaged after {args.transient + steady.discard_revolutions}, "
                f"gradients by shadowing (n_unstable {args.n_unstable})")
    held = f"; total mass of {' + '.join(total['bodies'])} fixed at {space.mass:g} kg" if total else ""
    ax.set_title(f"Design of the {preset}: RMS deviation from the ideal joint, best so far\n{runs}\n"
                 f"{', '.join(VARIABLES)}{held}", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(f"nominal objective {nominal:.6g}; written {args.json}, {args.png}")


if __name__ == "__main__":
    main()
