"""Traced programs kept on disk, so that a new process skips tracing and lowering.

JAX's persistent compilation cache (:mod:`jaxclear.cli.cache`) skips XLA compilation, but its
key is computed from the *lowered* program, so every new process still traces and lowers
:func:`~jaxclear.integrate.simulate` first: about 6 s of Python for the benchmark slider-crank
and its ideal-joint companion on a 2-core machine, most of a warm ``jaxclear simulate``. This
module stores the lowered program itself with :mod:`jax.export` (serialized StableHLO) under a
key of everything the trace depends on; a later process of the same structure deserializes it
(milliseconds) and calls it, and the compilation cache then finds the compiled program.

The key (SHA-256, :mod:`~jaxclear.integrate._program_keys`) covers everything the trace depends on:
the program's name, the libraries' versions and jaxclear's sources, JAX's options, the arguments'
structure, static values and types, and the shape and dtype of every array leaf; array *values* are
the program's inputs.

Only what the key can describe is stored; anything else makes the call unkeyable, traced as
usual and never served a program traced for another value: an argument whose ``repr`` does not
show its value in full (a Python callable such as a ``FunctionDriver``'s function, a lambda, a
function made inside another, or any other object shown by address, ``<... at 0x...>``; an
abbreviated array, ``...``), and any type defined outside jaxclear and the libraries above
(:data:`TRUSTED_MODULES`: a user's own law or element class, whose code the key does not cover).
A program that cannot be serialized (one with a host callback: a progress bar; one calling a
kernel of jaxlib outside JAX's stable ones and :data:`UNVERSIONED_CUSTOM_CALLS`) is run as usual
too.

:mod:`jax.export` does not serialize equinox modules as pytree nodes, so the program takes and
returns flat lists of arrays; the caller gives the output's structure (``out_structure``), which
it knows without tracing. Where the program is traced (a miss), the structure its output has is
compared with ``out_structure()``: a program whose caller would rebuild its output wrongly is
not stored (counted ``mismatched``) and runs as usual.

A file holds the serialized program behind its SHA-256: a file whose bytes changed (a bad disk,
a partial copy) is a miss, traced again and replaced, even where the damaged bytes would still
deserialize. A folder that cannot be written switches the store off with a warning. The store
keeps under a size limit (:func:`enable`'s ``max_bytes``): after a write, the least recently
used programs (file modification times, renewed on each load) are removed until it fits.

On by default: :mod:`jaxclear.caches` enables it at import, in the subfolder ``programs`` of
jaxclear's cache folder, for the Python API and the command line alike (``JAXCLEAR_CACHE_DIR=off``
or :func:`jaxclear.disable_cache` switches it off). :func:`counts` tells how many programs this
process loaded, traced, could not key, and removed. Needs the ``flatbuffers`` package (jax's
serializer).
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
import threading
import warnings
import weakref
from pathlib import Path
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import JaxclearError
from ._program_keys import KEYED_OPTIONS, KEYED_PACKAGES, TRUSTED_MODULES, _split, program_key

#: Suffix of the stored programs' file names.
SUFFIX = ".jaxexport"
#: First bytes of a stored program's file; the SHA-256 of the serialized program follows, then
#: the program itself.
MAGIC = b"jaxclear-program-1\n"
#: Kernels of jaxlib that a program may call although :mod:`jax.export` does not promise to keep
#: them from one jaxlib to the next (it refuses to serialize them by default): LAPACK's
#: multiplication by the Q of a QR factorisation, which lineax's QR solve (the fit's
#: Levenberg-Marquardt step) calls on a CPU. A stored program is only loaded by the jaxlib and
#: backend that wrote it (both are in the key), so that promise is not needed. Python host
#: callbacks stay refused: they name objects of the process that traced them.
UNVERSIONED_CUSTOM_CALLS = ("lapack_sormqr_ffi", "lapack_dormqr_ffi", "lapack_cunmqr_ffi", "lapack_zunmqr_ffi")

_FOLDER: list[Path | None] = [None]
_LIMIT: list[int | None] = [None]
_RUNNERS: dict[str, Callable] = {}
#: The output structure of each runner's program (:func:`call`), found once.
_STRUCTURES: dict[Callable, jax.tree_util.PyTreeDef] = {}
_LOCK = threading.Lock()
_COUNTS = {"loaded": 0, "traced": 0, "unkeyable": 0, "unserializable": 0, "mismatched": 0, "removed": 0}


def enable(folder: Path | str | None, max_bytes: int | None = None) -> Path | None:
    """Store and reuse traced programs in ``folder`` (created, mode 0700); ``None`` switches the
    store off. ``max_bytes``: the most the store's files may hold together (``None``: no limit);
    the least recently used are removed after a write that exceeds it. Returns the folder in use
    (None if off or if it cannot be created). Programs already loaded in this process are
    kept when the folder is the one in use (the command line's ``main``, called again in one
    process, enables the same folder each time: the programs are not loaded and compiled again),
    and forgotten otherwise (the next call reads the new ``folder``)."""
    _LIMIT[0] = max_bytes
    if folder is not None:
        folder = Path(folder).expanduser()
        try:
            folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        except OSError:
            folder = None
    if folder is None or folder != _FOLDER[0]:
        with _LOCK:
            _RUNNERS.clear()
            _STRUCTURES.clear()
    _FOLDER[0] = folder
    return folder


def counts() -> dict[str, int]:
    """How many programs this process ``loaded`` from the store, ``traced`` (and wrote) on a
    miss, ran as usual because their arguments could not be keyed (``unkeyable``), the program
    could not be serialized (``unserializable``) or its output's structure was not the one its
    caller gave (``mismatched``, a bug of the caller), and ``removed`` to keep the size limit."""
    with _LOCK:
        return dict(_COUNTS)


def _count(what: str) -> None:
    with _LOCK:
        _COUNTS[what] += 1


def folder() -> Path | None:
    """The store's folder in this process, or None when it is off."""
    return _FOLDER[0]


