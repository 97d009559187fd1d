r"""The parts of :class:`~jaxclear.Settings` that choose *how* a run is integrated, each a small
equinox module that owns its behaviour (diffrax's own design: an adjoint, a solver, a step-size
controller are objects, not names):

* the solver: a diffrax Runge-Kutta solver instance (:data:`SOLVERS` by name), its stages in
  diffrax's stage loop, or unrolled by :class:`~jaxclear.integrate.UnrolledExplicitRK`;
* the derivatives (:class:`AbstractDerivatives`): :class:`Sensitivity`, the error-controlled
  forward sensitivities (the default), or :class:`ThroughLoop`, JAX's derivative through diffrax's
  integration loop;
* the output sampling (:class:`AbstractSampling`): :class:`SampleLoop`, diffrax's saving (the
  default), or :class:`SampleBlock`, a step's samples written at once;
* the contact onsets (:class:`AbstractOnsets`): :class:`ExactOnsets` (the default) or
  :class:`StepOnsets`.

The integration (:func:`~jaxclear.integrate.integrate_system`, :func:`~jaxclear.simulate`) asks
these objects what to do instead of branching on names. Every field is static: a strategy is part
of a compiled program's structure (and of the key of the store of traced programs), never an
input. Names are still accepted where settings are written by hand (``jc.settings(adjoint=
"forward")``, the command line, sweep files): :func:`from_names` converts them, the one place.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, ClassVar

import diffrax
import equinox as eqx
import numpy as np

from .._errors import ParameterError
from ._sampling import BLOCK, SampleWriter
from ._sampling import adjoint as sampling_adjoint
from ._solvers import OnsetController, UnrolledExplicitRK

SOLVERS = {
    "tsit5": diffrax.Tsit5,
    "dopri5": diffrax.Dopri5,
    "dopri8": diffrax.Dopri8,
    "bosh3": diffrax.Bosh3,
    "kvaerno5": diffrax.Kvaerno5,
}
"""Solver name (``Settings(solver=NAME)``) -> diffrax solver class."""

#: The derivatives by name (the old ``Settings(adjoint=...)``): the error-controlled
#: sensitivities, then diffrax's adjoints through its loop.
ADJOINTS = ("sensitivity", "recursive", "forward", "direct")
#: diffrax's adjoints through its loop (:class:`ThroughLoop`'s ``adjoint``).
LOOP_ADJOINTS = ADJOINTS[1:]


# ---------------------------------------------------------------------------------------------
# derivatives


class AbstractDerivatives(eqx.Module):
    """How the derivatives of a run (``jax.jvp``, ``jax.jacfwd``, ``jax.grad``, ``jax.vjp``) are
    computed."""

    @property
    def name(self) -> str:
        """The old name of this choice (``Settings(adjoint=NAME)``)."""
        raise NotImplementedError

    def differentiable(self, run: Callable, rule: Callable) -> Callable:
        """``run(mech, settings, y0) -> Solution`` as JAX differentiates it under this choice;
        ``rule`` is the error-controlled JVP rule
        (:func:`~jaxclear.integrate._sensitivity.tangent_run`)."""
        raise NotImplementedError

    def solver(self, solver: diffrax.AbstractSolver) -> diffrax.AbstractSolver:
        """The solver as the integration loop runs it (its stage loop made differentiable where
        this choice differentiates through it)."""
        raise NotImplementedError

    def loop_adjoint(self, output: AbstractSampling) -> diffrax.AbstractAdjoint:
        """The diffrax adjoint handed to ``diffeqsolve`` (the one that knows ``output``'s
        buffers)."""
        raise NotImplementedError

    def for_mode(self, mode: str) -> AbstractDerivatives:
        """This choice for a derivative taken in ``mode`` (``"forward"``: ``jax.jacfwd``,
        ``"reverse"``: ``jax.grad``), as :func:`~jaxclear.parameter_grad` takes it."""
        raise NotImplementedError


class Sensitivity(AbstractDerivatives):
    """The error-controlled forward sensitivities (:mod:`jaxclear.integrate._sensitivity`), the
    default: the tangents of the perturbed inputs are integrated with the state, take part in the
    step-size control and carry the memory rules' derivatives; reverse mode costs one tangent per
    perturbed scalar input. Every JAX derivative of the run is this one.

    Attributes:
        tolerance: the sensitivity solve's ``rtol`` and ``atol`` are the values' times this [-],
            in (0, 1] (default 0.1): a derivative needs a tighter tolerance than a value to be
            smooth in the parameters, since the step sequence changes with them and a misfit's
            derivative is a sum whose terms cancel (measurements: ``benchmarks/README.md``,
            "Settings' measured choices"). The values of a plain run keep ``rtol``; those
            returned with derivatives come from the sensitivity solve.
    """

    tolerance: float = eqx.field(static=True, default=0.1, converter=float)

    def __check_init__(self):
        if not 0 < self.tolerance <= 1:
            raise ParameterError(f"Sensitivity tolerance = {self.tolerance:g} outside the allowed range (0, 1]")

    @property
    def name(self) -> str:
        return "sensitivity"

    def differentiable(self, run, rule):
        wrapped = eqx.filter_custom_jvp(run)
        wrapped.def_jvp(rule)
        return wrapped

    def solver(self, solver):
        return solver

    def loop_adjoint(self, output):
        # the loop is never differentiated: diffrax's default adjoint, its default checkpoints
        return output.adjoint("recursive", None)

    def for_mode(self, mode):
        return self

    def tolerances(self, rtol: float, atol: float) -> tuple[float, float]:
        """The sensitivity solve's ``(rtol, atol)`` for values at ``rtol``, ``atol``."""
        return rtol * self.tolerance, atol * self.tolerance


