"""Optional dependencies: which extra of ``pyproject.toml`` (``[project.optional-dependencies]``)
provides which importable module, and the one check that a feature needing an extra runs before
any work: :func:`require_extra`. Its error says, in one line, what is missing and the
``pip install`` line that provides it.

:data:`EXTRAS` mirrors ``pyproject.toml`` (tests/test_extras.py checks that every runtime extra
and its packages are in both).
"""

from __future__ import annotations

import importlib.util

from ._errors import MissingExtraError

#: extra -> the modules it provides that jaxclear imports (extras only the tests, the
#: documentation or the benchmarks need are not listed: ``test``, ``docs``)
EXTRAS = {
    # jaxclear.fitting.posterior (jaxclear fit --posterior): BlackJAX's NUTS, ArviZ's diagnostics,
    # NetCDF 4 groups through h5netcdf; jaxclear.tolerance (jaxclear tolerance): SALib's Sobol' indices
    "uncertainty": ("blackjax", "arviz", "h5netcdf", "SALib"),
    # jaxclear.chaos.signals.rosenstein: Rosenstein's time-series Lyapunov exponent (nolds)
    "chaos": ("nolds",),
    # benchmarks/bench_design.py: CMA-ES
    "bench": ("cma",),
}


def install_line(extra: str) -> str:
    """The command that installs ``extra``: ``pip install "jaxclear[EXTRA]"``."""
    return f'pip install "jaxclear[{extra}]"'


def missing_modules(extra: str, modules=None) -> list[str]:
    """The modules of ``extra`` (or the subset ``modules``) that cannot be found here, without
    importing them (``importlib.util.find_spec``: a module set to ``None`` in ``sys.modules``
    counts as missing)."""
    if extra not in EXTRAS:
        raise KeyError(f"unknown extra {extra!r}; known: {sorted(EXTRAS)}")
    wanted = EXTRAS[extra] if modules is None else tuple(modules)
    out = []
    for name in wanted:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a parent package that fails, a module without a spec
            found = False
        if not found:
            out.append(name)
    return out


def extra_message(extra: str, what: str, missing, reason: str = "") -> str:
    """The one-line message of a missing extra (the one format, also for a module that is found
    but fails on import: ``reason``)."""
    why = f" ({reason})" if reason else ""
    return (f"{what} needs {', '.join(missing)}, of the optional extra [{extra}], which is not installed{why}: "
            f"{install_line(extra)}")


def require_extra(extra: str, what: str, modules=None) -> None:
    """Raise :class:`~jaxclear.MissingExtraError` (a :class:`~jaxclear.JaxclearError` and an
    :class:`ImportError`) when a module of ``extra`` (or of the subset ``modules``) is missing.
    Call it before any work: ``what`` names the feature (``"jaxclear tolerance with sobol_n > 0"``)."""
    missing = missing_modules(extra, modules)
    if missing:
        err = MissingExtraError(extra_message(extra, what, missing))
        err.name = missing[0]  # ImportError's attribute: the first missing module
        raise err


__all__ = ["EXTRAS", "extra_message", "install_line", "missing_modules", "require_extra"]