def _export(fun: Callable, args) -> tuple[jax.export.Exported, jax.tree_util.PyTreeDef]:
    """``fun`` traced and lowered on the shapes of ``args``' arrays, taking and returning flat
    lists of arrays (:mod:`jax.export` serializes no equinox module as a pytree node), and the
    structure of its output."""
    leaves, treedef, static = _split(args)
    structure = []

    def flat(*xs):
        out = fun(*eqx.combine(jax.tree_util.tree_unflatten(treedef, xs), static))
        structure.append(jax.tree_util.tree_structure(out))
        return jax.tree_util.tree_leaves(out)

    allowed = [jax.export.DisabledSafetyCheck.custom_call(target) for target in UNVERSIONED_CUSTOM_CALLS]
    exp = jax.export.export(jax.jit(flat), disabled_checks=allowed)(
        *[jax.ShapeDtypeStruct(x.shape, x.dtype) for x in leaves])
    return exp, structure[0]


def _write(path: Path, blob: bytes) -> None:
    """Write atomically (a partial file is never read as a program), the blob behind
    :data:`MAGIC` and its SHA-256 (:func:`_unpack` checks it). A folder that cannot be written
    switches the store off with a warning: the run goes on, tracing as usual."""
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=SUFFIX)
        with os.fdopen(fd, "wb") as f:
            f.write(MAGIC + hashlib.sha256(blob).digest() + blob)
        os.replace(tmp, path)
    except OSError as err:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        _FOLDER[0] = None
        warnings.warn(f"cannot write to the program cache {str(path.parent)!r} ({err.strerror or err}); "
                      "going on without it (programs are traced as usual)", stacklevel=2)


def _unpack(data: bytes) -> bytes | None:
    """The serialized program of a file written by :func:`_write`, or None when the file is not
    one or its bytes changed since (a flipped byte can still deserialize, and then fails only
    when XLA parses the program: it is a miss instead)."""
    head = len(MAGIC) + hashlib.sha256().digest_size
    if len(data) <= head or not data.startswith(MAGIC):
        return None
    digest, blob = data[len(MAGIC):head], data[head:]
    return blob if hashlib.sha256(blob).digest() == digest else None


