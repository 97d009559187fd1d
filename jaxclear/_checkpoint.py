"""The one checkpoint/journal protocol: a resumable piece of long work in an output folder.

Every driver that resumes after a kill (the sweep's runs and chunks, the fit's
``fit_checkpoint.json``, the posterior's ``posterior_checkpoint.npz``, the design's journal
``design_evaluations.jsonl``, wear's ``wear.json``; the tolerance study resumes through its
sweeps) describes its work by a :class:`Work`: what it is (``kind``), the key that must match
for the folder's state to be resumed (a content fingerprint of everything that changes the
result, :func:`key`), the configuration that key was made of (JSON, kept in the state so that a
mismatch can say what changed) and the version of its file format. The :class:`Work` owns:

* **the header** every state carries: ``{"kind", "format", "key", "config"}`` (and ``finished``
  where the state is one file): the first line of a journal, the top-level keys of a JSON state,
  a ``header`` entry (JSON text) of an NPZ state;
* **the mismatch rule** (one for all): a folder whose state was made by another configuration
  is *refused* with a :class:`~jaxclear.ParameterError` naming the folder and what changed,
  unless the driver is told to start over (``--restart``: ``restart=True`` or
  ``resume=False``). Nothing is discarded silently: a sweep or a wear run keeps results that a
  typo would otherwise destroy, and a fit or a design the hours of a long optimisation.
* **the version rule** (one for all): a state whose ``format`` is not the one this jaxclear
  writes is a :class:`~jaxclear.CheckpointError` naming the file, both versions and the way out
  (``--restart``). A state without a ``format`` is of format 1, the format of every state
  written before this protocol (they all still resume);
* **damage**: a state that cannot be read is a :class:`~jaxclear.CheckpointError` naming the
  file (and the line of a journal) and offering ``--restart``; a journal's last line cut short
  by a kill is dropped (that piece of work is done again), any other damaged line is an error;
* **writing**: states replaced atomically (:mod:`jaxclear._storage`: temporary file, fsync,
  rename; JSON through the one JSON writer), journal lines appended and fsync-ed before the
  next piece of work starts;
* **the lock** of the folder (:func:`jaxclear._storage.locked_folder`) for the whole work.
"""

from __future__ import annotations

import contextlib
import json
import os
import zipfile

import numpy as np

from ._errors import CheckpointError, ParameterError
from ._storage import (atomic_write_json, atomic_write_npz, atomic_write_text, fingerprint, fsync_append, json_text,
                       locked_folder)

#: The format of a state that does not say (every state written before this protocol).
UNVERSIONED = 1
#: How many changed entries a mismatch message lists.
MAX_CHANGES = 6


def key(*items, length: int | None = None) -> str:
    """The key of a piece of work: :func:`jaxclear._storage.fingerprint` of ``items`` (arrays
    bit-exact, dicts and other values by their JSON text or repr)."""
    return fingerprint(*(json_text(i, indent=None, default=str) if isinstance(i, dict) else i for i in items),
                       length=length)


def plain_config(config) -> dict:
    """``config`` as plain JSON values (what is not JSON by its ``str``)."""
    return json.loads(json_text(config if config is not None else {}, indent=None, default=str))


