r"""The solver loop of one stage: optimistix's Levenberg-Marquardt, one step at a time.

The stage's residual ``r(x)`` ``(N,)`` (the windows' residuals stacked) is minimised in the
sense ``min 0.5 |r(x)|^2`` over the stage's unknowns ``x`` (``theta_z`` and/or window states)
by :class:`optimistix.LevenbergMarquardt`: Gauss-Newton steps damped by
``(J^T J + lambda I) dx = -J^T r``, with Nielsen's damping update as its search
(:class:`jaxclear.fitting.lm.NielsenTrustRegion`: a trial is accepted when it lowers the loss;
``lambda`` then shrinks by ``max(1/3, 1 - (2 rho - 1)^3)``, ``rho`` the actual over the
predicted decrease; a rejection multiplies it by ``nu = 2, 4, 8, ...``), and up to
:data:`EXTEND` extensions of an accepted step along its direction with every step capped at
:data:`MAX_STEP` (:class:`jaxclear.fitting.lm.ExtendedDampedNewtonDescent`). optimistix's own
classical trust region leaves ``lambda`` unchanged unless ``rho > 0.99`` (measured on the
acceptance records before the fit's model ran without exact onsets: 18, 12, 19, 23 iterations
against Nielsen's 15, 12, 21, 21; benchmarks/README.md, "Fitting: acceptance").

The Jacobian ``J = dr/dx`` is computed in forward mode (``jax.jacfwd``: a handful of columns,
hundreds of rows), by the compiled program of one window
(:func:`jaxclear.fitting.window.evaluate_window_jit`) window after window, **outside** the
solver's compiled step: before each step the model runs at the point the step evaluates (the
trial point ``y_eval`` of Levenberg-Marquardt), and the step receives ``r`` and ``J`` there as
arrays, with the residual function ``r(u_e) + J(u_e) (u - u_e)`` (:class:`StageResidual`),
whose value at ``u_e`` is ``r`` and whose linearisation (which optimistix takes with
``jax.linearize``) is ``J``. So one Levenberg-Marquardt step costs one forward-mode simulation
per window, the linear solves (QR) and trust-region updates act on an ``N x P`` matrix, and the
model is compiled once, in the window's program, not a second time inside the step (on a small
fit of the test suite the step's program had taken 21-37 s of compilation of its own; it is
now a program of linear algebra, shared by every stage of the same sizes).

The solver works in scaled unknowns ``u = D x`` (:func:`column_scale`: ``D_j = sqrt(1e-3)
|J_{:,j}|`` at the stage's start), so that optimistix's ``lambda I`` damping, which starts at
``lambda = 1``, acts like Marquardt's scale-invariant ``mu diag(J^T J)`` with ``mu = 1e-3``.

The loop calls ``solver.step`` and ``solver.terminate`` itself (compiled with
:class:`jaxclear.integrate.jit`, an ``equinox.filter_jit``), so that the fit's state, including the
solver state's array leaves, is checkpointed after every step, and a killed fit resumes bit for
bit. Both programs (:func:`_init`, :func:`_step`) go through the store of traced programs
(:meth:`jaxclear.integrate.jit.stored`), so that a new process fitting a record of the same
sizes loads them instead of tracing them. An optax
first-order optimiser can be used instead through :class:`optimistix.OptaxMinimiser` on ``0.5
|r|^2`` (with ``D = 1``: the learning rate is in the transformed parameters).

Stopping (per stage, besides optimistix's own Cauchy criterion): ``max_iter`` iterations
(accepted steps); an accepted step lowering the loss by less than ``ftol`` (relative); an
accepted step below ``xtol`` in every coordinate; a rejected trial below ``xtol`` or whose
predicted relative decrease is below ``ftol`` (nothing left to gain: MINPACK's rule); a trust
region below 1e-10. The stage loop (:func:`jaxclear.fitting.run.run_stage`) adds one: an accepted
step that lowers the sum of squares by less than :data:`jaxclear.fitting.run.DEVIANCE_TOL` noise
variances.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import optimistix as optx

from .._errors import ParameterError
from ..integrate import jit
from .lm import levenberg_marquardt, with_scale

#: Extension trials after an accepted Gauss-Newton step, and the step cap in the unknowns ``x``
#: (:func:`jaxclear.fitting.lm.levenberg_marquardt`). On the four acceptance records they take
#: 15, 11, 19 and 16 iterations against 15, 13, 21 and 19 without (``0``, ``inf``; benchmarks/README.md,
#: "Acceptance").
EXTEND = 3
MAX_STEP = 1.5
#: Smallest trust-region size (``1 / lambda``) before a stage is declared stalled.
MIN_STEP_SIZE = 1e-10
#: Largest Jacobian column norm (of the normalised residual, per unit of the unconstrained
#: unknowns) that counts as no influence: 1e-280 stays a normal float64 (above 2.2e-308) when
#: scaled by the 1e-12 floor of :func:`column_scale` and by ``sqrt(1e-3)``, so no scale is ever
#: flushed to zero.
MIN_COLUMN_NORM = 1e-280
_OPTIONS = {"jac": "fwd"}
_TAGS = frozenset()


class StageArgs(eqx.Module):
    """The stage's model evaluated where the solver's step evaluates it (:meth:`StageRun.step`):
    the residual ``(N,)``, its Jacobian ``(N, len(u))`` in the solver's unknowns ``u``, the point
    ``u`` ``(len(u),)`` and the signals ``(W_s, C, n_pad)``. Arrays all: every step of every
    stage of the same sizes shares one compiled step, which holds no copy of the model."""

    residual: jax.Array
    jacobian: jax.Array
    at: jax.Array
    signals: jax.Array


class StageResidual(eqx.Module):
    """``u -> (r, y)`` of a stage, linear about the point the step evaluates: ``r(u_e) + J(u_e)
    (u - u_e)``, whose value at ``u_e`` is the residual there and whose linearisation (which
    optimistix takes with ``jax.linearize``) is the Jacobian: all that a Levenberg-Marquardt
    step reads of the model (it evaluates ``fn`` once, at its trial point ``y_eval``), and, at
    the current point, all that a first-order step reads (the loss and its gradient)."""

    def __call__(self, u, args: StageArgs):
        return args.residual + args.jacobian @ (u - args.at), args.signals


def column_scale(jac: np.ndarray, damping: float = 1e-3) -> np.ndarray:
    r"""``D`` ``(P,)`` with ``u = D x`` the solver's unknowns: ``D_j = sqrt(damping) |J_{:,j}|``
    (column norms of the Jacobian at the stage's start, floored at 1e-12 of the largest).

    optimistix damps with ``lambda I`` and starts at ``lambda = 1``; in ``u`` the Gauss-Newton
    matrix has the diagonal ``1 / damping``, so the first steps are damped like Marquardt's
    ``(J^T J + mu diag(J^T J))`` with ``mu = damping`` (Marquardt 1963), whatever the units of
    the unknowns and of the residual.

    A Jacobian without a column above :data:`MIN_COLUMN_NORM` (no unknown influences the fitted
    samples; :func:`jaxclear.fitting.run.run_stage` skips such a stage) gives ``D = 1``: a floor
    relative to a zero norm would be a subnormal number, which XLA on CPU flushes to zero, so
    that ``x = u / D`` would be ``0 / 0``."""
    norms = _column_norms(jac)
    if not influences(jac):
        return np.ones_like(norms)
    return math.sqrt(damping) * np.maximum(norms, 1e-12 * float(np.max(norms)))


def _column_norms(jac: np.ndarray) -> np.ndarray:
    """Euclidean norms ``|J_{:,j}|`` ``(P,)`` of the Jacobian's columns."""
    return np.sqrt(np.sum(np.asarray(jac, dtype=float) ** 2, axis=0))


def influences(jac: np.ndarray) -> bool:
    """Whether any column of a stage's Jacobian exceeds :data:`MIN_COLUMN_NORM` (some unknown
    changes the fitted samples)."""
    return float(np.max(_column_norms(jac), initial=0.0)) > MIN_COLUMN_NORM


def stack_jacobian(jts, jss, theta_free: bool, free_rows: tuple):
    """Jacobian ``(W_s n_pad, P_stage)`` of the stacked residual of ``W_s`` windows: the windows'
    ``dr/dtheta`` ``(n_pad, P)`` stacked (if ``theta_free``), then one block column ``(W_s n_pad,
    4 n_c)`` per free window state (``free_rows``), non-zero only on that window's rows."""
    n_pad = jts[0].shape[0]
    n = n_pad * len(jts)
    blocks = [jnp.concatenate(jts, axis=0)] if theta_free else []
    for row in free_rows:
        col = jnp.zeros((n, jss[row].shape[1]), jnp.result_type(jss[row]))
        blocks.append(col.at[row * n_pad:(row + 1) * n_pad].set(jss[row]))
    return jnp.concatenate(blocks, axis=1) if blocks else jnp.zeros((n, 0))


class HalfSquares(eqx.Module):
    """``0.5 |r(x)|^2`` of a :class:`StageResidual`, for first-order minimisers."""

    residual: StageResidual

    def __call__(self, x, args: StageArgs):
        r, ys = self.residual(x, args)
        return 0.5 * jnp.sum(r**2), (r, ys)


class Optimizer(NamedTuple):
    """The stage solver: an optimistix solver, its name, and whether it is least squares."""

    solver: optx.LevenbergMarquardt | optx.OptaxMinimiser
    name: str
    least_squares: bool


_LM_CACHE: dict = {}


def lm_solver(rtol: float, atol: float) -> optx.LevenbergMarquardt:
    """One :class:`optimistix.LevenbergMarquardt` per tolerance pair (so compilations are shared)."""
    key = (float(rtol), float(atol))
    if key not in _LM_CACHE:
        _LM_CACHE[key] = levenberg_marquardt(key[0], key[1], extend=EXTEND, max_step=MAX_STEP)
    return _LM_CACHE[key]


def make_optimizer(spec=None, ftol: float = 1e-6, xtol: float = 1e-5) -> Optimizer:
    """The stage solver from ``None`` / ``"levenberg-marquardt"`` / ``"lm"`` (the default:
    :class:`optimistix.LevenbergMarquardt` with Cauchy tolerances ``rtol=ftol``,
    ``atol=xtol``), ``"adam"`` or ``"adam:LR"`` (learning rate in the transformed parameters,
    default 0.02), an optax transformation (run by :class:`optimistix.OptaxMinimiser`; named by
    its type, a checkpoint cannot tell two of them apart), or an
    :class:`optimistix.LevenbergMarquardt` of your own tolerances. The deprecated
    :func:`jaxclear.fitting.levenberg_marquardt` transformation selects the default."""
    if spec is None or spec in ("levenberg-marquardt", "lm") or getattr(spec, "_jaxclear_legacy_lm", False):
        return Optimizer(lm_solver(ftol, xtol), "levenberg-marquardt", True)
    if isinstance(spec, str):
        name, _, lr = spec.partition(":")
        if name == "adam":
            try:
                rate = float(lr) if lr else 0.02
            except ValueError:
                raise ParameterError(f"optimizer {spec!r}: the learning rate after ':' must be a number") from None
            return Optimizer(optx.OptaxMinimiser(optax.adam(rate), rtol=ftol, atol=xtol), f"adam:{rate:g}", False)
        raise ParameterError(f"unknown optimizer {spec!r}; valid: 'levenberg-marquardt', 'adam', 'adam:LR'")
    if isinstance(spec, optx.LevenbergMarquardt):
        return Optimizer(spec, f"optimistix:LevenbergMarquardt(rtol={spec.rtol:g}, atol={spec.atol:g})", True)
    name = f"custom:{type(spec).__name__}:{getattr(spec.update, '__qualname__', '')}"
    return Optimizer(optx.OptaxMinimiser(spec, rtol=ftol, atol=xtol), name, False)


def _objective(opt: Optimizer, fn: StageResidual):
    return fn if opt.least_squares else HalfSquares(fn)


def _structure(program, solver, fn, *rest):
    """The pytree structure of ``program(solver, fn, *rest)``'s output (:func:`_init`,
    :func:`_step`), traced for shapes only (milliseconds: the stage's residual holds no model).
    The store of traced programs checks it against the real program's output where it traces
    that (a miss), and stores nothing that differs."""
    return jax.tree_util.tree_structure(eqx.filter_eval_shape(program, solver, fn, *rest))


def _template(solver, fn, y, args):
    f_struct, aux_struct = eqx.filter_eval_shape(fn, y, args)
    return solver.init(fn, y, args, _OPTIONS, f_struct, aux_struct, _TAGS)


@jit
def _init(solver, fn, y, args):
    """Array leaves of a fresh solver state."""
    return eqx.filter(_template(solver, fn, y, args), eqx.is_array)


@jit
def _step(solver, fn, y, args, arrays):
    """One ``solver.step`` then ``solver.terminate`` from the state's array leaves (the static
    part is rebuilt by ``init`` inside the trace, so every step of every stage of the same shape
    shares one compilation). Also returns the decrease of ``0.5 |r|^2`` the Gauss-Newton model
    predicted for the trial point this step evaluates."""
    state = eqx.combine(arrays, eqx.filter(_template(solver, fn, y, args), eqx.is_array, inverse=True))
    if isinstance(solver, optx.LevenbergMarquardt):  # predicted decrease of the trial evaluated now
        predicted = -solver.search.predict_reduction(state.y_eval - y, state.f_info)
    else:
        predicted = jnp.zeros(())
    y, state, aux = solver.step(fn, y, args, _OPTIONS, state, _TAGS)
    done, _ = solver.terminate(fn, y, args, _OPTIONS, state, _TAGS)
    return y, eqx.filter(state, eqx.is_array), aux, done, predicted


def solver_leaves(arrays) -> list:
    """The solver state's array leaves as nested lists (for the checkpoint)."""
    return [np.asarray(v).tolist() for v in jax.tree_util.tree_leaves(arrays)]


def restore(template, leaves):
    """Solver state arrays of ``template``'s structure from saved ``leaves``."""
    flat, treedef = jax.tree_util.tree_flatten(template)
    return jax.tree_util.tree_unflatten(treedef, [jnp.asarray(v, dtype=t.dtype) for v, t in zip(leaves, flat)])


class StepReport(NamedTuple):
    """After a step: the accepted solver unknowns ``u`` and ``x = u / D``, the loss ``|r|^2``
    there, whether the step counts as an iteration, the stop reason ('' to go on) and the
    solver arrays. An iteration is a Levenberg-Marquardt update in the classical sense: an
    accepted step (its rejected trials, with more damping, belong to it), or the last update
    that finds no decreasing step; for first-order optimisers every step. Every step but the
    first (the evaluation of the start) evaluates one trial point."""

    u: np.ndarray
    x: np.ndarray
    loss: float
    counted: bool
    reason: str
    arrays: object


class StageRun:
    """The steps of one stage from the solver unknowns ``u`` (fresh, or the saved solver leaves
    of a killed run): :meth:`step` until a stop reason. ``evaluate(x)`` runs the model: the
    stage's residual ``(N,)``, its Jacobian in ``x = u / D`` ``(N, len(x))`` and the signals,
    NaN residuals where the model fails (:func:`jaxclear.fitting.run.stage_evaluation`);
    ``first``: its value at the start ``u / D`` where already computed."""

    def __init__(self, opt: Optimizer, evaluate, column_scale, u, leaves=None, first=None):
        self.fn = _objective(opt, StageResidual())
        self.opt = opt._replace(solver=with_scale(opt.solver, column_scale))
        self.scale = np.asarray(column_scale, dtype=float)
        self.evaluate = evaluate
        self.y = jnp.asarray(u, dtype=float)
        self._last = (np.asarray(self.y), first) if first is not None else None
        args = self._args(self.y)
        fresh = (opt.solver, self.fn, self.y, args)
        arrays = _init.stored("fit-solver-init", functools.cache(lambda: _structure(_init, *fresh)), *fresh)
        self.arrays = arrays if leaves is None else restore(arrays, leaves)

    def _args(self, point) -> StageArgs:
        """:class:`StageArgs`: the model evaluated at the solver unknowns ``point``."""
        point = np.asarray(point, dtype=float)
        if self._last is not None and np.array_equal(self._last[0], point):
            r, jac, ys = self._last[1]
        else:
            r, jac, ys = self.evaluate(point / self.scale)
            self._last = (point, (r, jac, ys))
        return StageArgs(jnp.asarray(r, dtype=float), jnp.asarray(np.asarray(jac) / self.scale, dtype=float),
                         jnp.asarray(point), jnp.asarray(ys, dtype=float))

    def step(self, iteration: int, limit: int, tol_f: float, xtol: float) -> StepReport:
        """One solver step; ``iteration``: iterations so far in this stage, ``limit`` their most.
        The model runs first, outside the compiled step, where the step evaluates it: at the
        trial point ``y_eval`` of Levenberg-Marquardt, at the current point for first-order
        optimisers."""
        before, old = np.asarray(self.y), self.arrays
        args = self._args(old.y_eval if self.opt.least_squares else self.y)
        step_in = (self.opt.solver, self.fn, self.y, args, self.arrays)
        y, arrays, aux, done, predicted = _step.stored("fit-solver-step",
                                                       functools.cache(lambda: _structure(_step, *step_in)), *step_in)
        self.y, self.arrays = y, arrays
        u = np.asarray(y)
        if not self.opt.least_squares:
            return self._after_minimiser(before, u, arrays, aux, bool(done), iteration, limit, xtol)
        loss = float(jnp.sum(arrays.f_info.residual**2))
        if int(old.num_steps) == 0:
            return StepReport(u, u / self.scale, loss, False, "" if np.isfinite(loss) else "not finite", arrays)
        loss_before = float(jnp.sum(old.f_info.residual**2))
        accepted = int(arrays.num_accepted_steps) > int(old.num_accepted_steps)
        if int(getattr(old.search_state, "ext", 0)) > 0:  # an extension trial: part of the last iteration
            reason = "optimistix: Cauchy criterion met" if done else ""
            return StepReport(u, u / self.scale, loss, False, reason, arrays)
        trial = float(np.max(np.abs((np.asarray(old.y_eval) - before) / self.scale), initial=0.0))
        rel = (loss_before - loss) / max(loss_before, 1e-300)
        rel_predicted = float(predicted) / max(0.5 * loss_before, 1e-300)
        reason = ""
        if accepted and 0 <= rel < tol_f:
            reason = f"relative loss decrease {rel:.2g} < ftol {tol_f:g}"
        elif accepted and trial < xtol:
            reason = f"step {trial:.2g} < xtol {xtol:g}"
        elif not accepted and (trial < xtol or rel_predicted < tol_f):
            reason = (f"no decreasing step (rejected trial: step {trial:.2g}, predicted relative decrease "
                      f"{rel_predicted:.2g}; converged within the solver's noise)")
        elif float(arrays.search_state.step_size) < MIN_STEP_SIZE:
            reason = "no decreasing step (trust region collapsed)"
        elif done:
            reason = "optimistix: Cauchy criterion met"
        elif accepted and iteration + 1 >= limit:
            reason = "max_iter"
        return StepReport(u, u / self.scale, loss, accepted or bool(reason), reason, arrays)

    def _after_minimiser(self, before, u, arrays, aux, done, iteration, limit, xtol) -> StepReport:
        loss = float(jnp.sum(aux[0] ** 2))  # at the point before the step
        if not np.isfinite(loss):
            return StepReport(before, before / self.scale, loss, True, "the model failed along the step", arrays)
        dx = float(np.max(np.abs((u - before) / self.scale), initial=0.0))
        reason = ""
        if dx < xtol:
            reason = f"step {dx:.2g} < xtol {xtol:g}"
        elif done:
            reason = "optimistix: Cauchy criterion met"
        elif iteration + 1 >= limit:
            reason = "max_iter"
        return StepReport(u, u / self.scale, loss, True, reason, arrays)
