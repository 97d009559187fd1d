r"""Profile likelihood of a fitted parameter: an honest interval where the Gauss-Newton std is not.

The Gauss-Newton std (:mod:`.uncertainty`) is the curvature of the loss at its minimum. Where
the loss is far from quadratic over the interval (a rugged loss through impacts, a window of
several milliseconds, the restitution near its bound) it is not the uncertainty: on records of
an independent simulator at the default 3 ms window its +-1.645 std missed the stiffness in 2 of
8 records (-2.4 and +2.1 std), and on records that begin mid-run it reported the restitution to
+-0.001 where another value fitted as well. The profile likelihood (Venzon and Moolgavkar 1988;
Raue et al., *Bioinformatics* 25, 2009, 1923-1929, for ODE models) holds the parameter at a
value, fits every other unknown (parameters and window start states) again, and reads the
interval off the rise of the loss:

.. math::

    D(\theta_i) = \frac{L(\theta_i) - L_{\min}}{s^2},
    \qquad s^2 = \frac{L_{\min}}{N - P},

with :math:`L = |r|^2` the sum of squares of the normalised residual at the refit, :math:`N`
fitted samples and :math:`P` unknowns. The 90 % interval is where :math:`D \le \chi^2_{1,0.90}
= 2.706` (Wilks; the likelihood ratio of white Gaussian noise of unknown level, to first order
in :math:`P/N`). Its ends are interpolated linearly in :math:`\sqrt{D}` (the signed root
deviance, linear in the parameter where the loss is quadratic) between the points of a walk;
where the loss jumps across the bracket (a contact that appears or vanishes: the deviance beyond
it exceeds four times the threshold) the bracket is first bisected (:data:`REFINE` times).

The walk: from the estimate outwards on each side, in the fit's transformed coordinate ``z``
(log of a stiffness, logit of a restitution; :mod:`.parameters`), at most :data:`MAX_POINTS`
points spaced geometrically from 1.5 Gauss-Newton std (:data:`FIRST_STEP`, at least :data:`MIN_STEP`) to
:data:`SPAN`, each point fitted from the one before (warm start) by the fit's own final stage
with the parameter held (its Jacobian column zero: :func:`~jaxclear.fitting.run.stage_evaluation`;
the solver's compiled step is the fit's own). A side whose walk reaches :data:`SPAN` below the threshold, or whose model
fails, is open: the record does not bound the parameter there, and the std is infinite. A point
whose loss lies below the estimate's by more than :data:`BETTER` (in :math:`s^2`) is a better
fit: the estimate is a local minimum. The fit then begins again from the best such point (the
fit's final stage, every unknown free, from the point's parameters and window starts; the point
itself where that refit's last step climbs, as in :mod:`.scan`), takes it where it fits better,
and walks the profiles again from there, at most :data:`RESTARTS` times (a ``"restart"`` entry
in ``FitState.profile`` records each; ``FitResult.profiles[name]["restarted_from"]``). A better
point still found after the last restart fails the fit (:mod:`.verdict`). Measured on
acceptance record 2 of the independent simulator fitted at rtol 1e-7 (benchmarks/README,
"Records that begin mid-run"): the fit ended at restitution 0.851, stiffness 3.0 % low, and its
profile found a fit 11 noise variances better at 0.862: before, a failed fit with the advice to
fit again from there; the restart does that, and the fit ends at 0.856 with the 90 % interval
[0.845, 0.866] (truth 0.85), the stiffness 1.1 % high, passed.

The std reported from a closed profile is the longer half of the 90 % interval over 1.645 (the
Gauss-Newton std is kept beside it as ``std_gauss_newton``). Every point is checkpointed in the
fit's state (``FitState.profile``), so a killed profile resumes after its last point; the points
are not part of the checkpoint's key, so adding a profile to a finished fit (same ``out``) runs
only the profile.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, Sequence

import numpy as np

from .._errors import ParameterError
from .parameters import dvalue_dz, from_z, transform
from .plan import Stage, final_stage
from .problem import FitProblem
from .run import evaluate_all, final_jacobian, fitted_mask, run_stage, sum_of_squares
from .solver import Optimizer
from .state import Checkpoint, FitState
from .uncertainty import estimate_uncertainty

#: Level of the interval, and the chi-square quantile (1 degree of freedom) that bounds it.
LEVEL = 0.90
THRESHOLD = 2.705543454095404  # scipy.stats.chi2.ppf(0.90, 1)
#: Normal quantile that turns the 90 % interval's half-width into a std.
Z_LEVEL = 1.6448536269514722  # scipy.stats.norm.ppf(0.95)
#: Points per side of the walk, and the farthest step from the estimate in ``z``: a factor 4 in
#: a stiffness (log), 6 in the logit of a restitution (0.9 -> 0.9994 and 0.022), 1 data RMS in a bias.
MAX_POINTS = 6
SPAN = {"log": math.log(4.0), "logit": 6.0, "scaled": 1.0}
#: The first step is :data:`FIRST_STEP` Gauss-Newton std (a deviance of about 2.25 where the loss
#: is quadratic, so the 90 % end lies between the first two points), at least ``MIN_STEP`` in ``z``
#: (0.01 % of a stiffness); an eighth of the span where the std is not finite.
FIRST_STEP = 1.5
MIN_STEP = {"log": 1e-4, "logit": 1e-4, "scaled": 1e-5}
#: Bisections of a bracket whose outer deviance exceeds ``CLIFF^2`` times the threshold (the
#: loss jumps there: a grazing impact that appears or vanishes; on a record of the independent
#: simulator the loss rose from 6.2 to 41.8 between +0.3 % and +0.4 % of the stiffness), so that
#: the end is not interpolated across a jump.
REFINE = 4
CLIFF = 2.0
#: A point whose deviance is below ``-BETTER`` fits better than the estimate.
BETTER = 1.0
#: Times the fit begins again from a better point its profile found (module docstring).
RESTARTS = 1


def check_profile(names, free: Sequence[str]) -> tuple:
    """``names`` (None, True for every free parameter, a name or a sequence of names) as a tuple
    of free parameter names; a :class:`~jaxclear.ParameterError` for a name that is not free."""
    if names is None or names is False:
        return ()
    if names is True:
        return tuple(free)
    names = (names,) if isinstance(names, str) else tuple(names)
    for n in names:
        if n not in free:
            raise ParameterError(f"profile = {n!r} is not a free parameter of this fit; valid: {', '.join(free)}")
    return names


def optimum(problem: FitProblem, st: FitState):
    """``(L_min, s^2, std_z)`` at the state's parameters: the sum of squares of the normalised
    residual, the noise variance in its units and the Gauss-Newton std in ``z`` per free name."""
    theta, states = np.asarray(st.theta, dtype=float), np.asarray(st.states, dtype=float)
    evals = evaluate_all(problem, theta, states, st.guesses)
    r, jac = final_jacobian(problem, evals)
    unc = estimate_uncertainty(r, jac, fitted_mask(problem), problem.win.scale, theta, problem.free, problem.mech)
    loss = sum_of_squares(problem, evals)
    s2 = loss / max(unc.n_samples - unc.n_unknowns, 1)
    std_z = {}
    for i, name in enumerate(problem.free):
        d = abs(dvalue_dz(name, float(theta[i]), problem.win.scale, problem.mech))
        std_z[name] = unc.std[name] / d if d > 0 else math.nan
    return loss, s2, std_z


def steps(name: str, std_z: float, mech=None) -> np.ndarray:
    """The walk's distances from the estimate in ``z`` ``(<= MAX_POINTS,)`` (module docstring)."""
    kind = transform(name, mech)
    span, floor = SPAN.get(kind, 1.0), MIN_STEP.get(kind, 0.001)
    first = min(max(FIRST_STEP * std_z, floor), span / 8) if math.isfinite(std_z) else span / 8
    growth = max(2.0, (span / first) ** (1.0 / (MAX_POINTS - 1)))
    out = [first]
    while out[-1] < span and len(out) < MAX_POINTS:
        out.append(min(out[-1] * growth, span))
    return np.asarray(out)