class ThroughLoop(AbstractDerivatives):
    """JAX's derivative through diffrax's integration loop: the derivative of the discretization
    whose steps were sized for the values only (after a contact ends it is off by 0.1 % to several
    times the derivative at the default tolerances and does not converge with them over several
    impacts: the sensitivities theory page, ``benchmarks/bench_gradients.py``).

    Attributes:
        adjoint: diffrax's adjoint: ``"recursive"`` (reverse mode with checkpoints,
            ``diffrax.RecursiveCheckpointAdjoint``), ``"forward"`` (forward mode,
            ``diffrax.ForwardMode``) or ``"direct"`` (``diffrax.DirectAdjoint``, both modes).
        checkpoints: number of checkpoints of ``"recursive"`` (``None``: diffrax's default,
            logarithmic in ``max_steps``); fewer checkpoints = less memory, more recomputation.
            Only with ``adjoint="recursive"``.
    """

    adjoint: str = eqx.field(static=True, default="recursive")
    checkpoints: int | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.adjoint not in LOOP_ADJOINTS:
            raise ParameterError(f"ThroughLoop adjoint must be one of {list(LOOP_ADJOINTS)}, got {self.adjoint!r}")
        if self.checkpoints is not None:
            if self.adjoint != "recursive":
                raise ParameterError(f"checkpoints = {self.checkpoints!r} is a setting of adjoint='recursive' only "
                                     f"(got adjoint={self.adjoint!r}); leave it None")
            if isinstance(self.checkpoints, bool) or not isinstance(self.checkpoints, int) or self.checkpoints < 1:
                raise ParameterError(f"checkpoints = {self.checkpoints!r} outside the allowed range: an integer >= 1 "
                                     "or None")

    @property
    def name(self) -> str:
        return self.adjoint

    def differentiable(self, run, rule):
        return run

    def solver(self, solver):
        # forward mode and the direct adjoint differentiate a Runge-Kutta solver's stage loop in
        # its "bounded" form (unrolled stages have no loop)
        if self.adjoint in ("forward", "direct") and not isinstance(solver, UnrolledExplicitRK):
            return dataclasses.replace(solver, scan_kind="bounded")
        return solver

    def loop_adjoint(self, output):
        return output.adjoint(self.adjoint, self.checkpoints)

    def for_mode(self, mode):
        if mode == "forward":
            return ThroughLoop("forward")
        return ThroughLoop("recursive") if self.adjoint == "forward" else self


# ---------------------------------------------------------------------------------------------
# output sampling


class AbstractSampling(eqx.Module):
    """How the output samples at the grid times are written during the integration."""

    #: Whether the solver hands its dense output to the step-size controller
    #: (:class:`~jaxclear.integrate.ImpactMemorySolver`'s ``dense_to_controller``).
    dense_to_controller: ClassVar[bool] = False

    @property
    def name(self) -> str:
        """The old name of this choice (``Settings(sampling=NAME)``)."""
        raise NotImplementedError

    def saving(self, controller, ts, interpolation_cls):
        """``(step-size controller, diffrax.SaveAt)`` of a solve sampled at ``ts`` (T,) [s]."""
        raise NotImplementedError

    def samples(self, sol: diffrax.Solution, controller, y0, ran):
        """The (T, N) packed states at the output times from the solve's ``sol`` (``controller``
        as :meth:`saving` returned it; ``y0`` the start, ``ran`` whether the run had length)."""
        raise NotImplementedError

    def adjoint(self, kind: str, checkpoints: int | None) -> diffrax.AbstractAdjoint:
        """diffrax's adjoint ``kind`` (``"recursive"``, ``"forward"``, ``"direct"``) fit for
        this sampling's buffers."""
        raise NotImplementedError


