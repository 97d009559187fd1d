"""What a finished design reports beyond its optimum: the status, the sensitivity of the optimum to
each variable, the least constraint violation found, and the runs of its comparison figure."""

from __future__ import annotations

import numpy as np

from ..params.registry import replace_many
from ..analysis import channels
from ..integrate import is_kinematic, kinematic_solution
from ..integrate import revolution_settings
from ..integrate import simulate
from ..model import Mechanism
from .objectives import RmsDeviation
from .optimize import Evaluator

#: A constraint residual below minus this counts as violated (residuals are dimensionless).
CONSTRAINT_TOL = 1e-5
#: The step of the sensitivity's simulated changes, as a fraction of each variable's range.
SENSITIVITY_STEP = 0.01


def violation(problem, values) -> float:
    """The largest violation of the constraints (0 where all hold): ``-r`` of an inequality's
    residual ``r < 0``, ``|r|`` of an equality's."""
    worst = 0.0
    for c, r in zip(problem.constraints, values[1:]):
        if not np.isfinite(r):
            return float("inf")
        worst = max(worst, abs(r) if c.equality else max(-r, 0.0))
    return float(worst)


def constraint_table(problem, start_values, values) -> list:
    """Per constraint: name, kind, residual at the start and at the optimum, whether it holds."""
    out = []
    for i, c in enumerate(problem.constraints):
        r = float(values[1 + i])
        ok = abs(r) <= CONSTRAINT_TOL if c.equality else r >= -CONSTRAINT_TOL
        out.append({"name": c.describe(), "kind": "eq" if c.equality else "ineq", "start": float(start_values[1 + i]),
                    "optimum": r, "satisfied": bool(ok)})
    return out


def status_of(res, feasible: bool, max_iter: int) -> str:
    """``converged``, ``max_iter``, ``infeasible`` or ``stopped`` from SciPy's result."""
    if not feasible:
        return "infeasible"
    if res.success:
        return "converged"
    if int(getattr(res, "nit", 0)) >= max_iter or "iteration" in str(res.message).lower():
        return "max_iter"
    return "stopped"


def least_violation(ev: Evaluator) -> dict | None:
    """The evaluated design closest to meeting the constraints: ``{"violation", "design"}``."""
    best = None
    for table in (ev.journal.gradients, ev.journal.values):
        for entry in table.values():
            v = violation(ev.problem, entry["values"])
            if np.isfinite(v) and (best is None or v < best[0]):
                best = (v, entry["u"])
    if best is None:
        return None
    x = [v.from_unit(u) for v, u in zip(ev.problem.variables, best[1])]
    return {"violation": best[0], "design": {v.name: float(xi) for v, xi in zip(ev.problem.variables, x)}}


def sensitivity(ev: Evaluator, u, values, jacobian) -> tuple[dict, dict]:
    """``(gradient, sensitivity)`` at the optimum: df/dx per variable, and per variable the
    elasticity and the objective's change for a move of :data:`SENSITIVITY_STEP` of the range
    down and up (simulated; a move that would leave the range is clipped to its bound), as a
    fraction of the start design's objective (``ev.scale``: an optimum near 0 has no scale)."""
    f = float(values[0])
    grad, sens = {}, {}
    for i, v in enumerate(ev.problem.variables):
        g = float(jacobian[0][i]) / v.span
        x = v.from_unit(float(u[i]))
        changes = []
        for sign in (-1.0, 1.0):
            w = np.array(u, dtype=float)
            w[i] = min(max(w[i] + sign * SENSITIVITY_STEP, 0.0), 1.0)
            fw = float(ev.value(w)["values"][0]) if w[i] != u[i] else f
            changes.append((fw - f) / ev.scale)
        grad[v.name] = g
        sens[v.name] = {"gradient": g, "elasticity": x * g / f if f else float("nan"), "change_minus": changes[0],
                        "change_plus": changes[1]}
    return grad, sens


def comparison_runs(problem, start: Mechanism, optimum: Mechanism, revolutions: float, per_revolution: int):
    """``(channel, (mech, sol, ideal_mech, ideal_sol) of the start, the same of the optimum)``:
    both at the first operating point over ``revolutions`` from the mechanism's own start (the
    design passes its runs' length: what the objective covered, or its first member's)."""
    values = {n: float(problem.members.values[0, i]) for i, n in enumerate(problem.members.names)}
    channel = problem.objective.channel_name(start) if isinstance(problem.objective, RmsDeviation) else \
        channels.default_channels(start)[2]
    out = []
    for m in (start, optimum):
        m = replace_many(m, values)
        s = revolution_settings(m, revolutions, samples_per_revolution=per_revolution, rtol=problem.rtol,
                                atol=problem.atol, max_steps=problem.max_steps, throw=False)
        sol = kinematic_solution(m, s) if is_kinematic(m) else simulate(m, s)
        im = m.ideal() if m.clearance_joints else None
        isol = None if im is None else (kinematic_solution(im, s) if is_kinematic(im) else simulate(im, s))
        out.append((m, sol, im, isol))
    return channel, out[0], out[1]


__all__ = ["CONSTRAINT_TOL", "comparison_runs", "constraint_table", "least_violation", "sensitivity", "status_of",
           "violation"]
