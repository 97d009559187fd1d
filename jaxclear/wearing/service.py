r"""Wear over a long service: simulate a window, wear the bearing, run the next window on the
worn profile (:func:`wear`).

Each update simulates the mechanism over the settings' span on the current profile (exact contact
onsets off: a worn profile's contact flickers at the Gauss points' resolution), discards
the first ``settle`` seconds (the start transient: every window starts from the assembled
initial state, so that all windows share one compiled program), integrates Archard's law over
the rest (:func:`~jaxclear.wear.archard.window_wear`), multiplies the window's wear by the
extrapolation factor ``cycles_per_update`` (a window stands for that many identical cycles, as in
Flores, Mech. Mach. Theory 44 (2009) 1211-1222, where wear is far too slow to simulate cycle by
cycle) and updates the bearing (:func:`~jaxclear.wear.profile.worn`).

With an output folder the work is written as it goes and resumes after a kill: after every
update ``profile_NNNN.csv`` (node angle, cumulative depth), a row of ``updates.csv``, the
state ``wear.json`` (atomically) and the polar figure ``profile.png``; the folder is locked
while it runs. ``wear.json`` is what a resume trusts: it rewrites ``updates.csv`` from the
state's records, so a row appended by a run killed before it replaced the state is never
listed twice.
A finished :class:`WearHistory` (an :class:`~jaxclear.AbstractResult`) writes the same files
into any folder through the same functions (:meth:`WearHistory.write`).
"""

from __future__ import annotations

import dataclasses
import os
import warnings

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from tqdm import tqdm

from .._errors import CheckpointError, ParameterError, check_range
from .._interrupt import stop_at_safe_points
from .._numbers import as_typed
from .._results import AbstractResult
from .._checkpoint import Work, key as work_key
from .._storage import atomic_write_json, atomic_write_text, fsync_append, jsonable
from ..integrate import Settings
from ..integrate import check_status, simulate
from ..integrate import ExactOnsets, StepOnsets
from ..model.mechanism import Mechanism
from .figures import plot_wear
from .archard import WindowWear, wear_element, window_wear
from .profile import node_angles, prepare, worn

#: A single update wearing more than this fraction of the clearance gets a warning.
STEP_WARNING = 0.05
#: Why wear runs with step onsets (:class:`~jaxclear.StepOnsets`), never exact ones: what
#: :func:`wear` and ``jaxclear wear --onsets exact`` say.
ONSETS_WHY = ("a worn bearing's contact flickers in and out at the hybrid law's Gauss points as they cross the worn "
              "profile, and exact onsets retry a step at every flicker (a worn benchmark window reached max_steps); "
              "the wear integral needs no onset timing")
#: Most bearing nodes (checked before the node arrays are made).
MAX_NODES = 100_000
STATE_FILE = "wear.json"
#: The format of ``wear.json`` (:mod:`jaxclear._checkpoint`'s version rule).
FORMAT = 1
UPDATES_FILE = "updates.csv"
FIGURE_FILE = "profile.png"
#: The numbers of an update's record in the state file (besides ``depth_m``, the depth at the nodes).
RECORD_KEYS = ("service_time_s", "cycles", "worn_volume_m3", "max_depth_m", "mean_depth_m", "peak_force_n",
               "max_penetration_m")
UPDATES_HEADER = "update,service_time_s,cycles,worn_volume_m3,max_depth_m,mean_depth_m,peak_force_n,max_penetration_m\n"