class SampleLoop(AbstractSampling):
    """diffrax's saving, the default: ``SaveAt(ts=...)``, one sample per iteration of a loop
    inside each step (the faster form with jaxclear's single-kernel loops; measurements:
    ``benchmarks/README.md``, "Settings' measured choices")."""

    @property
    def name(self) -> str:
        return "loop"

    def saving(self, controller, ts, interpolation_cls):
        return controller, diffrax.SaveAt(ts=ts)

    def samples(self, sol, controller, y0, ran):
        return sol.ys

    def adjoint(self, kind, checkpoints):
        return sampling_adjoint(kind, checkpoints, block=False)


class SampleBlock(AbstractSampling):
    """All of a step's samples written at once by the step-size controller
    (:class:`~jaxclear.integrate._sampling.SampleWriter`), a step ending by its ``size``-th
    unwritten sample; pays where a step holds many samples and XLA runs a kernel per operation
    (``JAXCLEAR_SMALL_LOOP_BYTES=0``). The fits use it.

    Attributes:
        size: most samples one step writes [-], >= 1 (default
            :data:`~jaxclear.integrate._sampling.BLOCK`).
    """

    size: int = eqx.field(static=True, default=BLOCK)
    dense_to_controller: ClassVar[bool] = True

    def __check_init__(self):
        if isinstance(self.size, bool) or not isinstance(self.size, int) or self.size < 1:
            raise ParameterError(f"SampleBlock size = {self.size!r} outside the allowed range: an integer >= 1")

    @property
    def name(self) -> str:
        return "block"

    def saving(self, controller, ts, interpolation_cls):
        writer = SampleWriter(controller, ts, interpolation_cls, self.size)
        return writer, diffrax.SaveAt(t1=True, controller_state=True)

    def samples(self, sol, controller, y0, ran):
        return controller.samples(sol.controller_state, y0, ran)

    def adjoint(self, kind, checkpoints):
        return sampling_adjoint(kind, checkpoints, block=True)


# ---------------------------------------------------------------------------------------------
# contact onsets


class AbstractOnsets(eqx.Module):
    """How a step that crosses into contact is treated."""

    @property
    def name(self) -> str:
        """This choice's name (``Settings(onsets=NAME)``, the command line's ``--onsets``)."""
        raise NotImplementedError

    def controller(self, controller, mech):
        """The step-size controller of a run of ``mech``, ``controller`` wrapped as this choice
        needs."""
        raise NotImplementedError


class ExactOnsets(AbstractOnsets):
    """The step that crosses into contact ends just past the onset (a rejected step per onset,
    :class:`~jaxclear.integrate.OnsetController`), so the dissipative laws use the
    approach speed at the onset throughout the contact; the default (a mechanism without
    clearance joints runs as :class:`StepOnsets`)."""

    @property
    def name(self) -> str:
        return "exact"

    def controller(self, controller, mech):
        return OnsetController(controller) if mech.clearance_joints else controller


class StepOnsets(AbstractOnsets):
    """The onset is found after the step that crosses it, whose force used the approach speed of
    its start (a worn bearing's flickering Gauss-point contacts: :func:`~jaxclear.wear`)."""

    @property
    def name(self) -> str:
        return "step"

    def controller(self, controller, mech):
        return controller


# ---------------------------------------------------------------------------------------------
# names -> objects, the one place


def _solver(solver, stages):
    if isinstance(solver, str):
        if solver not in SOLVERS:
            raise ParameterError(f"unknown solver {solver!r}; valid: {sorted(SOLVERS)} (or a diffrax Runge-Kutta "
                                 "solver instance)")
        solver = SOLVERS[solver]()
    inner = solver.solver if isinstance(solver, UnrolledExplicitRK) else solver
    if not isinstance(inner, diffrax.AbstractRungeKutta):
        raise ParameterError(f"solver = {solver!r}: expected one of {sorted(SOLVERS)} or a diffrax Runge-Kutta "
                             "solver instance (optionally in jaxclear.UnrolledExplicitRK)")
    if stages is None:
        return solver
    if stages not in ("unrolled", "loop"):
        raise ParameterError(f"stages must be 'unrolled' or 'loop', got {stages!r}")
    if stages == "unrolled" and not inner.tableau.implicit:  # an implicit solver keeps its own loop
        return UnrolledExplicitRK(inner)
    return inner


