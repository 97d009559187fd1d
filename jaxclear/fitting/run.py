"""Running the plan: stage after stage, each solved step by step (:mod:`.solver`), the fit's
state checkpointed after every step, so that a killed fit resumes where it stopped."""

from __future__ import annotations

import math
from typing import Callable

import jax.numpy as jnp
import numpy as np

from .._errors import FitDataError
from ..sweep.lanes import host_map
from .parameters import values_of
from .plan import Stage, final_stage
from .problem import FitProblem
from .solver import (
    Optimizer,
    StageRun,
    column_scale,
    influences,
    solver_leaves,
    stack_jacobian,
)
from .state import Checkpoint, FitState
from .way_in import (CHAIN_WHEN, CHAINED_FOLLOW, CHAINED_POLISH, CHAINED_SEEDS, WAY_IN_HORIZON, find_start,
                     rechoose_approach, search_around)
from .window import evaluate_window_jit
from .window_start import approach_candidates, state_to_z


def fresh_state(problem: FitProblem) -> FitState:
    """The state before the first stage."""
    w = problem.windows
    guesses = problem.window_guesses if problem.anywhere else [problem.guess0] * w
    return FitState().replace(theta=problem.z0.tolist(), states=[problem.state0.tolist()] * w,
                              guesses=[[np.asarray(q).tolist(), np.asarray(qd).tolist()] for q, qd in guesses])


def split(problem: FitProblem, st: FitState, stage: Stage, x) -> tuple:
    """``(theta (P,), states (W, 4 n_c))`` with the stage's unknowns ``x`` put in place."""
    p, n_state = len(problem.free), len(problem.state0)
    theta = np.array(st.theta, dtype=float)
    states = np.array(st.states, dtype=float)
    i = 0
    if stage.theta:
        theta, i = np.asarray(x[:p], dtype=float), p
    for k in stage.states:
        states[k] = x[i: i + n_state]
        i += n_state
    return theta, states


def join(st: FitState, stage: Stage) -> np.ndarray:
    """The stage's unknowns ``x``: ``theta`` if free, then the free window states."""
    parts = [np.asarray(st.theta, dtype=float)] if stage.theta else []
    parts += [np.asarray(st.states[k], dtype=float) for k in stage.states]
    return np.concatenate(parts) if parts else np.zeros(0)


def window_end(problem: FitProblem, st: FitState, k: int):
    """``(q, qdot, journal state)`` at the end of window ``k`` simulated at the current values."""
    win = problem.window_input(k, 1.0, False, st.guesses)
    _, _, _, _, (q1, qd1, end, *_) = evaluate_window_jit(problem.model, jnp.asarray(st.theta),
                                                         jnp.asarray(st.states[k]), win)
    return np.asarray(q1), np.asarray(qd1), np.asarray(end)


