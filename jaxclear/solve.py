r"""Integration with diffrax: settings, consistent initial conditions, the impact-memory
solver wrapper, and :func:`simulate`, the one pure function that sweeps ``vmap`` and fits
differentiate.

The impact speed :math:`\dot\delta^{(-)}` of each clearance joint is a component of the
solution with zero derivative; :class:`ImpactMemorySolver` wraps any diffrax solver and sets
it after every step with :func:`jaxclear.clearance.update_memory` (spec section 6). A
rejected step is discarded together with its update; gradients flow through the update.
"""

from __future__ import annotations

import math
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
from .dynamics import Baumgarte, State, accelerations, vector_field
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

    def __check_init__(self):
        if self.solver not in SOLVERS:
            raise ParameterError(f"unknown solver {self.solver!r}; valid: {sorted(SOLVERS)}")
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


def assemble(mech: Mechanism, t0=0.0) -> Assembly:
    r"""Consistent ``(q, qdot)`` at ``t0``.

    Positions: Newton iterations :math:`q \leftarrow q - D^+\Phi` (minimum-norm steps, so
    coordinates the constraints leave free stay at their guesses) on the joints, the drivers
    and every clearance joint held at its ``initial_offset`` (centred by default).
    Velocities: the guess corrected (minimum-norm) to :math:`D\dot q = -\Phi_t` on joints and
    drivers and to the prescribed relative velocity ``initial_velocity`` on every clearance
    joint (zero by default: the ideal-joint kinematics, journal moving with its bearing).
    """
    q, qd = mech.guess()
    t0 = jnp.asarray(t0, q.dtype)
    extra = mech.clearance_joints

    def newton(_, q):
        r = constraints.phi(mech, q, t0, extra)
        d = constraints.jacobian(mech, q, t0, extra)
        return q - jnp.linalg.pinv(d) @ r

    if mech.n_constraints + 2 * len(extra) == 0:
        return Assembly(q, qd, jnp.zeros((), q.dtype), jnp.zeros((0, q.shape[0]), q.dtype))
    q = jax.lax.fori_loop(0, NEWTON_ITERATIONS, newton, q)
    r = constraints.phi(mech, q, t0, extra)
    d = constraints.jacobian(mech, q, t0, extra)
    phit = constraints.time_derivative(mech, q, t0, extra)
    # clearance joints: prescribed relative journal velocity (zero by default)
    target = jnp.concatenate([jnp.zeros(mech.n_constraints, q.dtype)] + [c.initial_velocity for c in extra])
    qd = qd - jnp.linalg.pinv(d) @ (d @ qd + phit - target)
    return Assembly(q, qd, jnp.linalg.norm(r), d)


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
    asm = eqx.filter_jit(assemble)(mech, s.t_start)
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


class ImpactMemorySolver(diffrax.AbstractWrappedSolver):
    """Wraps a diffrax solver; after each step sets the contact memory of the state with
    :func:`jaxclear.clearance.update_memory`. When a joint enters contact during a step the
    next step re-evaluates its first stage (the force law changed), so FSAL solvers stay exact.
    ``args`` of the solve must be ``(mechanism, baumgarte)``."""

    solver: diffrax.AbstractSolver

    @property
    def term_structure(self):
        return self.solver.term_structure

    @property
    def interpolation_cls(self):  # pyright: ignore
        return self.solver.interpolation_cls

    @property
    def term_compatible_contr_kwargs(self):
        return self.solver.term_compatible_contr_kwargs

    @property
    def scan_kind(self):
        # DirectAdjoint/ForwardMode want a "bounded" scan; _inner_solver sets it on the inner solver.
        return getattr(self.solver, "scan_kind", None)

    def order(self, terms):
        return self.solver.order(terms)

    def strong_order(self, terms):
        return self.solver.strong_order(terms)

    def error_order(self, terms):
        return self.solver.error_order(terms)

    def init(self, terms, t0, t1, y0, args):
        return self.solver.init(terms, t0, t1, y0, args), jnp.zeros((), bool)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        inner_state, memory_changed = solver_state
        y1, y_error, dense_info, inner_state, result = self.solver.step(
            terms, t0, t1, y0, args, inner_state, made_jump | memory_changed
        )
        mech = args[0]
        memory, crossed = update_memory(mech, t0, y0.q, y0.qdot, t1, y1.q, y1.qdot, y1.memory)
        y1 = State(y1.q, y1.qdot, memory)
        return y1, y_error, dense_info, (inner_state, crossed), result

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)


def _state_norm(y: State):
    """Error norm on positions and velocities only (the memory is not error-controlled)."""
    return optx.rms_norm((y.q, y.qdot))


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
    if s.adjoint in ("forward", "direct"):
        return SOLVERS[s.solver](scan_kind="bounded")
    return SOLVERS[s.solver]()


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
    controller = diffrax.PIDController(rtol=s.rtol, atol=s.atol, dtmax=s.dtmax, norm=_state_norm)
    meter = diffrax.TqdmProgressMeter(refresh_steps=200) if s.progress else diffrax.NoProgressMeter()
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field),
        ImpactMemorySolver(_inner_solver(s)),
        t0,
        t1,
        s.dt0,
        y0,
        args=(mech, s.baumgarte),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=controller,
        max_steps=s.max_steps,
        adjoint=_adjoint(s),
        throw=False,
        progress_meter=meter,
    )
    ys: State = sol.ys
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


@eqx.filter_jit
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
        msg = str(err)
        if "jaxclear:" in msg:
            text = msg[msg.index("jaxclear:") :].splitlines()[0]
            raise SolverError(text) from None
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
    "SOLVERS",
    "STATUS",
    "crank_period",
    "wall_clock",
]
