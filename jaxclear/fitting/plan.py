"""The plan of a fit: its stages (continuation in the signal and in the horizon, window by
window, then all windows together) and its starts.

A stage is one least-squares problem: the residual of some windows over some horizon, in some
unknowns (the parameters ``theta_z`` and/or the start states of some windows).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from .._errors import ParameterError
from .parameters import transform

#: Default horizons of the continuation, as fractions of the window.
DEFAULT_HORIZONS = (0.25, 0.5, 1.0)


class Stage(NamedTuple):
    """One least-squares problem of the plan."""

    name: str
    windows: tuple  # window indices evaluated
    horizon: float  # fraction of the window
    theta: bool  # theta free
    states: tuple  # windows whose start state is free
    start: int  # index of the start (multi-start stages), -1 else
    final: bool  # the last stage: its stop reason is the fit's
    integrate: bool = False  # residual of the integrated signal (coarse stage)
    way_in: bool = False  # its window's start is first found by the way in (:mod:`.way_in`)
    held: tuple = ()  # parameters (indices into theta) held at their values: a profile point (:mod:`.profile`)
    revisit: bool = False  # windows not followed are searched anew at the fitted values first (:mod:`.way_in`)

    def max_iter(self, max_iter: int) -> int:
        """Iteration limit: ``max_iter`` for the final stage, ``max(5, max_iter // 2)`` else."""
        return max_iter if self.final else max(5, max_iter // 2)

    def ftol(self, ftol: float) -> float:
        """Relative loss decrease that ends the stage: ``ftol``, at least 1e-3 if not final."""
        return ftol if self.final else max(ftol, 1e-3)


def check_plan(windows, horizons: Sequence[float], starts, coarse) -> tuple:
    """Validate the plan's settings; returns the horizons as a tuple of floats."""
    if windows < 1 or int(windows) != windows:
        raise ParameterError(f"windows = {windows!r} must be an integer >= 1")
    horizons = tuple(float(h) for h in horizons)
    if not horizons or any(not 0 < h <= 1 for h in horizons) or horizons[-1] != 1.0 or list(horizons) != sorted(horizons):
        raise ParameterError(f"horizons = {horizons} must increase within (0, 1] and end at 1")
    if starts < 1:
        raise ParameterError(f"starts = {starts!r} must be >= 1")
    if coarse not in ("velocity", None):
        raise ParameterError(f"coarse = {coarse!r}; valid: 'velocity', None")
    return horizons


def plan_stages(windows: int, horizons: tuple, starts: int, coarse: str | None, anywhere: bool = False) -> list[Stage]:
    """The stages: every start on the first horizon of window 1 (in the velocity signal when
    ``coarse="velocity"``); window 1 from the best start through the horizons; the start state
    of each further window alone through the horizons; all windows and all unknowns at last.
    With ``anywhere`` (every window's start unknown: :func:`plan_free_starts`) another plan."""
    if anywhere:
        return plan_free_starts(windows, horizons, starts, coarse)
    velocity = coarse == "velocity"
    kind = "velocity" if velocity else "acceleration"
    stages = [Stage(f"start {j + 1}/{starts}, window 1, {kind}, horizon {horizons[0]:g}", (0,), horizons[0], True, (),
                    j, not velocity and len(horizons) == 1 and windows == 1, velocity) for j in range(starts)]
    for hz in horizons if velocity else horizons[1:]:
        stages.append(Stage(f"window 1, acceleration, horizon {hz:g}", (0,), hz, True, (), -1,
                            windows == 1 and hz == 1.0))
    for k in range(1, windows):
        if velocity:
            stages.append(Stage(f"window {k + 1} start state, velocity, horizon {horizons[0]:g}", (k,), horizons[0],
                                False, (k,), -1, False, True))
        for hz in horizons:
            stages.append(Stage(f"window {k + 1} start state, acceleration, horizon {hz:g}", (k,), hz, False, (k,),
                                -1, False))
    if windows > 1:
        stages.append(Stage(f"all {windows} windows", tuple(range(windows)), 1.0, True, tuple(range(1, windows)), -1,
                            True))
    return stages


def plan_free_starts(windows: int, horizons: tuple, starts: int, coarse: str | None) -> list[Stage]:
    """The plan of a record that begins mid-run (every window's start unknown, the first too):

    1. per window, its start alone at the start parameters on the first horizon, from the best
       of the way in's candidates (:mod:`.way_in`), in the acceleration: the start state is not
       a smooth unknown to begin from a guess, and the contact parameters cannot be fitted
       before it is found (a wrong start sends them to a bound). The velocity signal
       (``coarse``) is not used here: the way in has placed the start already, and on records
       of the independent simulator a velocity stage added 15 iterations a window (trials with
       the journal pushed deep into its bearing cost up to 20,000 solver steps each) for a start
       the acceleration stage reached as well;
    2. all windows, the parameters and every start, through the horizons (the last is final);
       with ``starts > 1`` once from each start of the parameters (:func:`spread_starts`), each
       from the starts the way in found (at the first start's values), the best of them the
       result, so that "estimates change with the start" (:mod:`.verdict`) can be checked;
    3. with several windows, once more all windows, the parameters and every start, after the
       windows the joint stages left unfollowed were searched anew at the fitted values over
       their whole length (:func:`jaxclear.fitting.run.revisit_windows`); skipped where every
       window follows the record as well as the others."""
    first = horizons[0]
    stages = [Stage(f"window {k + 1} start state (way in), acceleration, horizon {first:g}", (k,), first, False, (k,),
                    -1, False, False, True) for k in range(windows)]
    every = tuple(range(windows))
    for j in range(starts):
        prefix = f"start {j + 1}/{starts}, " if starts > 1 else ""
        for hz in horizons:
            stages.append(Stage(f"{prefix}all {windows} windows, parameters and start states, horizon {hz:g}", every,
                                hz, True, every, j if starts > 1 else -1, hz == 1.0))
    if windows > 1:
        stages.append(Stage(f"all {windows} windows again, the windows not followed searched anew", every, 1.0, True,
                            every, -1, True, revisit=True))
    return stages


def final_stage(windows: int, anywhere: bool = False) -> Stage:
    """All windows, all samples, all unknowns: where the uncertainty is evaluated."""
    return Stage("final", tuple(range(windows)), 1.0, True, tuple(range(0 if anywhere else 1, windows)), -1, True)


def spread_starts(z0: np.ndarray, free: Sequence[str], n: int, mech=None) -> list[np.ndarray]:
    """``n`` starts ``(P,)``: ``z0`` and ``n - 1`` points around it (deterministic: the first at
    alternating corners, the next on a Halton sequence in [-1, 1]^P) scaled by the span
    +-log 3 for log parameters, +-1 for logit ones, +-0.1 data RMS for the bias."""
    span = np.array([{"log": math.log(3.0), "logit": 1.0, "scaled": 0.1}.get(transform(f, mech), 0.1 * max(abs(z), 1.0))
                     for f, z in zip(free, z0)])
    out = [np.array(z0, dtype=float)]
    primes = [2, 3, 5, 7, 11, 13, 17, 19]
    for i in range(1, n):
        point = []
        for d in range(len(free)):
            p, f, x, k = primes[d % len(primes)], 1.0, 0.0, i
            while k:
                f /= p
                x += f * (k % p)
                k //= p
            point.append(2.0 * x - 1.0 if i > 1 else (1.0 if d % 2 == 0 else -1.0))
        out.append(z0 + span * np.array(point))
    return out