def run_profiles(problem: FitProblem, opt: Optimizer, st: FitState, ckpt: Checkpoint, names: tuple,
                 on_iteration: Callable[[dict, FitState], None], on_point: Callable[[str], None] = lambda text: None
                 ) -> FitState:
    """Walk the profile of each of ``names`` from the state's optimum (module docstring); every
    point is appended to ``FitState.profile`` and checkpointed. Points already in the state
    (a resumed fit) are not fitted again. Where a walk finds a better fit, the fit begins again
    from it and the profiles are walked anew, at most :data:`RESTARTS` times."""
    if not names:
        return st
    while True:
        st = _walk(problem, opt, st, ckpt, names, on_iteration, on_point)
        better = _better_point(st, names)
        if better is None or sum(p.get("kind") == "restart" for p in st.profile) >= RESTARTS:
            return st
        st = _restart(problem, opt, st, ckpt, better, on_iteration, on_point)


def _better_point(st: FitState, names: tuple) -> dict | None:
    """The walked point (of ``names``, since the last restart) with the lowest loss, where its
    deviance is below ``-BETTER``; else None."""
    points = [p for p in st.profile if p.get("name") in names and math.isfinite(p["loss"])]
    best = min(points, key=lambda p: p["loss"], default=None)
    return best if best is not None and best["deviance"] < -BETTER else None


