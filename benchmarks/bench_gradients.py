"""Accuracy and cost of jaxclear's derivatives through impacts, against the true derivative.

For each case (a mechanism, its friction coefficient and force exponent, named parameters, a
horizon and named outputs of one simulation):

* **truth**: central differences (one-sided, second order, for a parameter at 0: friction) of tight runs (rtol 1e-10 / atol 1e-13), relative steps 1e-3,
  1e-4, 1e-5, 1e-6 of each parameter (of 0.1 for a parameter at 0), and at rtol 1e-11 /
  atol 1e-14 with steps 1e-5 and 1e-6; the truth is, per output and parameter, the difference
  that agrees best with a neighbour in step (the next larger or smaller step, at either
  tolerance): the middle of the plateau, whose distance to that neighbour is the truth's own
  uncertainty. The raw differences and Jacobians are kept in ``results/raw/`` (not committed).
  The step sweep is written to the JSON, so the plateau can be read there.
* **sensitivities**: ``jax.jacfwd`` of the simulation at the default settings
  (``Settings(adjoint="sensitivity")``: error-controlled forward sensitivities);
* **loop**: ``jax.jacfwd`` through diffrax's loop (``adjoint="forward"``, the derivative of the
  discretization whose steps are sized for the values only), at the default tolerances and
  tightened (rtol 1e-8, 1e-10), to find the cheapest tolerance at which it is as accurate as the
  sensitivities (or 1e-3, whichever is larger);
* **scatter**: the sensitivities at parameter values 1e-7 apart (relative), which should agree
  to 1e-4; that change holds the derivative's true change (a misfit's curvature over several
  impacts moves its derivative by up to 5e-4 over 1e-7), so beside it the non-smooth part: at
  x (1 - 1e-7), x, x (1 + 1e-7), the middle one's distance from the mean of the other two;
* **cost**: steady-state wall time (best of ``--repeats``) of the value alone, of each Jacobian,
  and compile times, all in the same process.

Error of a derivative: for each output and parameter, the largest absolute error over the
output's samples divided by the largest absolute true derivative there (the parameter's own
scale); the tables show the worst over the parameters. The value's own error is measured the
same way against the tight run.

Outputs: the Flores benchmark slider-crank (slider acceleration and velocity over its first
impact, misfits of the slider acceleration over 0-2 and 2-4 ms of one run), the four-bar
(rocker angular velocity and acceleration over 0-3 ms, misfit of the rocker acceleration over
0-6 ms), the lubricated slider-crank (0.05 Pa s: film and dry contact; slider acceleration over
0-2 ms, misfit over 0-4 ms) and the slider-crank with a translational clearance joint (slider
acceleration over 0-4 ms, misfit over 0-8 ms); each with friction 0 and 0.1 and force
exponents 1, 1.5 and 2 (the stiffness scaled to keep the force at 10 um). A misfit is the mean square difference from a record made by the same
mechanism with 1.2 times the stiffness and restitution 0.85 (and, for the lubricated joint,
1.2 times the viscosity) (rtol 1e-10), over the record's mean square.

Usage: python benchmarks/bench_gradients.py [--cases slider-crank,four-bar,...] [--frictions 0,0.1]
[--exponents 1,1.5,2] [--repeats 3] [--json benchmarks/results/gradients.json] [--restart]
Results are written after each case; a second run skips the cases already in the JSON.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxclear as jc
from jaxclear import params
from jaxclear._storage import atomic_write_json

TIGHT = dict(rtol=1e-10, atol=1e-13, max_steps=4_000_000)
TIGHTER = dict(rtol=1e-11, atol=1e-14, max_steps=4_000_000)
STEPS = (1e-3, 1e-4, 1e-5, 1e-6)
SCATTER = 1e-7
LOOP_RTOLS = (1e-8, 1e-10)
LOOP_KEYS = ("loop",) + tuple(f"loop_rtol_{r:g}" for r in LOOP_RTOLS)  # the loop at rtol 1e-6 (default) and those


@dataclasses.dataclass(frozen=True)
class Case:
    """A mechanism family and its outputs (name -> function of (solution, mechanism, record))."""

    name: str
    build: object  # (friction, exponent) -> Mechanism
    names: tuple
    t_end: float
    n_out: int
    channel: object  # (solution, mechanism) -> (T,) the misfit's channel
    outputs: object  # (solution, mechanism, ts, misfit) -> dict name -> array


def _misfit(y, record, mask):
    return jnp.sum(jnp.where(mask, (y - record) ** 2, 0.0)) / jnp.sum(jnp.where(mask, record**2, 0.0))


def _window(ts, a, b):
    return (ts >= a) & (ts <= b)


def _slider(sol, m, k=2):
    return sol.coordinate(m, "slider", "x", derivative=k)


def _rocker(sol, m, k=2):
    return sol.coordinate(m, "rocker", "phi", derivative=k)


#: penetration [m] at which a law of another exponent n keeps the force of the preset's law
#: (K_n = K_1.5 DELTA_REF^(1.5 - n)), so that the contacts stay comparable
DELTA_REF = 1e-5


def _with(mech, exponent):
    if exponent == 1.5:
        return mech
    k = float(params.get(mech, "stiffness")) * DELTA_REF ** (1.5 - exponent)
    return params.replace_many(mech, {"exponent": exponent, "stiffness": k})


CASES = {
    "slider-crank": Case(
        "slider-crank", lambda mu, n: _with(jc.preset("flores-slider-crank", friction=mu), n),
        ("stiffness", "restitution", "clearance", "friction"), 4e-3, 801, _slider,
        lambda sol, m, ts, mis: {
            "impact: slider acc.": jnp.where(_window(ts, 0.2e-3, 0.36e-3), _slider(sol, m), 0.0),
            "impact: slider vel.": jnp.where(_window(ts, 0.2e-3, 0.36e-3), _slider(sol, m, 1), 0.0),
            "misfit 0-2 ms": mis(_window(ts, 0.0, 2e-3)),
            "misfit 2-4 ms": mis(_window(ts, 2e-3, 4e-3)),
        }),
    "four-bar": Case(
        "four-bar", lambda mu, n: _with(jc.preset("four-bar", friction=mu), n),
        ("stiffness", "restitution", "clearance", "friction"), 6e-3, 601, _rocker,
        lambda sol, m, ts, mis: {
            "rocker vel. 0-3 ms": jnp.where(_window(ts, 0.0, 3e-3), _rocker(sol, m, 1), 0.0),
            "rocker acc. 0-3 ms": jnp.where(_window(ts, 0.0, 3e-3), _rocker(sol, m), 0.0),
            "misfit 0-6 ms": mis(_window(ts, 0.0, 6e-3)),
        }),
    "lubricated": Case(
        "lubricated", lambda mu, n: _with(jc.preset("flores-slider-crank", friction=mu, viscosity=0.05), n),
        ("viscosity", "stiffness", "restitution", "clearance", "friction"), 4e-3, 801, _slider,
        lambda sol, m, ts, mis: {
            "slider acc. 0-2 ms": jnp.where(_window(ts, 0.0, 2e-3), _slider(sol, m), 0.0),
            "misfit 0-4 ms": mis(_window(ts, 0.0, 4e-3)),
        }),
    "translational": Case(
        "translational", lambda mu, n: _with(jc.preset("slider-crank-guide-clearance", friction=mu), n),
        ("stiffness", "restitution", "clearance", "friction"), 8e-3, 801,
        lambda sol, m, k=2: sol.coordinate(m, "slider", "y", derivative=k),
        lambda sol, m, ts, mis: {
            "slider lateral acc. 0-4 ms": jnp.where(_window(ts, 0.0, 4e-3),
                                                    sol.coordinate(m, "slider", "y", derivative=2), 0.0),
            "misfit 0-8 ms": mis(_window(ts, 0.0, 8e-3)),
        }),
}


def _record(case: Case, mech, x0):
    """The misfit's record: the same mechanism with 1.2 times the stiffness and restitution 0.85,
    and 1.2 times the viscosity where there is a film (the oil film keeps the journal off the
    bearing there, so the dry-contact parameters alone changed the record by parts in 1e8: a
    misfit of zero plus the discretization error, 22-30 % of its own value at rtol 1e-6)."""
    change = {"stiffness": 1.2 * x0[case.names.index("stiffness")], "restitution": 0.85}
    if "viscosity" in case.names:
        change["viscosity"] = 1.2 * x0[case.names.index("viscosity")]
    true = params.replace_many(mech, change)
    sol = jc.simulate(true, jc.settings(case.t_end, n_out=case.n_out, **TIGHT))
    return np.asarray(case.channel(sol, true))


def _function(case: Case, mech, record, settings, steps=False):
    """``f(x)``: the outputs (name -> array) for parameter values ``x``; with ``steps``, the pair
    (outputs, the run's solver steps, accepted and rejected: under ``jax.jacfwd`` with
    ``has_aux`` the sensitivity solve's own)."""
    names = case.names
    ts = jnp.linspace(0.0, case.t_end, case.n_out)
    rec = jnp.asarray(record)

    def outputs(x):
        m = params.replace_many(mech, {n: x[i] for i, n in enumerate(names)})
        sol = jc.simulate(m, settings)
        mis = lambda mask: _misfit(case.channel(sol, m), rec, mask)  # noqa: E731
        out = {k: jnp.atleast_1d(v) for k, v in case.outputs(sol, m, ts, mis).items()}
        return (out, sol.num_accepted_steps + sol.num_rejected_steps) if steps else out

    return outputs


def _flat(outputs):
    """``f(x)``: ``outputs(x)`` flattened ``(L,)`` (and its aux, where it returns a pair)."""
    def f(x):
        out = outputs(x)
        out, aux = out if isinstance(out, tuple) else (out, None)
        # in the keys' sorted order: the order of jax.eval_shape's dict, from which the blocks are cut
        flat = jnp.concatenate([out[k] for k in sorted(out)])
        return flat if aux is None else (flat, aux)
    return f


def _timed(fn, x, repeats):
    """``(fn(x) as NumPy arrays (a pytree of them where fn returns one), compile time, best steady
    time)``."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(x))
    first = time.perf_counter() - t0
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(x))
        best = min(best, time.perf_counter() - t0)
    return jax.tree.map(np.asarray, out), first - best, best


def _errors(J, T, blocks, scale):
    """Per output block: the worst over parameters of max|J - T| / max|T| (J, T (L, P))."""
    out = {}
    for k, sl in blocks.items():
        t, j = T[sl] * scale, J[sl] * scale
        den = np.max(np.abs(t), axis=0)
        err = np.max(np.abs(j - t), axis=0) / np.where(den > 0, den, 1.0)
        out[k] = float(np.max(err))
    return out


def _plateau(fd, blocks, scale):
    """The true derivative ``(L, P)`` and its uncertainty per block: for each output block and
    parameter, among the central differences (tolerance, step), the one closest to a neighbour
    in step (the next larger or smaller step, at either tolerance): the middle of the plateau
    over the step sweep; its uncertainty is that distance (relative to the derivative's largest
    magnitude over the block's samples). Agreement of two tolerances at one step is not a
    plateau: a step too large for the output's curvature gives the same wrong slope at both."""
    cands = [(tol, h) for tol, cols in fd.items() for h in cols]
    steps = {tol: sorted(cols, reverse=True) for tol, cols in fd.items()}

    def neighbours(c):  # the next larger and smaller steps, at either tolerance
        tol, h = c
        out = []
        for t in fd:
            larger = [g for g in steps[t] if g > h]
            smaller = [g for g in steps[t] if g < h]
            out += [(t, min(larger))] if larger else []
            out += [(t, max(smaller))] if smaller else []
        return out

    def dist(a, b, sl, i):
        x, y = fd[a[0]][a[1]][sl, i] * scale[i], fd[b[0]][b[1]][sl, i] * scale[i]
        return float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))

    any_cols = next(iter(next(iter(fd.values())).values()))
    truth = np.zeros_like(any_cols)
    spread = {}
    for k, sl in blocks.items():
        worst = 0.0
        for i in range(truth.shape[1]):
            score = {c: min(dist(c, nb, sl, i) for nb in neighbours(c)) for c in cands}
            best = min(score, key=score.get)
            truth[sl, i] = fd[best[0]][best[1]][sl, i]
            worst = max(worst, score[best])
        spread[k] = worst
    return truth, spread


