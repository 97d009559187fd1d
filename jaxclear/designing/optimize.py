r"""The optimiser: SciPy's bounded quasi-Newton and SQP methods on the unit cube, fed with the
simulations' error-controlled derivatives (theory: docs/theory/design.md).

Why SciPy's methods and not a first-order optimiser (optax) on a reparametrised problem: an
evaluation is a set of simulations (milliseconds to seconds), so the number of evaluations is
what counts, and a design has few variables (a handful to a few dozen). That is the regime of
quasi-Newton methods with bounds (L-BFGS-B, Byrd, Lu, Nocedal and Zhu 1995: the bounds are the
cube's faces, no reparametrisation bends the landscape) and of sequential quadratic programming
for general constraints (SLSQP, Kraft 1988: equality and inequality constraints with their
Jacobians, e.g. a total mass held fixed); optimistix has no constrained minimiser, and a penalty
or a sigmoid reparametrisation would trade exact bounds and constraints for tuning. Both SciPy
methods are deterministic, which the journal's resumption relies on (:mod:`.journal`).

``method="auto"``: L-BFGS-B without constraints, SLSQP with them; ``"trust-constr"`` is
offered for problems where SLSQP's line search struggles.

``method="differential-evolution"``: SciPy's differential evolution (Storn and Price, "Differential
evolution: a simple and efficient heuristic for global optimization over continuous spaces", J.
Global Optim. 11 (1997) 341-359; best1bin, constraints by Lampinen's feasibility rules: Lampinen,
"A constraint handling approach for the differential evolution algorithm", CEC 2002), no
gradients: for objectives a gradient cannot describe, a chaotic motion's one-revolution objective
or a steady average whose shadowing gradients are unresolved (benchmarks/README.md, "On steady
operation": 4,804 against SLSQP's 15,553 on bench_design's study). :data:`POPULATION_PER_VARIABLE`
members per variable (the start design one of them, the rest a Latin hypercube), ``max_iter``
generations, a fixed seed (:data:`SEED`), members evaluated one after another and no polishing:
deterministic, so the journal replays it. It stops where the population's objectives agree to
``ftol`` (relative). Inequality constraints only: no member meets an equality exactly, so
SciPy would evaluate no objective (:func:`choose_method` refuses it).

Scaling: the variables are unit-cube coordinates; the objective is divided by its magnitude at
the start, so the stopping tolerances are relative; the constraints' residuals are
dimensionless already (:mod:`.constraints`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial
from typing import Callable

import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from .journal import Journal
from .problem import DesignProblem, jacobian_at, values_at

#: The methods offered (``auto``: L-BFGS-B without constraints, SLSQP with them).
METHODS = ("auto", "L-BFGS-B", "SLSQP", "trust-constr", "differential-evolution")
#: The methods that use no gradient (the design then asks for none, at its iterates or its optimum).
GRADIENT_FREE = ("differential-evolution",)
#: Differential evolution's population per design variable (benchmarks/bench_design.py's).
POPULATION_PER_VARIABLE = 5
#: Differential evolution's random seed: a fixed one keeps a design deterministic (its journal).
SEED = 0
#: The scaled objective returned for a point where a run fails (the start's is 1): the line
#: searches step back from it.
FAILED = 1e6


@dataclass
class Counts:
    """Evaluations so far (this call and the journal's), their simulations and wall time."""

    values: int = 0
    gradients: int = 0
    runs: int = 0
    value_wall_s: float = 0.0
    gradient_wall_s: float = 0.0
    replayed: int = 0

    @property
    def gradient_cost(self) -> float:
        """Measured cost of one gradient evaluation in value evaluations (wall-time ratio; NaN
        until both kinds were computed)."""
        if not (self.values and self.gradients and self.value_wall_s > 0):
            return float("nan")
        return (self.gradient_wall_s / self.gradients) / (self.value_wall_s / self.values)


@dataclass
class Evaluator:
    """Answers the optimiser's requests from the journal or by evaluating the problem."""

    problem: DesignProblem
    journal: Journal
    counts: Counts = field(default_factory=Counts)
    scale: float = 1.0
    #: ``u -> (values, statuses)`` and ``u -> (values, jacobian, statuses)``; None: the problem's
    #: runs (:func:`~.problem.evaluate`, :func:`~.problem.evaluate_with_jacobian`); a design on
    #: steady operation gives its own (:class:`~.steady.SteadyEvaluation`), whose gradients also
    #: return a dict of what else they know (journaled as the entry's ``extra``).
    values_of: Callable | None = None
    jacobian_of: Callable | None = None

    def _record(self, entry: dict, gradient: bool, replayed: bool):
        b = self.problem.members.count
        if gradient:
            self.counts.gradients += 1
            self.counts.gradient_wall_s += entry["wall_s"]
        else:
            self.counts.values += 1
            self.counts.value_wall_s += entry["wall_s"]
        self.counts.runs += b
        self.counts.replayed += int(replayed)

    def value(self, u) -> dict:
        """The evaluation at ``u`` (values and statuses), from the journal if it holds one."""
        u = np.asarray(u, dtype=float)
        found = self.journal.find(u, gradient=False)
        if found is not None:
            if not found.get("_seen"):
                found["_seen"] = True
                self._record(found, found["kind"] == "gradient", True)
            return found
        t0 = time.perf_counter()
        values, status = (self.values_of or partial(values_at, self.problem))(jnp.asarray(u))
        values, status = np.asarray(values), np.asarray(status)
        entry = self.journal.add(u, values, status, time.perf_counter() - t0)
        entry["_seen"] = True
        self._record(entry, False, False)
        return entry

    def gradient(self, u) -> dict:
        """The evaluation with the Jacobian at ``u``."""
        u = np.asarray(u, dtype=float)
        found = self.journal.find(u, gradient=True)
        if found is not None:
            if not found.get("_seen"):
                found["_seen"] = True
                self._record(found, True, True)
            return found
        t0 = time.perf_counter()
        values, jac, status, *extra = (self.jacobian_of or partial(jacobian_at, self.problem))(
            jnp.asarray(u))
        values, jac, status = np.asarray(values), np.asarray(jac), np.asarray(status)
        entry = self.journal.add(u, values, status, time.perf_counter() - t0, jacobian=jac,
                                 extra=extra[0] if extra else None)
        entry["_seen"] = True
        self._record(entry, True, False)
        return entry

    # ---- what SciPy calls -----------------------------------------------------------------

    def _ok(self, entry) -> bool:
        return bool(np.all(np.isfinite(entry["values"])))

    def objective(self, u) -> float:
        e = self.value(u)
        return float(e["values"][0]) / self.scale if self._ok(e) else FAILED

    def objective_gradient(self, u) -> np.ndarray:
        e = self.gradient(u)
        return np.asarray(e["jacobian"][0]) / self.scale if self._ok(e) else np.zeros(len(u))

    def objective_and_gradient(self, u):
        e = self.gradient(u)
        if not self._ok(e):
            return FAILED, np.zeros(len(u))
        return float(e["values"][0]) / self.scale, np.asarray(e["jacobian"][0]) / self.scale

    def constraint(self, u, i: int) -> float:
        e = self.value(u)
        return float(e["values"][1 + i]) if self._ok(e) else -FAILED

    def constraint_gradient(self, u, i: int) -> np.ndarray:
        e = self.gradient(u)
        return np.asarray(e["jacobian"][1 + i]) if self._ok(e) else np.zeros(len(u))


def choose_method(method: str, constrained: bool, equality: bool = False) -> str:
    """The method to run (``auto`` resolved); refuses one that cannot take the constraints
    (``equality``: one of them is an equality, which differential evolution's members never meet
    exactly, so it would evaluate no objective)."""
    if method in GRADIENT_FREE and equality:
        raise ParameterError(f"method {method!r} takes inequality constraints only; the design has an equality "
                             "(such as total-mass), which no member of its population meets exactly: use 'SLSQP' "
                             "or 'trust-constr'")
    if method not in METHODS:
        raise ParameterError(f"design method {method!r} is not one of {list(METHODS)}")
    if method == "auto":
        return "SLSQP" if constrained else "L-BFGS-B"
    if method == "L-BFGS-B" and constrained:
        raise ParameterError("method 'L-BFGS-B' takes bounds only; the design has constraints: use 'SLSQP', "
                             "'trust-constr' or 'auto'")
    return method


def minimize(ev: Evaluator, u0: np.ndarray, method: str, max_iter: int, ftol: float, gtol: float, callback):
    """Run SciPy's ``method`` from ``u0`` on the unit cube; ``callback(u)`` after every iteration."""
    import scipy.optimize as so  # here: it is half a second of `import jaxclear` otherwise (issue 41)

    p = len(u0)
    # keep_feasible: trust-constr's interior-point method otherwise treats the bounds as constraints
    # that its iterates may violate, and the runs would leave the variables' ranges (a crank mass
    # of 0.03 kg for a range [0.1, 0.3] was simulated before this); L-BFGS-B and SLSQP keep their
    # bounds anyway and ignore the flag
    bounds = so.Bounds(np.zeros(p), np.ones(p), keep_feasible=True)
    cons = ev.problem.constraints

    def cb(intermediate_result):
        callback(np.asarray(intermediate_result.x, dtype=float))

    def nonlinear(gradients: bool):
        """Every constraint as SciPy's ``NonlinearConstraint``, residual >= 0 (= 0 for an
        equality), with its Jacobian where the method uses gradients."""
        return [so.NonlinearConstraint(lambda u, i=i: ev.constraint(u, i), 0.0, 0.0 if c.equality else np.inf,
                                       **({"jac": lambda u, i=i: ev.constraint_gradient(u, i)[None, :]}
                                          if gradients else {}))
                for i, c in enumerate(cons)]

    if method == "differential-evolution":
        # inequalities only (choose_method refuses an equality); SciPy's maxiter counts the
        # generations after the first: max_iter generations in all
        return so.differential_evolution(ev.objective, list(zip(np.zeros(p), np.ones(p))), x0=u0,
                                         popsize=POPULATION_PER_VARIABLE, maxiter=max_iter - 1, tol=ftol,
                                         seed=SEED, polish=False, updating="immediate", workers=1,
                                         constraints=nonlinear(False) or (), callback=cb)
    if method == "L-BFGS-B":
        return so.minimize(ev.objective_and_gradient, u0, jac=True, method=method, bounds=bounds, callback=cb,
                           options={"maxiter": max_iter, "ftol": ftol, "gtol": gtol})
    if method == "SLSQP":
        specs = [{"type": "eq" if c.equality else "ineq", "fun": (lambda u, i=i: ev.constraint(u, i)),
                  "jac": (lambda u, i=i: ev.constraint_gradient(u, i))} for i, c in enumerate(cons)]
        return so.minimize(ev.objective, u0, jac=ev.objective_gradient, method=method, bounds=bounds,
                           constraints=specs, callback=cb, options={"maxiter": max_iter, "ftol": ftol})
    return so.minimize(ev.objective_and_gradient, u0, jac=True, method=method, bounds=bounds,
                       constraints=nonlinear(True), callback=cb, options={"maxiter": max_iter, "gtol": gtol,
                                                                         "xtol": ftol})


def projected_gradient_norm(u, g) -> float:
    """Norm of the gradient ``g`` (unit coordinates, scaled objective) with the components that
    push against an active bound removed: 0 at a bounded stationary point."""
    u, g = np.asarray(u, dtype=float), np.asarray(g, dtype=float)
    free = ~(((u <= 0.0) & (g > 0)) | ((u >= 1.0) & (g < 0)))
    return float(np.linalg.norm(np.where(free, g, 0.0)))


__all__ = ["Counts", "Evaluator", "FAILED", "GRADIENT_FREE", "METHODS", "POPULATION_PER_VARIABLE", "SEED",
           "choose_method", "minimize", "projected_gradient_norm"]