def begin_stage(problem: FitProblem, opt: Optimizer, st: FitState) -> FitState:
    """Starting values of a stage not yet begun: its start, the best start after the starts, or
    (window-state stages) the end of the previous window's simulation. A way-in stage (every
    window's start free) takes the way in's best start, or the contender from the window before
    (:func:`chained_start`) where the way in left more than :data:`~.way_in.CHAIN_WHEN` times the
    least misfit of the windows so far and the contender follows the window's first half better."""
    stage = problem.stages[st.stage]
    before = problem.stages[st.stage - 1] if st.stage > 0 else None
    if stage.start >= 0 and (before is None or before.start != stage.start):  # a start's first stage
        st = st.replace(theta=problem.z_starts[stage.start].tolist())
        if problem.anywhere:  # every start from the window starts the way in found
            st = st.replace(found=st.states) if not st.found else st.replace(states=st.found)
    elif stage.start < 0 and before is not None and before.start >= 0:
        st = st.at_best_start().replace(stop_reason=st.stop_reason)
    if problem.anywhere and stage.way_in:
        k = stage.states[0]
        win = problem.window_input(k, stage.horizon, False, st.guesses)
        longer = None
        if WAY_IN_HORIZON > stage.horizon:
            longer = (problem.window_input(k, WAY_IN_HORIZON, False, st.guesses), WAY_IN_HORIZON)
        ranked, report = find_start(problem.model, problem.mech, st.theta, win, stage.horizon, longer)
        rank = _first_that_runs(problem, st.theta, ranked, win)
        start = ranked[rank]
        found = [w["best_loss"] for w in st.way_in] + [report["best_loss"]]
        if k > 0 and report["best_loss"] > CHAIN_WHEN * min(found):  # the grid missed: the window before's end
            polished, loss = chained_start(problem, opt, st, k, longer[1] if longer else stage.horizon)
            report["chained_loss"] = loss if np.isfinite(loss) else None  # None: no end to start from
            if loss < report["best_loss"]:
                start, report["chosen"] = polished, "chained"
        states = list(st.states)
        states[k] = np.asarray(start).tolist()
        st = st.replace(states=states, way_in=st.way_in + ({"window": k, **report, "rank": rank},))
    elif problem.anywhere and stage.theta and before is not None and not before.way_in \
            and before.horizon < stage.horizon:  # the joint stages' horizon grows
        st = rechosen_approaches(problem, st, stage)
    elif not problem.anywhere and not stage.theta and stage.states:
        k = stage.states[0]
        q1, qd1, end = window_end(problem, st, k - 1)
        guesses, states = list(st.guesses), list(st.states)
        guesses[k] = [q1.tolist(), qd1.tolist()]
        states[k] = state_to_z(end, problem.start_scales, problem.velocity_scale).tolist()
        st = st.replace(guesses=guesses, states=states)
    return st


def rechosen_approaches(problem: FitProblem, st: FitState, stage: Stage) -> FitState:
    """Every window's start with the approach speed of its contact under way chosen again over
    the stage's (longer) horizon (:func:`~jaxclear.fitting.way_in.rechoose_approach`), each
    choice added to its window's way-in report (``"rechosen"``)."""
    states, reports = list(st.states), [dict(w) for w in st.way_in]
    for k in stage.windows:
        win = problem.window_input(k, stage.horizon, False, st.guesses)
        z, rep = rechoose_approach(problem.model, problem.mech, st.theta, np.asarray(states[k]), win, stage.horizon)
        states[k] = z.tolist()
        for w in reports:
            if w.get("window") == k:
                w["rechosen"] = list(w.get("rechosen", [])) + [rep]
    return st.replace(states=states, way_in=tuple(reports))


#: A window whose misfit over its whole length, at the end of the joint stages, is more than this
#: many times the median of the windows' is searched anew (:func:`revisit_windows`). Four
#: windows of 3 ms at 50 kHz hold about 135 fitted samples each: a window's mean square of pure
#: noise scatters by sqrt(2/135) = 0.12 of itself, so 1.3 is 2.5 of those above the median. On
#: the acceptance records of the independent simulator a window whose start lay in another basin
#: ended at 1.7 and 3.1 times the median (record 1 and record 3, window 1).
REVISIT_RATIO = 1.3


def window_losses(problem: FitProblem, evals) -> list[float]:
    """Per window the mean square of the normalised residual over its fitted samples at horizon
    1 (:func:`evaluate_all`'s ``evals``)."""
    return [float(np.mean(e[0][problem.win.residual_mask(k, 1.0) > 0] ** 2)) for k, e in enumerate(evals)]