def _derivatives(derivatives, adjoint, tolerance, checkpoints):
    if isinstance(derivatives, str):
        derivatives, adjoint = None, derivatives if adjoint is None else adjoint
    if derivatives is None:
        derivatives = Sensitivity()
    if not isinstance(derivatives, AbstractDerivatives):
        raise ParameterError(f"derivatives = {derivatives!r}: expected Sensitivity(...), ThroughLoop(...) or one of "
                             f"the names {list(ADJOINTS)}")
    if adjoint is not None and adjoint not in ADJOINTS:
        raise ParameterError(f"adjoint must be one of {list(ADJOINTS)}, got {adjoint!r}")
    if tolerance is not None and not 0 < tolerance <= 1:
        raise ParameterError(f"derivative_tolerance = {tolerance:g} outside the allowed range (0, 1]")
    if adjoint is None and tolerance is None and checkpoints is None:
        return derivatives
    kind = derivatives.name if adjoint is None else adjoint
    # an old keyword replaces its part of the derivatives (so that dataclasses.replace(s, adjoint=...)
    # keeps the rest); a part the chosen kind does not have is dropped, as it was ignored
    if kind == "sensitivity":
        if tolerance is None:
            tolerance = derivatives.tolerance if isinstance(derivatives, Sensitivity) else Sensitivity().tolerance
        return Sensitivity(tolerance)
    if checkpoints is None and isinstance(derivatives, ThroughLoop):
        checkpoints = derivatives.checkpoints
    return ThroughLoop(kind, checkpoints if kind == "recursive" else None)


OUTPUTS = {"loop": SampleLoop, "block": SampleBlock}
"""Output sampling by name (the old ``Settings(sampling=NAME)``) -> its class."""


def _output(output, name):
    if name is not None:
        output = name
    if output is None:
        return SampleLoop()
    if isinstance(output, str):
        if output not in OUTPUTS:
            raise ParameterError(f"sampling must be 'loop' or 'block', got {output!r}")
        return OUTPUTS[output]()
    if not isinstance(output, AbstractSampling):
        raise ParameterError(f"output = {output!r}: expected SampleLoop(), SampleBlock(...) or one of the names "
                             f"{list(OUTPUTS)}")
    return output


ONSETS = {"exact": ExactOnsets, "step": StepOnsets}
"""Contact onsets by name (``onsets="step"``: the command line's ``--onsets``, a ``[settings]``
table) -> its class."""


def _onsets(onsets, exact):
    if exact is not None:
        if not isinstance(exact, bool):
            raise ParameterError(f"exact_onsets must be True or False, got {exact!r}")
        return ExactOnsets() if exact else StepOnsets()
    if onsets is None:
        return ExactOnsets()
    if isinstance(onsets, str):
        if onsets not in ONSETS:
            raise ParameterError(f"onsets = {onsets!r}: expected ExactOnsets() or StepOnsets() (or one of the names "
                                 f"{list(ONSETS)})")
        return ONSETS[onsets]()
    if not isinstance(onsets, AbstractOnsets):
        raise ParameterError(f"onsets = {onsets!r}: expected ExactOnsets() or StepOnsets() (or one of the names "
                             f"{list(ONSETS)})")
    return onsets


def from_names(solver, derivatives, output, onsets, *, adjoint=None, derivative_tolerance=None, checkpoints=None,
               stages=None, exact_onsets=None, sampling=None):
    """``(solver, derivatives, output, onsets)`` of :class:`~jaxclear.Settings` from what was
    given: each either its object, a name (``solver="tsit5"``, ``derivatives="forward"``,
    ``output="block"``, ``onsets="step"``) or None (the default), and the old keywords, each of which replaces its
    part of the field it now belongs to:

    * ``adjoint``: one of :data:`ADJOINTS` (``"sensitivity"``: :class:`Sensitivity`, else
      :class:`ThroughLoop` with that adjoint);
    * ``derivative_tolerance``: in (0, 1], :class:`Sensitivity`'s ``tolerance`` (ignored through
      the loop, as before);
    * ``checkpoints``: :class:`ThroughLoop`'s (kept for ``"recursive"`` only);
    * ``stages``: ``"loop"`` (the solver itself) or ``"unrolled"`` (an explicit solver in
      :class:`~jaxclear.integrate.UnrolledExplicitRK`);
    * ``exact_onsets``: True (:class:`ExactOnsets`) or False (:class:`StepOnsets`);
    * ``sampling``: ``"loop"`` (:class:`SampleLoop`) or ``"block"`` (:class:`SampleBlock`).

    A bad name or value is a :class:`~jaxclear.ParameterError` naming the parameter and the
    allowed values."""
    if isinstance(exact_onsets, np.bool_):
        exact_onsets = bool(exact_onsets)
    return (_solver(solver, stages), _derivatives(derivatives, adjoint, derivative_tolerance, checkpoints),
            _output(output, sampling), _onsets(onsets, exact_onsets))


#: The old keywords of ``Settings(...)`` that :func:`from_names` converts.
OLD_KEYWORDS = ("adjoint", "derivative_tolerance", "checkpoints", "stages", "exact_onsets", "sampling")


def stages_name(solver) -> str:
    """The old ``Settings.stages`` of a solver: ``"unrolled"`` or ``"loop"``."""
    return "unrolled" if isinstance(solver, UnrolledExplicitRK) else "loop"