def changes(old, new, prefix: str = "") -> list[str]:
    """``"name: old -> new"`` for every entry in which two configurations differ (nested
    dicts by their dotted names)."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for name in sorted(set(old) | set(new), key=str):
            where = f"{prefix}{name}"
            if name not in old:
                out.append(f"{where}: (none) -> {_short(new[name])}")
            elif name not in new:
                out.append(f"{where}: {_short(old[name])} -> (none)")
            else:
                out.extend(changes(old[name], new[name], where + "."))
        return out
    return [] if old == new else [f"{prefix.rstrip('.') or 'configuration'}: {_short(old)} -> {_short(new)}"]


def _short(value, limit: int = 60) -> str:
    text = json_text(value, indent=None, default=str)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class Work:
    """A resumable piece of long work in the output folder ``folder`` (None: nothing on disk).

    Args:
        folder: the output folder, or None.
        kind: what the work is (``"fit"``, ``"sweep"``...): the messages' word and the header's.
        key: the key a state must have to be resumed (:func:`key`).
        config: the configuration the key covers, JSON-ready (kept in the header; a mismatch
            names the entries that differ).
        version: the format of the driver's state files.
        restart: how the user starts over, as the messages say it (the CLI option and the
            API keyword).
    """

    def __init__(self, folder, kind: str, key: str, config=None, *, version: int = 1,
                 restart: str = "--restart (API: resume=False)"):
        self.folder = None if folder is None else os.fspath(folder)
        self.kind = kind
        self.key = None if key is None else str(key)
        self.config = plain_config(config)
        self.version = int(version)
        self.restart = restart

    # ---- the folder ---------------------------------------------------------------------------
    def path(self, name: str) -> str | None:
        """``folder/name``, or None without a folder."""
        return None if self.folder is None else os.path.join(self.folder, name)

    def lock(self):
        """:func:`locked` of the folder."""
        return locked(self.folder, self.kind)

    # ---- the header and its rules -------------------------------------------------------------
    def header(self, finished: bool | None = None) -> dict:
        """``{"kind", "format", "key", "config"}`` (and ``finished`` if given)."""
        head = {"kind": self.kind, "format": self.version, "key": self.key, "config": self.config}
        if finished is not None:
            head["finished"] = bool(finished)
        return head

    def damaged(self, path: str, detail: str) -> CheckpointError:
        """:func:`damaged` with this work's way to start over."""
        return damaged(path, detail, self.restart)

    def is_mine(self, stored: dict) -> bool:
        """Whether the stored header ``stored`` is this work's (its key; no rule applied)."""
        return isinstance(stored, dict) and stored.get("key") == self.key

    def check(self, stored: dict, path: str) -> None:
        """The rules applied to the header ``stored`` of the state at ``path``: the version rule
        (:class:`~jaxclear.CheckpointError`), then the mismatch rule
        (:class:`~jaxclear.ParameterError` naming the folder and what changed)."""
        if not isinstance(stored, dict):
            raise self.damaged(path, f"its header is {type(stored).__name__}, not a table")
        fmt = stored.get("format", UNVERSIONED)
        if fmt != self.version:
            raise CheckpointError(
                f"the {self.kind} state {path!r} is in format {fmt!r}; this version of jaxclear reads format "
                f"{self.version} only: start over with {self.restart}, or use another output folder")
        if stored.get("kind", self.kind) != self.kind:
            raise ParameterError(f"the output folder {os.path.dirname(path) or '.'!r} holds the state of a "
                                 f"{stored.get('kind')}, not of a {self.kind} ({path!r}); use another output folder")
        if not self.is_mine(stored):
            raise ParameterError(self.mismatch(stored, path))

    def mismatch(self, stored: dict, path: str) -> str:
        """The message of the mismatch rule: the folder, what changed, the way out."""
        old = stored.get("config")
        if isinstance(old, dict) and old:
            found = changes(old, self.config)
            what = "; ".join(found[:MAX_CHANGES]) + (f"; and {len(found) - MAX_CHANGES} more"
                                                    if len(found) > MAX_CHANGES else "")
            if not found:
                what = "inputs outside the listed settings (the data, the mechanism's numbers)"
        else:
            what = "not recorded in its state"
        folder = os.path.dirname(path) or "."
        return (f"the {self.kind} output folder {folder!r} holds a different {self.kind} (changed: {what}; "
                f"state {os.path.basename(path)}, key {str(stored.get('key'))[:12]}..., this one {self.key[:12]}...); "
                f"run with {self.restart} to discard it and start over, or use another output folder")

    def accept(self, stored: dict, path: str, restart: bool = False) -> bool:
        """Whether to resume from the state with header ``stored``: False with ``restart``, else
        True once the rules (:meth:`check`) pass (they raise otherwise)."""
        if restart:
            return False
        self.check(stored, path)
        return True

    # ---- one JSON state -----------------------------------------------------------------------
    def read_json(self, name: str, restart: bool = False, strict: bool = True, upgrade=None) -> dict | None:
        """The JSON state ``folder/name`` (header and body keys at its top level), or None when
        there is none, with ``restart``, or (``strict`` False) when it is another work's; the
        rules apply otherwise. ``upgrade(doc)``: a state of format 1 written before this
        protocol, with its header under other names, as the protocol's."""
        path = self.path(name)
        if path is None or restart or not os.path.isfile(path):
            return None
        try:
            with open(path, "rb") as f:
                doc = json.loads(f.read().decode("utf-8"))
        except (OSError, ValueError) as exc:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
            raise self.damaged(path, f"{type(exc).__name__}: {exc}") from None
        if not isinstance(doc, dict):
            raise self.damaged(path, f"it holds a {type(doc).__name__}, not a table")
        if upgrade is not None:
            doc = upgrade(doc)
        if not strict and not self.is_mine(doc):
            return None
        self.check(doc, path)
        return doc

    def document(self, body: dict, finished: bool | None = None) -> dict:
        """A JSON state: the header and the keys of ``body``."""
        return {**self.header(finished), **body}

    def write_json(self, name: str, body: dict, finished: bool | None = None, **options) -> str | None:
        """Replace ``folder/name`` atomically by :meth:`document` (``options``: of
        :func:`jaxclear._storage.atomic_write_json`). Returns the path (None without a folder)."""
        path = self.path(name)
        if path is None:
            return None
        os.makedirs(self.folder, exist_ok=True)
        return atomic_write_json(path, self.document(body, finished), **options)

    # ---- one NPZ state ------------------------------------------------------------------------
    def read_npz(self, name: str, restart: bool = False) -> dict | None:
        """The arrays of the NPZ state ``folder/name`` (its header checked), or None when there
        is none or with ``restart``. A state of format 1 without a header holds its key as the
        array ``key``."""
        path = self.path(name)
        if path is None or restart or not os.path.isfile(path):
            return None
        try:
            with np.load(path, allow_pickle=False) as f:
                arrays = {k: f[k] for k in f.files}
            stored = json.loads(str(arrays.pop("header"))) if "header" in arrays else {"key": str(arrays["key"])}
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise self.damaged(path, f"{type(exc).__name__}: {exc}") from None
        self.check(stored, path)
        return arrays

    def write_npz(self, name: str, arrays: dict, finished: bool | None = None) -> str | None:
        """Replace ``folder/name`` atomically by ``arrays`` and the header (as JSON text)."""
        path = self.path(name)
        if path is None:
            return None
        os.makedirs(self.folder, exist_ok=True)
        body = {k: v for k, v in arrays.items() if k not in ("header", "key")}
        return atomic_write_npz(path, {"header": np.asarray(json_text(self.header(finished), indent=None)), **body})

    # ---- an append-only journal ---------------------------------------------------------------
    def open_journal(self, name: str, restart: bool = False, parse=json.loads) -> list:
        """The entries of the journal ``folder/name`` (its first line the header, one entry a
        line, each read by ``parse``), after the rules; a fresh journal (its header line alone)
        when there is none or with ``restart``. A last line cut short by a kill is dropped and
        the file rewritten without it; another line ``parse`` refuses is a damage error."""
        path = self.path(name)
        if path is None:
            return []
        if restart or not os.path.isfile(path):
            os.makedirs(self.folder, exist_ok=True)
            atomic_write_text(path, json_text(self.header(), indent=None, sort_keys=False) + "\n")
            return []
        try:
            with open(path, "rb") as f:
                text = f.read().decode("utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise self.damaged(path, f"{type(exc).__name__}: {exc}") from None
        lines = text.split("\n")
        try:
            stored = json.loads(lines[0])
        except ValueError:
            raise self.damaged(path, "line 1: not the journal's header") from None
        self.check(stored, path)
        body = lines[1:]
        while body and not body[-1].strip():
            body.pop()
        entries = []
        for i, line in enumerate(body):
            try:
                entries.append(parse(line))
            except (ValueError, KeyError, TypeError) as exc:
                if i == len(body) - 1:  # cut short by a kill while it was written: that work is redone
                    break
                raise self.damaged(path, f"line {i + 2}: {type(exc).__name__}: {exc}") from None
        if len(entries) < len(body) or not text.endswith("\n"):  # rewrite without the cut line
            atomic_write_text(path, "\n".join([lines[0]] + body[: len(entries)]) + "\n")
        return entries

    def append(self, name: str, lines) -> str | None:
        """Append ``lines`` (text, one entry a line, without newlines) to the journal and fsync
        it before the next piece of work starts. Returns the path (None without a folder)."""
        path = self.path(name)
        if path is None or not lines:
            return path
        return append_lines(path, lines)


def damaged(path: str, detail: str, restart: str = "--restart (API: resume=False)") -> CheckpointError:
    """The error of a state or journal that cannot be used: names the file and what is wrong
    with it (the line of a journal), and offers to start over."""
    return CheckpointError(f"{path} is damaged ({detail}); start over with {restart}, which discards the folder's "
                           "earlier work, or use another output folder")


def append_lines(path: str, lines) -> str:
    """Append ``lines`` (text without newlines) to the journal ``path`` and fsync it: on disk
    before the next piece of work starts. Returns the path."""
    return fsync_append(path, "".join(line + "\n" for line in lines))


def locked(folder, kind: str):
    """The lock of the output folder of the work ``kind`` for a ``with`` block
    (:func:`jaxclear._storage.locked_folder`: a second process gets
    :class:`~jaxclear.OutputLockedError` at once, naming the holder); nothing without a folder."""
    if folder is None:
        return contextlib.nullcontext()
    return locked_folder(os.fspath(folder), f"{kind} output folder")


def cut_partial_line(path: str) -> bytes:
    """Cut a last line left without its newline by a kill from the file ``path`` (fsync-ed);
    returns the complete lines' bytes."""
    with open(path, "rb") as f:
        data = f.read()
    if data and not data.endswith(b"\n"):
        cut = data.rfind(b"\n") + 1
        with open(path, "r+b") as f:
            f.truncate(cut)
            f.flush()
            os.fsync(f.fileno())
        data = data[:cut]
    return data


__all__ = ["Work", "append_lines", "changes", "cut_partial_line", "damaged", "key", "locked", "plain_config"]