@dataclasses.dataclass(frozen=True)
class WearOptions:
    """What a wear run does.

    Attributes:
        coefficient: Archard's dimensional wear coefficient :math:`k_w` [m^2/N], > 0.
        updates: number of profile updates (windows) [-], >= 1.
        cycles_per_update: extrapolation factor [-], >= 1: the window's wear is multiplied by it.
        settle: start of each window discarded [s], >= 0 and below the settings' span.
        joint: the clearance joint worn (index or name; ``None``: the only one).
        n_nodes: bearing nodes [-], in [8, :data:`MAX_NODES`]; at most half the hybrid law's points (else a
            warning: points that turn little against the bearing wear their own tracks, seen as stripes).
        harmonics: Fourier terms of the worn profile [-], in [1, n_nodes / 2).
    """

    coefficient: float
    updates: int
    cycles_per_update: float = 1.0
    settle: float = 0.0
    joint: int | str | None = None
    n_nodes: int = 180
    harmonics: int = 24

    def check(self, settings: Settings):
        check_range("wear coefficient (coefficient)", self.coefficient, low=0.0, low_open=True, unit="m^2/N")
        check_range("extrapolation factor (cycles_per_update)", self.cycles_per_update, low=1.0)
        if int(self.updates) != self.updates or self.updates < 1:
            raise ParameterError(f"updates = {self.updates} is outside the allowed range: an integer >= 1")
        if int(self.n_nodes) != self.n_nodes or not 8 <= self.n_nodes <= MAX_NODES:
            raise ParameterError(f"n_nodes = {self.n_nodes} is outside the allowed range: an integer in [8, {MAX_NODES}]")
        if int(self.harmonics) != self.harmonics or not 1 <= self.harmonics < self.n_nodes / 2:
            raise ParameterError(f"harmonics = {self.harmonics} is outside the allowed range: an integer in "
                                 f"[1, n_nodes / 2 = {self.n_nodes / 2:g})")
        span = float(settings.t_end) - settings.t_start
        check_range("settle", self.settle, low=0.0, high=span, high_open=True, unit="s")


@dataclasses.dataclass
class WearHistory(AbstractResult):
    """Result of :func:`wear`: :meth:`to_dict`, :meth:`write`, :meth:`summary`, :meth:`plot`
    (:class:`~jaxclear.AbstractResult`); :meth:`write` writes the files :func:`wear` writes as
    it goes (``wear.json``, ``updates.csv``, ``profile_NNNN.csv``, ``profile.png``).

    Attributes:
        mechanism: the mechanism with the bearing worn by all updates.
        angles: bearing node angles [rad] ``(n,)``.
        depth: cumulative wear depth at the nodes after each update [m] ``(U, n)``.
        volume: worn volume of each update (window times the factor) [m^3] ``(U,)``.
        service_time: service time after each update [s] ``(U,)``.
        peak_force: largest contact force of each window [N] ``(U,)``.
        max_penetration: largest penetration of each window [m] ``(U,)``.
        resumed_from: updates found done in the output folder (0: a fresh run).
        cycles_per_update: the extrapolation factor [-] (keyword): update ``u`` stands for
            ``(u + 1) * cycles_per_update`` cycles.
        clearance: the unworn radial clearance of the worn joint [m] (keyword; the figure's scale).
        fingerprint: the key of the mechanism, settings and options that ``wear.json`` holds (its
            ``key``: a resume checks it, :mod:`jaxclear._checkpoint`); ``None`` for a history not
            made by :func:`wear` (its ``wear.json`` does not resume).
        config: the configuration the key covers (``wear.json``'s ``config``: a run of other
            options is refused naming what changed), or None.
    """

    mechanism: Mechanism
    angles: np.ndarray
    depth: np.ndarray
    volume: np.ndarray
    service_time: np.ndarray
    peak_force: np.ndarray
    max_penetration: np.ndarray
    resumed_from: int = 0
    cycles_per_update: float = dataclasses.field(kw_only=True)
    clearance: float = dataclasses.field(kw_only=True)
    fingerprint: str | None = dataclasses.field(default=None, kw_only=True)
    config: dict | None = dataclasses.field(default=None, kw_only=True)

    def records(self) -> list[dict]:
        """The update records of ``wear.json`` (:data:`RECORD_KEYS` and ``depth_m`` per update),
        the numbers :func:`wear` stored."""
        depth = np.asarray(self.depth, float)
        return [_record(service_time=self.service_time[u], cycles=(u + 1) * self.cycles_per_update,
                        volume=self.volume[u], depth=depth[u], peak=self.peak_force[u],
                        penetration=self.max_penetration[u]) for u in range(depth.shape[0])]

    def to_dict(self) -> dict:
        """The content of ``wear.json``: the checkpoint protocol's header (``kind``, ``format``,
        ``key`` (the :attr:`fingerprint`), ``config``) and ``updates`` (:meth:`records`)."""
        work = _work(None, self.fingerprint, self.config)
        return jsonable(work.document(_state(self.records())))

    def write(self, folder, *, plots: bool = True) -> list[str]:
        """The files :func:`wear` writes into its output folder, for all updates:
        ``profile_NNNN.csv`` each, ``updates.csv``, ``wear.json`` and, with ``plots``,
        ``profile.png``, into ``folder`` (created if missing); returns their paths."""
        folder = os.fspath(folder)
        os.makedirs(folder, exist_ok=True)
        records = self.records()
        paths = [_write_profile(folder, u, self.angles, r["depth_m"]) for u, r in enumerate(records)]
        paths.append(atomic_write_text(os.path.join(folder, UPDATES_FILE), _updates_text(records)))
        paths.append(_write_state(folder, self.fingerprint, self.config, records))
        if plots:
            paths.append(self.plot(os.path.join(folder, FIGURE_FILE)))
        return paths

    def summary(self) -> str:
        """Updates and service time, worn volume, largest and mean depth (against the
        clearance), the peak contact force of the first and last windows."""
        last = np.asarray(self.depth[-1])
        lines = [f"{len(self.depth)} update(s), service time {float(self.service_time[-1]):.4g} s "
                 f"({len(self.depth) * self.cycles_per_update:.4g} cycles)"
                 + (f", resumed after {self.resumed_from} update(s) found done" if self.resumed_from else ""),
                 f"  worn volume        {float(np.sum(self.volume)):.4g} m^3",
                 f"  largest depth      {float(last.max()):.4g} m (mean {float(last.mean()):.4g} m; "
                 f"{float(last.max()) / self.clearance:.2%} of the clearance {self.clearance:.4g} m)",
                 f"  peak contact force {float(self.peak_force[0]):.4g} N (first window) -> "
                 f"{float(self.peak_force[-1]):.4g} N (last)"]
        return "\n".join(lines)

    def plot(self, path=None):
        """The worn bearing (polar, wear magnified) and the depth after the updates
        (:func:`~jaxclear.wearing.plot_wear`, ``profile.png``): the figure, or ``path`` once saved."""
        fig = plot_wear(self.angles, self.depth, self.service_time, self.clearance, path)
        return fig if path is None else os.fspath(path)


