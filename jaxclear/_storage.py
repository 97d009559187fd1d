"""Crash-safe files and content fingerprints: the one place for atomic writes, fsync-ed
appends and hashing.

Long work (sweeps, fits, wear) writes as it goes and resumes after a kill: a file is either
its old content or its new content, never a mix (write to a temporary file beside it, fsync,
``os.replace``), and appended lines are on disk before the next piece of work starts.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import socket
import time

import filelock
import numpy as np

from ._errors import OutputLockedError


def fsync_append(path, text: str, mode: str = "a") -> str:
    """Write ``text`` to ``path`` (appending by default) and fsync it. Returns the path."""
    path = os.fspath(path)
    with open(path, mode, encoding="utf-8", newline="") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    return path


def atomic_write_bytes(path, data: bytes) -> str:
    """Replace ``path`` by ``data`` atomically (temporary file, fsync, rename). Returns the path."""
    path = os.fspath(path)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def atomic_write_netcdf(path, ds) -> str:
    """Write the xarray Dataset ``ds`` as NetCDF 3 (xarray's ``scipy`` engine) atomically: the
    file is the old or the new one, never a mix. Returns the path."""
    return atomic_write_bytes(path, ds.to_netcdf(engine="scipy"))


def atomic_write_text(path, text: str) -> str:
    """:func:`atomic_write_bytes` of UTF-8 text."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path, obj, **dump_kwargs) -> str:
    """:func:`atomic_write_text` of ``json.dumps(obj)`` (indented, sorted keys by default)."""
    dump_kwargs.setdefault("indent", 2)
    dump_kwargs.setdefault("sort_keys", True)
    return atomic_write_text(path, json.dumps(obj, **dump_kwargs) + "\n")


def atomic_write_npz(path, arrays: dict) -> str:
    """:func:`numpy.savez` to ``path`` atomically."""
    path = os.fspath(path)
    tmp = path + ".tmp.npz"
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def fingerprint(*items, length: int | None = None) -> str:
    """sha256 (hex) of ``items``: arrays by their float64 little-endian bytes (bit-exact),
    anything else by its ``repr``; JAX arrays and pytrees of arrays are flattened first (the
    tree structure is hashed too). ``length`` truncates the hex digest."""
    import jax  # deferred: hashing plain data needs no JAX

    h = hashlib.sha256()
    for item in items:
        leaves, treedef = jax.tree_util.tree_flatten(item)
        if len(leaves) != 1 or leaves[0] is not item:
            h.update(str(treedef).encode())
        for leaf in leaves:
            if isinstance(leaf, (np.ndarray, jax.Array, np.generic)) or (
                isinstance(leaf, float) and len(leaves) > 1
            ):
                h.update(np.ascontiguousarray(np.asarray(leaf, dtype="<f8")).tobytes())
            else:
                h.update(repr(leaf).encode())
    digest = h.hexdigest()
    return digest if length is None else digest[:length]


LOCK_NAME = ".jaxclear.lock"


@contextlib.contextmanager
def locked_folder(folder, what: str = "output folder"):
    """Hold an exclusive :mod:`filelock` lock on ``folder`` (file ``folder/.jaxclear.lock``) for
    the duration of the ``with`` block; the holder (host, process id, start time) is written to
    ``.jaxclear.lock.owner``. A second process gets :class:`~jaxclear.OutputLockedError`
    naming the folder and the holder at once (no waiting)."""
    folder = os.fspath(folder)
    os.makedirs(folder, exist_ok=True)
    owner = os.path.join(folder, LOCK_NAME + ".owner")
    lock = filelock.FileLock(os.path.join(folder, LOCK_NAME), timeout=0)
    try:
        lock.acquire()
    except filelock.Timeout:
        try:
            with open(owner, encoding="utf-8") as f:
                holder = f.read().strip() or "unknown"
        except OSError:
            holder = "unknown"
        raise OutputLockedError(
            f"the {what} {folder!r} is in use by another process ({holder}); wait for it to finish, "
            f"stop it, or choose another folder"
        ) from None
    try:
        atomic_write_text(owner, f"host {socket.gethostname()}, pid {os.getpid()}, since "
                                 f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n")
        yield folder
    finally:
        lock.release()