def _blocks(outputs, x0) -> dict:
    """The slices of the flattened outputs (:func:`_flat`: sorted keys), traced, not run."""
    blocks, start = {}, 0
    for k, v in sorted(jax.eval_shape(outputs, jnp.asarray(x0)).items()):
        blocks[k] = slice(start, start + v.shape[0])
        start += v.shape[0]
    return blocks


def _nominal(case: Case, mu: float, n: float):
    """The case's mechanism at friction ``mu`` and exponent ``n`` and its parameters' values."""
    mech = case.build(mu, n)
    return mech, np.array([float(params.get(mech, p)) for p in case.names])


def _raw_path(path: Path, case: str, mu: float, n: float) -> Path:
    """The raw arrays of a case, beside the JSON ``path`` (``raw/``, not committed)."""
    return path.parent / "raw" / f"gradients_{case}_{mu:g}_{n:g}.npz"


TOLERANCE_LABELS = ("1e-10", "1e-11")


def _differences(raw) -> dict:
    """The central differences ``{tolerance: {step: (L, P)}}`` among raw arrays (keys
    ``fd_TOL_STEP``)."""
    return {lab: {float(k.split("_")[2]): raw[k] for k in raw if k.startswith(f"fd_{lab}_")} for lab in TOLERANCE_LABELS}