def revisit_windows(problem: FitProblem, st: FitState) -> tuple[FitState, bool]:
    """The windows the joint stages left unfollowed (misfit above :data:`REVISIT_RATIO` times
    the windows' median), each searched anew by the way in at the fitted values over its whole
    length (:func:`~jaxclear.fitting.way_in.find_start` with the whole window as the scored
    horizon), its start replaced where the search's best follows the window better. Returns the
    state (the search's report added to the window's way-in report, ``"revisited"``) and whether
    a start was replaced.

    Why: the way in scores the starts over a window's first half at the start values, and over
    the first half two basins can score alike while only one follows the second: window 1 of
    acceptance record 1 of the independent simulator began sliding at 6.5 omega c in the way in's
    start and 4.9 in the simulator's, 0.0070 and 0.0075 of the data's mean square over the first
    half, 0.020 and 0.008 over the whole window (at the true values). The joint stages then
    bent the restitution to 0.93 (truth 0.75) to follow the other windows. At those fitted
    values the sector search scored over the whole window found the simulator's basin (sliding
    at 4.8 omega c, 0.0139, polished 0.0131 where the true start polished to 0.0132), as it did
    window 1 of record 3 (0.0162 where the joint stages had left 0.033)."""
    losses = window_losses(problem, evaluate_all(problem, st.theta, st.states, st.guesses))
    ref = float(np.median(losses))
    states, reports, changed = list(st.states), [dict(w) for w in st.way_in], False
    for k, loss in enumerate(losses):
        if not loss > REVISIT_RATIO * ref:
            continue
        win = problem.window_input(k, 1.0, False, st.guesses)
        ranked, report = find_start(problem.model, problem.mech, st.theta, win, 1.0)
        taken = _first_that_runs(problem, st.theta, ranked, win) == 0 and report["best_loss"] < loss
        if taken:
            states[k], changed = np.asarray(ranked[0]).tolist(), True
        note = {"loss_before": loss, "median": ref, "loss": report["best_loss"], "taken": bool(taken)}
        for w in reports:
            if w.get("window") == k:
                w["revisited"] = note
    return st.replace(states=states, way_in=tuple(reports)), changed


def chained_start(problem: FitProblem, opt: Optimizer, st: FitState, k: int, horizon: float) -> tuple:
    """Window ``k``'s start from the end of window ``k - 1`` and its loss over ``horizon`` of the
    window (``(z (S,), loss)``; ``(None, inf)`` where there is none): window ``k - 1``'s start
    followed to that window's end (:func:`polish` through the horizons after the first, the
    parameters held, kept aside: the state of window ``k - 1`` is not changed), its end at
    :data:`CHAINED_SEEDS` approach speeds (:func:`chained_seeds`), a local search round it
    (:func:`~jaxclear.fitting.way_in.search_around`) and its best polished over ``horizon``
    (:data:`CHAINED_POLISH` steps). Back-to-back windows: the end of a
    window followed over its whole length is the record's own estimate of the next one's start
    (a smoother's), close to it where a grid of starts is far (a start at a rebound, whose basin
    is narrower than the grid's spacing)."""
    z = np.asarray(st.states[k - 1], dtype=float)
    for h in problem.horizons[1:]:
        z, _ = polish(problem, opt, st, k - 1, z, h, CHAINED_FOLLOW)
    states = list(st.states)
    states[k - 1] = z.tolist()
    seeds = chained_seeds(problem, st.replace(states=states), k)
    if seeds is None:
        return None, float("inf")
    longer = (problem.window_input(k, horizon, False, st.guesses), horizon)
    first = problem.horizons[0] if problem.horizons[0] < horizon else horizon
    near, _ = search_around(problem.model, problem.mech, st.theta, seeds,
                            problem.window_input(k, first, False, st.guesses), first, longer)
    return polish(problem, opt, st, k, near, horizon)


def chained_seeds(problem: FitProblem, st: FitState, k: int) -> np.ndarray | None:
    """Starts of window ``k`` from the end of window ``k - 1`` simulated at the current values,
    one per approach speed of the way in's grid at :data:`CHAINED_SEEDS` speeds (``(n, S)``; the
    end's contact memory is not carried); None for the first window, windows not back to back,
    or where that run fails."""
    if k == 0 or problem.win.starts[k] - problem.win.starts[k - 1] > problem.win.length * (1 + 1e-9):
        return None
    q1, qd1, end = window_end(problem, st, k - 1)
    if not np.all(np.isfinite(end)):
        return None
    z = state_to_z(end, problem.start_scales, problem.velocity_scale,
                   [1.0] * len(problem.start_scales))
    return approach_candidates(z, problem.mech, CHAINED_SEEDS)


