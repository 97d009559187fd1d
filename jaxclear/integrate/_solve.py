r"""The integration itself, shared by :func:`~jaxclear.simulate` and its sensitivities
(:mod:`.sensitivity`): the start state, diffrax with jaxclear's solver and controller wrappers on
a system (:mod:`.system`), and the post-processing of the output samples into a
:class:`~jaxclear.integrate.Solution`.

Speed (the benchmark slider-crank takes a few thousand steps of a vector field with only a few
dozen flops per kernel, so per-kernel overhead dominates): the solver integrates one packed
vector rather than a pytree, the Runge-Kutta stages run in diffrax's stage loop (one copy of
the vector field; :class:`~jaxclear.integrate.UnrolledExplicitRK` unrolls them, see
``Settings.solver``), and XLA compiles with
:func:`~jaxclear.integrate.compiler_options`. ``benchmarks/bench_engine.py --profile``
measures each part.
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from .._errors import RESULTS, first_failure
from .._xla_flags import loop_kernels_active
from ..elements.base import contact_mode
from ..model.mechanism import Mechanism
from ._assembly import NEWTON_TOL, assemble, initial_state
from ._compile import without_input_callbacks
from ._dynamics import _accelerations
from ._settings import Settings, tolerance_rules
from ._solution import Solution
from ._solvers import ImpactMemorySolver, StopOnNonFinite
from ._state import State, stack_memory
from ._system import AbstractSystem, MechanismSystem, system_field


def _inner_solver(s: Settings, norm=None):
    """The solver of ``s`` as the integration loop runs it (its derivatives' form). An implicit
    solver's (``kvaerno5``) Newton iterations take the step-size controller's tolerances and
    error norm ``norm`` (default: optimistix's RMS norm), which diffrax would fill in itself for
    its own controller but not through the wrappers of the controller this integration uses."""
    solver = s.solver
    if isinstance(solver, diffrax.AbstractImplicitSolver):
        solver = eqx.tree_at(lambda x: (x.root_finder.rtol, x.root_finder.atol, x.root_finder.norm), solver,
                             (s.rtol, s.atol, optx.rms_norm if norm is None else norm))
    return s.derivatives.solver(solver)


#: Without single-kernel loops (``JAXCLEAR_SMALL_LOOP_BYTES=0``, see ``jaxclear/_xla_flags.py``):
#: most output samples whose accelerations and contact outputs are evaluated together (one
#: ``vmap`` batch of a ``lax.map``; a grid is cut into the fewest batches of at most this size,
#: of equal size). Measured 2026-11-25 on the post-processing of 24,001 samples (2 cores):
#: 21-24 ms with batches of 4096 (4001 after equal splitting), 39-48 ms with 256, 47-51 ms
#: with one batch of all. With single-kernel loops the samples are evaluated one by one in a
#: loop that XLA compiles into one kernel: 10.7 ms (0.45 us per sample) where the batches
#: took 24.9 ms (Intel Xeon, 2 cores).
POSTPROCESS_BATCH = 4096


def _postprocess(mech: Mechanism, s: Settings, ts, packed, ys: State):
    """Accelerations, reactions, constraint drift and contact outputs at the output samples
    ``ts`` (T,) of the packed states ``packed`` (T, N) (``ys`` the same, unpacked)."""
    def one(t, v):
        y = State.unpack(v, mech)
        qdd, lam, value, _, contact = _accelerations(mech, t, y.q, y.qdot, y.elements, s.baumgarte)
        return qdd, lam, value, contact

    # with single-kernel loops: sample by sample; else in equal batches of at most
    # POSTPROCESS_BATCH samples (vmap inside, a scan over the batches): one vmap over a long
    # grid at once is slower per sample
    n = ts.shape[0]
    if loop_kernels_active():
        qdd, lam, value, contact = jax.lax.map(lambda a: one(*a), (ts, packed))
    elif n <= POSTPROCESS_BATCH:
        qdd, lam, value, contact = jax.vmap(one)(ts, packed)
    else:
        m = -(-n // POSTPROCESS_BATCH)
        b = -(-n // m)
        pad = m * b - n
        tb = jnp.concatenate([ts, jnp.broadcast_to(ts[-1], (pad,))]).reshape(m, b)
        vb = jnp.concatenate([packed, jnp.broadcast_to(packed[-1], (pad, packed.shape[1]))]).reshape(m, b, -1)
        out = jax.lax.map(lambda a: jax.vmap(one)(*a), (tb, vb))
        qdd, lam, value, contact = jax.tree_util.tree_map(
            lambda x: x.reshape((m * b,) + x.shape[2:])[:n], out)
    drift = jnp.linalg.norm(value, axis=-1) if value.shape[-1] else jnp.zeros_like(ts)
    if contact is None:
        z = jnp.zeros((ts.shape[0], 0), ts.dtype)
        return qdd, lam, drift, jnp.zeros((ts.shape[0], 0, 2)), z, z, z, z.astype(jnp.int32)
    mode = contact_mode(ts[:, None], contact.penetration, ys.memory.contact_start, s.continuous_contact_after)
    return qdd, lam, drift, contact.ecc, contact.penetration, contact.normal_force, contact.friction_force, mode


def output_grid(s: Settings, dtype, run=True):
    """``(t0, t1, ts)``: start, end and the ``s.n_out`` uniform output samples [s], sorted and
    inside ``[t0, t1]`` by construction; ``t1 = t0`` where ``run`` is False."""
    t0 = jnp.asarray(s.t_start, dtype)
    t1 = jnp.where(run, jnp.asarray(s.t_end, dtype), t0)
    ts = t0 + (t1 - t0) * jnp.linspace(0.0, 1.0, s.n_out, dtype=dtype)
    return t0, t1, jnp.minimum(ts, t1).at[-1].set(t1)


class Start(eqx.Module):
    """What a run starts from: the packed start state, whether the mechanism assembled, its
    parameter check (a :class:`~jaxclear.RESULTS` entry) and the assembly (for its checks)."""

    packed: jax.Array
    assembled: jax.Array
    valid: RESULTS
    assembly: object


def start_run(mech: Mechanism, s: Settings, y0: State | None) -> Start:
    """The start of a run: the assembly at ``s.t_start`` (a member that cannot be assembled is
    not integrated: status ``assembly_failed``, a zero-length run) and the start state (``y0``,
    or the assembled one)."""
    asm = assemble(mech, s.t_start)
    assembled_ok = jnp.isfinite(asm.residual) & (asm.residual <= NEWTON_TOL)
    if y0 is None:
        y0 = initial_state(mech, s, asm)
    else:
        assembled_ok = jnp.asarray(True)
    return Start(y0.pack(), assembled_ok, first_failure(mech.check(), *tolerance_rules(s)), asm)


class Integration(eqx.Module):
    """The samples (T, M) of a system's packed vector at the output times and the solve's
    statistics and diffrax result."""

    samples: jax.Array
    num_steps: jax.Array
    num_accepted_steps: jax.Array
    num_rejected_steps: jax.Array
    result: diffrax.RESULTS


def integrate_system(system: AbstractSystem, s: Settings, t0, t1, ts, v0) -> Integration:
    """Integrate ``system`` from ``v0`` over ``[t0, t1]`` with the settings ``s``, sampled at
    ``ts``: diffrax's PID controller (the system's error norm) wrapped by
    :class:`~jaxclear.integrate._solvers.StopOnNonFinite` and as ``s.onsets`` needs; the solver
    (``s.derivatives``' form of ``s.solver``) wrapped by
    :class:`~jaxclear.integrate.ImpactMemorySolver`; the samples written as
    ``s.output`` writes them, the adjoint ``s.derivatives``'."""
    controller = StopOnNonFinite(diffrax.PIDController(rtol=s.rtol, atol=s.atol, dtmax=s.dtmax, norm=system.norm(),
                                                       dtmin=system.dtmin()))
    controller = s.onsets.controller(controller, system.mech)
    solver = ImpactMemorySolver(_inner_solver(s, system.norm()), dense_to_controller=s.output.dense_to_controller)
    controller, saveat = s.output.saving(controller, ts, solver.interpolation_cls)
    meter = diffrax.TqdmProgressMeter(refresh_steps=200) if s.progress else diffrax.NoProgressMeter()
    with without_input_callbacks():
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(system_field),
            solver,
            t0,
            t1,
            s.dt0,
            v0,
            args=system,
            saveat=saveat,
            stepsize_controller=controller,
            max_steps=s.max_steps,
            adjoint=s.derivatives.loop_adjoint(s.output),
            throw=False,
            progress_meter=meter,
        )
    packed = s.output.samples(sol, controller, v0, t1 > t0)
    return Integration(packed, sol.stats["num_steps"], sol.stats["num_accepted_steps"],
                       sol.stats["num_rejected_steps"], sol.result)


def solution(mech: Mechanism, s: Settings, ts, packed, run: Integration, begin: Start) -> tuple[Solution, RESULTS]:
    """The :class:`Solution` of the packed states ``packed`` (T, N) at ``ts`` (T,) of a run
    (statistics and diffrax result from ``run``, the assembly and parameter check from
    ``begin``): accelerations, reactions, drift and contact outputs at the samples, and the
    status, also as a :class:`~jaxclear.RESULTS` entry. Nothing raises here: the compiled
    program holds no host callback (JAX's persistent compilation cache stores no program that
    has one); :func:`~jaxclear.integrate.check_status` raises for the status after it."""
    ys: State = jax.vmap(lambda v: State.unpack(v, mech))(packed)
    qdd, lam, drift, ecc, pen, fn, ft, mode = _postprocess(mech, s, ts, packed, ys)
    finite = jnp.all(jnp.isfinite(ys.q)) & jnp.all(jnp.isfinite(ys.qdot)) & jnp.all(jnp.isfinite(qdd))
    result = RESULTS.where(finite, RESULTS.successful, RESULTS.nonfinite_state)
    result = RESULTS.where(run.result == diffrax.RESULTS.successful, result, RESULTS.solver_failed)
    result = RESULTS.where(run.result == diffrax.RESULTS.dt_min_reached, RESULTS.nonfinite_state, result)
    result = RESULTS.where(run.result == diffrax.RESULTS.max_steps_reached, RESULTS.max_steps_reached, result)
    result = RESULTS.where(begin.assembled, result, RESULTS.assembly_failed)
    result = RESULTS.where(_too_deep(mech, pen, ys.elements), RESULTS.penetration_too_deep, result)
    result = RESULTS.where(begin.valid == RESULTS.successful, result, begin.valid)
    return Solution(
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
        element_states=ys.elements,
        num_steps=run.num_steps,
        num_accepted_steps=run.num_accepted_steps,
        num_rejected_steps=run.num_rejected_steps,
        status=jnp.asarray(result._value, jnp.int32),
    ), result


def mechanism_system(mech: Mechanism, s: Settings) -> MechanismSystem:
    """What :func:`integrate_system` integrates for a run of ``mech`` alone: its packed state
    under the vector field with ``s``'s Baumgarte terms."""
    return MechanismSystem(mech, s.baumgarte)


def stored_solution(mech: Mechanism, s: Settings, ts, packed, num_steps) -> Solution:
    """The :class:`Solution` of packed states ``packed`` (T, N) stored at ``ts`` (T,) by a run
    that took ``num_steps`` steps (a Lyapunov run's trajectory): accelerations, reactions and
    contact outputs recomputed from them, as for a run. Traceable."""
    steps = jnp.asarray(num_steps)
    run = Integration(packed, steps, steps, jnp.zeros_like(steps), diffrax.RESULTS.successful)
    begin = Start(packed[0], jnp.asarray(True), RESULTS.successful, None)
    return solution(mech, s, ts, packed, run, begin)[0]


def grid(s: Settings, begin: Start, dtype):
    """The output grid of a run that starts at ``begin``: zero length for a member with invalid
    parameters or that cannot be assembled (:func:`output_grid`)."""
    return output_grid(s, dtype, (begin.valid == RESULTS.successful) & begin.assembled)


def run(mech: Mechanism, s: Settings, begin: Start) -> tuple[Solution, RESULTS]:
    """The run of ``mech`` from ``begin`` and its status (no error raised)."""
    t0, t1, ts = grid(s, begin, begin.packed.dtype)
    out = integrate_system(mechanism_system(mech, s), s, t0, t1, ts, begin.packed)
    return solution(mech, s, ts, out.samples, out, begin)


def _too_deep(mech: Mechanism, pen, element_states):
    """Whether any element went deeper than its ``penetration_limit()`` at any accepted step:
    the running peak of the elements' memories (``peak_penetration``, raised after every
    accepted step by the impact-memory rule, so a deep penetration between two output samples
    counts) and the output samples ``pen`` (T, k). Samples after a failed step (diffrax fills
    them with ``inf``) are left out: that failure has its own status."""
    if not mech.elements or pen.shape[-1] != len(mech.elements):
        return jnp.asarray(False)
    limits = jnp.stack([jnp.asarray(e.penetration_limit(), pen.dtype) for e in mech.elements])
    peak = stack_memory(element_states, pen).peak_penetration
    peak = jnp.where(jnp.isfinite(peak), peak, -jnp.inf)
    return jnp.any(pen > limits) | jnp.any(peak > limits)
