r"""Whether a design's derivatives mean anything: the horizon of predictability of its runs.

In a chaotic motion (a journal rattling in its bearing at high speed) the tangents of the state
grow like :math:`e^{\lambda t}` (:math:`\lambda` the largest Lyapunov exponent), and an objective
over a long horizon is a landscape of narrow wells whose gradient describes only changes far
below the solver's tolerance. :func:`horizon_report` measures it on the first run of a design:
the state's tangents with respect to every variable (one sensitivity solve), their
amplification (:func:`jaxclear.amplification`: the relative change of the state per full range
of the variable) and the derivative horizon (:func:`jaxclear.derivative_horizon`: the first time
at which a change of ``rtol`` times the range moves the state by a tenth of its size). A run
longer than a variable's horizon is past it: the report says so and
:func:`jaxclear.design` warns with :class:`jaxclear.DerivativeHorizonWarning`, naming
what works instead (an ensemble of shorter runs, :class:`~jaxclear.designing.Ensemble`).

A second, free sign is the spread between the objective of the plain run and of the sensitivity
solve (whose steps are sized for the tangents too): both are within the tolerance of the same
trajectory where the motion is predictable, and differ by far more where it is not.

Neither measure looks at the objective itself, and an objective can be rugged while the state's
tangents stay moderate (a mean over many impacts, each of which a tiny change moves to another
branch of the motion: the slider-crank's one-revolution RMS deviation changes by -6 % for any step
from 1e-12 to 1e-6 of the ranges, benchmarks/bench_design.py). :func:`roughness_report` measures it
directly: the plain objective at ``u +- h e_i`` for tiny steps ``h`` (:data:`ROUGHNESS_STEPS` of
each range, 6 P evaluations of the already compiled program), against the gradient's linear
prediction ``+- g_i h``. A smooth objective follows the prediction to the solver's noise; an
objective that moves by more than :data:`ROUGHNESS_LIMIT` (relative) beyond it is numerically
chaotic along that variable: :func:`jaxclear.design` warns with
:class:`RuggedObjectiveWarning` (a :class:`jaxclear.DerivativeHorizonWarning`).

Tiny steps do not see an objective that is smooth below 1e-6 of a range and rugged at the
scale the optimiser steps (a contact that comes or goes within a percent of the clearance's
range): a one-variable design reported "converged" while +-1 % of the range raised the objective
by 8.7 % and 5.5 % and its gradient predicted 0.003 %. :func:`scale_report` probes at
:data:`SCALE_STEPS` (+-1 % and +-5 % of each range, 4 P evaluations) at the start and at the
optimum, against the smooth curve ``f0 + g h + c h^2`` (``g`` the gradient, ``c`` fitted to the
probes): a smooth objective, however curved, follows it to its third-order term; one whose
probes depart from it by more than :data:`SCALE_LIMIT` is not described by its gradient at the
optimiser's steps, and the design warns and says so in its summary (:func:`scale_message`).
"""

from __future__ import annotations

from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np

from ..params.derivatives import DerivativeHorizonWarning, amplification, derivative_horizon
from .problem import DesignProblem, tangents_at

#: Steps of the roughness check, fractions of each variable's range: far below any design
#: tolerance (the gradient's prediction g h is then negligible for a smooth objective), far above
#: rounding of the unit coordinates (2e-16), and spread over four decades, since a chaotic
#: objective's jumps do not shrink with the step while a smooth one's changes do.
ROUGHNESS_STEPS = (1e-10, 1e-8, 1e-6)
#: Relative change of the objective beyond the gradient's prediction above which it is called
#: rugged. Measured on the RMS deviation with the variables of benchmarks/bench_design.py (rtol
#: 1e-6, +- each step of 1e-10..1e-6 of each range): the slider-crank over a quarter revolution
#: (predictable; 400 samples per revolution, 18 probes at the middle of the ranges) moves by
#: 6e-6..6.6e-4 (the step-size control's noise, not growing with the step); over a whole
#: revolution (chaotic; 1000 samples) by 3.3e-3..2.3e-2 at each of 20 probes around the nominal
#: design and 6e-2..1.4e-1 around the middle of the ranges; the four-bar over a revolution
#: (chaotic) by 1.2e-2..3.9e-1. 2e-3 lies 3x above the noise and 1.6x below the smallest jump.
ROUGHNESS_LIMIT = 2e-3


