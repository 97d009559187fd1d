r"""Dense output on the uniform grid: samples written several per loop iteration.

diffrax writes ``SaveAt(ts=...)`` samples inside its step loop, one iteration of an inner
``while_loop`` per sample (evaluate the step's interpolant at ``t_i``, write row ``i``). For
the small state of a planar mechanism the loop bookkeeping of that iteration costs more than
the interpolation itself (about 2.7 us per sample on the benchmark slider-crank, against
about 40 us per solver step), so a fine grid (24,001 samples over one crank revolution,
about 23 samples per step) more than doubled the run time.

:func:`chunked_adjoint` returns the same diffrax adjoint whose inner save loop runs
:data:`SAMPLES_PER_ITERATION` sample writes per iteration, unconditionally, and then sets the
sample counter to the number of those samples that really lie in the step (the times are
sorted, so they are the first ones). Samples written beyond the step's end hold the step's
extrapolation only until the step that contains them overwrites them (every later write
goes to a row at or after the counter); writes past the last row are dropped. Each sample's
final value is therefore the same interpolant at the same time as diffrax's, to rounding
(a test checks equality).
"""

from __future__ import annotations

import contextlib

import diffrax
import diffrax._integrate
import jax.numpy as jnp
from diffrax._integrate import SaveState  # the inner save loop's carry (diffrax internals, pinned)

#: Sample writes per iteration of the inner save loop. 8 keeps the cost of a step that holds a
#: single sample small and cuts the loop overhead of dense grids about eightfold.
SAMPLES_PER_ITERATION = 8


def _chunked_inner_loop(inner_while_loop, k: int):
    def loop(cond_fun, body_fun, init_val, *, max_steps, buffers, checkpoints=None, **kwargs):
        if not isinstance(init_val, SaveState):  # not the save loop: unchanged
            return inner_while_loop(cond_fun, body_fun, init_val, max_steps=max_steps, buffers=buffers,
                                    checkpoints=checkpoints, **kwargs)

        def body(state: SaveState) -> SaveState:
            n, s = jnp.zeros_like(state.saveat_ts_index), state
            for _ in range(k):
                n = n + cond_fun(s).astype(n.dtype)
                s = body_fun(s)
            return SaveState(saveat_ts_index=state.saveat_ts_index + n, ts=s.ts, ys=s.ys,
                             save_index=state.save_index + n.astype(jnp.result_type(state.save_index)))

        iterations = -(-max_steps // k)
        return inner_while_loop(cond_fun, body, init_val, max_steps=iterations, buffers=buffers,
                                checkpoints=iterations, **kwargs)
    return loop


def _with_chunked_loop(base_loop, k):
    def loop(*, inner_while_loop, **kwargs):
        return base_loop(inner_while_loop=_chunked_inner_loop(inner_while_loop, k), **kwargs)
    return loop


class ChunkedRecursiveCheckpointAdjoint(diffrax.RecursiveCheckpointAdjoint):
    """:class:`diffrax.RecursiveCheckpointAdjoint` with the chunked save loop."""

    @property
    def _loop(self):
        return _with_chunked_loop(super()._loop, SAMPLES_PER_ITERATION)


class ChunkedDirectAdjoint(diffrax.DirectAdjoint):
    """:class:`diffrax.DirectAdjoint` with the chunked save loop."""

    @property
    def _loop(self):
        return _with_chunked_loop(super()._loop, SAMPLES_PER_ITERATION)


class ChunkedForwardMode(diffrax.ForwardMode):
    """:class:`diffrax.ForwardMode` with the chunked save loop."""

    @property
    def _loop(self):
        return _with_chunked_loop(super()._loop, SAMPLES_PER_ITERATION)


class _ChecksOff:
    """``equinox.internal`` as diffrax's integrator sees it, with ``error_if`` returning its
    argument unchanged (see :func:`without_input_callbacks`)."""

    def __init__(self, module):
        self._module = module

    def __getattr__(self, name):
        return getattr(self._module, name)

    @staticmethod
    def error_if(x, pred, msg, **kwargs):
        return x


@contextlib.contextmanager
def without_input_callbacks():
    """While tracing ``diffrax.diffeqsolve``: its run-time input checks (``dt0`` sign,
    ``SaveAt.ts`` sorted and inside ``[t0, t1]``) are left out.

    Each such check is an ``equinox.error_if`` with a traced predicate, compiled as a host
    callback, and JAX never writes a program with host callbacks to its persistent compilation
    cache: with them :func:`jaxclear.simulate` was recompiled in every new process (the command
    line's startup). :func:`~jaxclear.integrate.simulate.simulate` builds inputs that satisfy
    the checks by construction (a sorted grid clipped to ``[t0, t1]``, ``dt0`` > 0 or None).
    Only diffrax's integrator module is affected, and only during the ``with`` block (the
    trace); the result of the solve is still checked (:class:`~jaxclear.RESULTS`)."""
    module = diffrax._integrate
    saved = module.eqxi
    module.eqxi = _ChecksOff(saved)
    try:
        yield
    finally:
        module.eqxi = saved
