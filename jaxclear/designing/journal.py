"""The journal of a design's evaluations: what makes a design resumable, bit for bit.

Every evaluation (the objective and constraints at a point, or those and their Jacobian) is
appended to ``design_evaluations.jsonl`` and fsync-ed before the optimiser sees it
(:func:`jaxclear._storage.fsync_append`). A design started again with the same inputs reads the
journal and runs the same optimiser from the same start: SciPy's methods are deterministic, so
it asks for the same points in the same order, and every point the journal holds is answered
from it (floats are written with Python's shortest round-trip repr, so the answers are the same
bits); the first point it does not hold is where the work continues. So the optimiser's own
state never needs saving, whatever the method. A value that is not finite (a failed run) is
written as ``null`` (:func:`jaxclear._storage.json_text`, strict JSON) and read back as NaN, as
are the strings ``"nan"``, ``"inf"`` and ``"-inf"`` of journals written before; the optimiser
takes any value that is not finite for a failed evaluation.

The journal follows the one checkpoint protocol (:mod:`jaxclear._checkpoint`): its first line
is the header ``{"kind", "format", "key", "config"}``, the key a fingerprint of the mechanism,
the variables, objective, constraints, members and settings. A journal of other inputs is
refused (a :class:`~jaxclear.ParameterError` naming what changed; ``--restart``,
``resume=False``, starts over); a last line cut short by a kill is dropped; any other line that
cannot be read is a :class:`~jaxclear.CheckpointError` naming the file and the line.
"""

from __future__ import annotations

import json
import math

import numpy as np

from .._checkpoint import Work
from .._storage import json_text

JOURNAL_NAME = "design_evaluations.jsonl"
FORMAT = 1


def _float(v) -> float:
    """A number of the journal: ``null`` (a value that was not finite) is NaN; the strings
    ``"nan"``, ``"inf"``, ``"-inf"`` of journals written before read as those floats."""
    return math.nan if v is None else float(v)


def _entry(line: str) -> dict:
    """One evaluation of the journal (a line of JSON), its numbers as floats."""
    entry = json.loads(line)
    entry["u"] = [_float(v) for v in entry["u"]]
    entry["values"] = [_float(v) for v in entry["values"]]
    if entry["kind"] == "gradient":
        entry["jacobian"] = [[_float(v) for v in row] for row in entry["jacobian"]]
    return entry


class Journal:
    """The evaluations of one design, in memory and (``folder`` not None) on disk: an append-only
    journal of the one checkpoint protocol (:class:`jaxclear._checkpoint.Work` of kind
    ``design``; ``config``: the design's settings, named by a mismatch)."""

    def __init__(self, folder, key: str, resume: bool = True, config: dict | None = None):
        self.work = Work(folder, "design", key, config, version=FORMAT)
        self.path = self.work.path(JOURNAL_NAME)
        self.key = key
        self.values: dict[bytes, dict] = {}
        self.gradients: dict[bytes, dict] = {}
        entries = self.work.open_journal(JOURNAL_NAME, restart=not resume, parse=_entry)
        for entry in entries:
            self._remember(entry)
        self.loaded = len(entries)

    @staticmethod
    def point_key(u) -> bytes:
        return np.ascontiguousarray(np.asarray(u, dtype="<f8")).tobytes()

    def _remember(self, entry: dict):
        table = self.gradients if entry["kind"] == "gradient" else self.values
        table[self.point_key(entry["u"])] = entry

    def find(self, u, gradient: bool) -> dict | None:
        """The evaluation at ``u``: with ``gradient``, one with the Jacobian; else the plain one
        if there is one, else one with the Jacobian. Deterministic whether the journal was filled
        as the design went or read back at once: a plain evaluation at ``u`` is only ever made
        while no Jacobian at ``u`` exists, so a request answered by a plain one the first time is
        answered by it again on resumption."""
        k = self.point_key(u)
        if gradient:
            return self.gradients.get(k)
        return self.values.get(k) or self.gradients.get(k)

    def add(self, u, values, status, wall_s: float, jacobian=None, extra: dict | None = None) -> dict:
        """Record an evaluation (on disk first); returns it. ``extra``: what else the evaluation
        knows, JSON (a steady design's gradient error, :mod:`.steady`), kept as ``entry["extra"]``."""
        entry = {"kind": "value" if jacobian is None else "gradient", "u": [float(v) for v in np.asarray(u)],
                 "values": [float(v) for v in np.asarray(values)], "status": [int(s) for s in np.asarray(status)],
                 "wall_s": float(wall_s)}
        if jacobian is not None:
            entry["jacobian"] = [[float(v) for v in row] for row in np.asarray(jacobian)]
        if extra is not None:
            entry["extra"] = extra
        self.work.append(JOURNAL_NAME, [json_text(entry, indent=None, sort_keys=False, separators=(",", ":"))])
        self._remember(entry)
        return entry


__all__ = ["JOURNAL_NAME", "Journal"]
