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
hundreds of rows) and handed to optimistix materialised: the residual function returns
``r(x0) + J(x0) (x - x0)`` with ``x0 = stop_gradient(x)``, whose value is ``r(x)`` and whose
linearisation (which optimistix takes with ``jax.linearize``) is the matrix ``J``. So one
Levenberg-Marquardt step costs one forward-mode simulation per window, and the linear solves
(QR) and trust-region updates act on an ``N x P`` matrix.

The solver works in scaled unknowns ``u = D x`` (:func:`column_scale`: ``D_j = sqrt(1e-3)
|J_{:,j}|`` at the stage's start), so that optimistix's ``lambda I`` damping, which starts at
``lambda = 1``, acts like Marquardt's scale-invariant ``mu diag(J^T J)`` with ``mu = 1e-3``.

The loop calls ``solver.step`` and ``solver.terminate`` itself (compiled with
:class:`jaxclear.integrate.jit`, an ``equinox.filter_jit``), so that the fit's state, including the
solver state's array leaves, is checkpointed after every step, and a killed fit resumes bit for
bit. Both programs (:func:`_init`, :func:`_step`) go through the store of traced programs
(:meth:`jaxclear.integrate.jit.stored`), so that a new process fitting a record of the same
structure loads them instead of tracing them (10-15 s each on 2 cores): their outputs' structures,
which the store needs without tracing the model, come from the same programs traced on a stand-in
of the stage's residual that returns zeros of its shapes (:class:`_Shapes`, milliseconds). An optax
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
from .window import WindowInput, WindowModel, evaluate_window

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
    """Data of a stage: the fixed ``theta`` ``(P,)``, the start states of its windows ``(W_s,
    S)`` (fixed rows used, free rows replaced by ``x``), the windows' inputs, stacked along a
    leading window axis (one :class:`WindowInput` whose leaves are ``(W_s, ...)``), and ``keep``
    ``(P,)``: a parameter whose entry is 0 is held (its Jacobian column is zero, so the
    Levenberg-Marquardt step leaves it where it is: the points of a profile likelihood,
    :mod:`jaxclear.fitting.profile`). An array, not a static field, so a profile point shares
    the compiled program of the stage it repeats."""

    theta: jax.Array
    states: jax.Array
    windows: tuple
    keep: jax.Array  # (P,): 1 for a free parameter, 0 for one held at its value (a profile point)


class StageResidual(eqx.Module):
    """``u -> (r, y)`` of a stage: residual ``(W_s n_pad,)`` and signals ``(W_s, n_pad)`` of the
    solver's unknowns ``u = D x`` (``D = column_scale``, see :func:`column_scale`)."""

    model: WindowModel
    column_scale: jax.Array
    theta_free: bool = eqx.field(static=True)
    free_rows: tuple = eqx.field(static=True)  # rows (into the stage's windows) whose state is free

    def evaluate(self, x, args: StageArgs):
        """Residual, Jacobian ``(N, len(x))`` and signals at ``x`` (forward mode). The windows
        are one ``jax.vmap`` of :func:`evaluate_window` (one copy of the model in the program
        whatever the number of windows: a stage of four 3 ms windows compiled in 137 s as four
        copies)."""
        p = args.theta.shape[0]
        n_state = args.states.shape[1]
        theta = x[:p] if self.theta_free else args.theta
        offset = p if self.theta_free else 0
        states = args.states
        for j, row in enumerate(self.free_rows):
            states = states.at[row].set(x[offset + j * n_state: offset + (j + 1) * n_state])
        r, jt, js, y, _ = jax.vmap(evaluate_window, in_axes=(None, None, 0, 0))(self.model, theta, states, args.windows)
        jt = jt * args.keep
        rows = range(r.shape[0])
        return (jnp.reshape(r, (-1,)), stack_jacobian([jt[k] for k in rows], [js[k] for k in rows], self.theta_free,
                                                      self.free_rows), y)

    def shapes(self, x, args: StageArgs) -> tuple:
        """The shapes of :meth:`evaluate`'s outputs, without running the model: residual
        ``(W_s C n_pad,)``, Jacobian ``(W_s C n_pad, len(x))``, signals ``(W_s, C, n_pad)``."""
        n_w, n_c, n_pad = args.windows.data.shape
        n, dtype = n_w * n_c * n_pad, jnp.result_type(x, args.windows.data)
        return (jax.ShapeDtypeStruct((n,), dtype), jax.ShapeDtypeStruct((n, x.shape[0]), dtype),
                jax.ShapeDtypeStruct((n_w, n_c, n_pad), dtype))

    def __call__(self, u, args: StageArgs):
        u0 = jax.lax.stop_gradient(u)
        r, jac, ys = self.evaluate(u0 / self.column_scale, args)
        return r + (jac / self.column_scale) @ (u - u0), ys


class _Shapes(StageResidual):
    """A :class:`StageResidual` whose :meth:`evaluate` is zeros of its shapes
    (:meth:`StageResidual.shapes`), running nothing of the model: a solver's state and step on it
    have the structures of the real stage's (``__call__``'s linear model is the same) for
    milliseconds of tracing instead of the model's (:func:`_structure`)."""

    def evaluate(self, x, args: StageArgs):
        return tuple(jnp.zeros(s.shape, s.dtype) for s in self.shapes(x, args))


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


def _stand_in(fn):
    """The objective ``fn`` (a :class:`StageResidual`, or :class:`HalfSquares` of one) on
    :class:`_Shapes`."""
    if isinstance(fn, HalfSquares):
        return HalfSquares(_stand_in(fn.residual))
    return _Shapes(fn.model, fn.column_scale, fn.theta_free, fn.free_rows)


def _structure(program, solver, fn, *rest):
    """The pytree structure of ``program(solver, fn, *rest)``'s output (:func:`_init`,
    :func:`_step`) without tracing the model: the program traced for shapes on the stand-in of
    ``fn`` (:func:`_stand_in`). The store of traced programs checks it against the real
    program's output where it traces that (a miss), and stores nothing that differs."""
    return jax.tree_util.tree_structure(eqx.filter_eval_shape(program, solver, _stand_in(fn), *rest))


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
    of a killed run): :meth:`step` until a stop reason."""

    def __init__(self, opt: Optimizer, fn: StageResidual, args: StageArgs, u, leaves=None):
        self.fn, self.args = _objective(opt, fn), args
        self.opt = opt._replace(solver=with_scale(opt.solver, fn.column_scale))
        self.scale = np.asarray(fn.column_scale)
        self.y = jnp.asarray(u, dtype=float)
        fresh = (opt.solver, self.fn, self.y, args)
        arrays = _init.stored("fit-solver-init", functools.cache(lambda: _structure(_init, *fresh)), *fresh)
        self.arrays = arrays if leaves is None else restore(arrays, leaves)
        self._step_structure = functools.cache(lambda: _structure(_step, self.opt.solver, self.fn, self.y, self.args,
                                                                  self.arrays))

    def step(self, iteration: int, limit: int, tol_f: float, xtol: float) -> StepReport:
        """One solver step; ``iteration``: iterations so far in this stage, ``limit`` their most."""
        before, old = np.asarray(self.y), self.arrays
        y, arrays, aux, done, predicted = _step.stored("fit-solver-step", self._step_structure, self.opt.solver,
                                                       self.fn, self.y, self.args, self.arrays)
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


def stage_arguments(theta, states, windows: list[WindowInput], held: tuple = ()) -> StageArgs:
    """:class:`StageArgs` from ``theta`` ``(P,)``, the stage windows' states and inputs (stacked)
    and the indices of the parameters ``held`` at their values."""
    stacked = jax.tree_util.tree_map(lambda *leaves: jnp.stack(leaves), *windows)
    theta = jnp.asarray(theta, dtype=float)
    keep = jnp.ones_like(theta).at[jnp.asarray(held, dtype=int)].set(0.0) if held else jnp.ones_like(theta)
    return StageArgs(theta, jnp.asarray(np.asarray(states, dtype=float)), stacked, keep)

