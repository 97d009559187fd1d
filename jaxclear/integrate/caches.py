"""Where jaxclear keeps what it compiled, so that a new process skips the work: JAX's persistent
compilation cache (compiled XLA programs) and jaxclear's store of traced programs
(:mod:`jaxclear.integrate._programs`: a new process skips tracing too). Both are on by default,
for the Python API (``import jaxclear`` enables them) and the command line alike, in one folder.

**Where**: ``$JAXCLEAR_CACHE_DIR`` if set, else the folder ``jaxclear/xla`` in the user's cache
folder: ``~/.cache/jaxclear/xla`` on Linux (``$XDG_CACHE_HOME/jaxclear/xla`` when that is set);
with the ``platformdirs`` package installed, the platform's own on macOS
(``~/Library/Caches/jaxclear/xla``) and Windows (``%LOCALAPPDATA%\\jaxclear\\Cache\\xla``). The
compiled programs lie in the folder, the traced ones in its subfolder ``programs``; created
per user, mode 0700. :func:`cache_folder` tells the folder in use.

**Size**: at most ``$JAXCLEAR_CACHE_MAX_MB`` megabytes (default :data:`DEFAULT_MAX_MB`) in all,
3/4 for the compiled programs (JAX's own least-recently-used eviction,
``jax_compilation_cache_max_size``) and 1/4 for the traced ones (least recently used removed
first). One entry holds 0.1-2 MB (benchmarks/README.md, "Time to first result").

**Off**: ``JAXCLEAR_CACHE_DIR=off`` (also ``0``, ``none``, ``false``, ``no`` or empty) before
``import jaxclear``, or :func:`disable_cache` in a process; ``jaxclear --no-cache`` for one
command. :func:`clear_cache` removes the files (only the cache's own).

**Your own JAX settings win**: where JAX's compilation cache was configured before
``import jaxclear`` (``JAX_COMPILATION_CACHE_DIR``, or ``jax.config.update(
"jax_compilation_cache_dir", ...)``), jaxclear leaves it, and JAX's thresholds, alone and keeps
only its traced programs in its folder. Otherwise it sets the folder, the size limit and a
minimum compile time of :data:`MIN_COMPILE_TIME_S` (the many tiny programs of eager operations
are not written).

**Safe**: a compiled program is keyed by JAX on its lowered program, options and versions; a
traced program by everything its trace depends on (jaxclear's sources, the library versions,
JAX's options, the structure and static values of the arguments). A call whose arguments cannot
be fingerprinted (a mechanism holding a Python callable, such as a ``FunctionDriver``'s
function, or a user's own law class) opts out by itself and is traced as usual. A new jaxclear,
jax or a changed structure is a miss, never a wrong program.
"""

from __future__ import annotations

import os
import tempfile
import time
import warnings
from pathlib import Path

import jax
from jax.experimental.compilation_cache import compilation_cache

from .._errors import ParameterError
from . import _programs as programs

#: Environment variable naming the cache folder (``off``, ``0``, ``none``, ``false``, ``no`` or
#: empty: no cache).
ENV = "JAXCLEAR_CACHE_DIR"
#: Environment variable with the size limit of the cache folder in megabytes.
SIZE_ENV = "JAXCLEAR_CACHE_MAX_MB"
#: The size limit without :data:`SIZE_ENV` [MB].
DEFAULT_MAX_MB = 2048
#: Subfolder of the traced programs (:mod:`jaxclear.integrate._programs`).
PROGRAMS = "programs"
#: Programs that compile faster than this [s] are not written (the many tiny eager-op programs).
MIN_COMPILE_TIME_S = 0.1
#: Share of the size limit for the traced programs (the rest: the compiled ones).
PROGRAMS_SHARE = 0.25

_OFF = {"", "0", "off", "none", "false", "no"}
_STATE = {"folder": None, "jax": False}  # the folder in use; whether jaxclear set JAX's cache