def _saved_truth(path: Path) -> tuple | None:
    """``(differences, value_true)`` of an earlier run's raw arrays (``--keep-truth``), or None
    where there are none."""
    if not path.exists():
        return None
    raw = dict(np.load(path))
    fd = _differences(raw)
    if not all(fd.values()) or "value_true" not in raw:
        return None
    return fd, raw["value_true"]


def _true_differences(case: Case, mech, record, x0, scale) -> tuple:
    """The truth's central differences of tight runs over the step sweep (one-sided, second
    order, for a parameter at 0), ``{tolerance: {step: (L, P)}}``, and the tight run's values."""
    fd = {}
    for label, tol, steps in zip(TOLERANCE_LABELS, (TIGHT, TIGHTER), (STEPS, STEPS[2:])):
        f = jax.jit(_flat(_function(case, mech, record, jc.settings(case.t_end, n_out=case.n_out, **tol))))
        cols = {}
        f0 = np.asarray(f(jnp.asarray(x0)))
        if label == TOLERANCE_LABELS[0]:
            value_true = f0
        for h in steps:
            J = []
            for i in range(len(x0)):
                e = np.zeros_like(x0)
                e[i] = h * scale[i]
                if x0[i] == 0.0:  # at the end of its range (friction 0): one-sided, second order
                    J.append((4 * np.asarray(f(jnp.asarray(x0 + e))) - np.asarray(f(jnp.asarray(x0 + 2 * e)))
                              - 3 * f0) / (2 * e[i]))
                else:
                    J.append((np.asarray(f(jnp.asarray(x0 + e))) - np.asarray(f(jnp.asarray(x0 - e)))) / (2 * e[i]))
            cols[h] = np.stack(J, axis=1)
        fd[label] = cols
    return fd, value_true


