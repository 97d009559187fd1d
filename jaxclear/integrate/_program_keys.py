"""The key of a traced program in the store (:mod:`~jaxclear.integrate._programs`).

The key (SHA-256) covers: the program's name and its function's qualified name; the versions of jax, jaxlib, diffrax, equinox,
optimistix and lineax; the bytes of every jaxclear source file (any code change is a miss);
JAX's options that change a trace (:data:`KEYED_OPTIONS`: x64, default matmul precision, dtype
and rank promotion); what else a trace reads of the process (:func:`_process_digest`: JAX's
default backend, and whether XLA's single-kernel loops are on, which :func:`jaxclear.integrate.simulate`'s
post-processing and :func:`jaxclear.sweep.lanes.over_lanes` read while tracing to pick
``jax.lax.map`` or ``jax.vmap``); the structure of the arguments with every non-array value in it (static fields
of the mechanism and the settings: names, laws, tolerances, sample counts) by its ``repr``, and
the module and name of every type in it; and the shape and dtype of every array leaf. Array
*values* (masses, clearance, stiffness, end time) are the program's inputs and do not enter the
key. A plain function among the non-array values (optimistix's ``norm`` of a solver) is keyed by
its module and qualified name where that names it exactly: a module of :data:`TRUSTED_MODULES`
(whose code, run at import, made it: the key covers it) has the function itself as its attribute of
that name (:func:`_by_name`).

A key is built from the arguments (:func:`_key`) the first time a structure is met; later calls
with an equal structure get it back from a memo (:func:`program_key`, :func:`_memo`).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import sys
import threading
import types
from pathlib import Path

import equinox as eqx
import jax

from .._xla_flags import loop_kernels_active

#: Libraries whose versions enter the key.
KEYED_PACKAGES = ("jax", "jaxlib", "diffrax", "equinox", "optimistix", "lineax")
#: JAX options that change what a trace produces; their values enter the key.
KEYED_OPTIONS = ("jax_enable_x64", "jax_default_matmul_precision", "jax_numpy_dtype_promotion",
                 "jax_numpy_rank_promotion")
#: Top-level modules whose types may appear in a keyed argument: their code is covered by the
#: key (jaxclear's sources, the versions of :data:`KEYED_PACKAGES`) or is Python's and NumPy's.
#: A type from anywhere else (a user's law class) makes the call unkeyable.
TRUSTED_MODULES = frozenset({"jaxclear", "builtins", "numpy", "collections", "jax", "jaxlib", "equinox", "diffrax",
                             "lineax", "optimistix"})
_LOCK = threading.Lock()


@functools.cache
def _environment_digest() -> str:
    """Library versions and the bytes of every jaxclear source file."""
    h = hashlib.sha256()
    for name in KEYED_PACKAGES:
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            version = "-"
        h.update(f"{name}={version};".encode())
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _process_digest() -> str:
    """What a trace reads of this process beyond JAX's options: the default backend (a program
    lowered for one platform does not run on another) and whether XLA's single-kernel loops are
    on (:func:`jaxclear._xla_flags.loop_kernels_active`: the lanes rule and the run's
    post-processing choose ``jax.lax.map`` or ``jax.vmap`` by it while tracing)."""
    return f"backend={jax.default_backend()};loop_kernels={loop_kernels_active()}"


class _FunctionName:
    """A plain function in a key, by its module and qualified name (:func:`_by_name`)."""

    def __init__(self, name: str):
        self.name = name

    def __repr__(self) -> str:
        return f"function({self.name})"


def _by_name(value):
    """``value`` as a :class:`_FunctionName` where it is a plain function that its module and
    qualified name identify, and whose code the key covers: its module is one of
    :data:`TRUSTED_MODULES` and that module's attribute of that name is ``value`` itself (made by
    the module's code at import: optimistix's ``max_norm`` is such a function, a wrapper made by a
    module-level call); else ``value`` unchanged (a user's function, a lambda, a function made
    inside another: shown by address, unkeyable)."""
    if not isinstance(value, types.FunctionType):
        return value
    module, qualname = value.__module__ or "", value.__qualname__
    if module.split(".")[0] not in TRUSTED_MODULES or "<" in qualname:
        return value
    found = sys.modules.get(module)
    for part in qualname.split("."):
        found = getattr(found, part, None)
    return _FunctionName(f"{module}.{qualname}") if found is value else value


def _faithful(text: str) -> bool:
    """Whether a ``repr`` shows its value in full (no object address, no abbreviation)."""
    return " at 0x" not in text and "..." not in text


def _split(args):
    """``(array leaves, their tree structure, the non-array rest)`` of ``args``."""
    dynamic, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    return leaves, treedef, static


def _types(value, found: set) -> None:
    """Every type in ``value``: its pytree nodes (with their auxiliary data: an equinox module's
    static fields) and its leaves, into ``found``."""
    stack = [value]
    while stack:
        x = stack.pop()
        found.add(type(x))
        if isinstance(x, jax.tree_util.PyTreeDef):
            data = x.node_data()
            if data is not None:
                found.add(data[0])
                stack.append(data[1])
            stack.extend(x.children())
        elif isinstance(x, (tuple, list, set, frozenset)):
            stack.extend(x)
        elif isinstance(x, dict):
            stack.extend(x.keys())
            stack.extend(x.values())


def _trusted(types) -> bool:
    """Whether every type comes from :data:`TRUSTED_MODULES` (its code is covered by the key)."""
    return all(str(getattr(t, "__module__", "") or "").split(".")[0] in TRUSTED_MODULES for t in types)


def program_key(name: str, args) -> tuple[str, list] | None:
    """``(key, array leaves)`` of a call of program ``name`` on ``args``, or None when the
    arguments' static part cannot be keyed faithfully (see the module's docstring).

    The key of a structure met before is remembered (:func:`_memo`): building it (the ``repr``
    of the arguments' static part, the walk over its types, the SHA-256) took a tenth of a warm
    call of the benchmark's run."""
    flat, treedef = jax.tree_util.tree_flatten(args)
    leaves = [x for x in flat if eqx.is_array(x)]
    options = ";".join(f"{o}={getattr(jax.config, o, None)}" for o in KEYED_OPTIONS)
    memo = _memo(name, treedef, flat, options)
    if memo is not None:
        with _LOCK:
            known = _KEYS.get(memo, _MISSING)
        if known is not _MISSING:
            return None if known is None else (known, leaves)
    key = _key(name, args, options)
    if memo is not None:
        with _LOCK:
            if len(_KEYS) >= MEMO_SIZE:
                _KEYS.clear()
            _KEYS[memo] = key
    return None if key is None else (key, leaves)


#: How many keys :func:`program_key` remembers (all are forgotten when it is full).
MEMO_SIZE = 512
_KEYS: dict = {}
_MISSING = object()


def _memo(name: str, treedef, flat: list, options: str):
    """What decides a call's key, cheaply and hashable: the name, JAX's options and the
    process's (:func:`_process_digest`), the arguments' tree structure (with every static field
    of their modules, compared by equality as :func:`jax.jit`'s own cache compares them), the
    shape and dtype of each array leaf, and each other leaf by its type and ``repr``. None when
    something in it cannot be hashed (its key is then built every time)."""
    parts = []
    for x in flat:
        if eqx.is_array(x):
            parts.append((x.shape, x.dtype))
        elif isinstance(x, (bool, int, float, complex, str, type(None))):
            parts.append((type(x), repr(x)))
        else:
            parts.append((type(x), x))
    memo = (name, options, _process_digest(), treedef, tuple(parts))
    try:
        hash(memo)
    except TypeError:
        return None
    return memo


def _key(name: str, args, options: str) -> str | None:
    """The key of :func:`program_key`, built from the arguments (None: unkeyable)."""
    leaves, treedef, static = _split(args)
    flat, static_def = jax.tree_util.tree_flatten(static)
    flat = [_by_name(x) for x in flat]
    text = repr((flat, static_def))
    if not _faithful(text):
        return None
    found: set = set()
    _types([flat, static_def, treedef], found)
    if not _trusted(found):
        return None
    h = hashlib.sha256()
    h.update(f"{name}\n{_environment_digest()}\n{options}\n{_process_digest()}\n".encode())
    h.update(",".join(sorted(f"{t.__module__}.{t.__qualname__}" for t in found)).encode())
    h.update(text.encode())
    h.update(repr(treedef).encode())
    for x in leaves:
        h.update(f"{x.shape}{x.dtype};".encode())
    return h.hexdigest()


__all__ = ["KEYED_OPTIONS", "KEYED_PACKAGES", "MEMO_SIZE", "TRUSTED_MODULES", "program_key"]