def _user_cache_root() -> Path:
    """The user's cache folder: platformdirs' where installed, else ``$XDG_CACHE_HOME`` or
    ``~/.cache``."""
    try:
        import platformdirs
    except ImportError:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        return Path(base) / "jaxclear"
    return Path(platformdirs.user_cache_dir("jaxclear", appauthor=False))


def default_dir(respect_off: bool = True) -> Path | None:
    """The cache folder the environment asks for: ``$JAXCLEAR_CACHE_DIR``, else the user's cache
    folder's ``jaxclear/xla``; None when ``$JAXCLEAR_CACHE_DIR`` switches it off (unless
    ``respect_off`` is False: then the user's cache folder)."""
    value = os.environ.get(ENV)
    if value is not None and value.strip().lower() in _OFF:
        return None if respect_off else _user_cache_root() / "xla"
    if value is not None:
        return Path(value).expanduser()
    return _user_cache_root() / "xla"


def max_megabytes() -> float:
    """The size limit of the cache folder [MB]: ``$JAXCLEAR_CACHE_MAX_MB``, else
    :data:`DEFAULT_MAX_MB`; a value that is not a number > 0 is refused with a warning."""
    value = os.environ.get(SIZE_ENV)
    if value is None:
        return float(DEFAULT_MAX_MB)
    try:
        mb = float(value)
        if not mb > 0 or mb == float("inf"):
            raise ValueError
    except ValueError:
        warnings.warn(f"{SIZE_ENV}={value!r} is not a number of megabytes > 0; using {DEFAULT_MAX_MB}",
                      stacklevel=2)
        return float(DEFAULT_MAX_MB)
    return mb


def unwritable(folder: Path) -> str | None:
    """Why ``folder`` cannot hold cache files (created if missing, mode 0700; a file is written
    and removed to find out), or None when it can."""
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".probe-")
        os.close(fd)
        os.unlink(probe)
    except FileExistsError:
        return f"the compilation cache folder {str(folder)!r} is a file, not a folder"
    except OSError as err:
        return f"the compilation cache folder {str(folder)!r} is not writable ({err.strerror or err})"
    return None


def _stamp_entries(folder: Path) -> None:
    """Give each compiled program in ``folder`` written without a size limit (by an older
    jaxclear, or JAX with ``jax_compilation_cache_max_size`` -1) the access-time file that JAX's
    least-recently-used eviction reads beside it (``KEY-atime``, 8 bytes of nanoseconds); without
    it JAX's eviction fails and no new program would be written."""
    now = time.time_ns().to_bytes(8, "little")
    for entry in folder.glob("*-cache"):
        stamp = entry.with_name(entry.name[: -len("-cache")] + "-atime")
        if not stamp.exists():
            try:
                stamp.write_bytes(now)
            except OSError:
                pass


def _use_jax_cache(folder: Path | None, limit_bytes: int | None = None) -> None:
    """Point JAX's persistent compilation cache at ``folder`` (None: off), with the size limit
    and :data:`MIN_COMPILE_TIME_S`; JAX reads them at its next compilation."""
    if folder is None:
        jax.config.update("jax_compilation_cache_dir", None)
    else:
        _stamp_entries(folder)
        jax.config.update("jax_compilation_cache_dir", str(folder))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_TIME_S)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
        jax.config.update("jax_compilation_cache_max_size", -1 if limit_bytes is None else int(limit_bytes))
    compilation_cache.reset_cache()  # a cache JAX already opened is opened again with these