def run_case(case: Case, mu: float, n: float, repeats: int, saved: tuple | None = None) -> dict:
    """One case's row (and its raw arrays under ``"raw"``); ``saved``: the truth's central
    differences and values of an earlier run (:func:`_saved_truth`), reused instead of
    recomputed (they depend on the values of tight runs only, not on how derivatives are
    computed)."""
    mech, x0 = _nominal(case, mu, n)
    scale = np.where(x0 != 0, np.abs(x0), 0.1)  # the parameters' scales (derivatives reported per unit log)
    record = _record(case, mech, x0)
    default = jc.settings(case.t_end, n_out=case.n_out)
    outputs = _function(case, mech, record, default)
    blocks = _blocks(outputs, x0)
    row = dict(case=case.name, friction=mu, exponent=n, parameters=list(case.names))

    # truth: central differences of tight runs, with the step sweep
    fd, value_true = saved if saved is not None else _true_differences(case, mech, record, x0, scale)
    truth, spread = _plateau(fd, blocks, scale)
    row["truth_spread"] = spread
    raw = {f"fd_{lab}_{h:g}": cols[h] for lab, cols in fd.items() for h in cols}
    raw.update(truth=truth, scale=scale, value_true=value_true)
    row["step_sweep"] = {lab: {f"{h:g}": {k: (cols[h][sl] * scale).tolist() if cols[h][sl].shape[0] == 1 else
                                         float(np.max(np.abs(cols[h][sl] * scale)))
                                         for k, sl in blocks.items()} for h in cols} for lab, cols in fd.items()}

    # the value and the derivatives at the default settings
    value_fn = jax.jit(_flat(outputs))
    value, value_compile, value_time = _timed(value_fn, jnp.asarray(x0), repeats)
    row["value_error"] = {k: float(np.max(np.abs(value[sl] - value_true[sl])) /
                                   max(np.max(np.abs(value_true[sl])), 1e-300)) for k, sl in blocks.items()}
    row["value_s"], row["value_compile_s"] = value_time, value_compile

    sens_fn = jax.jit(jax.jacfwd(_flat(outputs)))
    J, c, t = _timed(sens_fn, jnp.asarray(x0), repeats)
    J_sens = J
    row["sensitivity_error"], row["sensitivity_s"], row["sensitivity_compile_s"] = _errors(J, truth, blocks, scale), t, c
    J2, J0 = (np.asarray(sens_fn(jnp.asarray(x0 * (1 + sign * SCATTER)))) for sign in (1, -1))
    row["scatter"] = _errors(J2, J, blocks, scale)
    # the change over 1e-7 holds the derivative's true change (its curvature times the step),
    # the midpoint's departure from the mean of its neighbours only what is not smooth
    row["scatter_nonsmooth"] = _errors(0.5 * (J2 + J0), J, blocks, scale)
    raw["scatter_plus"], raw["scatter_minus"] = J2, J0

    for rtol in (None,) + LOOP_RTOLS:
        tol = {} if rtol is None else dict(rtol=rtol, atol=rtol * 1e-3, max_steps=4_000_000)
        s = jc.settings(case.t_end, n_out=case.n_out, adjoint="forward", **tol)
        fn = jax.jit(jax.jacfwd(_flat(_function(case, mech, record, s))))
        J, c, t = _timed(fn, jnp.asarray(x0), repeats)
        key = "loop" if rtol is None else f"loop_rtol_{rtol:g}"
        raw[key] = J
        row[f"{key}_error"], row[f"{key}_s"], row[f"{key}_compile_s"] = _errors(J, truth, blocks, scale), t, c
    raw["sensitivity"] = J_sens
    # equal accuracy: the cheapest loop tolerance at least as accurate as the sensitivities
    worst = {k: max(row[f"{k}_error"].values()) for k in ("sensitivity",) + LOOP_KEYS}
    row["equal_accuracy_loop"], row["equal_accuracy_ratio"] = _cheapest_loop(worst, row)
    row["raw"] = raw
    return row


