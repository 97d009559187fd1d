"""The state of a fit and its checkpoint.

:class:`FitState` is everything a fit needs to continue after a kill: the stage and iteration,
the accepted unknowns and the optimistix solver state of the current stage (its array leaves),
the parameters and window states reached so far, the results of the starts and the history
(and, in the automatic refit from several starts, why it runs).
It is immutable (an ``equinox.Module``): every iteration makes a new one with :meth:`replace`.

The checkpoint ``out/fit_checkpoint.json`` follows the one checkpoint protocol
(:mod:`jaxclear._checkpoint`): ``{"kind", "format", "key", "config", "state"}``: ``key`` is a
fingerprint of the record, the mechanism and sensor leaves and every setting, so a fit started
again with the same inputs resumes where it stopped, and a folder holding another fit's
checkpoint is refused (naming what changed) unless the fit starts over (``--restart``,
``resume=False``). Floats are written with Python's shortest round-trip repr, so a resumed fit
continues from bit-identical numbers. The file is replaced atomically.
"""

from __future__ import annotations

import dataclasses
import json
import math

import equinox as eqx
import numpy as np

from .._checkpoint import Work, key as work_key
from .._errors import CheckpointError

CHECKPOINT_NAME = "fit_checkpoint.json"
#: The format of ``fit_checkpoint.json`` (:mod:`jaxclear._checkpoint`'s version rule).
FORMAT = 1


def _plain(value):
    """Tuples of floats/ints (and nested) -> JSON-ready lists."""
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _frozen(value):
    """Nested lists -> nested tuples (the inverse of :func:`_plain`)."""
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    return value


class FitState(eqx.Module):
    """Where a fit stands.

    Attributes:
        stage, iteration: index of the current stage and of the iteration within it.
        total: iterations so far, all stages and starts (accepted steps and final updates,
            :class:`jaxclear.fitting.solver.StepReport`).
        evaluations: solver steps so far (each one evaluation of the model and its Jacobian).
        x: accepted solver unknowns ``u = D x`` of the current stage (``x``: ``theta_z`` then the
            free window states), or None before the stage has begun.
        column_scale: ``D`` of the current stage (:func:`jaxclear.fitting.solver.column_scale`).
        solver: array leaves of the stage's optimistix solver state (nested tuples), or None.
        theta: ``(P,)`` unconstrained parameters reached so far.
        states: ``(W, 4 n_c)`` unconstrained window start states.
        guesses: per window ``((3 n_b,), (3 n_b,))`` position and velocity guesses at its start.
        starts: per start index (str) ``{"loss", "theta", "reason"}`` of its stage.
        history: one record per iteration ``{"stage", "iteration", "loss", "values"}``.
        skipped: ``"stage name: reason"`` of each stage skipped because no unknown influenced its
            fitted samples (:func:`jaxclear.fitting.run.run_stage`).
        way_in: per window whose start the way in found (:mod:`jaxclear.fitting.way_in`) its
            report ``{"window", "candidates", "finite", "best_loss", "median_loss"}``.
        found: the window start states the way in found (``(W, S)``; every start of the
            parameters of a record that begins mid-run begins from them), or ``()``.
        profile: the points of the profile likelihood computed so far (:mod:`jaxclear.fitting.profile`),
            one dict each ``{"name", "side", "z", "loss", "theta", "states", "reason"}``.
        scan: the points of the scan of held values (:mod:`jaxclear.fitting.scan`), one dict
            each ``{"kind": "held", "name", "value", "loss", "states", "reason", "estimates"}``
            (its parameters: the estimates and the held value), then its ``{"kind": "decision", ...}`` once the scan is done.
        wall: wall time spent so far [s]; stop_reason: why the final stage ended.
        refit: in the automatic refit from several starts (``fit(starts=None)``), why the
            single start before it was not enough (``FitResult.settings["auto_starts"]``);
            "" otherwise. Kept in the refit's state, which is checkpointed from the switch on,
            so that a resumed refit neither fits the single start again nor forgets why it runs.
    """

    stage: int = 0
    iteration: int = 0
    total: int = 0
    evaluations: int = 0
    x: tuple | None = None
    column_scale: tuple | None = None
    solver: tuple | None = None
    theta: tuple = ()
    states: tuple = ()
    guesses: tuple = ()
    starts: tuple = ()
    history: tuple = ()
    skipped: tuple = ()
    way_in: tuple = ()
    found: tuple = ()
    profile: tuple = ()
    scan: tuple = ()
    wall: float = 0.0
    stop_reason: str = ""
    refit: str = ""

    def replace(self, **changes) -> "FitState":
        """A copy with ``changes`` (sequences frozen to tuples)."""
        return dataclasses.replace(self, **{k: _frozen(v) for k, v in changes.items()})

    def start_results(self) -> dict:
        """``{start index: {"loss", "theta", "reason"}}`` of the starts fitted so far."""
        return {int(k): dict(v) for k, v in self.starts}

    def with_start_result(self, index: int, loss: float, theta, reason: str, states=None) -> "FitState":
        """The result of start ``index`` recorded (its window states too where they were fitted)."""
        entry = (str(index), (("loss", float(loss)), ("theta", _frozen(np.asarray(theta).tolist())), ("reason", reason))
                 + ((("states", _frozen(np.asarray(states).tolist())),) if states is not None else ()))
        kept = tuple(e for e in self.starts if e[0] != str(index))
        return dataclasses.replace(self, starts=kept + (entry,))

    def best_start(self) -> dict:
        """The start with the lowest loss: ``{"loss", "theta", "reason"}`` (and ``"states"``)."""
        results = self.start_results()
        return results[min(results, key=lambda j: results[j]["loss"])]

    def at_best_start(self) -> "FitState":
        """A copy at the best start's parameters (and window states, where they were recorded),
        its stop reason the fit's."""
        best = self.best_start()
        return self.replace(theta=best["theta"], stop_reason=best["reason"],
                            **({"states": best["states"]} if "states" in best else {}))

    def to_json(self) -> dict:
        out = {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)}
        out["starts"] = {k: {name: _plain(value) for name, value in v} for k, v in self.starts}
        out["history"] = list(self.history)
        out["profile"] = [_plain_point(p) for p in self.profile]
        out["scan"] = [_plain_point(p) for p in self.scan]
        return out

    @classmethod
    def from_json(cls, data: dict) -> "FitState":
        fields = {f.name for f in dataclasses.fields(cls)}
        values = {k: v for k, v in data.items() if k in fields}
        values["starts"] = tuple((k, (("loss", _number(v["loss"])), ("theta", _frozen(v["theta"])),
                                      ("reason", v["reason"]))
                                  + ((("states", _frozen(v["states"])),) if "states" in v else ()))
                                 for k, v in data.get("starts", {}).items())
        values["history"] = tuple(dict(h, loss=_number(h["loss"])) if "loss" in h else h
                                  for h in data.get("history", ()))
        values["profile"] = tuple(dict(p, loss=_number(p["loss"])) for p in data.get("profile", ()))
        values["scan"] = tuple(dict(p, loss=_number(p["loss"])) for p in data.get("scan", ()))
        return cls(**{k: (v if k in ("history", "profile", "scan") else _frozen(v)) for k, v in values.items()})


