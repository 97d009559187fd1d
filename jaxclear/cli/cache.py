"""The command line's persistent compilation cache: compiled programs kept on disk, so that a
second ``jaxclear simulate`` (or sweep, fit, animate) of a mechanism with the same structure
skips XLA compilation.

JAX's persistent compilation cache (``jax_compilation_cache_dir``) stores each compiled program
under a key of its lowered program, compile options, backend and jax/jaxlib versions; a changed
structure (another law, another joint set) or a new jaxlib is a cache miss, never a wrong
program. Values of parameters are array leaves and do not enter the key. JAX computes that key
from the lowered program, so a process would still trace and lower first; the traced programs
themselves are kept beside it (subfolder ``programs``, :mod:`jaxclear.integrate.programs`), so a
warm run skips tracing too.

Where: ``$JAXCLEAR_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/jaxclear/xla`` (``XDG_CACHE_HOME``
defaults to ``~/.cache``): per user, never a shared folder. Off: ``--no-cache``, or
``JAXCLEAR_CACHE_DIR=off`` (also ``0``, ``none``, empty). The library itself (``import
jaxclear``) configures no cache; :func:`enable` is what the command line calls.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import jax

from ..integrate import programs

#: Environment variable naming the cache folder (``off``, ``0``, ``none`` or empty: no cache).
ENV = "JAXCLEAR_CACHE_DIR"
_OFF = {"", "0", "off", "none", "false", "no"}
#: Subfolder of the traced programs (:mod:`jaxclear.integrate.programs`).
PROGRAMS = "programs"
#: Programs that compile faster than this [s] are not written (the many tiny eager-op programs).
MIN_COMPILE_TIME_S = 0.1


def default_dir() -> Path | None:
    """The cache folder from the environment: ``$JAXCLEAR_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/jaxclear/xla`` or ``~/.cache/jaxclear/xla``; None when switched off."""
    value = os.environ.get(ENV)
    if value is not None:
        return None if value.strip().lower() in _OFF else Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "jaxclear" / "xla"


def enable(folder: Path | str | None) -> Path | None:
    """Point JAX's persistent compilation cache at ``folder`` (created, mode 0700), or leave it
    off when ``folder`` is None. Returns the folder in use. A folder (or its ``programs``
    subfolder) that cannot be created or written leaves the cache off with a one-line warning on
    stderr (the command still runs, compiling as usual)."""
    if folder is None:
        return None
    folder = Path(folder).expanduser()
    problem = _unwritable(folder) or _unwritable(folder / PROGRAMS)
    if problem is not None:
        print(f"warning: {problem}; running without the compilation cache (--cache-dir DIR or {ENV} chooses "
              "another folder, --no-cache switches it off)", file=sys.stderr)
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_TIME_S)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    programs.enable(folder / PROGRAMS)
    return folder


def _unwritable(folder: Path) -> str | None:
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


def active() -> bool:
    """Whether a persistent compilation cache folder is configured in this process."""
    return bool(jax.config.jax_compilation_cache_dir)


def progress_allowed(args) -> bool:
    """Whether to show the integration progress bar: asked for (no ``--no-progress``) and no
    cache active. The bar is a host callback, and JAX writes no program with a host callback to
    its cache; with the cache a repeated run takes well under a second anyway."""
    return not getattr(args, "no_progress", False) and not active()


def configure(args) -> Path | None:
    """Enable the cache for a parsed command line (``--no-cache``, ``--cache-dir``, else the
    environment's :func:`default_dir`). Returns the folder in use, or None."""
    programs.enable(None)  # until a folder is in use
    if getattr(args, "no_cache", False):
        return None
    folder = getattr(args, "cache_dir", None)
    return enable(Path(folder) if folder else default_dir())


__all__ = ["ENV", "MIN_COMPILE_TIME_S", "active", "configure", "default_dir", "enable", "progress_allowed"]