def _restart(problem: FitProblem, opt: Optimizer, st: FitState, ckpt: Checkpoint, point: dict, on_iteration,
             on_point) -> FitState:
    """Every unknown fitted again from the better profile ``point`` (the fit's final stage); the
    result (or the point itself, where the refit climbs) replaces the state's optimum where it
    fits better. The walked points are dropped (they were walked from the old optimum) and a
    ``"restart"`` entry is kept in their place; checkpointed."""
    here = sum_of_squares(problem, evaluate_all(problem, np.asarray(st.theta, dtype=float),
                                                np.asarray(st.states, dtype=float), st.guesses))
    refit = refit_from(problem, opt, st, point["theta"], point["states"], point["loss"], point["reason"], on_iteration)
    i = problem.free.index(point["name"])
    value = float(from_z(point["name"], point["theta"][i], problem.win.scale, problem.mech))
    taken = bool(refit["loss"] < here)
    entry = {"kind": "restart", "name": "", "side": 0, "dz": 0.0, "parameter": point["name"], "from": value,
             "loss": float(refit["loss"]), "estimate_loss": float(here), "taken": taken}
    kept = tuple(p for p in st.profile if p.get("kind") == "restart") + (entry,)
    if taken:
        st = st.replace(theta=list(map(float, refit["theta"])), states=np.asarray(refit["states"], dtype=float).tolist(),
                        stop_reason=refit["reason"], profile=kept)
    else:
        st = st.replace(profile=tuple(st.profile) + (entry,))
    ckpt.save(st)
    on_point(f"profile {point['name']}: a better fit at {value:.6g}; fitted again from it: loss {refit['loss']:.6g} "
             f"({'taken' if taken else 'kept the estimate'}: {here:.6g})")
    return st


def refit_from(problem: FitProblem, opt: Optimizer, st: FitState, theta, states, loss: float, reason: str,
               on_iteration) -> dict:
    """Every unknown fitted again from a point (``theta``, window ``states``; its sum of squares
    ``loss`` and stop ``reason``) by the fit's final stage: ``{"theta", "states", "loss",
    "reason"}`` of the refit, or of the point itself where the refit ends higher (a first-order
    optimiser's last step can climb). The one way out of a basin of the profile's restart and of
    the scan (:mod:`.scan`)."""
    single = dataclasses.replace(problem, stages=[final_stage(problem.windows, problem.anywhere)])
    refit = fit_point(single, opt, st, np.asarray(theta, dtype=float), np.asarray(states, dtype=float), on_iteration)
    if not refit["loss"] <= loss:
        return {"theta": list(map(float, theta)), "states": states, "loss": loss, "reason": reason}
    return refit


def _walk(problem: FitProblem, opt: Optimizer, st: FitState, ckpt: Checkpoint, names: tuple, on_iteration,
          on_point) -> FitState:
    """One walk of the profiles of ``names`` from the state's optimum."""
    loss_min, s2, std_z = optimum(problem, st)
    base = final_stage(problem.windows, problem.anywhere)
    for name in names:
        i = problem.free.index(name)
        stage = base._replace(name=f"profile {name}", held=(i,))
        single = dataclasses.replace(problem, stages=[stage])
        for side in (-1, 1):
            below = (0.0, np.asarray(st.theta, dtype=float), np.asarray(st.states, dtype=float))
            for dz in steps(name, std_z[name], problem.mech):
                st, point = _point(single, opt, st, ckpt, i, side, float(dz), below, loss_min, s2, on_iteration, on_point)
                if not math.isfinite(point["loss"]):
                    break
                if point["deviance"] > THRESHOLD:  # the end lies between `below` and this point
                    above = point
                    for _ in range(REFINE):  # a cliff (the loss jumps): bisect before interpolating
                        if above["deviance"] <= CLIFF**2 * THRESHOLD:
                            break
                        st, mid = _point(single, opt, st, ckpt, i, side, 0.5 * (below[0] + above["dz"]), below, loss_min,
                                         s2, on_iteration, on_point)
                        if not math.isfinite(mid["loss"]) or mid["deviance"] > THRESHOLD:
                            above = mid
                        else:
                            below = (mid["dz"], np.asarray(mid["theta"]), np.asarray(mid["states"]))
                    break
                below = (point["dz"], np.asarray(point["theta"], dtype=float), np.asarray(point["states"], dtype=float))
    return st