def polish(problem: FitProblem, opt: Optimizer, st: FitState, k: int, z: np.ndarray, horizon: float,
           steps: int = CHAINED_POLISH) -> tuple[np.ndarray, float]:
    """Window ``k``'s start ``z`` ``(S,)`` after at most ``steps`` accepted steps of the stages'
    own solver on that start alone (the parameters held) over ``horizon`` of the window, and its
    loss there (mean squares of the normalised residual; inf where the window cannot run)."""
    stage = Stage(f"window {k + 1} chained start", (k,), horizon, False, (k,), -1, False)
    states = list(st.states)
    states[k] = np.asarray(z, dtype=float).tolist()
    trial = st.replace(states=states, x=None, solver=None, column_scale=None)
    n_fit = max(float(problem.win.residual_mask(k, horizon).sum()), 1.0)
    first = stage_evaluation(problem, trial, stage)
    loss0 = float(np.sum(first[0] ** 2))
    if not (np.isfinite(loss0) and np.all(np.isfinite(first[1]))):
        return np.asarray(z, dtype=float), float("inf")
    run, trial = stage_run(problem, opt, trial, stage, first)
    best, loss, accepted = np.asarray(z, dtype=float), loss0, 0
    for _ in range(4 * steps):  # a rejected trial is a step too
        rep = run.step(accepted, steps, 1e-3, problem.settings["xtol"])
        if np.isfinite(rep.loss) and rep.loss < loss:
            best, loss = split(problem, trial, stage, rep.x)[1][k], rep.loss
        accepted += int(rep.counted)
        if rep.reason or accepted >= steps:
            break
    return best, float(loss) / n_fit


def _first_that_runs(problem: FitProblem, theta, ranked: np.ndarray, win) -> int:
    """Index of the first of the way in's starts ``ranked`` ``(k, S)`` whose window runs with its
    Jacobian (the way in scores values over the window's first part only: a start can run there
    and fail later in the window, or in the derivative's tighter solve); 0 when none does (the
    stage then reports the loss that is not finite)."""
    for i, z in enumerate(ranked):
        r = evaluate_window_jit(problem.model, jnp.asarray(theta), jnp.asarray(z), win)[0]
        if np.all(np.isfinite(np.asarray(r))):
            return i
    return 0


def stage_evaluation(problem: FitProblem, st: FitState, stage: Stage, x=None) -> tuple:
    """The stage's residual ``(N,)`` (its windows' samples stacked), its Jacobian over the
    stage's unknowns ``(N, len(x))`` (a held parameter's column zero) and the windows' signals
    ``(W_s, C, n_pad)``, at the stage's unknowns ``x`` put in place
    (:func:`split`; None: the state's values), from :func:`evaluate_windows`."""
    if x is None:
        theta, states = np.asarray(st.theta, dtype=float), np.asarray(st.states, dtype=float)
    else:
        theta, states = split(problem, st, stage, x)
    rs, jts, jss, ys, _ = zip(*evaluate_windows(problem, theta, states, st.guesses, stage.windows, stage.horizon,
                                                stage.integrate))
    jac = np.array(stack_jacobian(jts, jss, stage.theta, _free_rows(stage)))
    if stage.held and stage.theta:
        jac[:, list(stage.held)] = 0.0  # held parameters are no unknowns: the step leaves them
    return np.concatenate(rs), jac, np.stack(ys)


def _free_rows(stage: Stage) -> tuple:
    return tuple(stage.windows.index(k) for k in stage.states)


