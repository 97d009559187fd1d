"""Crash-safe files and content fingerprints: the one place for atomic writes, fsync-ed
appends, hashing, reading the text files a user gives (:func:`read_text`: a binary or
oversized file is a named error, not a decoding traceback; :func:`read_toml`, the one TOML
reader) and writing JSON (:func:`json_text`, the one JSON writer: strict JSON, NaN and
infinities as ``null``).

Long work (sweeps, fits, wear) writes as it goes and resumes after a kill: a file is either
its old content or its new content, never a mix (write to a temporary file beside it, fsync,
``os.replace``), and appended lines are on disk before the next piece of work starts.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import socket
import time
import tomllib

import filelock
import numpy as np

from ._errors import OutputLockedError, ParameterError

#: Largest text input read whole [bytes]: mechanism files, sweep configurations, channel files
#: (a 1000-body mechanism file, the largest :class:`~jaxclear.Mechanism` allowed, is about 250 kB).
MAX_TEXT_BYTES = 8 * 2**20
#: Largest measured record read [bytes] (two million samples of a few columns are about 200 MB).
MAX_RECORD_BYTES = 2**30


def read_text(path, what: str, error=ParameterError, max_bytes: int = MAX_TEXT_BYTES,
              encoding: str = "utf-8") -> str:
    """The text of the file ``path`` that a user gave as ``what`` (e.g. ``"mechanism file"``).

    Every way it can be unusable is one :class:`~jaxclear.JaxclearError` (class ``error``)
    naming the file: missing or unreadable, larger than ``max_bytes``, or not text in
    ``encoding`` (a binary file: the offset of the first bad byte is named)."""
    path = os.fspath(path)
    try:
        size = os.path.getsize(path)
        if size > max_bytes:
            raise error(f"{what} {path!r} has {size} bytes, outside the allowed range [0, {max_bytes}] bytes; "
                        "is it the right file?")
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as err:
        raise error(f"cannot read {what} {path!r}: {err.strerror or err}") from None
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as err:
        raise error(f"{what} {path!r} is not UTF-8 text (byte 0x{data[err.start]:02x} at offset {err.start}: a binary "
                    f"file?); allowed: a UTF-8 text file") from None


def parse_toml(text: str, source: str, error=ParameterError) -> dict:
    """The TOML document ``text`` (from ``source``, a file name or ``"<string>"``) as a dict; a
    syntax error is one :class:`~jaxclear.JaxclearError` (class ``error``) naming the source, the
    line and the column."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise error(f"{source}: not valid TOML: {err}") from None


def read_toml(path, what: str, error=ParameterError) -> dict:
    """The one TOML reader: :func:`parse_toml` of :func:`read_text` of the file ``path`` that a
    user gave as ``what`` (e.g. ``"sweep configuration"``)."""
    path = os.fspath(path)
    return parse_toml(read_text(path, what, error), path, error)


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


def atomic_write_by(path, write, suffix: str = ".tmp") -> str:
    """``write(tmp_path)`` writes the file under a temporary name (for writers that take a path,
    e.g. ArviZ's NetCDF 4 groups); it is then fsync-ed and renamed to ``path``. Returns the path."""
    path = os.fspath(path)
    tmp = path + suffix
    write(tmp)
    with open(tmp, "rb+") as f:
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def atomic_write_text(path, text: str) -> str:
    """:func:`atomic_write_bytes` of UTF-8 text."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def jsonable(obj):
    """``obj`` as plain JSON values: dicts (keys as strings), lists, numbers; numpy and jax arrays
    and scalars become lists and Python numbers, NaN and inf become None (JSON has neither)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if hasattr(obj, "shape") and hasattr(obj, "dtype"):  # numpy / jax arrays and scalars
        arr = np.asarray(obj)
        return jsonable(arr.tolist()) if arr.ndim else jsonable(arr.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def json_text(obj, *, indent: int | None = 2, sort_keys: bool = True, separators=None, default=None) -> str:
    """The one JSON writer: :func:`jsonable` of ``obj`` as strict JSON text (NaN and infinities
    as ``null``, never the bare ``NaN``/``Infinity`` that strict parsers refuse). Indented and
    with sorted keys by default; ``default`` (e.g. ``str``) turns what is not JSON into JSON,
    else that is a ``TypeError``. Readers of files written before take ``null`` for NaN."""
    return json.dumps(jsonable(obj), indent=indent, sort_keys=sort_keys, separators=separators, default=default,
                      allow_nan=False)


def atomic_write_json(path, obj, *, indent: int | None = 2, sort_keys: bool = True) -> str:
    """:func:`atomic_write_text` of :func:`json_text` (indented, sorted keys by default)."""
    return atomic_write_text(path, json_text(obj, indent=indent, sort_keys=sort_keys) + "\n")


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
                holder = f.read(200).strip() or "unknown"
        except (OSError, ValueError):  # unreadable, or not text
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