def _point(single: FitProblem, opt: Optimizer, st: FitState, ckpt: Checkpoint, i: int, side: int, dz: float,
           below: tuple, loss_min: float, s2: float, on_iteration, on_point) -> tuple[FitState, dict]:
    """The profile point at ``z_hat + side dz`` of parameter ``i``: read back from the state (a
    resumed profile) or fitted from ``below`` (``(dz, theta, states)`` of the nearest point
    inside, the estimate itself at first) and appended to the state, which is checkpointed."""
    name = single.free[i]
    for p in st.profile:
        if p["name"] == name and p["side"] == side and math.isclose(p["dz"], dz, rel_tol=1e-12):
            return st, p
    theta = np.array(below[1], dtype=float)
    theta[i] = float(st.theta[i]) + side * dz
    point = fit_point(single, opt, st, theta, np.asarray(below[2], dtype=float), on_iteration)
    point.update(name=name, side=side, dz=dz, deviance=(point["loss"] - loss_min) / s2)
    st = st.replace(profile=st.profile + (point,))
    ckpt.save(st)
    on_point(f"profile {name}: {from_z(name, theta[i], single.win.scale, single.mech):.6g}, deviance {point['deviance']:.3g}")
    return st, point


def fit_point(single: FitProblem, opt: Optimizer, st: FitState, theta, states, on_iteration) -> dict:
    """The other unknowns fitted at ``theta`` (its held entry fixed) from ``states``: the point's
    ``loss`` (sum of squares at horizon 1, all windows), ``theta``, ``states`` and stop ``reason``."""
    inner = st.replace(stage=0, iteration=0, x=None, column_scale=None, solver=None, theta=theta.tolist(),
                       states=states.tolist(), history=(), starts=(), profile=())
    stage: Stage = single.stages[0]
    reason = "evaluated (no other unknown)"
    if len(single.free) > 1 or stage.states:
        try:
            inner = run_stage(single, opt, inner, Checkpoint(None, "", {}), on_iteration)
            reason = inner.stop_reason
        except (ArithmeticError, ValueError) as exc:  # FitDataError: the model cannot run at this value
            return {"loss": math.nan, "theta": theta.tolist(), "states": states.tolist(), "reason": str(exc)}
    loss = sum_of_squares(single, evaluate_all(single, np.asarray(inner.theta, dtype=float),
                                               np.asarray(inner.states, dtype=float), inner.guesses))
    return {"loss": loss if math.isfinite(loss) else math.nan, "theta": list(map(float, inner.theta)),
            "states": np.asarray(inner.states, dtype=float).tolist(), "reason": reason}


def summarize(problem: FitProblem, st: FitState, names: tuple, std_gauss_newton: dict) -> dict:
    """name -> the profile's table and interval (JSON-ready; module docstring): ``values``,
    ``deviance`` (the estimate's point included at 0), ``interval`` ``[lo, hi]`` (None for an
    open side), ``level``, ``std`` (inf where open), ``std_gauss_newton``, ``better`` (the best
    point below the estimate's loss by more than :data:`BETTER`, or None), ``open`` (why a
    side is open) and ``restarted_from`` (the value of this parameter's better point the fit
    began again from and took, or None)."""
    out = {}
    scale = problem.win.scale
    for name in names:
        i = problem.free.index(name)
        z_hat = float(st.theta[i])
        est = float(from_z(name, z_hat, scale, problem.mech))
        ends, why, table = [], [], [(est, 0.0)]
        for side in (-1, 1):
            pts = sorted((p for p in st.profile if p["name"] == name and p["side"] == side), key=lambda p: p["dz"])
            end, last_dz, last_d = None, 0.0, 0.0
            for p in pts:
                table.append((float(from_z(name, z_hat + side * p["dz"], scale, problem.mech)), float(p["deviance"])))
                if not math.isfinite(p["loss"]):
                    why.append(f"the model fails at {name} = {table[-1][0]:.6g} ({p['reason']})")
                    break
                if p["deviance"] > THRESHOLD:
                    a, b = math.sqrt(max(last_d, 0.0)), math.sqrt(p["deviance"])
                    dz = last_dz + (p["dz"] - last_dz) * (math.sqrt(THRESHOLD) - a) / (b - a)
                    end = float(from_z(name, z_hat + side * dz, scale, problem.mech))
                    break
                last_dz, last_d = p["dz"], p["deviance"]
            else:
                if pts:
                    why.append(f"the deviance stays below {THRESHOLD:.3g} out to {name} = {table[-1][0]:.6g}")
            ends.append(end)
        table.sort()
        lowest = min(table, key=lambda vd: vd[1])
        closed = all(e is not None for e in ends)
        std = max(est - ends[0], ends[1] - est) / Z_LEVEL if closed else math.inf
        out[name] = {"values": [v for v, _ in table], "deviance": [d for _, d in table], "interval": ends,
                     "level": LEVEL, "std": std, "std_gauss_newton": std_gauss_newton.get(name, math.nan),
                     "better": ({"value": lowest[0], "deviance": lowest[1]} if lowest[1] < -BETTER else None),
                     "open": why,
                     "restarted_from": next((p["from"] for p in reversed(st.profile) if p.get("kind") == "restart"
                                             and p["parameter"] == name and p["taken"]), None)}
    return out
