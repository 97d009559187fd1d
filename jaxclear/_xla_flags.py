"""XLA:CPU option for loops of small kernels, set in ``XLA_FLAGS`` when jaxclear is imported.

Why: since JAX 0.4.32 XLA:CPU runs a compiled program as a sequence of *thunks*, one kernel
launch (and a dispatch over its thread pool) per fused operation. A solver step of a planar
mechanism is a few hundred tiny kernels (scalars, 2-vectors, a 7 x 7 solve), so on CPU the
launches, not the arithmetic, set the speed: about 350 launches of about 65 ns per step of the
benchmark slider-crank. XLA has a pass, ``SmallWhileLoopHoistingPass``, that compiles a
``while`` loop whose buffers are small into one kernel (the loop body becomes straight-line
machine code, as in XLA:CPU's runtime before thunks); its size limit is the backend option
``xla_cpu_small_while_loop_byte_threshold`` (1 kB by default, which none of jaxclear's loops
meets). Raising it runs a crank revolution about 4x faster on 2 cores (benchmarks/README.md).

A second flag goes with it: ``--xla_cpu_experimental_ynn_fusion_type=`` (empty: no YNNPACK
library fusions). XLA:CPU hands some matrix products (``dot``) to YNNPACK as *custom* fusions,
and ``SmallWhileLoopHoistingPass`` refuses a loop that contains one, so the whole loop falls
back to thunks. A plain simulation has no such product, but every batched one has: the
error-controlled sensitivities (:mod:`jaxclear.integrate._sensitivity`; the tangents' ``vmap``
turns the vector field's matrix-vector products into a 4 x 4 product) and a vmapped sweep.
Measured on the 2-core machine: ``jax.jacfwd`` of the slider-crank with a clearance guide (4
parameters) 144 ms -> 24 ms, a ``vmap`` of 32 runs of the benchmark 653 ms -> 282 ms; a single
run and a one-parameter ``jax.grad`` unchanged. The products are a few numbers each, where
YNNPACK has nothing to gain. A value the user set in ``XLA_FLAGS`` is kept; the flag is added
and withheld together with the loop option (``JAXCLEAR_SMALL_LOOP_BYTES=0`` leaves both).

The option can only be given through the ``XLA_FLAGS`` environment variable (JAX's per-call
``compiler_options`` cannot set XLA's map-valued ``xla_backend_extra_options``), and XLA reads
that variable once, when JAX starts its backends. So it is added here, at import, before any
JAX computation; it affects the whole process (every program XLA:CPU compiles: loops with small
buffers become single kernels; results agree to rounding). Rules:

* ``JAXCLEAR_SMALL_LOOP_BYTES`` (environment) sets the limit in bytes; ``0`` leaves XLA's
  default alone (jaxclear then runs at the thunk runtime's speed).
* A limit the user already set in ``XLA_FLAGS`` is kept as it is.
* Where JAX's backends were started before jaxclear was imported, ``XLA_FLAGS`` is no longer
  read: nothing is changed and a :class:`SlowLoopsWarning` says how to get the speed (import
  jaxclear first, or set the flag before starting Python).

The command line's ``jaxclear sweep`` also asks, through the same variable and before JAX
starts, for one host CPU device per usable core (:func:`request_host_devices`): a sweep's chunk
is split over the devices, and each device runs its runs one after another on a core of its own.

Written by hand because no library sets XLA options of this kind; the only other route, a
patched ``CompileOptions`` protocol buffer per compilation, depends on JAX internals.
"""

from __future__ import annotations

import os
import warnings

from ._errors import ParameterError

#: The XLA backend option that limits which while loops become single kernels.
OPTION = "xla_cpu_small_while_loop_byte_threshold"
#: jaxclear's limit (bytes): every loop of a simulation, sweep or fit, dense output included.
DEFAULT_BYTES = 1_000_000_000
#: Environment variable overriding :data:`DEFAULT_BYTES` (``0``: leave XLA's default).
ENV = "JAXCLEAR_SMALL_LOOP_BYTES"
_EXTRA = "--xla_backend_extra_options="
#: The XLA flag (empty value: none) that keeps small products out of YNNPACK's custom fusions,
#: which a single-kernel loop cannot hold.
NO_LIBRARY_FUSIONS = "--xla_cpu_experimental_ynn_fusion_type="
#: The XLA flag that splits the host CPU into several JAX devices.
HOST_DEVICES_FLAG = "--xla_force_host_platform_device_count"


class SlowLoopsWarning(UserWarning):
    """JAX's backends started before jaxclear was imported, so XLA runs jaxclear's solver loops
    as many small kernels (about 4x slower on CPU); see :mod:`jaxclear._xla_flags`."""


