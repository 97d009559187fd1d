"""The command line's caches: compiled and traced programs kept on disk, so that a second
``jaxclear simulate`` (or sweep, fit, animate) of a mechanism with the same structure skips
tracing and XLA compilation.

The caches themselves are jaxclear's, shared with the Python API (:mod:`jaxclear.caches`: JAX's
persistent compilation cache in the folder, the traced programs of
:mod:`jaxclear.integrate._programs` in its subfolder ``programs``, a size limit, least recently
used removed first); ``import jaxclear`` already enables them in the environment's folder. The
command line adds its options: ``--cache-dir DIR`` (another folder, JAX's compilation cache
included, whatever JAX's own settings) and ``--no-cache`` (both off for the command).

Where: ``$JAXCLEAR_CACHE_DIR`` if set, else the user's cache folder's ``jaxclear/xla``
(``~/.cache/jaxclear/xla`` on Linux, ``$XDG_CACHE_HOME/jaxclear/xla`` when that is set): per
user, never a shared folder. Off: ``--no-cache``, or ``JAXCLEAR_CACHE_DIR=off`` (also ``0``,
``none``, empty).
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax

from ..integrate import caches

#: Environment variable naming the cache folder (``off``, ``0``, ``none`` or empty: no cache).
ENV = caches.ENV
#: Subfolder of the traced programs (:mod:`jaxclear.integrate._programs`).
PROGRAMS = caches.PROGRAMS
#: Programs that compile faster than this [s] are not written (the many tiny eager-op programs).
MIN_COMPILE_TIME_S = caches.MIN_COMPILE_TIME_S


def default_dir() -> Path | None:
    """The cache folder from the environment (:func:`jaxclear.caches.default_dir`):
    ``$JAXCLEAR_CACHE_DIR``, else the user's cache folder's ``jaxclear/xla``; None when switched
    off."""
    return caches.default_dir()


def enable(folder: Path | str | None) -> Path | None:
    """Keep compiled and traced programs in ``folder`` (:func:`jaxclear.caches.enable_cache`), or
    switch both off when ``folder`` is None. Returns the folder in use. A folder (or its
    ``programs`` subfolder) that cannot be created or written leaves the caches off with a
    one-line warning on stderr (the command still runs, compiling as usual)."""
    if folder is None:
        caches.disable_cache()
        return None
    folder = Path(folder).expanduser()
    problem = caches.unwritable(folder) or caches.unwritable(folder / PROGRAMS)
    if problem is not None:
        caches.disable_cache()
        print(f"warning: {problem}; running without the compilation cache (--cache-dir DIR or {ENV} chooses "
              "another folder, --no-cache switches it off)", file=sys.stderr)
        return None
    return caches.enable_cache(folder, warn=False)


def active() -> bool:
    """Whether a persistent compilation cache folder is configured in this process."""
    return bool(jax.config.jax_compilation_cache_dir)


def progress_allowed(args) -> bool:
    """Whether to show the integration progress bar: asked for (no ``--no-progress``) and no
    cache active. The bar is a host callback, and JAX writes no program with a host callback to
    its cache; with the cache a repeated run takes well under a second anyway."""
    return not getattr(args, "no_progress", False) and not active()


def configure(args) -> Path | None:
    """Enable the caches for a parsed command line (``--no-cache``, ``--cache-dir``, else the
    environment's :func:`default_dir`). Returns the folder in use, or None."""
    if getattr(args, "no_cache", False):
        return enable(None)
    folder = getattr(args, "cache_dir", None)
    return enable(Path(folder) if folder else default_dir())


__all__ = ["ENV", "MIN_COMPILE_TIME_S", "PROGRAMS", "active", "configure", "default_dir", "enable", "progress_allowed"]
