r"""Integration with diffrax: :func:`simulate`, the one pure function that sweeps ``vmap`` and
fits differentiate.

Data path: mechanism and settings -> consistent start state (:mod:`.assembly`) -> packed state
vector (:mod:`.state`) -> vector field (forces -> augmented solve, :mod:`.dynamics`) ->
diffrax with the element-state solver wrapper (:mod:`.solvers`) -> post-processing on the
output grid -> :class:`~jaxclear.integrate.Solution` with a :class:`~jaxclear.RESULTS`
status.

Speed: the module docstring of :mod:`jaxclear.integrate._solve` (one packed vector, diffrax's
stage loop, XLA's options; ``benchmarks/bench_engine.py --profile`` measures each part).
"""

from __future__ import annotations

import dataclasses
import types

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import RESULTS, JaxclearError, ParameterError, SolverError, invalid_codes, is_concrete, status_message
from .._errors import STATUS
from ..model.mechanism import Mechanism
from . import _solve as solve
from ._assembly import ASSEMBLY_TEMPLATE, check_assembly
from ._compile import jit
from ._sensitivity import tangent_run
from ._settings import Settings, check_settings
from ._solution import Solution
# not used here, read from here: by _kinematics.py, tests/test_output.py, tests/test_sampling.py, and through the
# deprecated old path jaxclear.integrate.simulate (this package's _OldPath) for one release
from ._solve import POSTPROCESS_BATCH, output_grid  # noqa: F401
from ._state import State


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
    begin = solve.start_run(mech, s, y0)
    return solve.run(mech, s, begin)[0], begin.assembly


def _solution(mech: Mechanism, s: Settings, y0: State | None) -> Solution:
    return _run(mech, s, y0)[0]


@jit
def _simulate(mech: Mechanism, s: Settings, y0: State | None) -> Solution:
    """The run as ``s.derivatives`` differentiates it: under the default
    :class:`~jaxclear.integrate.Sensitivity` its derivatives (``jax.jvp``,
    ``jax.jacfwd``, ``jax.grad``, ...) are the error-controlled sensitivities of
    :func:`~jaxclear.integrate._sensitivity.tangent_run`."""
    return s.derivatives.differentiable(_solution, tangent_run)(mech, s, y0)


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
    without compiling it: :func:`~jaxclear.integrate.simulate_with_ideal` does this before
    it starts the ideal-joint run in a second thread, so that run's tracing overlaps this run's
    XLA compilation (which releases Python's lock) rather than its tracing."""
    if is_concrete((mech, s)):
        program, name, _, args = _concrete_call(mech, s)
        program.prepare(name, *args)


def check_status(value, status, s: Settings, what: str = "", mech: Mechanism | None = None):
    """``value``, once the run whose ``Solution.status`` is ``status`` is known to have succeeded
    (with ``s.throw``; without, ``value`` unchanged and the status left to the caller).

    A concrete status (a plain call; also ``jax.jacfwd``, ``jax.grad`` or ``jax.jvp`` called
    eagerly, where JAX hands integer outputs back as plain arrays) is checked here, in Python,
    after the compiled program returned: :func:`raise_for_status`. A traced one (inside a user's
    ``jax.jit`` or ``jax.vmap``) is guarded with ``equinox.branched_error_if`` and the messages
    of :class:`~jaxclear.RESULTS`, in the program the user traces: the host callback it compiles
    to is never part of jaxclear's own compiled run, which JAX's persistent compilation cache
    would then not keep (it stores no program with a host callback)."""
    if not s.throw:
        return value
    if is_concrete(status):
        raise_for_status(types.SimpleNamespace(status=status), s, what, mech)
        return value
    messages = [STATUS[code] for code in range(len(STATUS))]
    return eqx.branched_error_if(value, status != int(RESULTS.successful._value), status, messages)


def simulate(mech: Mechanism, s: Settings, y0: State | None = None) -> Solution:
    """Integrate ``mech`` with settings ``s``; pure, so ``jax.jit``, ``jax.vmap`` and
    ``jax.grad`` (of a scalar of the result) apply to it.

    With ``s.throw`` (default) a failed run raises: with concrete inputs a
    :class:`~jaxclear.SolverError` (after :func:`check_assembly`'s detailed checks) naming the
    :class:`~jaxclear.RESULTS` entry and what to change; the same under ``jax.jacfwd``,
    ``jax.grad`` or ``jax.jvp`` called eagerly (the status comes back concrete); inside a user's
    ``jax.jit`` or ``jax.vmap`` the same entry through ``equinox.error_if`` in the user's program
    (:func:`check_status`). The compiled run itself never holds that check, so JAX's persistent
    compilation cache can keep it. With ``s.throw`` False the status is reported in
    ``Solution.status`` and nothing raises (sweeps); with concrete inputs the run is the same
    compiled program as with ``s.throw`` (one compilation for both, the same numbers).

    Args:
        mech: the mechanism (structure + parameters).
        s: :class:`Settings`.
        y0: optional start :class:`~jaxclear.integrate.State`; default: assembled by
            :func:`~jaxclear.assemble`.
    """
    check_settings("simulate", s, required=True, name="s")
    if not is_concrete((mech, s, y0)):
        sol = _simulate(mech, s, y0)
        return check_status(sol, sol.status, s, mech=mech)
    # concrete: one program whatever s.throw (the checks run here, after it)
    if y0 is None:
        program, name, structure, args = _concrete_call(mech, s)
        sol, asm = program.stored(name, structure, *args)
        if s.throw:
            check_assembly(mech, s, asm)  # its detailed messages take precedence over the run's status
    else:
        quiet = dataclasses.replace(s, throw=False)
        sol = _simulate.stored("simulate-from-state", lambda: solution_structure(mech), mech, quiet, y0)
    if s.throw:
        raise_for_status(sol, s, mech=mech)
    return sol


def raise_for_status(result, s: Settings, what: str = "", mech: Mechanism | None = None,
                     error: type[JaxclearError] = SolverError) -> None:
    """Raise for a concrete result whose ``status`` (a :class:`~jaxclear.RESULTS` code: a
    :class:`Solution`'s, a :class:`~jaxclear.chaos.LyapunovResult`'s) is not successful: a
    :class:`~jaxclear.ParameterError` for an ``invalid_*`` status (a parameter outside its
    range), else ``error`` (:class:`~jaxclear.SolverError`; the Lyapunov driver's own
    :class:`~jaxclear.chaos.LyapunovError`); the message is the status's text with its remedy
    (``what`` appended). Given the concrete ``mech`` of the run, an ``invalid_*`` status is
    told by the check that failed (:meth:`~jaxclear.Mechanism.failed_check`: the body or element,
    the number, its value, the rule) instead of the status's list of rules. The one
    ``raise_for_status`` of jaxclear."""
    code = int(result.status)
    if code in invalid_codes():
        failed = mech.failed_check() if mech is not None and is_concrete(mech) else None
        told = f"invalid parameter: {failed}" if failed is not None else status_message(code)
        raise ParameterError(f"jaxclear: {told}{what}")
    if code != int(RESULTS.successful._value):
        raise error(f"jaxclear: {status_message(code, max_steps=s.max_steps)}{what}")
