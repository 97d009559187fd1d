"""Compilation of jaxclear's own functions: XLA options chosen for the small, scalar-heavy
kernels of a planar mechanism, applied only where JAX allows them (the outermost jit)."""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp

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