def per_parameter(raw, names, blocks) -> list:
    """Per output and parameter: the sensitivities' error against the truth, and the truth's
    plateau width: the largest distance from the chosen difference to the differences of both
    neighbouring steps (at either tolerance), a stricter measure of the truth's uncertainty than
    ``truth_spread`` (the distance to the closest neighbour, which two noisy differences can meet by
    chance). A derivative whose plateau is wider than 1e-3 cannot be checked to 1e-3 by central
    differences at these tolerances: its row says ``truth undetermined``."""
    fd = _differences(raw)
    truth, scale, sens = raw["truth"], raw["scale"], raw["sensitivity"]
    rows = []
    for k, sl in blocks.items():
        for i, name in enumerate(names):
            t = truth[sl, i] * scale[i]
            den = max(float(np.max(np.abs(t))), 1e-300)
            err = float(np.max(np.abs(sens[sl, i] * scale[i] - t)) / den)
            ordered = sorted(((h, lab) for lab, cs in fd.items() for h in cs), reverse=True)
            flat = [fd[lab][h][sl, i] * scale[i] for h, lab in ordered]
            chosen = min(range(len(flat)), key=lambda j: float(np.max(np.abs(flat[j] - t))))
            h0 = ordered[chosen][0]
            near = [j for j, (h, _) in enumerate(ordered) if h != h0 and
                    (h == min((g for g, _ in ordered if g > h0), default=None) or
                     h == max((g for g, _ in ordered if g < h0), default=None))]
            width = max((float(np.max(np.abs(flat[j] - t))) / den for j in near), default=0.0)
            verdict = ("within 1e-3" if err <= 1e-3 else
                       "truth undetermined" if width > 1e-3 and err <= 2 * width else "off")
            row = dict(output=k, parameter=name, error=err, plateau_width=width, verdict=verdict)
            if "sens_1e-11" in raw:  # the converged sensitivities as a sharper reference (--converged)
                ref = raw["sens_1e-11"][sl, i] * scale[i]
                rden = max(float(np.max(np.abs(ref))), 1e-300)
                row.update(converged_vs_fd=float(np.max(np.abs(ref - t)) / den),
                           convergence=float(np.max(np.abs(raw["sens_1e-10"][sl, i] * scale[i] - ref)) / rden),
                           error_vs_converged=float(np.max(np.abs(sens[sl, i] * scale[i] - ref)) / rden))
                if (verdict != "within 1e-3" and row["convergence"] <= 1e-4
                        and row["converged_vs_fd"] <= max(width, 1e-3)):
                    # the reference agrees with the differences within their own uncertainty and has
                    # converged in the tolerance: it decides what the differences cannot
                    row["verdict"] = ("within 1e-3 of the converged sensitivities"
                                      if row["error_vs_converged"] <= 1e-3 else "off against the converged sensitivities")
            rows.append(row)
    return rows


