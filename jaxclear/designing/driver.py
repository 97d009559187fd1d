"""The driver: :func:`design` checks the inputs, builds the problem, runs the optimiser with its
journal in a locked folder and returns a :class:`~jaxclear.designing.result.DesignResult`
(method: :mod:`jaxclear.designing`; theory: docs/theory/design.md)."""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from typing import Callable

import numpy as np
from tqdm.auto import tqdm

from .._errors import STATUS, DesignError, ParameterError
from .._interrupt import stop_at_safe_points
from .._checkpoint import key as work_key, locked
from ..params.derivatives import DerivativeHorizonWarning
from ..chaos import ShadowingWarning
from ..integrate import Settings
from ..model import Mechanism, crank_driver
from ..sweep.lanes import ahead
from .chaos import (RuggedObjectiveWarning, horizon_report, roughness_report, rugged_message, scale_message,
                    scale_report)
from .constraints import constraint as make_constraint
from .journal import Journal
from .objectives import objective as make_objective
from .optimize import GRADIENT_FREE, Evaluator, choose_method, minimize, projected_gradient_norm
from .problem import (SAMPLES_PER_REVOLUTION, Ensemble, OperatingPoint, build_problem, jacobian_at,
                      prepare_jacobian)
from .report import (CONSTRAINT_TOL, comparison_runs, constraint_table, least_violation, sensitivity, status_of,
                     violation)
from .result import DesignResult
from .steady import SteadyOperation, SteadyEvaluation
from .variables import apply, check_variables, to_unit


#: Relative difference between the start objective of the plain run and of the sensitivity solve
#: above which a design warns that the objective is dominated by the solver's error. Where the
#: motion is predictable both are within the tolerance of one trajectory (measured 3e-5 on the
#: slider acceleration of the benchmark at rtol 1e-8); over a revolution of the benchmark
#: slider-crank at 5000 rpm they differ by percents (benchmarks/bench_design.py).
SPREAD_LIMIT = 1e-2


def _spec(obj) -> str:
    """A text that identifies an objective or constraint across processes (a callable by its
    module and qualified name, not its address): part of the journal's key."""
    fields = []
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        fields.append(f"{f.name}={getattr(v, '__module__', '')}.{getattr(v, '__qualname__', '')}" if callable(v)
                      else f"{f.name}={v!r}")
    return f"{type(obj).__name__}({', '.join(fields)})"


def _points(points) -> tuple[OperatingPoint, ...]:
    """Operating points from None (the mechanism as given), :class:`OperatingPoint` or dicts
    ``{"values": {...}, "weight": w}`` / plain ``{name: value}``."""
    if points is None:
        return (OperatingPoint(),)
    out = []
    for p in points:
        if isinstance(p, dict):
            p = OperatingPoint(dict(p["values"]), float(p.get("weight", 1.0))) if "values" in p else OperatingPoint(dict(p))
        if not isinstance(p, OperatingPoint):
            raise ParameterError(f"operating point {p!r}: give an OperatingPoint or a dict of parameter values")
        if not (math.isfinite(p.weight) and p.weight > 0):
            raise ParameterError(f"operating point {p.values}: weight = {p.weight:g} outside the allowed range (0, inf)")
        out.append(p)
    if not out:
        raise ParameterError("points: give at least one operating point (or None for the mechanism as given)")
    return tuple(out)


def _start_error(problem, values, status) -> DesignError:
    """The one-line error for a start design whose objective or constraints are not finite."""
    names = [problem.objective.describe(problem.mech)] + [c.describe() for c in problem.constraints]
    bad = [n for n, v in zip(names, values) if not np.isfinite(v)]
    failed = [int(s) for s in np.asarray(status) if int(s) != 0]
    told = "; ".join(f"status {code}: {STATUS.get(code, 'unknown status')}" for code in sorted(set(failed)))
    why = f"; {len(failed)} of {len(status)} runs failed ({told})" if failed else ""
    return DesignError(f"design of {problem.mech.name!r}: not finite at the start design: {', '.join(bad)}{why}; "
                       "change the start, the variables' ranges or the run settings")