@eqx.filter_jit
def _window(mech, settings, index, coefficient, n_nodes, t_from):
    """One window's wear, peak force and penetration, and the run's status: returned, not
    raised here (the run without ``throw``), so that the program holds no host callback and
    JAX's persistent compilation cache keeps it; :func:`wear` raises for it."""
    sol = simulate(mech, dataclasses.replace(settings, throw=False))
    w: WindowWear = window_wear(mech, sol, index, coefficient, n_nodes, t_from)
    inside = sol.ts >= t_from
    peak = jnp.max(jnp.where(inside, sol.normal_force[:, index], 0.0))
    return w, peak, jnp.max(jnp.where(inside, sol.penetration[:, index], -jnp.inf)), sol.status


def _row(u: int, record: dict) -> str:
    return f"{u}," + ",".join(repr(float(record[k])) for k in RECORD_KEYS) + "\n"


def _check_records(records, n_nodes: int) -> str | None:
    """What is wrong with the update records of a state file, or None: each a table of the
    finite numbers :data:`RECORD_KEYS` and ``depth_m``, ``n_nodes`` finite depths >= 0."""
    if not isinstance(records, list):
        return f"'updates' is {type(records).__name__}, not a list"
    for u, r in enumerate(records):
        if not isinstance(r, dict):
            return f"update {u} is {type(r).__name__}, not a table"
        missing = [k for k in (*RECORD_KEYS, "depth_m") if k not in r]
        if missing:
            return f"update {u} misses the key(s) {missing}"
        for k in RECORD_KEYS:
            v = r[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                return f"update {u}: {k} = {v!r} is not a finite number"
        depth = r["depth_m"]
        ok = isinstance(depth, list) and len(depth) == n_nodes and all(
            isinstance(d, (int, float)) and not isinstance(d, bool) for d in depth)
        if not ok:
            return f"update {u}: depth_m is not a list of {n_nodes} numbers"
        d = np.asarray(depth, float)
        if not np.all(np.isfinite(d)) or np.any(d < 0.0):
            return f"update {u}: depth_m holds a value that is not finite and >= 0"
    return None


def _work(out, key: str | None, config: dict | None) -> Work:
    """The wear run in ``out`` as a piece of resumable work (:mod:`jaxclear._checkpoint`)."""
    return Work(out, "wear", key, config, version=FORMAT, restart="--restart (API: restart=True)")


def _upgrade(doc: dict) -> dict:
    """A state written before the checkpoint protocol (``{"fingerprint", "updates"}``, format 1):
    its fingerprint is its key."""
    return {**doc, "key": doc["fingerprint"]} if "key" not in doc and "fingerprint" in doc else doc


def _load_state(work: Work, restart: bool, n_nodes: int) -> list[dict]:
    """The update records of the state file (none on a fresh start or with ``restart``); the
    checkpoint protocol's rules (a state of another run is refused, naming what changed); a file
    that cannot be read, is not a wear state, or holds a damaged record is a
    :class:`~jaxclear.CheckpointError` naming it and the record."""
    state = work.read_json(STATE_FILE, restart=restart, upgrade=_upgrade)
    if state is None:
        return []
    path = work.path(STATE_FILE)
    again = "run again with --restart (restart=True) to start over"
    if "updates" not in state:
        raise CheckpointError(f"the wear state {path!r} is unreadable (key 'updates' missing); {again}")
    records = state["updates"]
    problem = _check_records(records, n_nodes)
    if problem is not None:
        raise CheckpointError(f"the wear state {path!r} is damaged ({problem}); {again}")
    return records


def _updates_text(records: list[dict]) -> str:
    """``updates.csv`` of the records: the header and one row per update."""
    return UPDATES_HEADER + "".join(_row(i, r) for i, r in enumerate(records))


def _record(*, service_time, cycles, volume, depth, peak, penetration) -> dict:
    """One update's record in the state file: the numbers as Python floats (``depth``, the
    cumulative depth at the nodes, as a list)."""
    depth = np.asarray(depth, float)
    return {"service_time_s": float(service_time), "cycles": cycles, "worn_volume_m3": float(volume),
            "max_depth_m": float(depth.max()), "mean_depth_m": float(depth.mean()), "peak_force_n": float(peak),
            "max_penetration_m": float(penetration), "depth_m": depth.tolist()}


def _state(records: list[dict]) -> dict:
    return {"updates": records}


def _write_state(out: str, key: str | None, config: dict | None, records: list[dict]) -> str:
    work = _work(out, key, config)  # the state through this module's name of the writer: a test stops a run there
    return atomic_write_json(work.path(STATE_FILE), work.document(_state(records)), indent=1)


def _write_profile(out: str, u: int, angles, depth) -> str:
    """``profile_NNNN.csv`` of update ``u``: node angle [rad], cumulative depth [m]."""
    # repr of a Python float: the shortest text that reads back bit for bit (a NumPy 2 scalar's
    # repr is "np.float64(...)", which a CSV reader takes for text)
    lines = ["angle_rad,depth_m\n"] + [f"{float(a)!r},{float(d)!r}\n" for a, d in zip(angles, depth)]
    return atomic_write_text(os.path.join(out, f"profile_{u:04d}.csv"), "".join(lines))


def _write(out: str, key: str, config: dict, records: list[dict], angles, clearance: float):
    """The files after the last of ``records``: its profile, its row of ``updates.csv``
    (appended), the state and the figure."""
    u = len(records) - 1
    _write_profile(out, u, angles, records[-1]["depth_m"])
    updates = os.path.join(out, UPDATES_FILE)
    if u == 0 or not os.path.exists(updates):
        atomic_write_text(updates, _updates_text(records))
    else:
        fsync_append(updates, _row(u, records[-1]))
    _write_state(out, key, config, records)
    plot_wear(angles, np.asarray([r["depth_m"] for r in records]), np.asarray([r["service_time_s"] for r in records]),
              clearance, os.path.join(out, FIGURE_FILE))


def wear(mech: Mechanism, settings: Settings, options: WearOptions, out: str | None = None, *,
         restart: bool = False, progress: bool = True) -> WearHistory:
    """Wear the bearing of one clearance joint of ``mech`` over ``options.updates`` windows of
    ``settings`` (see the module docstring). ``settings`` (:class:`~jaxclear.Settings`, whole,
    required: its ``[t_start, t_end]`` is a window) are every window's, the wear replacing only
    what it owns: ``onsets`` where left at ``Settings``' default (:class:`~jaxclear.ExactOnsets`,
    which a run of wear cannot use and which cannot be told apart from the default, so it is
    never an error here: :class:`~jaxclear.StepOnsets` replaces it, :data:`ONSETS_WHY`; another
    onsets strategy is used as given; the command line refuses ``--onsets exact``) and ``throw``
    (False: a failed window is reported by its status). ``out``: output folder
    (written as it goes, resumed if it holds a run of the same mechanism, settings and options;
    ``restart`` starts over)."""
    options.check(settings)
    # exact onsets (Settings' default) cannot serve a worn bearing (ONSETS_WHY): wear's own choice
    if isinstance(settings.onsets, ExactOnsets):
        settings = dataclasses.replace(settings, onsets=StepOnsets())
    index = wear_element(mech, options.joint)
    law = mech.elements[index].law
    if options.n_nodes > law.n_elements * law.n_gauss / 2:
        warnings.warn(f"n_nodes = {options.n_nodes} is more than half the hybrid law's {law.n_elements * law.n_gauss} "
                      "points: where the joint turns little, each point wears its own track and the depth shows "
                      "stripes at the point spacing; use fewer nodes or more elements", stacklevel=2)
    base = prepare(mech, index, options.harmonics)
    window_time = float(settings.t_end) - settings.t_start - options.settle
    t_from = settings.t_start + options.settle
    key = work_key(base, settings, repr(dataclasses.replace(options, updates=0)))
    config = {"mechanism": mech.name, "joint": index, "options": dataclasses.asdict(dataclasses.replace(options, updates=0)),
              "settings": {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}}
    work = _work(out, key, config)
    clearance = float(mech.elements[index].clearance)
    angles = node_angles(options.n_nodes)

    def run(records: list[dict]) -> list[dict]:
        done = len(records)
        if done:
            tqdm.write(f"jaxclear wear: resuming in {out}: {done} of {options.updates} updates already done")
        depth = np.asarray(records[-1]["depth_m"], float) if records else np.zeros(options.n_nodes)
        bar = None
        for u in range(done, options.updates):
            current = worn(base, index, depth)
            w, peak, pen, status = _window(current, settings, index, options.coefficient, options.n_nodes, t_from)
            check_status(None, status, settings, f" (the window of wear update {u})", current)
            window_depth = np.asarray(w.depth)
            if not np.all(np.isfinite(window_depth)):
                raise ParameterError(f"update {u}: the wear depth is not finite (the window's run failed)")
            step = options.cycles_per_update * window_depth
            if step.max() > STEP_WARNING * clearance:
                warnings.warn(f"update {u} wears {step.max():.3g} m in one step, {step.max() / clearance:.0%} of the "
                              f"clearance: the profile changes too much between windows; lower cycles_per_update "
                              f"(now {options.cycles_per_update:g})", stacklevel=3)
            depth = depth + step
            cycles = (u + 1) * options.cycles_per_update
            records.append(_record(service_time=as_typed(cycles * window_time), cycles=cycles,
                                   volume=options.cycles_per_update * float(w.volume), depth=depth, peak=peak,
                                   penetration=pen))
            if out is not None:
                _write(out, key, work.config, records, angles, clearance)
            if bar is None:  # the bar starts after the first (compiling) update
                bar = tqdm(total=options.updates, initial=u + 1, unit="update", desc="wear", disable=not progress)
            else:
                bar.update(1)
            if float(depth.max()) >= clearance:
                bar.close()
                raise ParameterError(
                    f"after update {u} the wear depth {depth.max():.3g} m exceeds the clearance {clearance:.3g} m: "
                    "the extrapolation factor (cycles_per_update) is too large for a profile update this coarse")
            if interrupt.requested:  # a Ctrl-C stops here, the update written
                bar.close()
                interrupt.check()
        if bar is not None:
            bar.close()
        return records

    with stop_at_safe_points("the current update") as interrupt:
        if out is None:
            records = run([])
            resumed = 0
        else:
            with work.lock():
                records = _load_state(work, restart, options.n_nodes)
                resumed = len(records)
                if records:  # the rows of exactly the updates in the state: a row appended by a run killed
                    # before it replaced the state is dropped (that update is computed again)
                    atomic_write_text(os.path.join(out, UPDATES_FILE), _updates_text(records[: options.updates]))
                records = run(records[: options.updates])
    depth = np.asarray([r["depth_m"] for r in records], float)
    return WearHistory(
        mechanism=worn(base, index, depth[-1]),
        angles=angles,
        depth=depth,
        volume=np.asarray([r["worn_volume_m3"] for r in records]),
        service_time=np.asarray([r["service_time_s"] for r in records]),
        peak_force=np.asarray([r["peak_force_n"] for r in records]),
        max_penetration=np.asarray([r["max_penetration_m"] for r in records]),
        resumed_from=resumed,
        cycles_per_update=options.cycles_per_update,
        clearance=clearance,
        fingerprint=key,
        config=work.config,
    )