def converge(path: Path, cases=None) -> None:
    """Add the sensitivities at rtol 1e-10 and 1e-11 (``sens_1e-10``, ``sens_1e-11``;
    ``derivative_tolerance=1``) to the raw
    arrays of every case in the JSON (or of ``cases``, ``case|mu|n`` keys): a reference for the
    derivatives whose central differences have no plateau to 1e-3. It is the same program at a
    tight tolerance, so it counts only where it agrees with the central differences within their
    plateau and the two tolerances agree to 1e-4 (:func:`per_parameter`)."""
    for r in json.loads(path.read_text())["rows"]:
        key = _key(r["case"], r["friction"], r["exponent"])
        f = _raw_path(path, r["case"], r["friction"], r["exponent"])
        if not f.exists() or (cases and key not in cases):
            continue
        raw = dict(np.load(f))
        if "sens_1e-11" in raw:
            continue
        t0 = time.perf_counter()
        case = CASES[r["case"]]
        mech, x0 = _nominal(case, r["friction"], r["exponent"])
        record = _record(case, mech, x0)
        for label, tol in zip(TOLERANCE_LABELS, (TIGHT, TIGHTER)):
            # the sensitivities at exactly these tolerances (not a tenth of them)
            s = jc.settings(case.t_end, n_out=case.n_out, derivative_tolerance=1.0, **tol)
            raw[f"sens_{label}"] = np.asarray(jax.jit(jax.jacfwd(_flat(_function(case, mech, record, s))))(jnp.asarray(x0)))
        np.savez(f, **raw)
        print(f"{key}: converged sensitivities in {time.perf_counter() - t0:.0f} s", flush=True)


def settled_accuracy(raw, rows, blocks, names, timing) -> dict:
    """The sensitivities' and the loop's worst errors over the derivatives whose true value is
    settled (:func:`per_parameter`'s ``rows``: the converged sensitivities where they decided
    the verdict, else the central differences where their plateau is within 1e-3; the
    undetermined ones left out), and the cheapest loop tolerance at least as accurate there as
    the sensitivities (or 1e-3, whichever is larger) with its time over theirs (``timing``: a
    results row). Unlike ``equal_accuracy_loop``, which measures both against the raw
    differences, whose own error (up to 0.2 where they have no plateau) lets the loop "reach"
    them."""
    refs = settled_references(raw, rows, blocks, names)
    worst = {k: settled_error(raw[k], refs, raw["scale"]) for k in ("sensitivity",) + LOOP_KEYS}
    loop, ratio = _cheapest_loop(worst, timing)
    return dict(settled=len(refs), of=len(rows), worst=worst, loop=loop, ratio=ratio,
                tightest_loop_ratio=timing[f"{LOOP_KEYS[-1]}_s"] / timing["sensitivity_s"])