def _evict(folder: Path, limit: int | None) -> None:
    """Remove the least recently used programs of ``folder`` (oldest modification time first:
    a load renews it) until the rest hold at most ``limit`` bytes."""
    if limit is None:
        return
    entries = []
    for path in folder.glob(f"*{SUFFIX}"):
        try:
            st = path.stat()
        except OSError:  # removed meanwhile by another process
            continue
        entries.append((st.st_mtime_ns, st.st_size, path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries, key=lambda e: e[0]):
        if total <= limit:
            break
        try:
            path.unlink()
            _count("removed")
        except OSError:
            pass
        total -= size


def _load(key: str, fun: Callable, args, out_structure: Callable | None) -> jax.export.Exported | None:
    """The program ``key`` from its file, or traced, exported and written on a miss; None when
    the program cannot be serialized (a host callback in it: the caller runs it as usual) or
    its output's structure is not ``out_structure()`` (when given)."""
    exp = None
    path = _FOLDER[0] / f"{key}{SUFFIX}"  # type: ignore[operator]
    blob = None
    if path.is_file():
        try:
            blob = _unpack(path.read_bytes())
            exp = None if blob is None else jax.export.deserialize(bytearray(blob))
        except Exception:  # an unreadable, truncated or damaged file: trace again and replace it
            exp = None
        if exp is not None:
            _count("loaded")
            try:
                os.utime(path)  # recently used: the last to be removed by the size limit
            except OSError:
                pass
    if exp is None:
        try:
            exported, structure = _export(fun, args)
            blob = exported.serialize()
        except JaxclearError:  # the user's error, found while tracing: said as in a plain call
            raise
        except Exception:  # a program JAX cannot export (a host callback: a progress bar): run as usual
            _count("unserializable")
            return None
        if out_structure is not None and structure != out_structure():  # its output would be rebuilt wrongly
            _count("mismatched")
            return None
        _write(path, blob)
        _count("traced")
        if _FOLDER[0] is not None:
            _evict(_FOLDER[0], _LIMIT[0])
        # the deserialized form, also on this first call: it lowers to the same module as in
        # later processes, so the compilation cache's key matches theirs
        exp = jax.export.deserialize(bytearray(blob))
    return exp


def call(name: str, fun: Callable, args: tuple, out_structure: Callable[[], jax.tree_util.PyTreeDef],
         *, compiler_options: dict | None = None):
    """``fun(*args)`` through the store when it is enabled and the arguments can be keyed,
    else ``None`` (the caller then runs its usual jitted function).

    Args:
        name: the program's name (part of the key).
        fun: the function (traced on a miss).
        args: its arguments (a tuple of pytrees: arrays are inputs, everything else is keyed).
        out_structure: returns the pytree structure of ``fun``'s output without tracing it.
        compiler_options: XLA options of the compilation (:func:`~jaxclear.integrate.compiler_options`).
    """
    prepared = _prepared(name, fun, args, compiler_options, out_structure)
    if prepared is None:
        return None
    run, leaves = prepared
    with _LOCK:
        structure = _STRUCTURES.get(run)
    if structure is None:  # one per program: out_structure (an eval_shape) took a third of a warm call
        structure = out_structure()
        with _LOCK:
            _STRUCTURES[run] = structure
    return jax.tree_util.tree_unflatten(structure, run(leaves))


def prepare(name: str, fun: Callable, args: tuple, *, compiler_options: dict | None = None) -> bool:
    """Load (or, on a miss, trace and store) the program that :func:`call` with the same
    arguments will run, without compiling or running it; returns whether the store took it.
    Tracing holds Python's lock and XLA's compilation does not: a caller that runs two programs
    in two threads prepares the first, so that the second's tracing overlaps the first's
    compilation instead of competing with its tracing."""
    prepared = _prepared(name, fun, args, compiler_options)
    if prepared is None:
        return False
    run, leaves = prepared
    run.lower(leaves)  # JAX keeps the lowering for the call
    return True


def _prepared(name, fun, args, compiler_options, out_structure=None):
    """``(jitted caller, array leaves)`` of the stored program for this call, or None when the
    store is off or the arguments cannot be keyed."""
    if _FOLDER[0] is None:
        return None
    keyed = program_key(f"{name}:{getattr(fun, '__module__', '')}.{getattr(fun, '__qualname__', '')}", args)
    if keyed is None:
        _count("unkeyable")
        return None
    key, leaves = keyed
    run = _runner(key, fun, args, compiler_options or {}, out_structure)
    return None if run is None else (run, _placed(leaves))


def _placed(leaves: list) -> list:
    """The array leaves, each committed to the device it is on (:func:`jax.device_put` with its
    own sharding; a NumPy array first to JAX's default device, where it would go). A stored
    program's outputs come back committed, and ``jax.jit`` lowers and compiles a program anew
    when an argument's commitment changes: the fit's solver step, called first on fresh unknowns
    and then on its own outputs, was compiled twice (41 s each on 2 cores for a small fit), as
    two entries of JAX's compilation cache. Committed alike on every call, it compiles once.

    The committed copy of an uncommitted array is kept while the array lives (:data:`_COPIES`, by
    identity: a JAX array never changes, nor does a read-only NumPy array that owns its data, such
    as the leaves of :data:`jaxclear.contact.STEEL`), so a mechanism passed again is not transferred
    again (its transfers took a tenth of a warm call of the benchmark's run, a quarter of a short
    one)."""
    arrays, loose = list(leaves), []
    for i, x in enumerate(leaves):
        if isinstance(x, jax.core.Tracer) or (isinstance(x, jax.Array) and x.committed):
            continue
        known = _COPIES.get(id(x))
        if known is not None and known[0]() is x:
            arrays[i] = known[1]
        else:
            arrays[i] = jnp.asarray(x)
            loose.append(i)
    if loose:  # one batched transfer (42 single ones took 40 % of a warm call of the benchmark's run)
        placed = jax.device_put([arrays[i] for i in loose], [arrays[i].sharding for i in loose])
        for i, copy in zip(loose, placed):
            x = leaves[i]
            arrays[i] = copy
            # a JAX array never changes; a NumPy array only where it may be written (the module
            # constants of jaxclear are read-only: STEEL's leaves)
            if isinstance(x, jax.Array) or (isinstance(x, np.ndarray) and not x.flags.writeable and x.base is None):
                with _LOCK:
                    _COPIES[id(x)] = (weakref.ref(x, functools.partial(_forget, id(x))), copy)
    return arrays


#: Committed copies of uncommitted arrays (:func:`_placed`): id -> (weak reference, copy).
_COPIES: dict[int, tuple] = {}


def _forget(ident: int, _ref) -> None:
    """Drop the copy of an array that no longer lives."""
    with _LOCK:
        _COPIES.pop(ident, None)


class _Runner:
    """The jitted caller of one stored program. Its first call (the compilation) is made by one
    thread at a time: threads that ask for the same program together (a window's candidate starts
    split over the host's threads, :func:`jaxclear.sweep.lanes.host_rows`) each compiled it, and
    traced it, the same seconds twice."""

    def __init__(self, jitted):
        self.jitted = jitted
        self.gate = threading.Lock()
        self.ready = False

    def __call__(self, leaves):
        if self.ready:
            return self.jitted(leaves)
        with self.gate:
            out = self.jitted(leaves)
            self.ready = True
        return out

    def lower(self, leaves):
        return self.jitted.lower(leaves)


#: Per key, the lock of the thread that is loading or tracing that program (:func:`_runner`).
_PENDING: dict[str, threading.Lock] = {}


def _runner(key: str, fun: Callable, args, options: dict, out_structure: Callable | None = None) -> Callable | None:
    """The caller (:class:`_Runner`) of the stored program ``key`` (one per program and process,
    so its compiled executable is reused by later calls); None when it cannot be stored. One
    thread loads or traces a program; another asking for it meanwhile waits and gets the same."""
    with _LOCK:
        run = _RUNNERS.get(key)
        gate = _PENDING.setdefault(key, threading.Lock()) if run is None else None
    if run is not None:
        return run
    with gate:
        with _LOCK:
            run = _RUNNERS.get(key)
        if run is not None:
            return run
        try:
            exp = _load(key, fun, args, out_structure)
            if exp is None:
                return None
            kwargs = {"compiler_options": dict(options)} if options else {}

            def stored_program(xs):  # the name JAX's logs and the compilation cache show
                return exp.call(*xs)

            run = _Runner(jax.jit(stored_program, **kwargs))
            with _LOCK:
                _RUNNERS[key] = run
        finally:
            with _LOCK:
                _PENDING.pop(key, None)
    return run


__all__ = ["KEYED_OPTIONS", "KEYED_PACKAGES", "SUFFIX", "TRUSTED_MODULES", "UNVERSIONED_CUSTOM_CALLS", "call", "counts",
           "enable", "folder", "prepare", "program_key"]
