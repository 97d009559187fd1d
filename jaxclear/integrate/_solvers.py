r"""Solver wrappers around diffrax's Runge-Kutta solvers.

* :class:`UnrolledExplicitRK`: the same step as a diffrax explicit Runge-Kutta solver (its
  tableau and interpolation), with the stages unrolled into straight-line code; per-kernel
  overhead dominates the small right-hand side of a planar mechanism
  (``Settings(solver=UnrolledExplicitRK(diffrax.Tsit5()))``, or ``stages="unrolled"``; the
  default is diffrax's stage loop, which compiles in half the time and runs as fast or faster
  on the benchmark: ``benchmarks/README.md``, "Settings' measured choices").
* :class:`ImpactMemorySolver`: wraps any solver; after every accepted step it calls every force
  element's ``after_step`` (the impact-memory rule), so history-dependent force laws see the
  approach speed at the onset; the step's dense output carries the updated memory.
* :class:`OnsetController`: wraps the step-size controller; a step that crosses into contact
  well before its end is rejected and retried so that it ends just past the onset (exact
  contact onsets): within the accepted step the force used the approach speed of the step's
  start, which is then (nearly) the speed at the onset.

Both rely on diffrax's solver internals (``AbstractWrappedSolver``, the Butcher tableau fields,
the ``(y1, y_error, dense_info, solver_state, result)`` step protocol): the versions they are
tested with are pinned in ``pyproject.toml`` and checked by :mod:`jaxclear.integrate._versions`.
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError
from ..elements.memory import ONSET_MARGIN
from ._state import State


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

    @property
    def root_finder(self):
        # diffrax treats a wrapper as the solver it wraps (``isinstance``): an implicit one's
        # Newton solver is read through the wrapper (its tolerances: ``_solve._inner_solver``).
        return self.solver.root_finder

    @property
    def root_find_max_steps(self):
        return self.solver.root_find_max_steps


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
            # why diffrax's stage loop is the faster form for batches)
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
    """Wraps a diffrax solver; after each step updates every force element's state with its
    ``after_step`` (for a clearance joint, the impact-memory rule of
    :mod:`jaxclear.elements.memory`). When an element's force law changed during a step (a
    contact onset) the next step re-evaluates its first stage, so FSAL solvers stay exact.
    ``args`` of the solve must be a :class:`~jaxclear.integrate._system.AbstractSystem` (its
    ``after_step`` is the update: the packed state of :meth:`State.pack`, or that state with its
    tangents).

    With ``dense_to_controller`` the step's error estimate is handed on as the pair ``(error
    estimate, dense output)``, for :class:`~jaxclear.integrate._sampling.SampleWriter`, which
    writes the output samples of each accepted step (the controller must be one)."""

    solver: diffrax.AbstractSolver
    dense_to_controller: bool = eqx.field(static=True, default=False)


    @property
    def scan_kind(self):
        # DirectAdjoint/ForwardMode want a "bounded" scan; ThroughLoop.solver sets it on the inner solver.
        return getattr(self.solver, "scan_kind", None)


    def init(self, terms, t0, t1, y0, args):
        return self.solver.init(terms, t0, t1, y0, args), jnp.zeros((), bool)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        inner_state, memory_changed = solver_state
        y1, y_error, dense_info, inner_state, result = self.solver.step(
            terms, t0, t1, y0, args, inner_state, made_jump | memory_changed
        )
        y1_new, changed = args.after_step(t0, y0, t1, y1)
        # the memory jumps at the onset inside the step (or is the rate at the step's end out of
        # contact): the dense output of the step carries the updated memory throughout, so
        # output samples inside a crossing step read the new onset time and approach speed
        # (interpolations reproduce a common shift of their end values). Where a component
        # jumped, its end values are the new one minus the step's own change, not the old one
        # plus the jump: the jump away from the sentinel contact_start (-1e9 s) would keep only
        # ~1e-7 s of the onset (a sample before the onset read it up to 43 ns off); a memory
        # field is constant over a step, so its dense output is then exactly the new value.
        moved = y1_new != y1
        dense_info = {k: (jnp.where(moved, y1_new - (y1 - v) if k == "y0" else y1_new, v) if k in ("y0", "y1") else v)
                      for k, v in dense_info.items()}
        if self.dense_to_controller:
            y_error = (y_error, dense_info)
        return y1_new, y_error, dense_info, (inner_state, changed), result

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)


class AbstractDelegatingController(diffrax.AbstractAdaptiveStepSizeController):
    """A step-size controller that wraps ``inner`` and takes its tolerances and norm: the base
    of :class:`AbstractWrappedController` and of
    :class:`~jaxclear.integrate._sampling.SampleWriter`."""

    inner: eqx.AbstractVar[diffrax.AbstractAdaptiveStepSizeController]

    @property
    def rtol(self):
        return self.inner.rtol

    @property
    def atol(self):
        return self.inner.atol

    @property
    def norm(self):
        return self.inner.norm

    def wrap(self, direction):
        return eqx.tree_at(lambda c: c.inner, self, self.inner.wrap(direction))


class AbstractWrappedController(AbstractDelegatingController):
    """A step-size controller that delegates to ``inner`` (tolerances, norm, initial step) and
    changes only :meth:`adapt_step_size`: the base of :class:`OnsetController` and
    :class:`StopOnNonFinite`. Its state is ``(inner state, retries)``: the count of candidate
    steps the wrapper has rejected in a row (0 at the start)."""

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        t1_, state = self.inner.init(terms, t0, t1, y0, dt0, args, func, error_order)
        return t1_, (state, jnp.zeros((), jnp.int32))


#: Consecutive non-finite candidate steps that :class:`StopOnNonFinite` retries, each with
#: :data:`NONFINITE_SHRINK` times the length of the last, before it ends the solve.
MAX_NONFINITE = 4
NONFINITE_SHRINK = 0.2


class StopOnNonFinite(AbstractWrappedController):
    """A step-size controller that delegates to ``inner`` (a :class:`diffrax.PIDController`)
    and ends the solve when a candidate state is not finite :data:`MAX_NONFINITE` + 1 times in a
    row, each retry from the same point with :data:`NONFINITE_SHRINK` (diffrax's smallest
    factor, 0.2) times the last length (diffrax would otherwise retry until ``max_steps``, with
    a step size computed from a non-finite error). The retries are for a first step that the
    initial step-size heuristic overestimates (the ``persson`` law on the benchmark: a 10 ms
    first step, 0.83 of the revolution, whose candidate overflows; 2 ms is finite); a state that
    is not finite at any step length ends the solve after 5 tries. The solve then reports
    ``diffrax.RESULTS.dt_min_reached``, which :func:`~jaxclear.simulate` maps to
    ``nonfinite_state``.

    Being the wrapper next to the PID controller, it also hands the step's error estimate to the
    system's :meth:`~jaxclear.integrate._system.AbstractSystem.weigh_error` before the PID
    controller scales it (diffrax takes one scalar ``atol``; a Lyapunov run's tangents need
    their own)."""

    inner: diffrax.AbstractAdaptiveStepSizeController

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        inner_state, fails = controller_state
        # the system's own weighing of the error (AbstractSystem.weigh_error) before the
        # controller scales it by atol + rtol |y|
        y_error = args.weigh_error(y0, y1_candidate, y_error, self.inner.rtol, self.inner.atol)
        keep, tprev, tnext, jump, state, result = self.inner.adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, inner_state
        )
        finite = jnp.all(jnp.isfinite(y1_candidate))
        fails = jnp.where(finite, 0, fails + 1)
        # a non-finite candidate: retried from t0, shorter; the inner state is left as it was
        # (its error history would be non-finite)
        tprev = jnp.where(finite, tprev, t0)
        tnext = jnp.where(finite, tnext, t0 + NONFINITE_SHRINK * (t1 - t0))
        state = jax.tree_util.tree_map(lambda new, old: jnp.where(finite, new, old), state, inner_state)
        result = diffrax.RESULTS.where(fails <= MAX_NONFINITE, result, diffrax.RESULTS.dt_min_reached)
        return keep & finite, tprev, tnext, jump & finite, (state, fails), result


#: Retries of one step that :class:`OnsetController` may ask for in a row to locate a switch
#: (one suffices for a smooth penetration; the bound keeps a kinked one from stalling the solve).
MAX_SPLITS = 3


class OnsetController(AbstractWrappedController):
    r"""Step-size controller for exact contact switches: delegates to ``inner`` and, when a
    candidate step ``[t0, t0 + h]`` must be split at the fraction ``s`` (the earliest contact
    onset or separation over the force elements, :meth:`AbstractForceElement.onset
    <jaxclear.elements.base.AbstractForceElement.onset>`: sign changes of the cubic Hermite
    interpolant of the penetration, :func:`~jaxclear.elements.memory.onset_fraction`), rejects
    it and proposes :math:`\min(h_{inner}, s h (1 + \epsilon))` (:data:`~jaxclear.elements.memory.ONSET_MARGIN`
    :math:`\epsilon`). The accepted step then ends just past the switch: past an onset, the
    memory rule (:class:`ImpactMemorySolver`) stores the approach speed at the onset before the
    contact force grows; past a separation, the force's kink lies at a step boundary and a free
    flight between two contacts ends a step, so its re-contact is counted as an impact. This is
    the event location of an event-restart integrator (restarted at every onset and
    separation), as one more rejected step per switch. Like diffrax's controllers the step-size
    decision is not differentiated (``stop_gradient``). Branch-free (``where``), so under
    ``vmap`` it costs the elements' kinematics at both ends of each step.

    ``args`` of the solve must be a :class:`~jaxclear.integrate._system.AbstractSystem`; the
    onsets are those of its primal (mechanism) state."""

    inner: diffrax.AbstractAdaptiveStepSizeController

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        inner_state, splits = controller_state
        keep, tprev, tnext, jump, state, result = self.inner.adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, inner_state
        )
        mech = args.mech
        a, b = State.unpack(args.primal(y0), mech), State.unpack(args.primal(y1_candidate), mech)
        s = jnp.ones((), jnp.result_type(t1))
        split = jnp.zeros((), bool)
        if args.split_at_kinks:  # the accelerations at the step's start (the slips' rates)
            qdd0 = State.unpack(args.primal_rate(t0, y0), mech).qdot
        for element, state0 in zip(mech.clearance_joints, a.elements):
            found = [element.onset(mech, t0, a.q, a.qdot, t1, b.q, b.qdot, state0)]
            if args.split_at_kinks:
                found.append(element.kinks(mech, t0, a.q, a.qdot, qdd0, t1, b.q, b.qdot, state0))
            for s_e, split_e in found:
                s = jnp.minimum(s, jnp.where(split_e, s_e, 1.0))
                split = split | split_e
        eps = ONSET_MARGIN
        split = split & jnp.all(jnp.isfinite(args.primal(y1_candidate)))
        h = t1 - t0
        dt_inner = tnext - tprev
        dt_split = jax.lax.stop_gradient(jnp.minimum(dt_inner, s * h * (1.0 + eps)))
        split = split & (t0 + dt_split > t0)  # never a step below the resolution of t
        floor = args.dtmin()
        if floor is not None:  # nor below the system's shortest step: the switch is taken at the start
            split = split & (dt_split >= floor)
        # a switch that moves with the step (a penetration with kinks, e.g. the deepest of a
        # profile's Gauss points) is located at most MAX_SPLITS times in a row, then accepted
        split = split & (splits < MAX_SPLITS)
        tprev = jnp.where(split, t0, tprev)
        tnext = jnp.where(split, t0 + dt_split, tnext)
        accepted = keep & ~split
        splits = jnp.where(split, splits + 1, jnp.where(accepted, 0, splits))
        return accepted, tprev, tnext, jump & ~split, (state, splits), result