def stage_run(problem: FitProblem, opt: Optimizer, st: FitState, stage: Stage, first=None) -> tuple[StageRun, FitState]:
    """The solver run of the stage: fresh (its unknowns scaled by :func:`column_scale` of the
    Jacobian of ``first``, the stage's :func:`stage_evaluation` at its start; 1 for first-order
    optimisers) or from the state's saved solver leaves."""
    if st.x is None:
        x = join(st, stage)
        scale = column_scale(first[1]) if first is not None else np.ones_like(x)
        st = st.replace(column_scale=scale.tolist())
        u = x * scale
    else:
        u, first = np.asarray(st.x, dtype=float), None
    at_start = st
    return StageRun(opt, lambda x: stage_evaluation(problem, at_start, stage, x), np.asarray(st.column_scale, dtype=float),
                    u, st.solver, first), st


def _cannot_simulate(problem: FitProblem, theta) -> FitDataError:
    values = dict(zip(problem.free, values_of(problem.free, theta, problem.win.scale, problem.mech)))
    where = problem.meas.path or "the record"
    return FitDataError(f"{where}: the loss at the start is not finite: the model cannot be simulated at the "
                        f"values {values} (solver failure or non-finite state); choose other start values")


def check_start_loss(problem: FitProblem, stage: Stage, loss: float, theta):
    """Refuse a fit whose loss at the start values is not finite (:func:`_cannot_simulate`) or,
    at the first stage, exactly zero (:class:`~jaxclear.FitDataError` naming the record: the
    record equals the model already, or the fitted samples are empty, so the Jacobian scaling
    and the relative stopping rules are undefined)."""
    if not np.isfinite(loss):
        raise _cannot_simulate(problem, theta)
    if loss == 0.0 and stage is problem.stages[0]:
        where = problem.meas.path or "the record"
        raise FitDataError(f"{where}: the loss at the start values is exactly 0 on stage {stage.name!r} (the record "
                           "equals the model at the start, or no sample is fitted): there is nothing to fit; check "
                           "the record and the start values")


def _no_influence(problem: FitProblem, stage: Stage, theta) -> str:
    """The reason a stage none of whose unknowns changes its fitted samples is skipped; for the
    final stage a :class:`~jaxclear.FitDataError` (the record cannot tell the values apart)."""
    end = max(problem.win.cuts.get((k, stage.horizon), stage.horizon * problem.win.length) for k in stage.windows)
    text = (f"no free unknown changes the fitted samples up to {end:.6g} s of the window (they end, for "
            "example, before the first contact)")
    if stage.final:
        values = dict(zip(problem.free, values_of(problem.free, np.asarray(theta, dtype=float), problem.win.scale, problem.mech)))
        raise FitDataError(f"{problem.meas.path or 'the record'}: {text} at the values {values}: there is nothing "
                           "to fit; give a longer window or other free parameters")
    return f"skipped: {text}"