#: Steps of the check at the optimiser's scale (:func:`scale_report`), fractions of each range:
#: the report's +-1 % sensitivity (:data:`jaxclear.designing.report.SENSITIVITY_STEP`) and 5 %,
#: the size of L-BFGS-B's steps once its first step has been scaled.
SCALE_STEPS = (1e-2, 5e-2)
#: Departure of a probe from the smooth curve through the others (relative to the objective)
#: above which the objective is called rugged at the optimiser's scale: 5x the solver's noise
#: at tiny steps (:data:`ROUGHNESS_LIMIT`), and far above the third-order term of a smooth
#: objective that changes by a factor of two over its range (~ h^3: 1e-4 at 5 %).
SCALE_LIMIT = 1e-2


class RuggedObjectiveWarning(DerivativeHorizonWarning):
    """The objective of a design changes by far more than its gradient predicts for a tiny step of
    a variable (:func:`jaxclear.designing.chaos.roughness_report`): it is numerically chaotic
    there, and a gradient-based search follows noise."""


def horizon_report(problem: DesignProblem, u) -> dict:
    """``{"run_s", "amplification": {name: A}, "horizon_s": {name: t}, "past_horizon": [names]}``
    of the first member at unit coordinates ``u`` (``horizon_s`` None where it is never reached)."""
    ts, q, qdot, dq, dqdot = tangents_at(problem, jnp.asarray(u, dtype=float))
    sol = SimpleNamespace(ts=ts, q=q, qdot=qdot)  # what the amplification and the horizon read
    run_s = float(np.asarray(sol.ts)[-1] - np.asarray(sol.ts)[0])
    amp, horizon, past = {}, {}, []
    for i, v in enumerate(problem.variables):
        t_i = SimpleNamespace(q=dq[i], qdot=dqdot[i])
        a = float(amplification(sol, t_i, 1.0))
        h = derivative_horizon(sol, t_i, problem.rtol, 1.0)
        amp[v.name] = a
        horizon[v.name] = None if not np.isfinite(h) else h - float(np.asarray(sol.ts)[0])
        if np.isfinite(h) or not np.isfinite(a):
            past.append(v.name)
    return {"run_s": run_s, "amplification": amp, "horizon_s": horizon, "past_horizon": past}


def roughness_report(value, u, f0: float, gradient, names, steps: tuple | None = None,
                     limit: float | None = None) -> dict:
    """How far the objective departs from its linear prediction for tiny steps of each variable.

    Args:
        value: ``value(u) -> float``, the plain objective at unit coordinates.
        u: the unit coordinates (P,) of the design.
        f0: ``value(u)``.
        gradient: the objective's gradient (P,) with respect to ``u``.
        names: the variables' names (P).
        steps: the steps as fractions of each range; each coordinate moves by ``+- step`` (only
            inwards at a bound); None: :data:`ROUGHNESS_STEPS`.
        limit: relative excess over the prediction above which a variable is reported rugged;
            None: :data:`ROUGHNESS_LIMIT`.

    Returns:
        ``{"steps", "limit", "step": {name: the step of the largest excess}, "change": {name:
        the relative change there}, "predicted": {name: the gradient's relative prediction
        there}, "excess": {name: |change - predicted|}, "rugged": [names above limit]}`` (a
        non-finite change counts as rugged).
    """
    steps = tuple(ROUGHNESS_STEPS if steps is None else steps)
    limit = ROUGHNESS_LIMIT if limit is None else limit
    u = np.asarray(u, dtype=float)
    g = np.asarray(gradient, dtype=float)
    scale = abs(f0) if f0 != 0 else 1.0
    out = {"steps": list(steps), "limit": limit, "step": {}, "change": {}, "predicted": {}, "excess": {},
           "rugged": []}
    for i, name in enumerate(names):
        worst = None
        for step in steps:
            for sign in (1.0, -1.0):
                v = u.copy()
                v[i] = np.clip(u[i] + sign * step, 0.0, 1.0)
                h = v[i] - u[i]
                if h == 0.0:
                    continue  # at a bound: only the inward step
                change = (float(value(v)) - f0) / scale
                predicted = float(g[i]) * h / scale
                excess = abs(change - predicted) if np.isfinite(change) else float("inf")
                if worst is None or not excess <= worst[3]:
                    worst = (sign * step, change, predicted, excess)
        (out["step"][name], out["change"][name], out["predicted"][name], out["excess"][name]) = worst
        if not worst[3] <= limit:
            out["rugged"].append(name)
    return out


