r"""Integration with diffrax: settings, consistent initial conditions, the impact-memory
solver wrapper, and :func:`simulate`, the one pure function that sweeps ``vmap`` and fits
differentiate.

The impact speed :math:`\dot\delta^{(-)}` of each clearance joint is a component of the
solution with zero derivative; :class:`ImpactMemorySolver` wraps any diffrax solver and sets
it after every step with :func:`jaxclear.clearance.update_memory` (spec section 6). A
rejected step is discarded together with its update; gradients flow through the update.

Speed (the benchmark slider-crank takes a few thousand steps of a vector field with only a few
dozen flops per kernel, so per-kernel overhead dominates): the solver integrates one packed
vector (:meth:`~jaxclear.dynamics.State.pack`) rather than a pytree, the explicit Runge-Kutta
stages are unrolled (:class:`UnrolledExplicitRK`), and XLA compiles with
:func:`compiler_options`. ``benchmarks/bench_engine.py --profile`` measures each part.
"""

from __future__ import annotations

import functools
import math
import re
import time
import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from . import constraints
from .clearance import ContactMemory, update_memory
from .dynamics import Baumgarte, State, accelerations, flat_vector_field, spd_solve
from .errors import InitialConditionError, MechanismError, ParameterError, SolverError, _is_concrete
from .mechanism import AngleDriver, FunctionDriver, Mechanism

SOLVERS = {
    "tsit5": diffrax.Tsit5,
    "dopri5": diffrax.Dopri5,
    "dopri8": diffrax.Dopri8,
    "bosh3": diffrax.Bosh3,
    "kvaerno5": diffrax.Kvaerno5,
}

#: Status codes of a :class:`Solution`.
STATUS = {
    0: "ok",
    1: "the solver reached max_steps before t_end",
    2: "non-finite state (singular constraint Jacobian, lock-up, or diverging contact)",
    3: "the solver failed (step size underflow or another diffrax error)",
    4: "the initial configuration could not be assembled (Newton did not converge)",
}


class Settings(eqx.Module):
    """How to integrate.

    Attributes:
        t_end: end time [s] (array leaf: may be swept).
        t_start: start time [s].
        n_out: number of output samples on the uniform grid ``[t_start, t_end]``.
        solver: one of :data:`SOLVERS` (default ``"tsit5"``).
        rtol, atol: tolerances of the adaptive PID step controller (relative, absolute [SI]).
        dt0: first step [s]; ``None`` lets diffrax choose.
        dtmax: largest step [s] or ``None``.
        max_steps: step limit; reaching it is an error (or status 1 with ``throw=False``).
        baumgarte: stabilization gains (alpha, beta) [1/s].
        adjoint: ``"recursive"`` (reverse mode with checkpoints), ``"forward"`` (forward mode),
            ``"direct"``.
        checkpoints: number of checkpoints of reverse mode (``None``: diffrax's default,
            logarithmic in ``max_steps``); fewer checkpoints = less memory, more recomputation.
        throw: raise errors (True) or report them in ``Solution.status`` (False; sweeps).
        progress: show a progress bar while integrating.
        continuous_contact_after: a contact lasting longer than this [s] is classed as
            continuous contact (mode 2) instead of impact (mode 1).
        allow_free_dof: a driven mechanism normally has all its motion determined by the
            drivers (plus the journal's freedom); set True to allow additional free motion.
        stages: how an explicit Runge-Kutta solver evaluates its stages: ``"unrolled"``
            (:class:`UnrolledExplicitRK`; fastest for a single run) or ``"loop"`` (diffrax's
            own ``while_loop`` over the stages; faster under ``jax.vmap`` with more than a few
            members, where one copy of the vector field serves every stage: measured 1.7x
            faster per member at a batch of 32). The two compute the same step. Sweeps use
            ``"loop"``.
    """

    t_end: Float[Array, ""]
    t_start: float = eqx.field(static=True, default=0.0)
    n_out: int = eqx.field(static=True, default=1001)
    solver: str = eqx.field(static=True, default="tsit5")
    rtol: float = eqx.field(static=True, default=1e-6)
    atol: float = eqx.field(static=True, default=1e-9)
    dt0: float | None = eqx.field(static=True, default=None)
    dtmax: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=400_000)
    baumgarte: Baumgarte = eqx.field(default_factory=lambda: Baumgarte(jnp.asarray(5.0), jnp.asarray(5.0)))
    adjoint: str = eqx.field(static=True, default="recursive")
    checkpoints: int | None = eqx.field(static=True, default=None)
    throw: bool = eqx.field(static=True, default=True)
    progress: bool = eqx.field(static=True, default=False)
    continuous_contact_after: float = eqx.field(static=True, default=2e-4)
    allow_free_dof: bool = eqx.field(static=True, default=False)
    stages: str = eqx.field(static=True, default="unrolled")

    def __check_init__(self):
        if self.solver not in SOLVERS:
            raise ParameterError(f"unknown solver {self.solver!r}; valid: {sorted(SOLVERS)}")
        if self.stages not in ("unrolled", "loop"):
            raise ParameterError(f"stages must be 'unrolled' or 'loop', got {self.stages!r}")
        if self.adjoint not in ("recursive", "forward", "direct"):
            raise ParameterError(f"adjoint must be 'recursive', 'forward' or 'direct', got {self.adjoint!r}")
        if not (0 < self.rtol < 1):
            raise ParameterError(f"rtol = {self.rtol:g} outside the allowed range (0, 1)")
        if not (self.atol > 0):
            raise ParameterError(f"atol = {self.atol:g} outside the allowed range (0, inf)")
        if self.n_out < 2:
            raise ParameterError(f"n_out = {self.n_out} outside the allowed range [2, inf)")
        if self.max_steps < 1:
            raise ParameterError(f"max_steps = {self.max_steps} outside the allowed range [1, inf)")
        if _is_concrete(self.t_end) and not float(self.t_end) > self.t_start:
            raise ParameterError(
                f"t_end = {float(self.t_end):g} s must be greater than t_start = {self.t_start:g} s"
            )