def design(mech: Mechanism, variables: dict, objective="rms-deviation", constraints=(), *, start: dict | None = None,
           settings: Settings | None = None, points=None, ensemble: Ensemble | None = None, revolutions: float = 1.0,
           samples_per_revolution: int = SAMPLES_PER_REVOLUTION, method: str = "auto", max_iter: int = 30,
           ftol: float = 1e-6, gtol: float = 1e-5, out=None, resume: bool = True, progress: bool = True,
           check_chaos: bool = True, report_sensitivity: bool = True, plots: bool = True,
           callback: Callable | None = None, steady: SteadyOperation | None = None) -> DesignResult:
    """Minimise an objective of simulations of ``mech`` over named design variables within
    bounds and under constraints, with gradients through the simulations (method:
    :mod:`jaxclear.designing`).

    Args:
        mech: the nominal mechanism; it needs a crank driver (the runs last ``revolutions`` of it).
        variables: ``{name: (low, high)}``, :mod:`jaxclear.params` names
            (:func:`jaxclear.differentiable_names`: masses, ``centroid_x:BODY``, point coordinates,
            clearance, law and friction parameters, ``speed_rpm``...).
        objective: a name of :data:`jaxclear.designing.OBJECTIVES` with options
            (``"rms-deviation:skip=0.5"``), an :class:`~jaxclear.designing.AbstractObjective`, or a
            callable ``fn(solution, mechanism) -> scalar``.
        constraints: texts (``"total-mass"``, ``"assembles"``, ``"peak-force<=N"``...) or
            constraint objects (:mod:`jaxclear.designing.constraints`).
        start: start values (default: the mechanism's; a ``centroid_*`` variable's is 0).
        settings: how every run is integrated (:class:`~jaxclear.Settings`, whole: solver,
            tolerances, step limit, derivatives (``Sensitivity(tolerance)`` or ``ThroughLoop``),
            onsets...); the design replaces only what it owns: ``t_start`` 0, ``t_end`` and
            ``n_out`` (from ``revolutions`` and ``samples_per_revolution`` of each run's crank
            speed), ``throw`` and ``progress``. Default None: ``Settings``' defaults.
        points: operating points (:class:`~jaxclear.designing.OperatingPoint` or dicts of
            parameter values), averaged with their weights.
        ensemble: several starts per point (:class:`~jaxclear.designing.Ensemble`).
        revolutions, samples_per_revolution: length and sampling of each run.
        method: ``"auto"`` (L-BFGS-B without constraints, SLSQP with), ``"L-BFGS-B"``,
            ``"SLSQP"``, ``"trust-constr"``, or ``"differential-evolution"`` (gradient-free: for
            objectives a gradient cannot describe; no gradient is computed, and ``check_chaos``'
            gradient checks are left out; :mod:`jaxclear.designing.optimize`).
        max_iter, ftol, gtol: the method's iteration limit (differential evolution: its
            generations, of 5 members per variable) and tolerances (relative objective).
        out: folder for the journal and the reports (locked while the design runs); None:
            nothing written.
        resume: answer from a journal of the same design in ``out`` (bit-identical result).
        progress: a tqdm bar over the iterations with the objective.
        check_chaos: measure the derivative horizon at the start (one sensitivity solve) and
            warn with :class:`jaxclear.DerivativeHorizonWarning` where a run is past it; and
            the objective's roughness (6 evaluations per variable, at +- 1e-10, 1e-8 and 1e-6 of
            its range, against the gradient's prediction), warning with :class:`jaxclear.RuggedObjectiveWarning`;
            and at the optimiser's steps (+-1 %, +-5 % of each range, at the start and at the
            optimum: :func:`~jaxclear.designing.chaos.scale_report`), warning and saying so in
            the summary where the objective departs from a smooth curve.
        report_sensitivity: simulate the objective at +-1 % of each range around the optimum.
        plots: the comparison runs and ``design.png`` (with ``out``).
        callback: ``callback(record)`` after every iteration (the history's record).
        steady: a :class:`~jaxclear.designing.SteadyOperation`: the objective is averaged over steady
            operation (after a transient, over ``steady.revolutions``) and its gradient taken by
            least-squares shadowing (:mod:`jaxclear.designing.steady`); the objective
            ``rms-deviation`` or a callable per sample ``fn(t, q, qdot, qddot, mech) -> scalar``
            (averaged), no points or ensemble, constraints on the design only;
            ``check_chaos`` then reports the shadowing gradients' errors (``result.chaos["steady"]``)
            and warns (:class:`jaxclear.chaos.ShadowingWarning`) where they were unresolved. ``revolutions``
            is then the length of the before/after comparison runs only.

    Raises:
        ParameterError: a bad variable (unknown or structural name, empty or inverted range,
            start outside it), objective, constraint, point, ensemble or method.
        DesignError: the objective or a constraint is not finite at the start design.
        OutputLockedError: another process holds ``out``.
        CheckpointError: the journal in ``out`` is damaged.
    """
    t0 = time.perf_counter()
    if not isinstance(mech, Mechanism) or crank_driver(mech) is None:
        raise ParameterError("design: give a Mechanism with a crank driver (the runs last a number of its revolutions)")
    if not (isinstance(revolutions, (int, float)) and math.isfinite(revolutions) and revolutions > 0):
        raise ParameterError(f"revolutions = {revolutions!r} outside the allowed range (0, inf)")
    for name, v, low in (("max_iter", max_iter, 1), ("samples_per_revolution", samples_per_revolution, 8)):
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise ParameterError(f"{name} = {v!r} outside the allowed range [{low}, inf) (an integer)")
    variables_ = check_variables(mech, variables, start)
    obj = make_objective(objective)
    obj.check(mech)
    x0 = np.asarray([v.start for v in variables_])
    start_mech = apply(mech, variables_, x0)
    cons = []
    for spec in (constraints if isinstance(constraints, (list, tuple)) else (constraints,)):
        c = make_constraint(spec)
        c.check(mech)
        cons.append(c.calibrated(start_mech))
    method_ = choose_method(method, bool(cons), any(c.equality for c in cons))
    if steady is not None:
        if not isinstance(steady, SteadyOperation):
            raise ParameterError(f"steady must be a jaxclear.designing.SteadyOperation or None, got {steady!r}")
        steady.check()
        if points is not None or ensemble is not None:
            raise ParameterError("design(steady=...): operating points and ensembles do not apply (the steady "
                                 "average holds every start); give neither")
    ensemble = ensemble or Ensemble()
    ensemble.check()
    base = settings if settings is not None else Settings(t_end=1.0)
    problem = build_problem(mech, variables_, obj, tuple(cons), _points(points), ensemble, revolutions,
                            samples_per_revolution, base)
    key = work_key(mech, [(v.name, v.low, v.high, v.start) for v in variables_], _spec(obj),
                   [_spec(c) for c in cons], problem.members, problem.base, revolutions, problem.n_out, method_,
                   max_iter, ftol, gtol, *([dataclasses.asdict(steady)] if steady is not None else []))
    steady_eval = SteadyEvaluation(problem, steady) if steady is not None else None
    described = obj.describe(mech) + (steady.describe(method_ not in GRADIENT_FREE) if steady is not None else "")
    config = dict(variables={v.name: [v.low, v.high] for v in variables_}, objective=described,
                  constraints=[c.describe() for c in cons], method=method_, max_iter=max_iter, ftol=ftol, gtol=gtol,
                  revolutions=revolutions, samples_per_revolution=samples_per_revolution, runs_per_evaluation=
                  problem.members.count, points=[dict(p.values, weight=p.weight) for p in _points(points)],
                  ensemble=dataclasses.asdict(ensemble), rtol=problem.rtol, atol=problem.atol,
                  steady=None if steady is None else dataclasses.asdict(steady))
    with locked(out, "design"):
        return _design_locked(problem, variables_, to_unit(variables_, x0), start_mech, key, config, out, resume,
                              progress, check_chaos, report_sensitivity, plots, callback, t0, steady_eval)