def enable_cache(folder: str | os.PathLike | None = None, *, max_mb: float | None = None,
                 compilation: bool = True, warn: bool = True) -> Path | None:
    """Keep compiled and traced programs in ``folder`` for this process and later ones.

    Args:
        folder: the cache folder (created, mode 0700); default: ``$JAXCLEAR_CACHE_DIR`` if it
            names a folder, else the user's cache folder (an explicit call overrides
            ``JAXCLEAR_CACHE_DIR=off``).
        max_mb: size limit of the folder [MB] (default: ``$JAXCLEAR_CACHE_MAX_MB`` or
            :data:`DEFAULT_MAX_MB`); 3/4 for the compiled programs, 1/4 for the traced ones.
        compilation: also point JAX's persistent compilation cache at the folder (False: the
            traced programs only, JAX's settings left as they are).
        warn: warn when the folder cannot be written (the command line prints its own line).

    Returns:
        The folder in use, or None when it cannot be written (the caches then stay off, with a
        warning: the work goes on, compiling as usual).
    """
    folder = Path(folder).expanduser() if folder is not None else default_dir(respect_off=False)
    mb = max_megabytes() if max_mb is None else float(max_mb)
    if not 0 < mb < float("inf"):
        raise ParameterError(f"max_mb = {max_mb} is outside the allowed range (0, inf)")
    problem = unwritable(folder) or unwritable(folder / PROGRAMS)
    if problem is not None:
        disable_cache()
        if warn:
            warnings.warn(f"{problem}; going on without the compilation cache ({ENV}=DIR chooses another "
                          f"folder, {ENV}=off switches it off)", stacklevel=2)
        return None
    limit = int(mb * 1e6)
    if compilation:
        _use_jax_cache(folder, int(limit * (1 - PROGRAMS_SHARE)))
    elif _STATE["jax"]:  # jaxclear's earlier choice, not the user's: leave JAX's cache off
        _use_jax_cache(None)
    _STATE.update(folder=folder, jax=compilation)
    programs.enable(folder / PROGRAMS, max_bytes=int(limit * PROGRAMS_SHARE))
    return folder


def disable_cache() -> None:
    """No compiled or traced programs kept from now on in this process (none read either):
    jaxclear's store of traced programs off, and JAX's persistent compilation cache off where
    jaxclear switched it on (one the user configured in JAX is left alone). The files stay
    (:func:`clear_cache` removes them)."""
    programs.enable(None)
    if _STATE["jax"]:
        _use_jax_cache(None)
    _STATE.update(folder=None, jax=False)


def cache_folder() -> Path | None:
    """The cache folder in use in this process (None: off)."""
    return _STATE["folder"]


def clear_cache(folder: str | os.PathLike | None = None) -> int:
    """Remove the cache's files from ``folder`` (default: the folder in use, else the one the
    environment names): JAX's compiled programs (``*-cache``, ``*-atime``) and the traced ones
    (``programs/*.jaxexport``); nothing else in the folder is touched. Returns how many files
    were removed. Programs already loaded in this process stay in its memory."""
    folder = Path(folder).expanduser() if folder is not None else (cache_folder() or default_dir(respect_off=False))
    removed = 0
    patterns = [(folder, "*-cache"), (folder, "*-atime"), (folder / PROGRAMS, f"*{programs.SUFFIX}")]
    for where, pattern in patterns:
        for path in where.glob(pattern):
            try:
                path.unlink()
                removed += 1
            except OSError:
                pass
    return removed


def enable_at_import() -> Path | None:
    """What ``import jaxclear`` does: :func:`enable_cache` in the environment's folder, unless
    ``JAXCLEAR_CACHE_DIR`` switches it off; JAX's compilation cache only where the user has not
    configured one (``JAX_COMPILATION_CACHE_DIR`` or ``jax_compilation_cache_dir``)."""
    folder = default_dir()
    if folder is None:
        return None
    users = bool(jax.config.jax_compilation_cache_dir) and not _STATE["jax"]
    return enable_cache(folder, compilation=not users)


__all__ = ["DEFAULT_MAX_MB", "ENV", "MIN_COMPILE_TIME_S", "PROGRAMS", "PROGRAMS_SHARE", "SIZE_ENV", "cache_folder",
           "clear_cache", "default_dir", "disable_cache", "enable_at_import", "enable_cache", "max_megabytes",
           "unwritable"]