def settings(t_end, **kwargs) -> Settings:
    """Build :class:`Settings` with ``t_end`` [s] as a float64 array leaf."""
    return Settings(t_end=jnp.asarray(t_end, dtype=float), **kwargs)


def crank_period(mech: Mechanism) -> float:
    """Period [s] of the first :class:`AngleDriver` (for 'revolutions' options)."""
    for d in mech.drivers:
        if isinstance(d, AngleDriver):
            w = float(d.speed)
            if w == 0.0:
                raise ParameterError("driver speed is 0 rad/s: revolutions are undefined, give t_end instead")
            return 2.0 * math.pi / abs(w)
    raise MechanismError("the mechanism has no AngleDriver: give t_end instead of revolutions")


# --------------------------------------------------------------------------------------
# Compilation
# --------------------------------------------------------------------------------------

#: XLA options for jaxclear's own compiled functions. ``xla_cpu_use_fusion_emitters=False``
#: selects XLA:CPU's older elemental emitters for fused kernels; for the small scalar-heavy
#: kernels of a planar mechanism they compile in about half the time (benchmark slider-crank:
#: 7.3 s -> 4.2 s of XLA compilation) and run at least as fast. Other backends ignore it.
PREFERRED_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}


@functools.cache
def compiler_options() -> dict:
    """:data:`PREFERRED_COMPILER_OPTIONS` if this jaxlib accepts them (probed once with a
    trivial compilation), else ``{}``."""
    try:
        jax.jit(lambda x: x + 1, compiler_options=PREFERRED_COMPILER_OPTIONS)(jnp.zeros(()))
    except Exception:  # an XLA that no longer knows the option: compile with its defaults
        return {}
    return dict(PREFERRED_COMPILER_OPTIONS)


class jit:  # noqa: N801 (used like a decorator, as eqx.filter_jit)
    """``eqx.filter_jit`` with :func:`compiler_options` at top level, created on the first call
    (so that importing jaxclear compiles nothing). Inside another transformation (``jax.jit``,
    ``vmap``, ``grad`` of a user's function) JAX accepts compiler options only on the outermost
    jit, so there it is a plain ``eqx.filter_jit``, inlined like any nested jit."""

    def __init__(self, fun):
        functools.update_wrapper(self, fun)
        self._fun = fun
        self._plain = eqx.filter_jit(fun)
        self._top = None

    def _get(self):
        if self._top is None:
            options = compiler_options()
            self._top = eqx.filter_jit(self._fun, compiler_options=options) if options else self._plain
        return self._top

    def __call__(self, *args, **kwargs):
        if any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves((args, kwargs))):
            return self._plain(*args, **kwargs)
        try:
            return self._get()(*args, **kwargs)
        except ValueError as err:  # concrete arguments, but inside a user's jit
            if "compiler_options" not in str(err):
                raise
            return self._plain(*args, **kwargs)

    def lower(self, *args, **kwargs):
        return self._get().lower(*args, **kwargs)


