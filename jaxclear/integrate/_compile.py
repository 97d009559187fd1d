"""Compilation of jaxclear's own functions: XLA options chosen for the small, scalar-heavy
kernels of a planar mechanism, applied only where JAX allows them (the outermost jit), and
programs free of host callbacks, so that JAX's persistent compilation cache can store them
(:func:`without_input_callbacks`)."""

from __future__ import annotations

import contextlib
import functools
import threading

import diffrax
import diffrax._integrate
import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import is_concrete
from . import _programs as programs

#: XLA options for jaxclear's own compiled functions. ``xla_cpu_use_fusion_emitters=False``
#: selects XLA:CPU's older elemental emitters for fused kernels; for the small scalar-heavy
#: kernels of a planar mechanism they compile in about half the time (benchmark slider-crank:
#: 7.3 s -> 4.2 s of XLA compilation) and run at least as fast. Other backends ignore it.
PREFERRED_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False, "xla_cpu_experimental_ynn_fusion_type": ""}


@functools.cache
def compiler_options() -> dict:
    """:data:`PREFERRED_COMPILER_OPTIONS` if this jaxlib accepts them (probed once with a
    trivial compilation), else ``{}``."""
    try:
        jax.jit(lambda x: x + 1, compiler_options=PREFERRED_COMPILER_OPTIONS)(jnp.zeros(()))
    except Exception:  # an XLA that no longer knows the option: compile with its defaults
        return {}
    return dict(PREFERRED_COMPILER_OPTIONS)


#: Called with the function's name whenever a :class:`jit` program is traced at top level (a
#: cache miss: JAX compiles it, or loads it from the persistent cache, next); see :func:`on_trace`.
_TRACE_LISTENERS: list = []


@contextlib.contextmanager
def on_trace(listener):
    """Within the block, ``listener(name)`` is called each time one of jaxclear's compiled
    programs (:class:`jit`, called on concrete arrays) is traced, i.e. is not in JAX's in-memory
    cache and is about to be compiled: the moment to say "compiling ...", and only then."""
    _TRACE_LISTENERS.append(listener)
    try:
        yield
    finally:
        _TRACE_LISTENERS.remove(listener)


def _telling(fun):
    """``fun``, calling the :func:`on_trace` listeners with its name first: the function that a
    top-level trace runs (of JAX's jit, or of the store of traced programs on a miss). Its module
    and qualified name are ``fun``'s (the store's key reads them)."""
    name = getattr(fun, "__name__", "program")

    @functools.wraps(fun)
    def traced(*args, **kwargs):  # runs only while a top-level program is traced
        for listener in tuple(_TRACE_LISTENERS):
            listener(name)
        return fun(*args, **kwargs)

    return traced


class jit:  # noqa: N801 (used like a decorator, as eqx.filter_jit)
    """``eqx.filter_jit`` with :func:`compiler_options` at top level, created on the first call
    (so that importing jaxclear compiles nothing). Inside another transformation (``jax.jit``,
    ``vmap``, ``grad`` of a user's function) JAX accepts compiler options only on the outermost
    jit, so there it is a plain ``eqx.filter_jit``, inlined like any nested jit. A trace of the
    top-level program (also :meth:`stored`'s, on a miss of the store) calls the :func:`on_trace`
    listeners."""

    def __init__(self, fun):
        functools.update_wrapper(self, fun)
        self._fun = fun
        self._traced = _telling(fun)
        self._plain = eqx.filter_jit(fun)
        self._top = None

    def _get(self):
        if self._top is None:
            self._top = eqx.filter_jit(self._traced, compiler_options=compiler_options())
        return self._top

    def __call__(self, *args, **kwargs):
        if not is_concrete((args, kwargs)):
            return self._plain(*args, **kwargs)
        try:
            return self._get()(*args, **kwargs)
        except ValueError as err:  # concrete arguments, but inside a user's jit
            if "compiler_options" not in str(err):
                raise
            return self._plain(*args, **kwargs)

    def lower(self, *args, **kwargs):
        return self._get().lower(*args, **kwargs)

    def stored(self, name: str, out_structure, *args):
        """Call on concrete ``args`` through the store of traced programs
        (:mod:`~jaxclear.integrate._programs`, on by default: :mod:`jaxclear.caches`), so that a new
        process skips tracing; as a plain call when the store is off or the arguments cannot
        be keyed. ``out_structure()`` returns the output's pytree structure without tracing."""
        if not is_concrete(args):
            return self(*args)
        out = programs.call(name, self._traced, args, out_structure, compiler_options=compiler_options())
        return self(*args) if out is None else out

    def prepare(self, name: str, *args) -> None:
        """Trace (or load) what :meth:`stored` with the same arguments will run, without
        compiling it (:func:`~jaxclear.integrate._programs.prepare`); with the store off, lower
        it (JAX keeps the trace for the call). Nothing under a transformation."""
        if not is_concrete(args):
            return
        if not programs.prepare(name, self._traced, args, compiler_options=compiler_options()):
            self.lower(*args)


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


_LOCK = threading.Lock()
_SAVED: list = [None]
_depth = 0


@contextlib.contextmanager
def without_input_callbacks():
    """While tracing ``diffrax.diffeqsolve``: its run-time input checks (``dt0`` sign,
    ``SaveAt.ts`` sorted and inside ``[t0, t1]``) are left out.

    Each such check is an ``equinox.error_if`` with a traced predicate, compiled as a host
    callback, and JAX never writes a program with host callbacks to its persistent compilation
    cache: with them :func:`jaxclear.simulate` was recompiled in every new process (the command
    line's startup). :func:`~jaxclear.integrate.simulate` builds inputs that satisfy
    the checks by construction (a sorted grid clipped to ``[t0, t1]``, ``dt0`` > 0 or None).
    Only diffrax's integrator module is affected, and only during the ``with`` block (the
    trace); the result of the solve is still checked (:class:`~jaxclear.RESULTS`)."""
    global _depth
    module = diffrax._integrate
    with _LOCK:  # traces may overlap (simulate_with_ideal compiles two programs in two threads)
        if _depth == 0:
            _SAVED[0] = module.eqxi
            module.eqxi = _ChecksOff(module.eqxi)
        _depth += 1
    try:
        yield
    finally:
        with _LOCK:
            _depth -= 1
            if _depth == 0:
                module.eqxi = _SAVED[0]