def run_stage(problem: FitProblem, opt: Optimizer, st: FitState, ckpt: Checkpoint,
              report: Callable[[dict, FitState], None]) -> FitState:
    """Solve the current stage to its stop reason; returns the state at the next stage.

    A fresh least-squares stage whose Jacobian at its start is zero (no unknown influences its
    fitted samples: a partial horizon that ends before the first contact, where the contact
    parameters act on nothing) is skipped, its reason kept in ``FitState.skipped``; the next
    stage starts from the same values. A final stage without influence is an error."""
    if st.iteration == 0 and st.x is None:
        st = begin_stage(problem, opt, st)
        if problem.stages[st.stage].revisit:
            st, changed = revisit_windows(problem, st)
            if not changed:  # every window followed, or no better start found: the fit stands
                why = f"{problem.stages[st.stage].name}: skipped, no window's start was bettered"
                st = st.replace(stage=st.stage + 1, iteration=0, x=None, column_scale=None, solver=None,
                                skipped=st.skipped + (why,))
                ckpt.save(st)
                return st
    stage = problem.stages[st.stage]
    first = None
    if st.x is None and opt.least_squares:
        first = stage_evaluation(problem, st, stage)
        loss0, jac = float(np.sum(first[0] ** 2)), first[1]
        check_start_loss(problem, stage, loss0, np.asarray(st.theta, dtype=float))
        if not influences(jac):
            reason = _no_influence(problem, stage, st.theta)
            return _end_stage(st.replace(skipped=st.skipped + (f"{stage.name}: {reason}",)), stage, loss0, reason,
                              ckpt, problem.anywhere)
    run, st = stage_run(problem, opt, st, stage, first)
    s = problem.settings
    limit, tol_f = stage.max_iter(s["max_iter"]), stage.ftol(s["ftol"])
    n_fit = max(float(sum(problem.win.residual_mask(k, stage.horizon).sum() for k in stage.windows)), 1.0)
    reason, loss = ("max_iter", float("nan")) if st.iteration >= limit else ("", float("nan"))
    dof = max(n_fit - float(np.size(run.y)), 1.0)
    while not reason:
        last = st.history[-1] if st.iteration > 0 and st.history else {}
        before = last["loss"] * n_fit if last.get("stage") == stage.name else float("nan")  # as after a resume
        fresh = st.x is None
        rep = run.step(st.iteration, limit, tol_f, s["xtol"])
        if fresh:
            check_start_loss(problem, stage, rep.loss, split(problem, st, stage, join(st, stage))[0])
        theta, states = split(problem, st, stage, rep.x)
        st = st.replace(x=rep.u.tolist(), solver=solver_leaves(rep.arrays), theta=theta.tolist(),
                        states=states.tolist(), evaluations=st.evaluations + 1)
        loss, reason = rep.loss, rep.reason or statistically_converged(before, rep.loss, dof, rep.counted)
        if rep.counted:
            record = {"stage": stage.name, "iteration": st.total + 1, "loss": loss / n_fit,
                      "values": dict(zip(problem.free, values_of(problem.free, theta, problem.win.scale, problem.mech))),
                      **({"stop": reason} if reason else {})}
            st = st.replace(iteration=st.iteration + 1, total=st.total + 1, history=st.history + (record,))
        ckpt.save(st)
        if rep.counted:
            report(record, st)
    return _end_stage(st, stage, loss, reason, ckpt, problem.anywhere)


#: A stage ends when an accepted step lowers the sum of squares by less than this many noise
#: variances (s^2 = SS / (N - P), N fitted samples, P unknowns of the stage): a change of the
#: deviance far below the likelihood ratio's 2.706 of a 90 % interval, so the estimates no longer
#: move by a meaningful part of their uncertainty. It is ``ftol`` in the statistics' units
#: (relative decrease 0.1 / (N - P): 4e-5 on a record of four 3 ms windows at 50 kHz, where the
#: default ftol of 1e-6 let the joint stage of free starts creep on to max_iter: acceptance
#: record 2 of the independent simulator lowered its loss by 0.07 % over its last 20 iterations
#: and moved the stiffness by 0.14 %, 0.06 of its std; benchmarks/README.md).
DEVIANCE_TOL = 0.1


def statistically_converged(before: float, loss: float, dof: float, accepted: bool) -> str:
    """The stop reason of an accepted step from the sum of squares ``before`` to ``loss`` with
    ``dof`` degrees of freedom, where it fell by less than :data:`DEVIANCE_TOL` noise variances;
    "" otherwise."""
    if not accepted or not np.isfinite(before) or not np.isfinite(loss):
        return ""
    drop = (before - loss) / max(loss / dof, 1e-300)
    if 0.0 <= drop < DEVIANCE_TOL:
        return f"the sum of squares fell by {drop:.2g} noise variances < {DEVIANCE_TOL:g} (statistically converged)"
    return ""


