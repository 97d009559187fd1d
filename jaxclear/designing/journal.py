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

The first line holds the design's key (:func:`jaxclear._storage.fingerprint` of the mechanism,
the variables, objective, constraints, members and settings): a journal of other inputs is
replaced, as a fit's checkpoint is. A last line cut short by a kill is dropped; any other line
that cannot be read is a :class:`~jaxclear.CheckpointError` naming the file.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from .._errors import CheckpointError
from .._storage import atomic_write_text, fsync_append, json_text

JOURNAL_NAME = "design_evaluations.jsonl"
FORMAT = 1


def _float(v) -> float:
    """A number of the journal: ``null`` (a value that was not finite) is NaN; the strings
    ``"nan"``, ``"inf"``, ``"-inf"`` of journals written before read as those floats."""
    return math.nan if v is None else float(v)


class Journal:
    """The evaluations of one design, in memory and (``folder`` not None) on disk."""

    def __init__(self, folder, key: str, resume: bool = True):
        self.path = None if folder is None else os.path.join(os.fspath(folder), JOURNAL_NAME)
        self.key = key
        self.values: dict[bytes, dict] = {}
        self.gradients: dict[bytes, dict] = {}
        self.loaded = 0
        if self.path is None:
            return
        if resume and os.path.isfile(self.path):
            self._load()
        if not self.loaded:
            atomic_write_text(self.path, json_text({"key": key, "format": FORMAT}, indent=None, sort_keys=False) + "\n")

    @staticmethod
    def point_key(u) -> bytes:
        return np.ascontiguousarray(np.asarray(u, dtype="<f8")).tobytes()

    def _load(self):
        with open(self.path, encoding="utf-8") as f:
            lines = f.read().split("\n")
        try:
            head = json.loads(lines[0])
        except ValueError:
            head = None
        if not isinstance(head, dict) or head.get("key") != self.key:
            return  # another design's journal (or none): replaced
        body = [line for line in lines[1:]]
        while body and not body[-1].strip():
            body.pop()
        for i, line in enumerate(body):
            try:
                entry = json.loads(line)
                entry["u"] = [_float(v) for v in entry["u"]]
                entry["values"] = [_float(v) for v in entry["values"]]
                if entry["kind"] == "gradient":
                    entry["jacobian"] = [[_float(v) for v in row] for row in entry["jacobian"]]
            except (ValueError, KeyError, TypeError) as exc:
                if i == len(body) - 1:  # cut short by a kill while it was written: that evaluation is redone
                    break
                raise CheckpointError(f"the design journal {self.path!r} is damaged at line {i + 2} "
                                      f"({type(exc).__name__}: {exc}); delete it, or start over with --restart "
                                      "(API: resume=False)") from None
            self._remember(entry)
            self.loaded += 1
        if self.loaded < len(body):  # rewrite without the cut line
            text = "\n".join([lines[0]] + body[: self.loaded]) + "\n"
            atomic_write_text(self.path, text)

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

    def add(self, u, values, status, wall_s: float, jacobian=None) -> dict:
        """Record an evaluation (on disk first); returns it."""
        entry = {"kind": "value" if jacobian is None else "gradient", "u": [float(v) for v in np.asarray(u)],
                 "values": [float(v) for v in np.asarray(values)], "status": [int(s) for s in np.asarray(status)],
                 "wall_s": float(wall_s)}
        if jacobian is not None:
            entry["jacobian"] = [[float(v) for v in row] for row in np.asarray(jacobian)]
        if self.path is not None:
            line = json_text(entry, indent=None, sort_keys=False, separators=(",", ":"))
            fsync_append(self.path, line + "\n")
        self._remember(entry)
        return entry


__all__ = ["JOURNAL_NAME", "Journal"]
