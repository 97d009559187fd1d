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
(:func:`jaxclear.fitting.window_start.candidates`, 840 candidates for one journal), each
simulated at the start parameters and scored by the misfit of its sensor output over the first
horizon of the window (a quarter of it by default); the best is the start of the window's
least-squares stages (:func:`jaxclear.fitting.plan.plan_free_starts`), which polish it before
the parameters are freed. The approach speed of a contact under way at the window's start is
scored next, over a log grid at the best geometry (as many candidates: the same program), and
then held (:mod:`.window_start`). The candidates are one ``jax.vmap`` of the window model
(values only): on the benchmark the two passes and the window's first Jacobian take 5-13 s
together after compilation.

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
from .window import WindowInput, WindowModel
from .window_start import approach_candidates, candidates


def _scores(model: WindowModel, theta_z, states, win: WindowInput):
    """Mean square residual of each candidate start ``states`` ``(M, S)`` on the window's fitted
    samples (``inf`` where the run failed or is not finite), ``(M,)``."""

    def one(state):
        r, (_, extra) = model.residual(theta_z, state, win)
        ok = (extra[3] == 0) & jnp.all(jnp.isfinite(r))
        return jnp.where(ok, jnp.sum(r ** 2), jnp.inf)

    return jax.vmap(one)(states)


_scores_jit = jit(_scores)


#: The part of a window the way in integrates, beyond its first horizon, as a fraction of the
#: window: a partial horizon ends at the quietest sample within the next tenth of the window
#: (:func:`.records.quiet_cut`). The candidates are run this far only (a third of a window by
#: default, not all of it: the way in's cost drops about threefold).
SCORED_BEYOND = 0.1
#: Geometries whose approach speeds are scored in the second pass (the best ones of the first).
APPROACH_GEOMETRIES = 12


def scoring_model(model: WindowModel, horizon: float) -> WindowModel:
    """``model`` run over the first ``horizon + SCORED_BEYOND`` of its window only (whole fine
    steps; the samples beyond are masked by the horizon's cut)."""
    n_fine = model.settings.n_out - 1
    n = min(n_fine, int(math.ceil((horizon + SCORED_BEYOND) * n_fine)))
    if n == n_fine:
        return model
    return dataclasses.replace(model, settings=dataclasses.replace(model.settings, t_end=jnp.asarray(n * model.h),
                                                                   n_out=n + 1))


def find_start(model: WindowModel, mech, theta_z, win: WindowInput, horizon: float = 1.0) -> tuple[np.ndarray, dict]:
    """The best candidate start ``(S,)`` of the window ``win`` (its mask: the fitted samples of
    the first ``horizon``) at the parameters ``theta_z``, and a report: ``{"candidates": M,
    "best_loss", "median_loss", "finite": number of candidates that ran}`` (losses: mean squares
    of the normalised residual over the fitted samples).

    Two passes of as many runs (one compiled program): the geometries of
    :func:`~jaxclear.fitting.window_start.candidates` at a middling approach speed, then the
    :data:`APPROACH_GEOMETRIES` best of them, each over a log grid of the approach speed of the
    contact under way."""
    short = scoring_model(model, horizon)
    cands = candidates(mech)
    m = cands.shape[0]
    scores = np.asarray(_scores_jit(short, jnp.asarray(theta_z), jnp.asarray(cands), win))  # inf: failed
    order = np.argsort(scores)
    best = int(order[0])
    k = max(1, min(APPROACH_GEOMETRIES, m))
    per = max(1, m // k)
    speeds = np.concatenate([approach_candidates(cands[i], mech, per) for i in order[:k]])[:m]
    speeds = np.concatenate([speeds, np.repeat(cands[best][None, :], m - speeds.shape[0], axis=0)])
    second = np.asarray(_scores_jit(short, jnp.asarray(theta_z), jnp.asarray(speeds), win))
    found, loss = (speeds[int(np.argmin(second))], float(np.min(second))) if np.min(second) < scores[best] else \
        (cands[best], float(scores[best]))
    n_fit = max(float(np.sum(np.asarray(win.mask))) * model.weights.shape[0], 1.0)
    finite = np.isfinite(scores)
    report = {"candidates": int(2 * m), "finite": int(finite.sum() + np.isfinite(second).sum()),
              "best_loss": loss / n_fit,
              "median_loss": float(np.median(scores[finite]) / n_fit) if finite.any() else float("nan")}
    return found, report
