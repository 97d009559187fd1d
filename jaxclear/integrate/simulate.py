r"""Integration with diffrax: :func:`simulate`, the one pure function that sweeps ``vmap`` and
fits differentiate.

Data path: mechanism and settings -> consistent start state (:mod:`.assembly`) -> packed state
vector (:mod:`.state`) -> vector field (forces -> augmented solve, :mod:`.dynamics`) ->
diffrax with the element-state solver wrapper (:mod:`.solvers`) -> post-processing on the
output grid -> :class:`~jaxclear.integrate.solution.Solution` with a :class:`~jaxclear.RESULTS`
status.

Speed (the benchmark slider-crank takes a few thousand steps of a vector field with only a few
dozen flops per kernel, so per-kernel overhead dominates): the solver integrates one packed
vector rather than a pytree, the Runge-Kutta stages run in diffrax's stage loop (one copy of
the vector field; :class:`~jaxclear.integrate.solvers.UnrolledExplicitRK` unrolls them, see
``Settings.stages``), and XLA compiles with
:func:`~jaxclear.integrate.compile.compiler_options`. ``benchmarks/bench_engine.py --profile``
measures each part.
"""

from __future__ import annotations

import dataclasses

import diffrax
import jax
import jax.numpy as jnp

from .._errors import RESULTS, ParameterError, SolverError, invalid_codes, is_concrete, status_message
from .._xla_flags import loop_kernels_active
from ..elements.base import contact_mode
from ..model.mechanism import Mechanism
from .assembly import ASSEMBLY_TEMPLATE, NEWTON_TOL, assemble, check_assembly, initial_state
from .compile import jit, without_input_callbacks
from .dynamics import _accelerations, flat_vector_field
from .settings import SOLVERS, Settings
from .solution import Solution
from . import sampling
from .solvers import ImpactMemorySolver, OnsetController, StateNorm, StopOnNonFinite, UnrolledExplicitRK
from .state import State, stack_memory


def _inner_solver(s: Settings):
    solver = SOLVERS[s.solver]()
    if not solver.tableau.implicit and s.stages == "unrolled":
        return UnrolledExplicitRK(solver)
    if s.adjoint in ("forward", "direct"):
        return SOLVERS[s.solver](scan_kind="bounded")
    return solver


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


def _solve(mech: Mechanism, s: Settings, y0: State, assembled_ok, valid=RESULTS.successful):
    # an invalid member (parameters outside their ranges) or one that cannot be assembled is not
    # integrated: zero-length run
    t0, t1, ts = output_grid(s, y0.q.dtype, (valid == RESULTS.successful) & assembled_ok)
    norm = StateNorm(mech.n_coordinates)
    controller = StopOnNonFinite(diffrax.PIDController(rtol=s.rtol, atol=s.atol, dtmax=s.dtmax, norm=norm))
    if s.exact_onsets and mech.clearance_joints:
        controller = OnsetController(controller)
    block = s.sampling == "block"
    solver = ImpactMemorySolver(_inner_solver(s), dense_to_controller=block)
    if block:  # the output samples are written by the controller, a block per accepted step
        controller = sampling.SampleWriter(controller, ts, solver.interpolation_cls, sampling.BLOCK)
        saveat = diffrax.SaveAt(t1=True, controller_state=True)
    else:  # diffrax's saving loop, one sample per iteration
        saveat = diffrax.SaveAt(ts=ts)
    meter = diffrax.TqdmProgressMeter(refresh_steps=200) if s.progress else diffrax.NoProgressMeter()
    y0_packed = y0.pack()
    with without_input_callbacks():
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(flat_vector_field),
            solver,
            t0,
            t1,
            s.dt0,
            y0_packed,
            args=(mech, s.baumgarte),
            saveat=saveat,
            stepsize_controller=controller,
            max_steps=s.max_steps,
            adjoint=sampling.adjoint(s.adjoint, s.checkpoints, block),
            throw=False,
            progress_meter=meter,
        )
    packed = controller.samples(sol.controller_state, y0_packed, t1 > t0) if block else sol.ys
    ys: State = jax.vmap(lambda v: State.unpack(v, mech))(packed)
    qdd, lam, drift, ecc, pen, fn, ft, mode = _postprocess(mech, s, ts, packed, ys)
    finite = jnp.all(jnp.isfinite(ys.q)) & jnp.all(jnp.isfinite(ys.qdot)) & jnp.all(jnp.isfinite(qdd))
    result = RESULTS.where(finite, RESULTS.successful, RESULTS.nonfinite_state)
    result = RESULTS.where(sol.result == diffrax.RESULTS.successful, result, RESULTS.solver_failed)
    result = RESULTS.where(sol.result == diffrax.RESULTS.dt_min_reached, RESULTS.nonfinite_state, result)
    result = RESULTS.where(sol.result == diffrax.RESULTS.max_steps_reached, RESULTS.max_steps_reached, result)
    result = RESULTS.where(assembled_ok, result, RESULTS.assembly_failed)
    result = RESULTS.where(_too_deep(mech, pen, ys.elements), RESULTS.penetration_too_deep, result)
    result = RESULTS.where(valid == RESULTS.successful, result, valid)
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
        element_states=ys.elements,
        num_steps=sol.stats["num_steps"],
        num_accepted_steps=sol.stats["num_accepted_steps"],
        num_rejected_steps=sol.stats["num_rejected_steps"],
        status=jnp.asarray(result._value, jnp.int32),
    )
    if s.throw:  # under a user's transformation (concrete calls are checked in simulate)
        out = result.error_if(out, result != RESULTS.successful)
    return out


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