# --------------------------------------------------------------------------------------
# Consistent initial conditions
# --------------------------------------------------------------------------------------

NEWTON_ITERATIONS = 30
NEWTON_TOL = 1e-10  # [m or rad], residual norm of Phi
RANK_TOL = 1e-9  # relative singular value below which constraints count as dependent


class Assembly(eqx.Module):
    """Result of the position/velocity solve (all arrays)."""

    q: Float[Array, " n"]
    qdot: Float[Array, " n"]
    residual: Float[Array, ""]
    jacobian: Float[Array, "m n"]


def minimum_norm_correction(d, r):
    r"""Minimum-norm :math:`x` with :math:`D x = r`: :math:`x = D^T (D D^T + \epsilon I)^{-1} r`
    (m, n) x (m,) -> (n,).

    The small Tikhonov term :math:`\epsilon = 10^{-13}\,\mathrm{tr}(D D^T)/m` keeps the solve
    finite for redundant (rank-deficient but consistent) constraints, which the eager checks
    then name; for independent constraints it changes the result by a relative
    :math:`\epsilon/\sigma_{min}^2`, removed by the Newton iterations (positions) and by one
    refinement step (velocities). The solve is :func:`~jaxclear.dynamics.spd_solve`, an unrolled
    elimination: no LAPACK call, so a vmapped batch of assemblies (sweeps) never reaches jaxlib's
    batched CPU LAPACK kernels."""
    dd = jnp.sum(d[:, None, :] * d[None, :, :], axis=-1)
    m = dd.shape[0]
    eps = 1e-13 * jnp.trace(dd) / m
    y = spd_solve(dd + eps * jnp.eye(m, dtype=dd.dtype), r)
    return jnp.sum(d * y[:, None], axis=0)


def assemble(mech: Mechanism, t0=0.0) -> Assembly:
    r"""Consistent ``(q, qdot)`` at ``t0``.

    Positions: Newton iterations :math:`q \leftarrow q - D^+\Phi` (minimum-norm steps, so
    coordinates the constraints leave free stay at their guesses) on the joints, the drivers
    and every clearance joint held at its ``initial_offset`` (centred by default).
    Velocities: the guess corrected (minimum-norm) to :math:`D\dot q = -\Phi_t` on joints and
    drivers and to the prescribed relative velocity ``initial_velocity`` on every clearance
    joint (zero by default: the ideal-joint kinematics, journal moving with its bearing).
    :math:`D^+` is applied by :func:`minimum_norm_correction` (no LAPACK).
    """
    q, qd = mech.guess()
    t0 = jnp.asarray(t0, q.dtype)
    extra = mech.clearance_joints

    def newton(_, q):
        r = constraints.phi(mech, q, t0, extra)
        d = constraints.jacobian(mech, q, t0, extra)
        return q - minimum_norm_correction(d, r)

    if mech.n_constraints + 2 * len(extra) == 0:
        return Assembly(q, qd, jnp.zeros((), q.dtype), jnp.zeros((0, q.shape[0]), q.dtype))
    q = jax.lax.fori_loop(0, NEWTON_ITERATIONS, newton, q)
    r = constraints.phi(mech, q, t0, extra)
    d = constraints.jacobian(mech, q, t0, extra)
    phit = constraints.time_derivative(mech, q, t0, extra)
    # clearance joints: prescribed relative journal velocity (zero by default)
    target = jnp.concatenate([jnp.zeros(mech.n_constraints, q.dtype)] + [c.initial_velocity for c in extra])
    for _ in range(2):  # one projection and one refinement step
        qd = qd - minimum_norm_correction(d, d @ qd + phit - target)
    return Assembly(q, qd, jnp.linalg.norm(r), d)


_assemble_jit = jit(assemble)


def _dependent_rows(d: np.ndarray, tol: float) -> list[int]:
    rows, kept = [], []
    scale = max(np.abs(d).max(), 1.0)
    for k in range(d.shape[0]):
        trial = d[kept + [k]]
        if np.linalg.matrix_rank(trial, tol=tol * scale) < len(kept) + 1:
            rows.append(k)
        else:
            kept.append(k)
    return rows