def scale_report(value, u, f0: float, gradient, names, steps: tuple | None = None,
                 limit: float | None = None) -> dict:
    r"""The objective at the optimiser's steps against the smooth curve its gradient starts.

    For each variable ``i`` the relative changes ``r_k = (f(u + h_k e_i) - f0) / |f0|`` at
    ``h_k = +-step`` (clipped to the unit cube; only inwards at a bound) are compared with
    :math:`(g_i h_k + c\,h_k^2)/|f_0|`, ``c`` the least-squares curvature of the probes
    (:math:`c = \sum d_k h_k^2 / \sum h_k^4`, :math:`d_k` the change beyond the gradient's
    prediction). A smooth objective, however curved, departs by its third-order term only.

    Args: as :func:`roughness_report`; ``steps`` default :data:`SCALE_STEPS`, ``limit``
    :data:`SCALE_LIMIT`.

    Returns:
        ``{"steps", "limit", "probes": {name: [[h, change, predicted], ...]}, "curvature":
        {name: c / |f0|}, "excess": {name: the largest departure from the curve}, "rugged":
        [names above limit]}`` (changes relative; a non-finite change counts as rugged).
    """
    steps = tuple(SCALE_STEPS if steps is None else steps)
    limit = SCALE_LIMIT if limit is None else limit
    u, g = np.asarray(u, dtype=float), np.asarray(gradient, dtype=float)
    scale = abs(f0) if f0 != 0 else 1.0
    out = {"steps": list(steps), "limit": limit, "probes": {}, "curvature": {}, "excess": {}, "rugged": []}
    for i, name in enumerate(names):
        probes = []
        for step in steps:
            for sign in (-1.0, 1.0):
                v = u.copy()
                v[i] = np.clip(u[i] + sign * step, 0.0, 1.0)
                h = float(v[i] - u[i])
                if h != 0.0:
                    probes.append([h, (float(value(v)) - f0) / scale, float(g[i]) * h / scale])
        h, r, p = (np.array(c, dtype=float) for c in zip(*probes)) if probes else (np.zeros(0),) * 3
        c = float(np.sum((r - p) * h**2) / np.sum(h**4)) if probes and np.all(np.isfinite(r)) else float("nan")
        excess = float(np.max(np.abs(r - p - c * h**2))) if probes and np.isfinite(c) else (
            0.0 if not probes else float("inf"))
        out["probes"][name], out["curvature"][name], out["excess"][name] = probes, c, excess
        if not excess <= limit:
            out["rugged"].append(name)
    return out


def scale_message(mech_name: str, report: dict, where: str) -> str:
    """The one line for an objective rugged at the optimiser's steps (:func:`scale_report`) at
    ``where`` (``"start"``, ``"optimum"``): the worst variable, its probes, the gradient's
    prediction, what it means and what to do."""
    name = max(report["rugged"], key=lambda n: report["excess"][n])
    others = [n for n in report["rugged"] if n != name]
    probes = ", ".join(f"{100 * h:+g} %: {100 * r:+.3g} %" for h, r, _ in report["probes"][name])
    pred = max((abs(p) for _, _, p in report["probes"][name]), default=0.0)
    return (f"design of {mech_name!r}: at the {where} the objective is not smooth at the optimiser's steps: moving "
            f"{name}{' (also ' + ', '.join(others) + ')' if others else ''} by a share of its range changes it by "
            f"{probes}, where its gradient predicts at most {100 * pred:.2g} % and no smooth curve through the probes "
            f"fits them (off by {100 * report['excess'][name]:.2g} %): the gradient does not describe the objective "
            "there, and a 'converged' status means the method's stopping rule, not a minimum; average over an "
            "ensemble of starts (--ensemble K), shorten or lengthen the runs, or use a gradient-free search "
            "(method 'differential-evolution')")


def rugged_message(mech_name: str, report: dict) -> str:
    """The one warning line for a rugged objective: the worst variable, its change, the remedy."""
    name = max(report["rugged"], key=lambda n: report["excess"][n])
    others = [n for n in report["rugged"] if n != name]
    also = f" (also {', '.join(others)})" if others else ""
    return (f"design of {mech_name!r}: the objective is rugged at the start: a step of {report['step'][name]:+.0e} "
            f"of the range of {name}{also} changes it by {100 * report['change'][name]:+.3g} % where its gradient "
            f"predicts {100 * report['predicted'][name]:+.2g} %: it is numerically chaotic there and a gradient "
            "follows noise; average shorter runs over an ensemble of starts (jaxclear.designing.Ensemble(starts=k), "
            "--ensemble K with --revolutions R/K), shorten the runs (revolutions), or use a "
            "gradient-free search (method 'differential-evolution')")


__all__ = ["ROUGHNESS_LIMIT", "ROUGHNESS_STEPS", "RuggedObjectiveWarning", "SCALE_LIMIT", "SCALE_STEPS",
           "horizon_report", "roughness_report", "rugged_message", "scale_message", "scale_report"]