def _design_locked(problem, variables, u0, start_mech, key, config, out, resume, progress, check_chaos,
                   report_sensitivity, plots, callback, t0, steady_eval=None) -> DesignResult:
    journal = Journal(out, key, resume, config)
    ev = Evaluator(problem, journal) if steady_eval is None else Evaluator(
        problem, journal, values_of=steady_eval.value, jacobian_of=steady_eval.with_jacobian)
    if progress and journal.loaded:
        tqdm.write(f"jaxclear design: resuming in {out}: {journal.loaded} evaluations in the journal")
    if progress and not journal.loaded:
        tqdm.write("jaxclear design: compiling the runs and their sensitivities (tens of seconds, once per structure)")
    with_gradients = config["method"] not in GRADIENT_FREE
    # the first gradient (asked at u0 next) is traced here and compiled on a thread of its own
    # while the first values' program and the report's runs (the same structures as at the
    # optimum) are traced and compiled beside it; its outputs are kept for ev.gradient(u0)
    first_gradient = None
    if with_gradients and steady_eval is None and not journal.loaded:
        prepare_jacobian(problem, u0)
        first_gradient = ahead(jacobian_at, problem, u0)
    first = ev.value(u0)
    if first_gradient is not None:
        if plots:
            comparison_runs(problem, start_mech, start_mech, config["revolutions"], config["samples_per_revolution"])
        first_gradient.exception()  # waits for it
    if not np.all(np.isfinite(first["values"])):
        raise _start_error(problem, first["values"], first["status"])
    f0 = float(first["values"][0])
    ev.scale = abs(f0) if f0 != 0 else 1.0
    chaos = None
    # the checks of whether gradients mean anything: a steady design has its own (its gradients'
    # errors, at the end), a gradient-free method needs none
    if check_chaos and steady_eval is None and with_gradients:
        # the plain run against the sensitivity solve at the start (the optimiser asks for this
        # gradient first anyway): within the tolerance of each other where the motion is predictable
        start_grad = ev.gradient(u0)
        chaos = horizon_report(problem, u0)  # the same program's state tangents: nothing runs again
        tangent = float(start_grad["values"][0])
        chaos["objective_spread"] = abs(tangent - f0) / abs(f0) if f0 else abs(tangent)
        # the objective itself at u0 +- a tiny step of each range against the gradient's prediction
        # (6 P plain evaluations, journaled like the optimiser's so a resumed design replays them)
        chaos["roughness"] = roughness_report(lambda u: ev.value(u)["values"][0], u0, f0,
                                              np.asarray(start_grad["jacobian"][0]), [v.name for v in variables])
        chaos["warnings"] = []
        if chaos["roughness"]["rugged"]:
            chaos["warnings"].append(rugged_message(problem.mech.name, chaos["roughness"]))
            warnings.warn(chaos["warnings"][-1], RuggedObjectiveWarning, stacklevel=3)
        # and at the optimiser's own steps (+-1 %, +-5 % of each range: 4 P evaluations)
        chaos["scale"] = _scale_check(ev, problem, u0, f0, start_grad["jacobian"][0], "start", chaos["warnings"])
        why = []
        if chaos["past_horizon"]:
            why.append(f"a run of {chaos['run_s']:.3g} s is past the derivative horizon of "
                       f"{', '.join(chaos['past_horizon'])}")
        if chaos["objective_spread"] > SPREAD_LIMIT:
            why.append(f"the objective of the plain run and of the sensitivity solve differ by "
                       f"{100 * chaos['objective_spread']:.2g} % (the solver's error dominates it)")
        if why:
            chaos["warnings"].append(f"design of {problem.mech.name!r}: {'; '.join(why)}: the motion is chaotic there "
                                     "and gradients describe changes below the tolerance; use shorter runs over an "
                                     "ensemble of starts (Ensemble(starts=...)) or a gradient-free search "
                                     "(method='differential-evolution')")
            warnings.warn(chaos["warnings"][-1], DerivativeHorizonWarning, stacklevel=3)
    history, bars = [], []

    def record(u, interrupt):
        # the gradient at every iterate (L-BFGS-B has it; SLSQP asks for it next): asking here keeps
        # the order of evaluations, hence a resumed design, deterministic; a gradient-free method
        # asks for none (its iterates' gradient norm is NaN)
        grad_entry = ev.gradient(u) if interrupt is not None and with_gradients else None
        e = ev.value(u)
        g = float("nan") if grad_entry is None else projected_gradient_norm(u, np.asarray(grad_entry["jacobian"][0]) / ev.scale)
        h = {"iteration": len(history), "objective": float(e["values"][0]), "violation": violation(problem, e["values"]),
             "gradient_norm": g, "design": {v.name: float(v.from_unit(ui)) for v, ui in zip(variables, u)},
             "evaluations": ev.counts.values + ev.counts.gradients, "gradients": ev.counts.gradients,
             "runs": ev.counts.runs,
             "wall_s": time.perf_counter() - t0}
        history.append(h)
        if progress and not bars and len(history) > 1:
            bars.append(tqdm(total=config["max_iter"], initial=len(history) - 2, desc="design", unit="it"))
        if bars:
            bars[0].update(1)
            bars[0].set_postfix({"objective": f"{h['objective']:.5g}", "|g|": f"{g:.3g}"})
        if callback is not None:
            callback(h)
        if interrupt is not None:
            interrupt.check()  # a Ctrl-C stops here: every evaluation so far is in the journal

    try:
        with stop_at_safe_points("the current iteration") as interrupt:
            record(u0, None)
            res = minimize(ev, np.asarray(u0, dtype=float), config["method"], config["max_iter"], config["ftol"],
                           config["gtol"], lambda u: record(u, interrupt))
    finally:
        for bar in bars:
            bar.close()
    u = np.clip(np.asarray(res.x, dtype=float), 0.0, 1.0)
    # a gradient-free method's optimum gets no gradient either (on steady operation a shadowing
    # solve whose answer is the noise the method was chosen to avoid): NaN in the report
    final = ev.gradient(u) if with_gradients else ev.value(u)
    values = np.asarray(final["values"])
    jac = np.asarray(final["jacobian"]) if with_gradients else np.full((values.shape[0], len(u)), np.nan)
    feasible = np.all(np.isfinite(values)) and violation(problem, values) <= CONSTRAINT_TOL
    status = status_of(res, bool(feasible), config["max_iter"])
    grad, sens = sensitivity(ev, u, values, jac) if report_sensitivity else (
        {v.name: float(jac[0][i]) / v.span for i, v in enumerate(variables)}, {})
    if steady_eval is not None and check_chaos:
        summary = steady_eval.summary(journal.gradients.values())
        said = steady_eval.message(problem.mech.name, summary)
        chaos = {"steady": summary, "warnings": [said] if said else []}
        if said:
            warnings.warn(said, ShadowingWarning, stacklevel=3)
    elif chaos is not None and np.all(np.isfinite(values)) and with_gradients:  # the same check where it ends
        chaos["scale_optimum"] = _scale_check(ev, problem, u, float(values[0]), jac[0], "optimum", chaos["warnings"])
    start_eval = first
    x = [float(v.from_unit(ui)) for v, ui in zip(variables, u)]
    opt_mech = apply(problem.mech, variables, np.asarray(x))
    f_start, f_opt = f0, float(values[0])
    result = DesignResult(
        status=status, message=str(res.message), design={v.name: xi for v, xi in zip(variables, x)},
        start={v.name: float(v.start) for v in variables},
        objective={"name": problem.objective.name, "description": config["objective"],
                   "unit": problem.objective.unit(problem.mech), "start": f_start, "optimum": f_opt,
                   "improvement": 1.0 - f_opt / f_start if f_start else float("nan")},
        constraints=constraint_table(problem, start_eval["values"], values), gradient=grad,
        gradient_norm=projected_gradient_norm(u, jac[0] / ev.scale), sensitivity=sens,
        iterations=int(getattr(res, "nit", len(history) - 1)),
        evaluations={"values": ev.counts.values, "gradients": ev.counts.gradients, "replayed": ev.counts.replayed},
        runs=ev.counts.runs, gradient_cost=ev.counts.gradient_cost,
        wall_time_s=time.perf_counter() - t0, history=history, chaos=chaos, settings=config,
        least_violation=None if feasible else least_violation(ev), mechanism=opt_mech, start_mechanism=start_mech)
    if plots:
        result.comparison = comparison_runs(problem, start_mech, opt_mech, config["revolutions"],
                                            config["samples_per_revolution"])
    if out is not None:
        result.write(out)
    return result


def _scale_check(ev, problem, u, f: float, gradient, where: str, said: list) -> dict:
    """:func:`~.chaos.scale_report` at ``u`` (objective ``f``, its gradient over the unit
    coordinates); a rugged one is warned of and its line added to ``said`` (the summary's)."""
    report = scale_report(lambda w: ev.value(w)["values"][0], u, f, np.asarray(gradient),
                          [v.name for v in problem.variables])
    if report["rugged"]:
        said.append(scale_message(problem.mech.name, report, where))
        warnings.warn(said[-1], RuggedObjectiveWarning, stacklevel=4)
    return report


__all__ = ["design"]