def _end_stage(st: FitState, stage: Stage, loss: float, reason: str, ckpt: Checkpoint,
               with_states: bool = False) -> FitState:
    """Record a start's result (its window states too ``with_states``: every window's start
    free) and the final stop reason, move to the next stage, checkpoint."""
    if stage.start >= 0:
        st = st.with_start_result(stage.start, loss, st.theta, reason, st.states if with_states else None)
    if stage.final:
        st = st.replace(stop_reason=reason)
    st = st.replace(stage=st.stage + 1, iteration=0, x=None, column_scale=None, solver=None)
    ckpt.save(st)
    return st


def run_plan(problem: FitProblem, opt: Optimizer, st: FitState, ckpt: Checkpoint,
             report: Callable[[dict, FitState], None]) -> FitState:
    """All remaining stages; then, if the last stage is a start (one horizon, one window, no
    coarse stage; or the joint stages of several starts of a record that begins mid-run), the
    best start is the result, checkpointed as such (the checkpoint held the last start's values);
    not where a scan of held values has begun (:mod:`.scan`), which starts from that result and
    may have replaced it."""
    while st.stage < len(problem.stages):
        st = run_stage(problem, opt, st, ckpt, report)
    if problem.stages[-1].start >= 0 and not st.scan:  # a scan began after this: its result may be taken
        st = st.at_best_start()
        ckpt.save(st)
    return st


def evaluate_windows(problem: FitProblem, theta, states, guesses, windows, horizon: float = 1.0,
                     integrate: bool = False) -> list:
    """Per window of ``windows`` over ``horizon``: its residual, Jacobians, signal (host
    arrays, the compiled window function) and the contact onsets of its motion (a float: not
    finite where the run failed), the windows spread over the host's threads
    (:func:`jaxclear.sweep.lanes.host_map`)."""
    def one(k):
        win = problem.window_input(k, horizon, integrate, guesses)
        r, jt, js, y, end = evaluate_window_jit(problem.model, jnp.asarray(theta), jnp.asarray(states[k]), win)
        return np.asarray(r), np.asarray(jt), np.asarray(js), np.asarray(y), float(end[4])

    return host_map(one, windows)


def evaluate_all(problem: FitProblem, theta, states, guesses):
    """Per window at horizon 1: residual, Jacobians and signal (:func:`evaluate_windows`)."""
    return evaluate_windows(problem, theta, states, guesses, range(problem.windows))


def final_jacobian(problem: FitProblem, evals) -> tuple[np.ndarray, np.ndarray]:
    """Stacked residual ``(W n_pad,)`` and Jacobian over the parameters and the free window
    states (2..W, or all with a free start); a window-state column that is exactly zero (a
    coordinate the fit holds: the approach speed of a contact under way, :mod:`.window_start`)
    is not an unknown and is left out."""
    stage = final_stage(problem.windows, problem.anywhere)
    r = np.concatenate([e[0] for e in evals])
    jac = np.asarray(stack_jacobian([e[1] for e in evals], [e[2] for e in evals], True, stage.states))
    p = len(problem.free)
    keep = np.concatenate([np.ones(p, dtype=bool), np.any(jac[:, p:] != 0.0, axis=0)])
    return r, jac[:, keep]


def window_onsets(evals) -> list:
    """Per window the contact onsets of the fitted motion (:func:`evaluate_all`'s ``evals``;
    None where the window's run failed)."""
    return [int(round(e[4])) if math.isfinite(e[4]) else None for e in evals]


def fitted_mask(problem: FitProblem) -> np.ndarray:
    """``(W n_pad,)``: 1 on the fitted samples of every window at horizon 1 (the stacked residual's
    layout of :func:`final_jacobian`), 0 elsewhere."""
    return np.concatenate([problem.win.residual_mask(k, 1.0) for k in range(problem.windows)])


def sum_of_squares(problem: FitProblem, evals) -> float:
    """``|r|^2`` of the normalised residual over the fitted samples of every window
    (:func:`evaluate_all`'s ``evals``)."""
    r = np.concatenate([e[0] for e in evals])
    return float(np.sum(r[fitted_mask(problem) > 0] ** 2))