def check_assembly(mech: Mechanism, s: Settings) -> Assembly:
    """Eager checks with detailed messages (concrete inputs only): Newton convergence,
    redundant constraints, too few constraints for the drivers. Returns the assembly."""
    asm = _assemble_jit(mech, s.t_start)
    if not np.isfinite(float(asm.residual)) or float(asm.residual) > NEWTON_TOL:
        raise InitialConditionError(
            f"the Newton solve of Phi(q, {s.t_start:g}) = 0 did not converge: residual "
            f"{float(asm.residual):.3g} > {NEWTON_TOL:g} after {NEWTON_ITERATIONS} iterations from the "
            "bodies' position guesses; improve Body.position (or check that the links can be assembled)"
        )
    extra = mech.clearance_joints
    d = np.asarray(asm.jacobian)
    m, n = d.shape
    dependent = _dependent_rows(d, RANK_TOL) if m else []
    if dependent:
        labels = constraints.constraint_labels(mech, extra=[_Labelled(c) for c in extra])
        names = ", ".join(labels[k] for k in dependent)
        raise MechanismError(
            f"redundant or conflicting constraints: rows {names} depend on the others at the initial "
            f"configuration (rank {m - len(dependent)} < {m} equations); remove them (allowed: "
            "independent constraint equations only)"
        )
    if mech.drivers and m < n and not s.allow_free_dof:
        raise MechanismError(
            f"too few constraints for the drivers: {n} coordinates but only {m} independent equations "
            f"(joints, drivers, clearance joints held centred), so {n - m} degree(s) of freedom are neither "
            "driven nor constrained; add joints/drivers or pass Settings(allow_free_dof=True)"
        )
    return asm


class _Labelled:
    def __init__(self, c):
        self.n_equations = 2
        self.name = f"clearance joint {c.name}"


def initial_state(mech: Mechanism, s: Settings | None = None, assembly: Assembly | None = None) -> State:
    """The start state: assembled ``(q, qdot)`` and empty contact memory."""
    asm = assemble(mech, 0.0 if s is None else s.t_start) if assembly is None else assembly
    mem = ContactMemory.initial(len(mech.clearance_joints), asm.q.dtype)
    return State(asm.q, asm.qdot, mem)


# --------------------------------------------------------------------------------------
# The solver wrapper
# --------------------------------------------------------------------------------------


class _Forwarding(diffrax.AbstractWrappedSolver):
    """A wrapper of a diffrax solver that forwards its structure, interpolation and orders."""

    @property
    def term_structure(self):
        return self.solver.term_structure

    @property
    def interpolation_cls(self):  # pyright: ignore
        return self.solver.interpolation_cls

    @property
    def term_compatible_contr_kwargs(self):
        return self.solver.term_compatible_contr_kwargs

    def order(self, terms):
        return self.solver.order(terms)

    def strong_order(self, terms):
        return self.solver.strong_order(terms)

    def error_order(self, terms):
        return self.solver.error_order(terms)