def settled_references(raw, rows, blocks, names) -> list:
    """``[(block slice, parameter index, reference (L_block,))]``, per unit log parameter: the
    derivatives whose true value is settled (:func:`per_parameter`'s ``rows``: the converged
    sensitivities where they decided the verdict, else the central differences where their
    plateau is within 1e-3; the undetermined ones left out)."""
    scale = raw["scale"]
    where = [(sl, i) for sl in blocks.values() for i in range(len(names))]
    out = []
    for q, (sl, i) in zip(rows, where):
        if "converged sensitivities" in q["verdict"]:
            out.append((sl, i, raw["sens_1e-11"][sl, i] * scale[i]))
        elif q["plateau_width"] <= 1e-3:
            out.append((sl, i, raw["truth"][sl, i] * scale[i]))
    return out


def settled_error(J, refs, scale) -> float:
    """The worst relative error of a Jacobian ``J`` (L, P) over ``refs``
    (:func:`settled_references`): per derivative, the largest absolute error over the block's
    samples over the reference's largest magnitude; 0 where ``refs`` is empty."""
    return max((float(np.max(np.abs(J[sl, i] * scale[i] - r))) / max(float(np.max(np.abs(r))), 1e-300)
                for sl, i, r in refs), default=0.0)


def _cheapest_loop(worst, timing):
    """The cheapest loop tolerance whose worst error (``worst``: key -> error) is within
    max(the sensitivities' error, 1e-3), and its time over the sensitivities' (``timing``: a
    results row); ``(None, None)`` where none is."""
    target = max(worst["sensitivity"], 1e-3)
    loop = next((k for k in LOOP_KEYS if worst[k] <= target), None)
    return loop, (timing[f"{loop}_s"] / timing["sensitivity_s"] if loop else None)


def summary(path: Path) -> None:
    """Print the per-parameter table of every case whose raw arrays are in ``results/raw/``, then
    per case the accuracy on the settled derivatives (:func:`settled_accuracy`)."""
    rows = json.loads(path.read_text())["rows"]
    print(f"{'case':14s} {'mu':>4s} {'n':>4s} {'output':26s} {'parameter':12s} {'error':>8s} {'plateau':>8s} "
          f"{'vs conv.':>8s} {'conv-fd':>8s} {'1e-10/11':>8s}  verdict")
    for r in rows:
        f = _raw_path(path, r["case"], r["friction"], r["exponent"])
        if not f.exists():
            continue
        raw = dict(np.load(f))
        case = CASES[r["case"]]
        mech, x0 = _nominal(case, r["friction"], r["exponent"])
        blocks = _blocks(_function(case, mech, np.zeros(case.n_out), jc.settings(case.t_end, n_out=case.n_out)), x0)
        r["per_parameter"] = per_parameter(raw, r["parameters"], blocks)
        for q in r["per_parameter"]:
            conv = (f" {q['error_vs_converged']:8.1e} {q['converged_vs_fd']:8.1e} {q['convergence']:8.1e}"
                    if "convergence" in q else " " * 27)
            print(f"{r['case']:14s} {r['friction']:4g} {r['exponent']:4g} {q['output']:26s} {q['parameter']:12s} "
                  f"{q['error']:8.1e} {q['plateau_width']:8.1e}{conv}  {q['verdict']}")
        r["settled_accuracy"] = settled_accuracy(raw, r["per_parameter"], blocks, r["parameters"], r)
    print(f"\n{'case':14s} {'mu':>4s} {'n':>4s} {'settled':>8s} {'sens.':>8s} "
          + " ".join(f"{k.replace('loop_rtol_', 'loop '):>10s}" for k in LOOP_KEYS) + "  loop at equal accuracy")
    for r in rows:
        a = r.get("settled_accuracy")
        if a:
            eq = (f"{a['loop']}: {a['ratio']:.2f}x the sensitivities' time" if a["loop"] else
                  f"none (rtol 1e-10 takes {a['tightest_loop_ratio']:.2f}x their time)")
            print(f"{r['case']:14s} {r['friction']:4g} {r['exponent']:4g} {a['settled']:>4d}/{a['of']:<3d} "
                  f"{a['worst']['sensitivity']:8.1e} " + " ".join(f"{a['worst'][k]:10.1e}" for k in LOOP_KEYS) + f"  {eq}")
    data = json.loads(path.read_text())
    data["rows"] = rows
    atomic_write_json(path, data, indent=1, sort_keys=False)