def _plain_point(point: dict) -> dict:
    """A profile or scan point JSON-ready (its arrays as lists)."""
    return {k: _plain(v) for k, v in point.items()}


def _number(value) -> float:
    """A loss read back from the checkpoint: ``null`` (how the one JSON writer,
    :func:`jaxclear._storage.json_text`, writes NaN) is NaN."""
    return math.nan if value is None else float(value)


def checkpoint_key(t_rec, y_rec, leaves, config: dict) -> str:
    """Fingerprint of the record (times, values), the mechanism/sensor leaves and the settings."""
    return work_key(np.asarray(t_rec, dtype=float), np.asarray(y_rec, dtype=float), np.asarray(leaves, dtype=float),
                    json.dumps(config, default=str, sort_keys=True), length=20)


class Checkpoint:
    """The checkpoint file of a fit (``out`` None: no checkpoint), a :class:`jaxclear._checkpoint.Work`
    of kind ``fit``; ``clock()`` gives the fit's wall time so far [s], stored with every save."""

    def __init__(self, out, key: str, config: dict, clock=None):
        self.clock = clock
        self.work = Work(out, "fit", key, config, version=FORMAT)
        self.path = self.work.path(CHECKPOINT_NAME)
        self.key = key
        self.config = self.work.config

    def _state(self, saved: dict | None) -> FitState | None:
        if saved is None:
            return None
        try:
            return FitState.from_json(saved["state"])
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise CheckpointError(
                f"the fit checkpoint {self.path!r} is corrupt or unreadable ({type(exc).__name__}: {exc}); "
                f"delete it, or start over with --restart (API: resume=False)"
            ) from None

    def load(self) -> FitState | None:
        """The saved state if the file exists and is this fit's, else None (another fit's
        checkpoint: not this one; :meth:`resume` applies the protocol's mismatch rule). A file
        that cannot be read raises :class:`~jaxclear.CheckpointError` naming it."""
        return self._state(self.work.read_json(CHECKPOINT_NAME, strict=False))

    def resume(self) -> FitState | None:
        """The saved state to resume from, None if there is none; the protocol's rules
        (:mod:`jaxclear._checkpoint`): a checkpoint of another fit is refused
        (:class:`~jaxclear.ParameterError` naming what changed: start over with ``--restart``,
        API ``resume=False``), one of another format or unreadable is a
        :class:`~jaxclear.CheckpointError`."""
        return self._state(self.work.read_json(CHECKPOINT_NAME))

    def save(self, state: FitState):
        if self.path is None:
            return
        if self.clock is not None:
            state = state.replace(wall=float(self.clock()))
        self.work.write_json(CHECKPOINT_NAME, {"state": state.to_json()}, indent=None, sort_keys=False)