class UnrolledExplicitRK(_Forwarding):
    """An explicit Runge-Kutta solver of diffrax (Tsit5, Dopri5, Dopri8, Bosh3) with its stages
    unrolled into straight-line code, for ODE terms.

    It takes the wrapped solver's Butcher tableau and interpolation, so it computes the same
    step, error estimate and dense output as diffrax (a test checks equality to rounding).
    diffrax runs the stages in a ``while_loop`` (shorter compilation, one code path for every
    Runge-Kutta family); for a vector field as small as a planar mechanism's, each stage
    iteration then costs more loop bookkeeping (stage-buffer copies and dynamic slices, per
    state leaf) than the vector field itself. Unrolled, XLA fuses the stage combinations into
    the vector field's kernels; :mod:`benchmarks.bench_engine` measures the difference.

    ``solver_state = (f0, first)``: the vector field at the step's start (first same as last)
    and whether it must be evaluated afresh (first step, or after a jump in the vector field).
    """

    solver: diffrax.AbstractERK

    def __check_init__(self):
        tab = self.solver.tableau
        if not isinstance(tab, diffrax.ButcherTableau) or tab.implicit:
            raise ParameterError(f"{type(self.solver).__name__} is not an explicit Runge-Kutta solver")


    @property
    def scan_kind(self):
        # diffrax's forward-mode and direct adjoints swap a Runge-Kutta solver's stage loop for
        # a differentiable one when this is None; unrolled stages have no loop to swap.
        return "bounded"


    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def init(self, terms, t0, t1, y0, args):
        zeros = jax.tree_util.tree_map(jnp.zeros_like, y0)
        return zeros, jnp.array(True)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        tab = self.solver.tableau
        f0, first = solver_state
        dt = t1 - t0
        tmap = jax.tree_util.tree_map
        if tab.fsal:
            # re-evaluate the first stage on the first step and after a jump (under vmap this
            # cond becomes a select that evaluates it for every member at every step: one reason
            # why Settings(stages="loop") is the faster form for batches)
            f0 = jax.lax.cond(first | made_jump, lambda: terms.vf(t0, y0, args), lambda: f0)
        else:
            f0 = terms.vf(t0, y0, args)

        def combine(base, coeffs, ks):
            pairs = [(float(a), k) for a, k in zip(coeffs, ks) if a != 0.0]
            if not pairs:
                return base if base is not None else tmap(jnp.zeros_like, ks[0])
            def leaf(b, *kk):
                acc = sum(a * x for (a, _), x in zip(pairs, kk))
                return acc if b is None else b + acc
            if base is None:
                return tmap(lambda *kk: leaf(None, *kk), *[k for _, k in pairs])
            return tmap(leaf, base, *[k for _, k in pairs])

        ks = [tmap(lambda f: f * dt, f0)]
        fi = f0
        for a_row, c in zip(tab.a_lower, tab.c):
            yi = combine(y0, a_row, ks)
            fi = terms.vf(t0 + float(c) * dt, yi, args)
            ks.append(tmap(lambda f: f * dt, fi))
        y1 = yi if tab.ssal else combine(y0, tab.b_sol, ks)
        y_error = combine(None, tab.b_error, ks)
        k = tmap(lambda *xs: jnp.stack(xs), *ks)
        dense_info = dict(y0=y0, y1=y1, k=k)
        f1 = fi if tab.fsal else f0
        return y1, y_error, dense_info, (f1, jnp.array(False)), diffrax.RESULTS.successful


class ImpactMemorySolver(_Forwarding):
    """Wraps a diffrax solver; after each step sets the contact memory of the state with
    :func:`jaxclear.clearance.update_memory`. When a joint enters contact during a step the
    next step re-evaluates its first stage (the force law changed), so FSAL solvers stay exact.
    The state is the packed vector of :meth:`State.pack` and the term
    :func:`~jaxclear.dynamics.flat_vector_field`; ``args`` of the solve must be
    ``(mechanism, baumgarte)``."""

    solver: diffrax.AbstractSolver


    @property
    def scan_kind(self):
        # DirectAdjoint/ForwardMode want a "bounded" scan; _inner_solver sets it on the inner solver.
        return getattr(self.solver, "scan_kind", None)


    def init(self, terms, t0, t1, y0, args):
        return self.solver.init(terms, t0, t1, y0, args), jnp.zeros((), bool)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        inner_state, memory_changed = solver_state
        y1, y_error, dense_info, inner_state, result = self.solver.step(
            terms, t0, t1, y0, args, inner_state, made_jump | memory_changed
        )
        mech = args[0]
        n, k = mech.n_coordinates, len(mech.clearance_joints)
        a, b = State.unpack(y0, n, k), State.unpack(y1, n, k)
        memory, crossed = update_memory(mech, t0, a.q, a.qdot, t1, b.q, b.qdot, b.memory)
        y1 = State(b.q, b.qdot, memory).pack()
        return y1, y_error, dense_info, (inner_state, crossed), result

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)


class _StateNorm(eqx.Module):
    """Error norm of the packed state on positions and velocities only (the memory is not
    error-controlled): RMS over the first ``2n`` entries."""

    n: int = eqx.field(static=True)

    def __call__(self, v):
        return optx.rms_norm(v[: 2 * self.n])


# --------------------------------------------------------------------------------------
# Solution and simulate
# --------------------------------------------------------------------------------------


