r"""Output samples written inside the integration loop, a block of them per accepted step.

diffrax's ``SaveAt(ts=...)`` writes one sample per iteration of a ``while_loop`` nested in every
step (the interpolant evaluated at one time, two row writes): on XLA:CPU about a dozen kernel
launches per sample, 0.8 us on the benchmark machine, so that a grid of 24,001 samples per
crank revolution (19 per step) cost more than the integration itself. :class:`SampleWriter`
writes all of a step's samples at once: it wraps the step-size controller (the one place that
sees whether a step is accepted and keeps a state that diffrax passes on without selecting it
whole at every step), evaluates the step's interpolant at up to :data:`BLOCK` sample times in
one vectorised call and gathers the rows into whole blocks of its buffer (:class:`Samples`).
So that one block always suffices, it ends a step no later than the :data:`BLOCK`-th unwritten
sample (a long step on a dense grid is cut there, as diffrax's ``step_ts`` would cut it). Its
cost per step (the block's interpolation and the gathering, about 10 us on the benchmark with
XLA's kernel-per-operation runtime) makes it pay only from about 10 samples per step there;
with jaxclear's single-kernel loops (``jaxclear/_xla_flags.py``) diffrax's saving is faster on
every grid measured (``benchmarks/README.md``, "Settings' measured choices"), so
``Settings(output=SampleBlock())`` (:class:`~jaxclear.integrate.SampleBlock`) is opt-in.

The step's interpolant comes from the solver (:class:`~jaxclear.integrate.ImpactMemorySolver`
with ``dense_to_controller``, which hands its dense output to the controller beside the error
estimate), so samples read what diffrax's own saving would read: the same interpolation class
on the same coefficients, the memory of the step's end included (equal to rounding; a test).

The buffer is a buffer of the integration loop in ``equinox.internal.while_loop``'s sense (each
row written once, so reverse mode neither checkpoints it nor copies it at every step): the
adjoints of :func:`adjoint` declare it to diffrax's loop beside diffrax's own save buffers.
Without that, reverse mode through a run of 12,001 samples took 10 times as long and 4 times
the memory.

Written by hand because diffrax has no place for it: its solver state is selected whole at
every step (a buffer there would be copied at every step), and its saving loop is fixed.
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, Float, Int
from ._solvers import AbstractDelegatingController

#: Most output samples one accepted step writes (its interpolant evaluated at once, vectorised);
#: a step is ended no later than the BLOCK-th unwritten sample. Measured 2026-11-25 on the
#: benchmark slider-crank, one revolution, 24,001 samples: 1798, 1295 and 1166 steps (the cut
#: steps) and 60.7, 50.5 and 46.1 ms with 16, 32 and 64; at 241 samples 25.2, 26.7 and 29.0 us
#: per step (diffrax's loop: 22-24 us).
BLOCK = 64


class Samples(eqx.Module):
    """The output buffer, the rows being gathered and the rows of the last step.

    Rows are assigned to accepted steps in order; a step's rows are computed when it is
    attempted (``pending``), moved into ``staging`` at the next call once the step is known to
    be accepted, and written to the buffer a whole block of ``block`` rows at a time, once the
    block is complete. So every row of the buffer is written once, with one
    ``dynamic_update_slice`` per block (what the loop's buffer semantics need in reverse mode;
    a scatter of single rows compiles to a loop over them on XLA:CPU).

    Attributes:
        values: (nb + 1, block, N) blocks of rows of the packed state at the output times (the
            last block a bin for the steps that complete none).
        count: number of rows assigned to accepted steps.
        start: rows ``start ... count - 1`` belong to the last attempted step (accepted).
        pending: (block, N) the last attempted step's interpolant at the times of rows
            ``start ...``.
        staging: (2 block, N) rows gathered so far of blocks ``start // block`` and the next.
    """

    values: Float[Array, "nb B N"]
    count: Int[Array, ""]
    start: Int[Array, ""]
    pending: Float[Array, "B N"]
    staging: Float[Array, "2B N"]


class SampleWriter(AbstractDelegatingController):
    r"""A step-size controller that delegates to ``inner`` and writes the output samples of
    every accepted step (module docstring). ``y_error`` of the solver's step must be the pair
    ``(error estimate, dense output)`` (:class:`~jaxclear.integrate.ImpactMemorySolver`
    with ``dense_to_controller=True``); ``inner`` sees the error estimate only. The state is
    ``(inner state, Samples)``; :meth:`samples` reads the outputs off the final state.

    Attributes:
        inner: the step-size controller that decides.
        ts: output times (T,) [s], sorted, inside ``[t0, t1]`` of the solve.
        interpolation: the solver's interpolation class (``solver.interpolation_cls``).
        block: most samples per step (:data:`BLOCK`; at most T are used).
    """

    inner: diffrax.AbstractAdaptiveStepSizeController
    ts: Float[Array, " T"]
    interpolation: type = eqx.field(static=True)
    block: int = eqx.field(static=True, default=BLOCK)

    @property
    def _size(self) -> tuple[int, int, int]:
        """Samples T, rows per block, blocks."""
        n = self.ts.shape[0]
        b = min(self.block, n)
        return n, b, -(-n // b)

    def _limit(self, tnext, count):
        """``tnext`` cut at the ``block``-th unwritten sample (so a step holds at most ``block``)."""
        n, b, _ = self._size
        last = count + b - 1
        return jnp.where(last < n, jnp.minimum(tnext, self.ts[jnp.minimum(last, n - 1)]), tnext)

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        tnext, state = self.inner.init(terms, t0, t1, y0, dt0, args, func, error_order)
        n, b, nb = self._size
        dtype, width = jnp.result_type(y0), jnp.size(y0)
        zero = jnp.zeros((), jnp.int32)
        samples = Samples(jnp.full((nb + 1, b, width), jnp.inf, dtype), zero, zero, jnp.zeros((b, width), dtype),
                          jnp.zeros((2 * b, width), dtype))
        return self._limit(tnext, zero), (state, samples)

    def _gather(self, samples: Samples):
        """The pending rows moved into ``staging``; a completed block written. Returns
        ``(values, staging, filled)``, ``filled`` the block that ``staging`` then begins with.
        Staging begins at block ``start // block`` (a step's rows, at most a block, complete at
        most that one). The pending rows past ``count`` are zeros (rows that a later step fills
        in; their cotangents, if any, end at these constants)."""
        _, b, nb = self._size
        filled = samples.start // b
        rows = jnp.where((samples.start + jnp.arange(b) < samples.count)[:, None], samples.pending, 0.0)
        offset = (samples.start - filled * b, jnp.zeros((), jnp.int32))
        staging = jax.lax.dynamic_update_slice(samples.staging, rows, offset)
        complete = samples.count >= (filled + 1) * b
        values = samples.values.at[jnp.where(complete, filled, nb)].set(staging[:b])
        staging = jnp.where(complete, jnp.concatenate([staging[b:], jnp.zeros_like(staging[b:])]), staging)
        return values, staging, filled + complete.astype(jnp.int32)

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        inner_state, samples = controller_state
        y_error, dense_info = y_error
        # the last step's rows go in now, when its acceptance is a carried number (the count):
        # fused into the rows directly, the accept decision (the controllers' root brackets)
        # was recomputed per row in a vmapped run, or, fused into scatter indices, made an
        # expression that LLVM took minutes to vectorise
        values, staging, _ = self._gather(samples)
        keep, tprev, tnext, jump, state, result = self.inner.adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, inner_state
        )
        n, b, _ = self._size
        index = samples.count + jnp.arange(b, dtype=jnp.int32)
        times = self.ts[jnp.minimum(index, n - 1)]
        inside = (index < n) & (times <= t1)
        rows = jax.vmap(self.interpolation(t0=t0, t1=t1, **dense_info).evaluate)(times)
        count = samples.count + jnp.where(keep, jnp.sum(inside, dtype=jnp.int32), 0)
        new = Samples(values, count, samples.count, rows.astype(staging.dtype), staging)
        return keep, tprev, self._limit(tnext, count), jump, (state, new), result

    def samples(self, final_state, y0, ran) -> Float[Array, "T N"]:
        """The output rows (T, N) from the controller's final state (the last step's rows and
        the partly filled blocks written): rows not written are ``inf`` (after a failed step,
        as diffrax leaves them), or ``y0`` where the run had zero length (``ran`` False:
        diffrax takes no step, and every sample is the start)."""
        samples = final_state[1]
        n, b, nb = self._size
        values, staging, filled = self._gather(samples)
        values = values.at[filled].set(staging[:b]).at[jnp.minimum(filled + 1, nb)].set(staging[b:])
        values = values[:nb].reshape(nb * b, -1)[:n]
        values = jnp.where((jnp.arange(n) < samples.count)[:, None], values, jnp.inf)
        return jnp.where(ran, values, jnp.broadcast_to(y0, values.shape))


def _loop_with_samples(loop):
    """diffrax's integration loop whose outer ``while_loop`` also treats the sample buffer of a
    :class:`SampleWriter` (the controller state's ``[1].values``) as a buffer."""

    def wrapped(*, outer_while_loop, **kwargs):
        def outer(cond_fun, body_fun, init_val, *, buffers, **kw):
            def with_samples(state):
                return [buffers(state), state.controller_state[1].values]  # Samples.values

            return outer_while_loop(cond_fun, body_fun, init_val, buffers=with_samples, **kw)

        return loop(outer_while_loop=outer, **kwargs)

    return wrapped


class RecursiveCheckpointAdjoint(diffrax.RecursiveCheckpointAdjoint):
    """diffrax's adjoint of the same name, with :class:`SampleWriter`'s buffer declared."""

    @property
    def _loop(self):
        return _loop_with_samples(super()._loop)


class ForwardMode(diffrax.ForwardMode):
    """diffrax's adjoint of the same name, with :class:`SampleWriter`'s buffer declared."""

    @property
    def _loop(self):
        return _loop_with_samples(super()._loop)


class DirectAdjoint(diffrax.DirectAdjoint):
    """diffrax's adjoint of the same name, with :class:`SampleWriter`'s buffer declared."""

    @property
    def _loop(self):
        return _loop_with_samples(super()._loop)


def adjoint(kind: str, checkpoints: int | None = None, block: bool = True) -> diffrax.AbstractAdjoint:
    """diffrax's adjoint ``kind`` (``"recursive"`` with ``checkpoints``, ``"forward"``,
    ``"direct"``; :class:`~jaxclear.integrate.ThroughLoop`); with ``block`` the one that
    declares a :class:`SampleWriter`'s buffer."""
    if kind == "forward":
        return ForwardMode() if block else diffrax.ForwardMode()
    if kind == "direct":
        return DirectAdjoint() if block else diffrax.DirectAdjoint()
    cls = RecursiveCheckpointAdjoint if block else diffrax.RecursiveCheckpointAdjoint
    return cls(checkpoints=checkpoints)