def with_loop_option(flags: str, nbytes: int) -> str:
    """``flags`` (an ``XLA_FLAGS`` value) with ``OPTION=nbytes`` added to its
    ``--xla_backend_extra_options`` (a comma-separated ``key=value`` list), or that flag
    appended, and :data:`NO_LIBRARY_FUSIONS` appended where the YNNPACK fusion flag is not
    there; unchanged where ``OPTION`` is already there (the user's choice)."""
    if OPTION in flags:
        return flags
    tokens = flags.split()
    for i, token in enumerate(tokens):
        if token.startswith(_EXTRA):
            value = token[len(_EXTRA):]
            tokens[i] = f"{_EXTRA}{value},{OPTION}={nbytes}" if value else f"{_EXTRA}{OPTION}={nbytes}"
            break
    else:
        tokens.append(f"{_EXTRA}{OPTION}={nbytes}")
    if not any(t.startswith(NO_LIBRARY_FUSIONS.rstrip("=")) for t in tokens):
        tokens.append(NO_LIBRARY_FUSIONS)
    return " ".join(tokens)


def requested_bytes() -> int:
    """The limit asked for: ``JAXCLEAR_SMALL_LOOP_BYTES`` or :data:`DEFAULT_BYTES`."""
    raw = os.environ.get(ENV, "").strip()
    if not raw:
        return DEFAULT_BYTES
    message = f"{ENV}={raw!r}: expected a whole number of bytes >= 0 (0 keeps XLA's default)"
    try:
        value = float(raw)
    except ValueError:
        raise ParameterError(message) from None
    if not (value >= 0 and value == int(value)):
        raise ParameterError(message)
    return int(value)


def loop_kernels_active() -> bool:
    """Whether ``XLA_FLAGS`` (as this process has it now) raises XLA's small-loop limit. Only
    meaningful before JAX's backends start or when the flag was set before they did."""
    return OPTION in os.environ.get("XLA_FLAGS", "")


def backends_started() -> bool:
    """Whether JAX has started its backends (and so read ``XLA_FLAGS``); False where this JAX
    does not say (its private ``xla_bridge.backends_are_initialized``)."""
    import jax

    probe = getattr(getattr(getattr(jax, "_src", None), "xla_bridge", None), "backends_are_initialized", None)
    return bool(probe()) if probe is not None else False


def apply(started: bool | None = None) -> bool:
    """Add the option to ``XLA_FLAGS`` (see the module docstring); returns whether it is in
    effect for this process. ``started``: whether JAX's backends have started (default: ask
    JAX, :func:`backends_started`)."""
    if started is None:
        started = backends_started()
    nbytes = requested_bytes()
    flags = os.environ.get("XLA_FLAGS", "")
    if nbytes == 0 or OPTION in flags:
        return OPTION in flags
    if started:
        warnings.warn(
            "JAX's backends were started before jaxclear was imported, so XLA cannot be told to "
            "compile jaxclear's solver loops as single kernels (about 4x slower on CPU). Import "
            f"jaxclear before running any JAX computation, or start Python with XLA_FLAGS="
            f"'{with_loop_option('', nbytes)}'; set {ENV}=0 to silence this.",
            SlowLoopsWarning,
            stacklevel=3,
        )
        return False
    os.environ["XLA_FLAGS"] = with_loop_option(flags, nbytes)
    return True


def usable_cpus() -> int:
    """CPU cores this process may run on (its affinity mask; ``os.cpu_count()`` where the
    platform has none)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def request_host_devices(n: int | None = None, started: bool | None = None) -> bool:
    """Ask XLA for ``n`` host CPU devices (default: one per usable core, :func:`usable_cpus`) by
    adding ``--xla_force_host_platform_device_count=n`` to ``XLA_FLAGS``, so that a sweep
    (``jaxclear.sweep.run_sweep``) splits its chunks over the cores. Call it after
    ``import jaxclear`` and before any JAX computation: nothing is changed where JAX's backends
    have started (``started``; default: ask JAX), since XLA reads the variable only then, where
    ``XLA_FLAGS`` already names a count (the user's choice), or where ``n < 2``. Returns whether
    it was added. ``jaxclear sweep`` calls it."""
    if n is None:
        n = usable_cpus()
    if n < 2:
        return False
    if started is None:
        started = backends_started()
    flags = os.environ.get("XLA_FLAGS", "")
    if started or HOST_DEVICES_FLAG in flags:
        return False
    os.environ["XLA_FLAGS"] = " ".join(flags.split() + [f"{HOST_DEVICES_FLAG}={int(n)}"])
    return True