class Solution(eqx.Module):
    """Outputs on the uniform grid ``ts`` (leading axis ``n_out``; joint axis ``k``).

    Attributes:
        ts: times [s] (T,).
        q, qdot, qddot: coordinates and derivatives (T, n) [m, rad, /s, /s^2].
        reactions: Lagrange multipliers (T, m) of the joints then drivers
            (for a driver: minus the driving torque/force).
        drift: :math:`|\\Phi|` (T,).
        ecc: eccentricity vectors (T, k, 2) [m]; penetration (T, k) [m] (negative = gap).
        normal_force, friction_force: contact forces (T, k) [N].
        mode: contact mode (T, k): 0 free flight, 1 impact, 2 continuous contact.
        memory: contact memory at the samples (impact speeds, onsets, impacts, work).
        num_steps, num_accepted_steps, num_rejected_steps: solver statistics.
        status: 0 ok, else see :data:`STATUS`.
    """

    ts: Float[Array, " T"]
    q: Float[Array, "T n"]
    qdot: Float[Array, "T n"]
    qddot: Float[Array, "T n"]
    reactions: Float[Array, "T m"]
    drift: Float[Array, " T"]
    ecc: Float[Array, "T k 2"]
    penetration: Float[Array, "T k"]
    normal_force: Float[Array, "T k"]
    friction_force: Float[Array, "T k"]
    mode: Array
    memory: ContactMemory
    num_steps: Array
    num_accepted_steps: Array
    num_rejected_steps: Array
    status: Array

    @property
    def ok(self):
        return self.status == 0

    @property
    def impacts(self):
        """Number of contact onsets per joint over the run (counted at every solver step)."""
        return self.memory.impacts[..., -1, :]

    @property
    def peak_force(self):
        """Largest normal force per joint [N] over all accepted steps (not only output samples)."""
        return self.memory.peak_force[..., -1, :]

    @property
    def peak_penetration(self):
        """Largest penetration per joint [m] over all accepted steps."""
        return self.memory.peak_penetration[..., -1, :]

    def coordinate(self, mech: Mechanism, body: str, which: str, derivative: int = 0):
        """Time series of one coordinate (``x``, ``y`` or ``phi``) of a body."""
        i = 3 * mech.body_index(body) + {"x": 0, "y": 1, "phi": 2}[which]
        return (self.q, self.qdot, self.qddot)[derivative][..., i]


def _inner_solver(s: Settings):
    solver = SOLVERS[s.solver]()
    if not solver.tableau.implicit and s.stages == "unrolled":
        return UnrolledExplicitRK(solver)
    if s.adjoint in ("forward", "direct"):
        return SOLVERS[s.solver](scan_kind="bounded")
    return solver


def _adjoint(s: Settings):
    if s.adjoint == "forward":
        return diffrax.ForwardMode()
    if s.adjoint == "direct":
        return diffrax.DirectAdjoint()
    return diffrax.RecursiveCheckpointAdjoint(checkpoints=s.checkpoints)


def _postprocess(mech: Mechanism, s: Settings, ts, ys: State):
    def one(t, y):
        return accelerations(mech, t, y.q, y.qdot, y.memory, s.baumgarte)

    qdd, lam, value, contact = jax.vmap(one)(ts, ys)
    drift = jnp.linalg.norm(value, axis=-1) if value.shape[-1] else jnp.zeros_like(ts)
    if contact is None:
        z = jnp.zeros((ts.shape[0], 0), ts.dtype)
        return qdd, lam, drift, jnp.zeros((ts.shape[0], 0, 2)), z, z, z, z.astype(jnp.int32)
    in_contact = contact.penetration > 0.0
    long = (ts[:, None] - ys.memory.contact_start) > s.continuous_contact_after
    mode = jnp.where(in_contact, jnp.where(long, 2, 1), 0).astype(jnp.int32)
    return qdd, lam, drift, contact.ecc, contact.penetration, contact.normal_force, contact.friction_force, mode