def solution_template(mech: Mechanism) -> Solution:
    """A :class:`Solution` with the pytree structure of :func:`simulate`'s for ``mech`` (leaves
    are placeholders), built without tracing the run: the element states' structure comes from
    :meth:`State.unpack` of an abstract vector."""
    vector = jax.ShapeDtypeStruct((State.size(mech),), jnp.float64 if jax.config.jax_enable_x64 else jnp.float32)
    states = jax.eval_shape(lambda v: State.unpack(v, mech).elements, vector)
    return Solution(*([0] * 11), element_states=states, num_steps=0, num_accepted_steps=0, num_rejected_steps=0,
                    status=0)


def solution_structure(mech: Mechanism):
    """The pytree structure of :func:`simulate`'s :class:`Solution` for ``mech``."""
    return jax.tree_util.tree_structure(solution_template(mech))


def _run(mech: Mechanism, s: Settings, y0: State | None):
    """The solution and the assembly at ``s.t_start`` (a member that cannot be assembled is not
    integrated: status ``assembly_failed``, a zero-length run)."""
    asm = assemble(mech, s.t_start)
    assembled_ok = jnp.isfinite(asm.residual) & (asm.residual <= NEWTON_TOL)
    if y0 is None:
        y0 = initial_state(mech, s, asm)
    else:
        assembled_ok = jnp.asarray(True)
    return _solve(mech, s, y0, assembled_ok, mech.check()), asm


@jit
def _simulate(mech: Mechanism, s: Settings, y0: State | None) -> Solution:
    return _run(mech, s, y0)[0]


@jit
def _simulate_and_assemble(mech: Mechanism, s: Settings):
    """``(solution, assembly)``: one program for a concrete :func:`simulate`, whose assembly
    checks (:func:`check_assembly`) then read the assembly it returns."""
    return _run(mech, s, None)


def _concrete_call(mech: Mechanism, s: Settings):
    """The program, name, output structure and arguments of a concrete :func:`simulate` without
    a start state."""
    return (_simulate_and_assemble, "simulate",
            lambda: jax.tree_util.tree_structure((solution_template(mech), ASSEMBLY_TEMPLATE)),
            (mech, dataclasses.replace(s, throw=False)))


def prepare_simulate(mech: Mechanism, s: Settings) -> None:
    """Trace (or load from the store of traced programs) what ``simulate(mech, s)`` will run,
    without compiling it: :func:`~jaxclear.integrate.runs.simulate_with_ideal` does this before
    it starts the ideal-joint run in a second thread, so that run's tracing overlaps this run's
    XLA compilation (which releases Python's lock) rather than its tracing."""
    if s.throw and is_concrete((mech, s)):
        program, name, _, args = _concrete_call(mech, s)
        program.prepare(name, *args)


def simulate(mech: Mechanism, s: Settings, y0: State | None = None) -> Solution:
    """Integrate ``mech`` with settings ``s``; pure, so ``jax.jit``, ``jax.vmap`` and
    ``jax.grad`` (of a scalar of the result) apply to it.

    With ``s.throw`` (default) a failed run raises: with concrete inputs a
    :class:`~jaxclear.SolverError` (after :func:`check_assembly`'s detailed checks) naming the
    :class:`~jaxclear.RESULTS` entry and what to change; under a transformation the same entry
    through ``RESULTS.error_if``. With ``s.throw`` False the status is reported in
    ``Solution.status`` and nothing raises (sweeps).

    Args:
        mech: the mechanism (structure + parameters).
        s: :class:`Settings`.
        y0: optional start :class:`~jaxclear.integrate.state.State`; default: assembled by
            :func:`~jaxclear.assemble`.
    """
    if not (s.throw and is_concrete((mech, s, y0))):
        return _simulate(mech, s, y0)
    if y0 is None:
        program, name, structure, args = _concrete_call(mech, s)
        sol, asm = program.stored(name, structure, *args)
        check_assembly(mech, s, asm)  # its detailed messages take precedence over the run's status
    else:
        s = dataclasses.replace(s, throw=False)
        sol = _simulate.stored("simulate-from-state", lambda: solution_structure(mech), mech, s, y0)
    raise_for_status(sol, s)
    return sol


def raise_for_status(sol: Solution, s: Settings, what: str = "") -> None:
    """Raise for a concrete solution whose status is not successful: a
    :class:`~jaxclear.ParameterError` for an ``invalid_*`` status (a parameter outside its
    range), else a :class:`~jaxclear.SolverError`; the message is the status's text
    (``what`` appended)."""
    code = int(sol.status)
    if code in invalid_codes():
        raise ParameterError(f"jaxclear: {status_message(code)}{what}")
    if code != int(RESULTS.successful._value):
        raise SolverError(f"jaxclear: {status_message(code, max_steps=s.max_steps)}{what}")
