"""The one protocol of a driver's result (issue 40): :class:`AbstractResult`.

Every driver returns a result that can say what it found in four ways, each with one name:
``to_dict()`` (JSON-ready values: :func:`jaxclear._storage.jsonable`'s rules, NaN and infinities
as ``None``), ``write(folder)`` (its files, through the atomic writers of
:mod:`jaxclear._storage`; returns their paths), ``summary()`` (a few lines of text for a
terminal) and ``plot(path=None)`` (its main figure: the figure, or ``path`` once written). The
command line writes a result's files through ``write`` only, so each file format has one writer.
"""

from __future__ import annotations

import abc
import warnings
from collections.abc import Mapping


class AbstractResult(abc.ABC):
    """What every driver's result implements: :meth:`to_dict`, :meth:`write`, :meth:`summary`
    and :meth:`plot` (the fit's :class:`~jaxclear.FitResult` and :class:`~jaxclear.StatisticsFitResult`,
    :class:`~jaxclear.PosteriorResult`,
    :class:`~jaxclear.DesignResult`, :class:`~jaxclear.ToleranceResult`, the Lyapunov report
    :class:`~jaxclear.chaos.report.ChaosReport`, :class:`~jaxclear.SweepResult`, the wear
    history :class:`~jaxclear.WearHistory`)."""

    @abc.abstractmethod
    def to_dict(self) -> dict:
        """The result as JSON-ready values (dicts with string keys, lists, numbers, strings,
        ``None`` for NaN and infinities): what its JSON file holds."""

    @abc.abstractmethod
    def write(self, folder, *, plots: bool = True) -> list[str]:
        """Write the result's files (its JSON, tables and, with ``plots``, figures) into
        ``folder`` (created if missing), atomically each; returns their paths."""

    @abc.abstractmethod
    def summary(self) -> str:
        """A few lines of text for a terminal: the outcome first, then the numbers that matter."""

    @abc.abstractmethod
    def plot(self, path=None):
        """The result's main figure: the :class:`matplotlib.figure.Figure` (``path`` None), or
        ``path`` once the figure is saved there."""


def deprecated(old: str, new: str, *, stacklevel: int = 2) -> None:
    """The :class:`DeprecationWarning` of an old spelling ``old`` (use ``new``), removed in the
    next release (CHANGELOG.md lists each), in the one wording of every old spelling: "``old``
    is deprecated and will be removed in the next release; use ``new``". ``stacklevel``: as
    :func:`warnings.warn`'s, counted from the caller of this function (2, the default: the
    caller's caller, whose line the warning names)."""
    warnings.warn(f"{old} is deprecated and will be removed in the next release; use {new}", DeprecationWarning,
                  stacklevel=stacklevel + 1)


class SummaryTable(Mapping):
    """A result's ``summary``, where it once was a table (a field): called, the text of
    :meth:`AbstractResult.summary`; read as the old mapping (``res.summary["name"]``), the table
    now named ``new``, with a :class:`DeprecationWarning` (one release)."""

    def __init__(self, table: Mapping, text, old: str, new: str):
        self._table, self._text, self._old, self._new = table, text, old, new

    def __call__(self) -> str:
        return self._text()

    def _warn(self) -> None:
        warnings.warn(f"{self._old} as a table is deprecated: it is now the method summary() (the text); the table is "
                      f"{self._new}; reading it here will be removed in the next release", DeprecationWarning,
                      stacklevel=3)

    def __getitem__(self, key):
        self._warn()
        return self._table[key]

    def __iter__(self):
        self._warn()
        return iter(self._table)

    def __len__(self) -> int:
        self._warn()
        return len(self._table)

    def __repr__(self) -> str:
        return self._text()


__all__ = ["AbstractResult", "SummaryTable", "deprecated"]