def _solve(mech: Mechanism, s: Settings, y0: State, assembled_ok):
    t0 = jnp.asarray(s.t_start, y0.q.dtype)
    t1 = jnp.asarray(s.t_end, y0.q.dtype)
    ts = t0 + (t1 - t0) * jnp.linspace(0.0, 1.0, s.n_out, dtype=y0.q.dtype)
    ts = ts.at[-1].set(t1)
    n, k = mech.n_coordinates, len(mech.clearance_joints)
    norm = _StateNorm(n)
    controller = diffrax.PIDController(rtol=s.rtol, atol=s.atol, dtmax=s.dtmax, norm=norm)
    meter = diffrax.TqdmProgressMeter(refresh_steps=200) if s.progress else diffrax.NoProgressMeter()
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(flat_vector_field),
        ImpactMemorySolver(_inner_solver(s)),
        t0,
        t1,
        s.dt0,
        y0.pack(),
        args=(mech, s.baumgarte),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=controller,
        max_steps=s.max_steps,
        adjoint=_adjoint(s),
        throw=False,
        progress_meter=meter,
    )
    ys: State = jax.vmap(lambda v: State.unpack(v, n, k))(sol.ys)
    qdd, lam, drift, ecc, pen, fn, ft, mode = _postprocess(mech, s, ts, ys)
    finite = jnp.all(jnp.isfinite(ys.q)) & jnp.all(jnp.isfinite(ys.qdot)) & jnp.all(jnp.isfinite(qdd))
    status = jnp.where(
        ~assembled_ok,
        4,
        jnp.where(
            sol.result == diffrax.RESULTS.max_steps_reached,
            1,
            jnp.where(sol.result != diffrax.RESULTS.successful, 3, jnp.where(finite, 0, 2)),
        ),
    ).astype(jnp.int32)
    out = Solution(
        ts=ts,
        q=ys.q,
        qdot=ys.qdot,
        qddot=qdd,
        reactions=lam,
        drift=drift,
        ecc=ecc,
        penetration=pen,
        normal_force=fn,
        friction_force=ft,
        mode=mode,
        memory=ys.memory,
        num_steps=sol.stats["num_steps"],
        num_accepted_steps=sol.stats["num_accepted_steps"],
        num_rejected_steps=sol.stats["num_rejected_steps"],
        status=status,
    )
    if s.throw:
        out = eqx.error_if(out, status == 4, "jaxclear: " + STATUS[4] + "; improve the bodies' position guesses")
        out = eqx.error_if(
            out, status == 1, f"jaxclear: {STATUS[1]}; raise Settings.max_steps (now {s.max_steps}, allowed >= 1) "
            "or loosen rtol/atol"
        )
        out = eqx.error_if(out, status == 3, "jaxclear: " + STATUS[3])
        out = eqx.error_if(out, status == 2, "jaxclear: " + STATUS[2])
    return out


@jit
def _simulate(mech: Mechanism, s: Settings, y0: State | None) -> Solution:
    asm = assemble(mech, s.t_start)
    assembled_ok = jnp.isfinite(asm.residual) & (asm.residual <= NEWTON_TOL)
    if y0 is None:
        y0 = initial_state(mech, s, asm)
    else:
        assembled_ok = jnp.asarray(True)
    return _solve(mech, s, y0, assembled_ok)


def simulate(mech: Mechanism, s: Settings, y0: State | None = None) -> Solution:
    """Integrate ``mech`` with settings ``s``; pure, so ``jax.jit``, ``jax.vmap`` and
    ``jax.grad`` (of a scalar of the result) apply to it.

    With concrete inputs it first runs :func:`check_assembly` for detailed errors; under a
    transformation it guards the same failures with :func:`equinox.error_if` (or reports them in
    ``Solution.status`` when ``s.throw`` is False).

    Args:
        mech: the mechanism (structure + parameters).
        s: :class:`Settings`.
        y0: optional start :class:`~jaxclear.dynamics.State`; default: assembled by :func:`assemble`.
    """
    if y0 is None and s.throw and _is_concrete((mech, s)):
        check_assembly(mech, s)
    try:
        return _simulate(mech, s, y0)
    except Exception as err:  # turn equinox's runtime errors into ours
        # the message line, not a quoted source line of the stack equinox prints above it
        found = re.search(r"^(?:\S*Error: )?(jaxclear: [^\n]*)$", str(err), flags=re.MULTILINE)
        if found:
            raise SolverError(found.group(1)) from None
        raise


def wall_clock(fn, *args, repeat: int = 1):
    """Run ``fn(*args)`` ``repeat`` times blocking on the result; returns (result, seconds per run)."""
    out = None
    t = time.perf_counter()
    for _ in range(repeat):
        out = jax.block_until_ready(fn(*args))
    return out, (time.perf_counter() - t) / repeat


__all__ = [
    "Settings",
    "settings",
    "Solution",
    "simulate",
    "assemble",
    "check_assembly",
    "initial_state",
    "ImpactMemorySolver",
    "UnrolledExplicitRK",
    "compiler_options",
    "SOLVERS",
    "STATUS",
    "crank_period",
    "wall_clock",
]