def _key(case, mu, n):
    return f"{case}|{mu:g}|{n:g}"


def _print(row):
    print(f"\n{row['case']}  friction {row['friction']:g}  exponent {row['exponent']:g}  "
          f"(value {row['value_s'] * 1e3:.1f} ms; sensitivities {row['sensitivity_s'] / row['value_s']:.1f}x, "
          f"loop {row['loop_s'] / row['value_s']:.1f}x the value)")
    print(f"  {'output':28s} {'value err':>9s} {'truth':>8s} {'sens.':>8s} {'scatter':>8s} {'non-sm.':>8s} {'loop':>8s} "
          + " ".join(f"{'loop ' + format(r, 'g'):>10s}" for r in LOOP_RTOLS))
    for k in row["sensitivity_error"]:
        print(f"  {k:28s} {row['value_error'][k]:9.1e} {row['truth_spread'][k]:8.1e} {row['sensitivity_error'][k]:8.1e} "
              f"{row['scatter'][k]:8.1e} {row.get('scatter_nonsmooth', {}).get(k, np.nan):8.1e} {row['loop_error'][k]:8.1e} "
              + " ".join(f"{row[f'loop_rtol_{r:g}_error'][k]:10.1e}" for r in LOOP_RTOLS))
    ratio = row["equal_accuracy_ratio"]
    print(f"  equal accuracy: {row['equal_accuracy_loop'] or 'no loop tolerance tried reaches it'}"
          + (f", {ratio:.1f}x the sensitivities' time" if ratio else ""))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--frictions", default="0,0.1")
    ap.add_argument("--exponents", default="1,1.5,2")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=str(Path(__file__).parent / "results" / "gradients.json"))
    ap.add_argument("--restart", action="store_true", help="ignore the cases already in the JSON")
    ap.add_argument("--keep-truth", action="store_true",
                    help="reuse the central differences of results/raw/ (they depend on tight runs' values only) "
                    "and recompute everything else (give a new --json to resume it)")
    ap.add_argument("--summary", action="store_true",
                    help="only print (and add to the JSON) the per-parameter table from results/raw/")
    ap.add_argument("--converged", action="store_true",
                    help="only add the sensitivities at rtol 1e-10 and 1e-11 to the raw arrays of the cases "
                    "chosen by --cases/--frictions/--exponents (a sharper reference; --summary then uses it)")
    args = ap.parse_args(argv)
    path = Path(args.json)
    if args.converged:
        converge(path, {_key(c, float(mu), float(n)) for c in args.cases.split(",")
                        for mu in args.frictions.split(",") for n in args.exponents.split(",")})
        return
    if args.summary:
        summary(path)
        return
    done = {}
    if path.exists() and not args.restart:
        done = {_key(r["case"], r["friction"], r["exponent"]): r for r in json.loads(path.read_text())["rows"]}
    meta = dict(machine=platform.processor() or platform.machine(), cores=os.cpu_count(), jax=jax.__version__,
                date=time.strftime("%Y-%m-%d"), tight=TIGHT, tighter=TIGHTER, steps=STEPS, scatter=SCATTER)
    for name in args.cases.split(","):
        for mu in (float(v) for v in args.frictions.split(",")):
            for n in (float(v) for v in args.exponents.split(",")):
                key = _key(name, mu, n)
                if key in done:
                    _print(done[key])
                    continue
                t0 = time.perf_counter()
                saved = _saved_truth(_raw_path(path, name, mu, n)) if args.keep_truth else None
                row = run_case(CASES[name], mu, n, args.repeats, saved)
                row["case_wall_s"] = time.perf_counter() - t0
                raw = row.pop("raw")
                (path.parent / "raw").mkdir(parents=True, exist_ok=True)
                np.savez(_raw_path(path, name, mu, n), **raw)
                done[key] = row
                _print(row)
                atomic_write_json(path, dict(meta=meta, rows=list(done.values())), indent=1, sort_keys=False)


if __name__ == "__main__":
    main()
