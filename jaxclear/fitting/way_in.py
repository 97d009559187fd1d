r"""The way in: finding a window's unknown start before it is fitted.

A record taken in steady running begins with the journal somewhere in its bearing, most of the
time pressed against it and sliding round (80-97 % of the time in contact on the Flores
benchmark at 5000 rpm), with the ongoing contact's approach speed unknown too. That start is not
a smooth unknown to begin from a guess: from the centre, or from a point on the wrong side of
the bearing, the first milliseconds of the model differ from the record by whole impacts, and a
least-squares fit of the contact parameters from there drives them to a bound (stiffness 1e9 or
1e14 N/m^1.5, restitution 0 or 1) before the state can move.

What is done (the choice, and why). The window's start is chosen by **scoring an ensemble of
candidate starts** on the window's first part: a grid over the clearance circle (directions),
radii inside and just beyond it (free flight, or pressed in by 2, 7.5 and 19 micrometres on the
benchmark: a continuous contact), and sliding velocities along the wall
(:func:`jaxclear.fitting.window_start.candidates`, 1560 candidates for one journal), each
simulated at the start parameters and scored by the misfit of its sensor output over the first
horizon of the window (a quarter by default), the last round of the search below over its first
half (:data:`WAY_IN_HORIZON`); the best is the start of the window's
least-squares stages (:func:`jaxclear.fitting.plan.plan_free_starts`), which polish it before
the parameters are freed. The approach speed of a contact under way at the window's start is
scored next, over a log grid at the best geometries (as many candidates: the same program), and
then held (:mod:`.window_start`). **One journal** (one force element with two offset
coordinates, the common case): instead of these passes, a local search in every sector of the
bearing (:func:`search_sectors`): each of 24 sectors of directions keeps its own lineage from
its best grid candidate, searched in the coordinates of a contact (direction, radius, sliding and
normal rate, approach speed) with spreads that shrink round by round; the lineages' ends are
ranked over the window's first half. A journal in continuous contact has a narrow basin (0.5
omega c along the wall, a few degrees, 2.5 micrometres in depth leave 1.5-3.5 times the noise),
and the grid's best candidates can all lie on the far side of the bearing in a basin of their
own: on acceptance record 2 of the independent simulator at its true parameters the passes
below left windows 1 and 2 at 4 times the noise over the first half (70 degrees against the
true -147), the sector search found all four windows at 0.9-1.2 times it. **Other elements**:
two rounds of a local search follow (the sampling of the
cross-entropy method round the best starts so far, every start number perturbed): the grid's
free-flight candidates move along the wall only, and a journal in flight towards the wall
(window 2 of an acceptance record of the independent simulator: 28 micrometres off the wall,
closing at 4.4 omega c, striking it 0.02 ms into the window) is reached only so (best misfit
0.21 of the data's mean square after the grid, 0.0143 after the search, 0.0115 from the true
start). **The window before, followed to its end.** The windows are back to back, so the end of
window ``k - 1``, once that window's start is followed over its whole length, is the record's own
estimate of window ``k``'s start: a smoother's, where the grid has nothing near a narrow basin.
A journal at a rebound (window 2 of acceptance record 3 of the independent simulator: 0.2
micrometres off the wall, leaving it at 2.4 omega c while sliding at 7.7; its basin 0.5 omega c
and 5 micrometres wide) is missed by the grid and the search (0.077 of the data's mean square
over the first half, against the true start's 0.009). Where a window's way in leaves more than
:data:`CHAIN_WHEN` times the least misfit of the windows so far, window ``k - 1``'s start is
followed to its end (the parameters held; :data:`CHAINED_FOLLOW` solver steps per horizon, set
aside), two rounds of the local search are run **round that end** (:func:`search_around`: spreads
a third and a tenth of the grid's), their best is polished by a few steps of the stages' own
solver (:data:`CHAINED_POLISH`, :func:`jaxclear.fitting.run.chained_start`) and taken where it
then follows the first half better than the way in's best (on that window: 0.0084-0.0090, the
true basin). The end itself is 4-10 micrometres and 0.1-0.7 omega c from the true start: its raw
score is no better than the grid's (0.13-0.19 on the half), and solver steps from it alone reached
the basin from one end of window 1 (followed at the start values: 0.009) and not from another
(at the true values: 0.051). Only where the way in missed: followed on every
window (a plan stage per horizon), it cost record 2 twice the iterations (37 for 18) and moved its
stiffness from -3.1 % to -5.0 %. An earlier trial, not kept, offered the end of window ``k - 1``
fitted on its first quarter only, unpolished, as one more candidate of the first pass: it won that
pass on later windows and moved the fit to other basins (acceptance record 3: stiffness -27 % for
-13 %). The candidates are runs of the window model (values only; one after another on a CPU,
:func:`jaxclear.sweep.lanes.over_lanes`; each pass's starts split over the host's threads,
:func:`jaxclear.sweep.lanes.host_rows`), four passes of 1560; a window's start is the best of
them whose whole window runs with its Jacobian
(:func:`jaxclear.fitting.run.begin_stage`).

**Later in the fit.** The approach speed a start holds is chosen again over the longer horizon
each time the joint stages' horizon grows (:func:`rechoose_approach`), and a window the joint
stages leave unfollowed is searched anew by :func:`find_start` at the fitted values, scored over
its whole length (:func:`jaxclear.fitting.run.revisit_windows`): over a window's first half two
basins can score alike where only one follows the second half.

The alternatives considered: reading impact instants and directions from the record itself
(the spikes of the acceleration) needs impacts, and a journal in continuous contact makes none
for milliseconds at a time; a filter or smoother along the record (extended or unscented
Kalman, synchronisation) needs a model of the process noise through the non-smooth contact
and a tuning per record. Scoring the candidates is the same model the fit uses, has no tuning
beyond the grid, and works in contact and in flight alike: in continuous contact the slider's
acceleration is the contact force's component along the guide, which fixes the direction of the
contact on the circle, while the contact stiffness (unknown at this point) sets only the
penetration, a few micrometres, so the score does not depend on the stiffness's start value.

References: Bock 1981 and Baake, Baake, Bock and Briggs 1992 (multiple shooting for parameter
estimation in chaotic systems); Voss, Timmer and Kurths 2004 (a review of nonlinear parameter
estimation from data, the start of a shooting segment as the method's weak point).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from ..integrate import jit
from ..sweep.lanes import host_rows, over_lanes
from .window import WindowInput, WindowModel
from .window_start import (
    APPROACH_SPAN,
    approach_candidates,
    approach_columns,
    candidates,
    pressed_radius,
    unpressed_radius,
)


def _scores(model: WindowModel, theta_z, states, win: WindowInput):
    """Mean square residual of each candidate start ``states`` ``(M, S)`` on the window's fitted
    samples (``inf`` where the run failed or is not finite), ``(M,)``."""

    def one(state):
        r, (_, extra) = model.residual(theta_z, state, win)
        ok = (extra[3] == 0) & jnp.all(jnp.isfinite(r))
        return jnp.where(ok, jnp.sum(r ** 2), jnp.inf)

    return over_lanes(one, states)


_scores_jit = jit(_scores)
#: The structure of :func:`_scores`' output, one array (the store of traced programs rebuilds it).
_SCORES_STRUCTURE = jax.tree_util.tree_structure(0)


#: The part of a window the way in integrates, beyond its scored horizon, as a fraction of the
#: window: a partial horizon ends at the quietest sample within the next tenth of the window
#: (:func:`.records.quiet_cut`). The first rounds' candidates run this far only; a horizon of
#: :data:`WAY_IN_HORIZON` or more runs the whole window (:func:`scoring_model`).
SCORED_BEYOND = 0.1
#: The longer part of a window the way in's last round scores the candidates on, as a fraction
#: of the window (``find_start``'s ``longer``; the earlier passes score on the first stage's
#: horizon, a quarter). Measured on the acceptance records of the independent simulator
#: (benchmarks/README.md, "Records that begin mid-run"): scored on the first quarter only, the
#: way in missed window 3's start of record 2 even at the true parameters (the whole window's
#: misfit 0.030 against a noise of 0.010): in continuous contact the first quarter holds little
#: of where the journal goes next. With the last round over the first half, record 2's fit from
#: the nominal start ended with the stiffness 3.1 % and the restitution 0.014 from the truth
#: (11.8 % and 0.031 before) at a misfit of 0.0102, in 18 joint iterations. On record 3 window
#: 2's best start scored 0.069 on the quarter and 0.077 on the half: its fit now fails (misfit
#: 0.076, refused by the noise rule) where before it followed the record to the noise with the
#: stiffness 13 % off (a wrong basin no rule could see).
WAY_IN_HORIZON = 0.5
#: Starts carried from the shorter scored horizon to the longer one (``find_start``'s
#: ``longer``): the best so far, scored again there before the last round of the local search.
LONGER_ELITES = 48
#: Geometries whose approach speeds are scored in the second pass (the best ones of the first),
#: and elites of each round of the local search.
APPROACH_GEOMETRIES = 12

#: A window whose way in leaves more than this many times the least misfit the way in left on
#: the windows so far (the first's, near the noise) gets the contender from the window before
#: (:func:`~jaxclear.fitting.run.chained_start`). A window's mean square over its first half
#: (about 70 samples at 50 kHz) spreads by +-17 % (one chi-square std) from noise alone, so 1.4
#: is 2.4 std. Measured on the pinned acceptance records of the independent simulator at the fit's
#: start values: 1.09-1.32 on the windows where the fits that followed found the start (records 2
#: and 3), 1.50, 2.52 and 1.54 on windows 2-4 of record 1, whose way in misses windows 1-3 even at
#: the true values (their true starts follow the whole windows at 0.0080-0.0093 of the data's mean
#: square, the way in's best at 0.0111-0.0167), and 7.4 on record 2's window 4. At the true
#: values the contender chained from a window's true start lands in the next window's true basin
#: (0.0094, 0.0081, 0.0106 against the true starts' 0.0093, 0.0081, 0.0110 on record 1). With
#: the threshold at 2 (its value before) record 1's fit ended at 0.0099 of the mean square, the
#: truth's starts and values giving 0.0091 (a deviance of about 45 against it, so a search
#: failure, not the record's limit); with 1.4, at 0.00915 (records 2 and 3 unchanged).
#: Always chaining (0) left record 2 in a worse minimum (stiffness +6.0 % for +1.2 %, its misfit
#: 0.00998 for 0.00983). The margin between 1.32 and 1.50 is thin: three records set it.
CHAIN_WHEN = 1.4
#: The window before's end at this many approach speeds of the contact under way (the end's
#: memory is not carried; :func:`~jaxclear.fitting.run.chained_seeds`), spread over the grid's span.
CHAINED_SEEDS = 3
#: Accepted solver steps per horizon that follow the window before to its end (its start alone,
#: the parameters held, through the horizons after the first).
CHAINED_FOLLOW = 8
#: Spreads of the local search round the window before's end (:func:`search_around`), in units
#: of :func:`refine_scales`: a third and a tenth of the grid's spacing.
CHAINED_SPREADS = (0.3, 0.1)
#: Accepted solver steps that polish the best chained seed (:func:`~jaxclear.fitting.run.chained_start`)
#: before it is weighed against the way in's best start: the end of the window before lies in
#: the basin of the true start where the grid has nothing, but its raw score is no better than
#: the grid's (acceptance record 3 of the independent simulator, window 2: 0.173 of the data's
#: mean square on the quarter against the grid's 0.168; polished, 0.009 on the half).
CHAINED_POLISH = 6

#: Spreads of the local search's rounds, in units of :func:`refine_scales`: the grid's spacing
#: first (15 degrees of direction at the clearance is 0.13 of it; sliding speeds 1.5-7 apart),
#: then half of it. The grid's free-flight candidates move along the wall only; a journal in
#: flight towards the wall (a start 28 micrometres off it, closing at 4.4 omega c: window 2 of
#: an acceptance record of the independent simulator) is reached by these rounds only.
REFINE_SPREADS = (1.0, 0.4)
#: Seed of the local search's perturbations (the way in is deterministic).
REFINE_SEED = 20261129
#: Lineages of the sector search (:func:`search_sectors`): the journal's directions round its
#: bearing cut into this many sectors (15 degrees, the grid's spacing), each searched from its own
#: best candidate.
SECTORS = 24
#: Rounds of the sector search, its first spreads (standard deviations of the direction [rad],
#: the radius [units of the clearance], the sliding and the normal rate [units of ``v_s c``] and
#: the log approach speed) and their shrink factor from one round to the next. The basin of a
#: journal in continuous contact is narrow: at the true parameters of an acceptance record of
#: the independent simulator (window 1: 5.5 micrometres deep, sliding at 6.75 omega c), moving
#: the start by 0.5 omega c along the wall, 0.05 of the clearance round it or 2.5 micrometres in
#: depth leaves 1.5 to 3.5 times the noise over the window's first half.
SECTOR_ROUNDS = 6
SECTOR_SPREADS = (0.13, 0.01, 2.0, 0.5, 0.7)
SECTOR_SHRINK = 0.6


def refine_scales(mech) -> np.ndarray:
    """Standard deviations ``(S,)`` of the local search's perturbations at spread 1, per start
    number of the anywhere layout: 0.06 in the offset (units of the start scale: 30
    micrometres on the benchmark's 0.5 mm clearance), 2 in the rate (units of ``v_s S``), 0.7
    in the log approach speed (a factor 2)."""
    out = []
    for el in mech.clearance_joints:
        e = el.n_equations
        out += [0.06] * e + [2.0] * e + [0.7]
    return np.array(out)


def scoring_model(model: WindowModel, horizon: float) -> WindowModel:
    """``model`` run over the first ``horizon + SCORED_BEYOND`` of its window only (whole fine
    steps; the samples beyond are masked by the horizon's cut), or over the whole window for a
    horizon of :data:`WAY_IN_HORIZON` or more: a sample count is part of a compiled program, so
    the longer scorings (tens of candidates; the samples past the cut masked, the filter causal)
    are one program (benchmarks/README.md, "Tolerances as inputs")."""
    if horizon >= WAY_IN_HORIZON:
        return model
    n_fine = model.settings.n_out - 1
    n = min(n_fine, int(math.ceil((horizon + SCORED_BEYOND) * n_fine)))
    if n == n_fine:
        return model
    return dataclasses.replace(model, settings=dataclasses.replace(model.settings, t_end=jnp.asarray(n * model.h),
                                                                   n_out=n + 1))


def find_start(model: WindowModel, mech, theta_z, win: WindowInput, horizon: float = 1.0,
               longer: tuple[WindowInput, float] | None = None) -> tuple[np.ndarray, dict]:
    """The best candidate starts ``(APPROACH_GEOMETRIES, S)``, best first, of the window ``win``
    (its mask: the fitted samples of the first ``horizon``) at the parameters ``theta_z``, and a
    report: ``{"candidates": runs,
    "best_loss", "median_loss", "finite": number of candidates that ran, "passes": best loss
    after each pass}`` (losses: mean squares of the normalised residual over the fitted samples;
    with ``longer``, ``best_loss`` and the last passes are over the longer horizon).

    Passes of as many runs each (one compiled program): the geometries of
    :func:`~jaxclear.fitting.window_start.candidates` at a middling approach speed; the
    :data:`APPROACH_GEOMETRIES` best of them, each over a log grid of the approach speed of the
    contact under way; then :data:`REFINE_SPREADS` rounds of a local search (the cross-entropy
    method's sampling round the elites, Rubinstein and Kroese 2004): the
    :data:`APPROACH_GEOMETRIES` best starts scored so far, each with Gaussian perturbations of
    every start number (position, velocity in any direction, approach speed), the spread
    shrinking round by round.

    ``longer = (win_long, horizon_long)``: a continuation in the scored horizon. The passes up to
    the first round of the local search score on ``horizon`` (where the candidates are told apart
    without the journal's later motion amplifying a small error of the start); then the
    :data:`LONGER_ELITES` best are scored again over ``horizon_long``, and the rounds that
    follow search round the best of them there: the start chosen is the one that follows the
    longer part of the window."""
    def scorer(w, h):
        return _scorer(model, theta_z, w, h)

    score = scorer(win, horizon)
    cands = candidates(mech)
    m = cands.shape[0]
    scores = score(cands)
    if _one_journal(mech):
        return search_sectors(cands, scores, score, scorer, win, longer, model.weights.shape[0])
    order = np.argsort(scores)
    k = max(1, min(APPROACH_GEOMETRIES, m))
    per = max(1, m // k)
    speeds = np.concatenate([approach_candidates(cands[i], mech, per) for i in order[:k]])[:m]
    speeds = np.concatenate([speeds, np.repeat(cands[int(order[0])][None, :], m - speeds.shape[0], axis=0)])
    seen, seen_scores = np.concatenate([cands, speeds]), np.concatenate([scores, score(speeds)])
    def fitted(w):
        return _fitted(w, model.weights.shape[0])

    n_first = n_fit = fitted(win)
    passes = [float(np.min(scores)) / n_fit, float(np.min(seen_scores)) / n_fit]
    rng = np.random.default_rng(REFINE_SEED)
    for j, spread in enumerate(REFINE_SPREADS):
        if longer is not None and j == 1:  # the continuation: the elites scored over the longer horizon
            score = scorer(*longer)
            n_fit = fitted(longer[0])
            seen = seen[np.argsort(seen_scores)[:LONGER_ELITES]]
            seen_scores = score(seen)
            passes.append(float(np.min(seen_scores)) / n_fit)
        elite = seen[np.argsort(seen_scores)[:k]]
        sigma = spread * refine_scales(mech)
        local = np.repeat(elite, per, axis=0)[:m]
        local = np.concatenate([local, np.repeat(elite[:1], m - local.shape[0], axis=0)])
        local = local + sigma * rng.standard_normal(local.shape)
        local = _in_span(local, mech)
        local[::per] = elite[: local[::per].shape[0]]  # each elite itself is kept
        seen, seen_scores = np.concatenate([seen, local]), np.concatenate([seen_scores, score(local)])
        passes.append(float(np.min(seen_scores)) / n_fit)
    ranked = np.argsort(seen_scores)[:k]
    best = int(ranked[0])
    finite = np.isfinite(scores)
    report = {"candidates": int(cands.shape[0] + speeds.shape[0] + m * len(REFINE_SPREADS)
                                + (LONGER_ELITES if longer is not None else 0)),
              "finite": int(np.isfinite(seen_scores).sum()),
              "best_loss": float(seen_scores[best]) / n_fit,
              "median_loss": float(np.median(scores[finite]) / n_first) if finite.any() else float("nan"),
              "passes": passes}
    return seen[ranked], report


def _scorer(model: WindowModel, theta_z, w: WindowInput, h: float):
    """Scores (sums of squares; inf: failed) of starts ``(m, S)`` over the first ``h`` of ``w``."""
    run, theta = scoring_model(model, h), jnp.asarray(theta_z)

    def part(states):
        return np.asarray(_scores_jit.stored("way-in-scores", lambda: _SCORES_STRUCTURE, run, theta,
                                             jnp.asarray(states), w))

    return lambda states: host_rows(part, states)


def _in_span(starts: np.ndarray, mech) -> np.ndarray:
    """Starts ``(m, S)`` with their approach numbers inside the approach grid's span (a ``nu``
    outside it is a stiff contact: thousands of steps)."""
    span = np.log(APPROACH_SPAN)
    starts[:, approach_columns(mech)] = np.clip(starts[:, approach_columns(mech)], span[0], span[1])
    return starts


def search_around(model: WindowModel, mech, theta_z, seeds: np.ndarray, win: WindowInput, horizon: float,
                  longer: tuple[WindowInput, float]) -> tuple[np.ndarray, float]:
    """The best start ``(S,)`` near ``seeds`` ``(n, S)`` (the window before's end at several
    approach speeds) and its loss over the longer horizon (mean squares of the normalised
    residual): :data:`CHAINED_SPREADS` rounds of the local search (as many runs as the way in's
    passes, the same compiled program), each round's starts Gaussian perturbations of the best
    so far, scored on ``horizon``, the :data:`LONGER_ELITES` best rescored over ``longer``. The
    window before's end lies 4-10 micrometres and 0.1-0.7 omega c from the true start (acceptance
    record 3, window 2): inside a basin 5 micrometres and 0.5 omega c wide only sometimes, so
    solver steps from the end itself reach it from one end and not from another; the search's
    samples round it reached it from both (0.0084 and 0.0090 of the data's mean square over the
    first half, the true start 0.0090 and 0.0097)."""
    m = candidates(mech).shape[0]
    score, score_long = _scorer(model, theta_z, win, horizon), _scorer(model, theta_z, *longer)
    n_long = _fitted(longer[0], model.weights.shape[0])
    seeds = np.asarray(seeds, dtype=float)
    first = score(np.concatenate([seeds, np.repeat(seeds[:1], m - seeds.shape[0], axis=0)]))[: seeds.shape[0]]
    center = seeds[int(np.argmin(np.where(np.isfinite(first), first, np.inf)))]
    best_long = float(score_long(np.repeat(center[None, :], LONGER_ELITES, axis=0))[0])
    rng = np.random.default_rng(REFINE_SEED)
    for spread in CHAINED_SPREADS:
        local = center + spread * refine_scales(mech) * rng.standard_normal((m, center.shape[0]))
        local[0] = center
        local = _in_span(local, mech)
        elite = local[np.argsort(score(local))[:LONGER_ELITES]]
        rescored = score_long(elite)
        if np.min(rescored) < best_long:
            center, best_long = elite[int(np.argmin(rescored))], float(np.min(rescored))
    return center, best_long / n_long


def _one_journal(mech) -> bool:
    """The sector search applies: one force element, a journal (two offset coordinates)."""
    return len(mech.clearance_joints) == 1 and mech.clearance_joints[0].n_equations == 2


def _polar(z: np.ndarray) -> np.ndarray:
    """Starts ``(n, 5)`` of one journal (anywhere layout) as ``(n, 5)`` columns direction [rad],
    radius [units of the clearance], sliding rate and normal rate [units of ``v_s c``] and ``m``."""
    r = pressed_radius(np.linalg.norm(z[:, :2], axis=1))
    phi = np.arctan2(z[:, 1], z[:, 0])
    n = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    return np.stack([phi, r, np.sum(z[:, 2:4] * t, axis=1), np.sum(z[:, 2:4] * n, axis=1), z[:, 4]], axis=1)


def _from_polar(p: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_polar`."""
    n = np.stack([np.cos(p[:, 0]), np.sin(p[:, 0])], axis=1)
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    u = n * unpressed_radius(p[:, 1])[:, None]
    return np.concatenate([u, p[:, 2:3] * t + p[:, 3:4] * n, p[:, 4:5]], axis=1)


def search_sectors(cands: np.ndarray, scores: np.ndarray, score, scorer, win: WindowInput,
                   longer: tuple[WindowInput, float] | None, channels: int) -> tuple[np.ndarray, dict]:
    """:func:`find_start` for one journal: **a local search in every sector of the bearing**.

    The grid's candidates ``cands`` ``(M, 5)`` (scored: ``scores``) are cut into
    :data:`SECTORS` sectors by their direction; each sector's best is the root of a lineage,
    searched for :data:`SECTOR_ROUNDS` rounds in the coordinates of a contact (direction, radius,
    sliding rate, normal rate, log approach speed; spreads :data:`SECTOR_SPREADS` shrinking by
    :data:`SECTOR_SHRINK`), each round one pass of ``M`` runs (``M / SECTORS`` a lineage), a
    lineage moving to its best sample where that scores lower. The lineages' ends are ranked over
    the longer horizon (where given; ``scorer(win, horizon)`` makes the scores of starts there).
    Why lineages and not the global elites of the cross-entropy rounds (used for other elements): at the true parameters of an acceptance record
    of the independent simulator, the global elites of the grid all lay on the far side of the
    bearing from the true start (70 against -147 degrees), in a basin that followed the window's
    first half at 4 times the noise and its whole at 80 times; the sector lineages found every
    window's start of that record (directions within 1.7 degrees, sliding rates within 0.25
    omega c of the simulator's; the first half at 0.92-1.16 times the noise) and, at the fit's
    start values, every window of the three acceptance records at 0.72-1.28 times the noise over
    the first half but one (7 times, which the joint stages closed)."""
    m = cands.shape[0]
    per = max(1, m // SECTORS)
    polar = _polar(cands)
    sector = np.round(polar[:, 0] / (2.0 * math.pi) * SECTORS).astype(int) % SECTORS
    finite_scores = np.where(np.isfinite(scores), scores, np.inf)  # NaN ranks last too
    roots = [int(np.flatnonzero(sector == j)[np.argmin(finite_scores[sector == j])]) for j in range(SECTORS)
             if np.any(sector == j)]
    best_z, best_s = cands[roots].copy(), finite_scores[roots].copy()
    n_first = n_fit = _fitted(win, channels)
    passes = [float(np.min(finite_scores)) / n_fit]
    rng = np.random.default_rng(REFINE_SEED)
    spread = np.asarray(SECTOR_SPREADS, dtype=float)
    span = np.log(APPROACH_SPAN)
    lineages = best_z.shape[0]
    for _ in range(SECTOR_ROUNDS):
        base = np.repeat(_polar(best_z), per, axis=0)
        base = np.concatenate([base, np.repeat(base[:1], m - base.shape[0], axis=0)])
        sample = base + spread * rng.standard_normal(base.shape)
        sample[:, 1] = np.maximum(sample[:, 1], 0.3)
        sample[:, 4] = np.clip(sample[:, 4], span[0], span[1])
        z = _from_polar(sample)
        s = score(z)
        s = np.where(np.isfinite(s), s, np.inf)
        for j in range(lineages):
            seg = s[j * per:(j + 1) * per]
            i = int(np.argmin(seg))
            if seg[i] < best_s[j]:
                best_z[j], best_s[j] = z[j * per + i], seg[i]
        spread = spread * SECTOR_SHRINK
        passes.append(float(np.min(best_s)) / n_fit)
    ranked_s = best_s
    if longer is not None:
        n_fit = _fitted(longer[0], channels)
        padded = np.concatenate([best_z, np.repeat(best_z[:1], max(LONGER_ELITES - lineages, 0), axis=0)])
        ranked_s = scorer(*longer)(padded)[:lineages]
        ranked_s = np.where(np.isfinite(ranked_s), ranked_s, np.inf)
        passes.append(float(np.min(ranked_s)) / n_fit)
    order = np.argsort(ranked_s)[:APPROACH_GEOMETRIES]
    finite = np.isfinite(scores)
    report = {"candidates": int(m * (1 + SECTOR_ROUNDS) + (lineages if longer is not None else 0)),
              "finite": int(finite.sum()),
              "best_loss": float(ranked_s[order[0]]) / n_fit,
              "median_loss": float(np.median(scores[finite])) / n_first if finite.any() else float("nan"),
              "passes": passes, "search": "sectors"}
    return best_z[order], report


#: Approach speeds of a contact under way rescored at each step of the joint stages' horizon
#: (:func:`rechoose_approach`; the longer scoring's count, one compiled program a horizon).
RECHOSEN_APPROACHES = LONGER_ELITES
#: The factor by which another approach speed must lower a window's misfit over the longer
#: horizon to replace the one held (:func:`rechoose_approach`). The held value is where the
#: stages' other start numbers have settled; a small gain on a slice through the approach speed
#: alone is no evidence of a better basin, and taking it can leave the solver with no
#: decreasing step: on acceptance record 2 of the independent simulator, rechoices that gained a
#: factor 1.004-1.13 at the horizon-0.5 stage stopped that stage at its first iteration (window
#: 4 at 4 times the noise) and the fit ended with the stiffness 18 % low; the rechoice that
#: found window 1 of record 3 gained a factor 13.
RECHOSEN_GAIN = 1.5


def rechoose_approach(model: WindowModel, mech, theta_z, z: np.ndarray, win: WindowInput,
                      horizon: float) -> tuple[np.ndarray, dict]:
    """Window start ``z`` ``(S,)`` with the approach speed of its contact under way chosen
    again over ``horizon`` of the window ``win`` at the parameters ``theta_z``, and a report
    ``{"horizon", "loss_before", "loss", "m_before", "m", "best_other"}`` (mean squares of the normalised
    residual; ``m``: the log approach numbers, :mod:`.window_start`).

    The approach speed is held by the least-squares stages (its column stopped: with the
    restitution it acts only through their ratio inside a contact that began before the window),
    so it stays what the way in chose over the window's first half, where it is hardly seen:
    the damping of a contact under way shapes its later part (how long the journal stays
    pressed, when it leaves the wall). Where the stages' horizon grows, :data:`RECHOSEN_APPROACHES`
    values over the approach grid's span (:func:`~jaxclear.fitting.window_start.approach_candidates`;
    the start's other numbers held) are scored over the new horizon and the best kept where it
    is lower by more than a factor :data:`RECHOSEN_GAIN`. Measured on window 1 of acceptance record 3 of the independent simulator (in
    contact at its start), at the end of the horizon-0.5 stage: over the first half every
    approach speed within a factor 3 scored 0.0097-0.0105 of the data's mean square, over the
    whole window 0.10-0.22 but at the true one's neighbourhood, 0.014 (the true start 0.010);
    the way in's choice, 2.8 times too slow, left 0.186 and the fit's stiffness 3.2 % and
    restitution 0.029 off."""
    z = np.asarray(z, dtype=float)
    cands = np.concatenate([z[None, :], approach_candidates(z, mech, RECHOSEN_APPROACHES - 1)])
    s = _scorer(model, theta_z, win, horizon)(cands)
    s = np.where(np.isfinite(s), s, np.inf)
    n = _fitted(win, model.weights.shape[0])
    i = int(np.argmin(s))
    if not s[i] * RECHOSEN_GAIN < s[0]:
        i = 0
    cols = approach_columns(mech)
    return cands[i], {"horizon": float(horizon), "loss_before": float(s[0]) / n, "loss": float(s[i]) / n,
                      "m_before": z[cols].tolist(), "m": cands[i][cols].tolist(),
                      "best_other": float(np.min(s[1:])) / n}


def _fitted(win: WindowInput, channels: int) -> float:
    """Fitted numbers of a window input (its masked samples times the channels; at least 1): the
    divisor that makes a sum of squares a mean square."""
    return max(float(np.sum(np.asarray(win.mask))) * channels, 1.0)
