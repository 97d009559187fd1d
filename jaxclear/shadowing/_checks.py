"""The inputs of :func:`~jaxclear.shadowing.nilss`, checked before any work: every message names
the parameter, the value it got and the range it allows (:class:`jaxclear.ParameterError`)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError, check_integer, check_range, function_name


def check_state(u0):
    """``u0`` as a finite float64 1-D array."""
    arr = np.asarray(u0, dtype=float)
    if arr.ndim != 1 or arr.size < 1:
        raise ParameterError(f"u0 must be a 1-D state vector of at least one entry, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"u0 must be finite, got {arr.tolist()!r}; allowed range (-inf, inf) in every entry")
    return jnp.asarray(arr)


def check_parameters(s):
    """``s`` as a finite float64 scalar or 1-D array."""
    arr = np.asarray(s, dtype=float)
    if arr.ndim > 1 or arr.size < 1:
        raise ParameterError(f"s must be a scalar or a 1-D vector of parameters, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"s must be finite, got {arr.tolist()!r}; allowed range (-inf, inf)")
    return jnp.asarray(arr)


def check_functions(f, objective, u0, s):
    """``f(u0, s)`` is a finite vector of ``u0``'s shape and ``objective(u0, s)`` a finite scalar."""
    for name, fn in (("f", f), ("objective", objective)):
        if not callable(fn):
            raise ParameterError(f"{name} must be a function (u, s) -> ..., got {fn!r}")
    rate = np.asarray(f(u0, s))
    if rate.shape != u0.shape or not np.all(np.isfinite(rate)):
        raise ParameterError(f"f = {function_name(f)} must return a finite vector of u0's shape {u0.shape}; "
                             f"f(u0, s) gave shape {rate.shape}, {rate.tolist()!r}")
    value = np.asarray(objective(u0, s))
    if value.shape != () or not np.isfinite(value):
        raise ParameterError(f"objective = {function_name(objective)} must return a finite scalar; "
                             f"objective(u0, s) gave shape {value.shape}, {value.tolist()!r}")


def check_options(*, n: int, n_unstable, segments, segment_time, members, transient, rtol, atol,
                  steps_per_segment, max_steps, spread):
    """The numbers that shape the run; returns the integers as ``int``."""
    n_unstable = check_integer("n_unstable", n_unstable, 0, n - 1,
                               "the unstable directions besides the flow's, at most the state's dimension less one")
    segments = check_integer("segments", segments, 2, None, "the least-squares problem joins at least two segments")
    members = check_integer("members", members, 2, None,
                            "independent trajectories, at least two for the error estimate")
    check_range("segment_time", segment_time, low=0.0, low_open=True)
    check_range("transient", transient, low=0.0)
    check_range("rtol", rtol, low=0.0, low_open=True)
    check_range("atol", atol, low=0.0, low_open=True)
    check_range("spread", spread, low=0.0)
    if steps_per_segment is not None:
        steps_per_segment = check_integer("steps_per_segment", steps_per_segment, 1, None, "fixed steps per segment")
    max_steps = check_integer("max_steps", max_steps, 1, None, "steps per segment")
    return n_unstable, segments, members, steps_per_segment, max_steps
