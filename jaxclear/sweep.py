r"""Parameter sweeps: many simulations of one mechanism, batched with ``jax.vmap``, sharded over
the devices with :mod:`jax.sharding`, compiled once, written to disk chunk by chunk and
resumable.

A sweep is a grid (Cartesian product) or a list (zipped values) over any numeric parameters
that :mod:`jaxclear.params` names: ``clearance``, ``restitution``, ``friction``, ``stiffness``,
``exponent``, ``length``, ``speed`` / ``speed_rpm``, ``mass:BODY``, ``inertia:BODY``
(``NAME@J`` for clearance joint J). Each run simulates ``revolutions`` crank revolutions, so
``t_end = revolutions * 2 pi / |omega|`` follows the swept speed; the output grid has
``samples_per_revolution`` samples per revolution (the same number of samples for every run).

How it runs:

* every input is checked before anything is compiled (:class:`SweepConfig`: unknown keys,
  unknown or conflicting parameter names, empty or inconsistent grids, values outside their
  physical range, bad run settings);
* one pure function ``values (B, P) -> outputs`` (:func:`_runs`: the clearance simulations,
  then the ideal-joint ones, then the metrics, each phase vmapped over the batch; inside
  ``jax.shard_map`` over a 1-D :class:`jax.sharding.Mesh` of the devices, the batch axis split
  with ``NamedSharding(mesh, P("batch"))``) is jitted once per sweep; every chunk has the same
  size (the last one padded by repeating its last run, the padded rows dropped), so the whole
  sweep compiles exactly once (:data:`TRACE_COUNT` counts the traces; the tests assert it), and
  a later sweep of the same structure (same names and run settings, other numbers) reuses it;
* ``Settings(throw=False)``: a failed run gets a non-zero ``status`` and NaN metrics, the others
  are unaffected;
* on CPU, jaxlib 0.10's batched LAPACK kernels can deadlock when every thread of the CPU pool
  waits in one of them; the phases are ordered so that one device never runs two large ones at
  once (:func:`_after`), and with as many CPU devices as cores the runs per device are limited
  (:func:`max_runs_per_device`);
* results go to ``OUT/runs.csv`` (one row per run, appended and ``fsync``-ed chunk by chunk),
  ``OUT/manifest.json`` (the sweep's definition and its hash) and ``OUT/chunks/chunk_NNNNNN.npz``
  (Poincare points, and the time series when ``trajectories`` is on). Running the same sweep
  again into the same folder resumes: run indices already in the CSV are skipped, a partial last
  line left by a kill is cut off, and a folder that holds a *different* sweep is an error.

Chunks are laid out over the global run indices (chunk ``c`` = runs ``c*S .. c*S+S-1``), so a
resumed sweep batches every run exactly as an uninterrupted one does and gets the same bits.

Metrics per run: :func:`jaxclear.analysis.metrics.run_metrics` over the window after
``transient_revolutions``, the slider-acceleration deviation against the ideal-joint mechanism
(``jc.preset(..., ideal=True)``, same speed, same time grid, vmapped alongside). Poincare
points: the journal state (eccentricity ``e_x, e_y`` [m] and its rate ``v_x, v_y`` [m/s],
journal centre relative to bearing centre) at every whole crank revolution after the transient.

Several hosts: call ``jax.distributed.initialize()`` in every process before
:func:`run_sweep`; the mesh then spans every device of every process, each process feeds its
own shards (``jax.make_array_from_callback``), the metrics are gathered
(``multihost_utils.process_allgather``) and process 0 alone writes the files (see README).
"""

from __future__ import annotations

import csv
import hashlib
import inspect
import io as _io
import json
import math
import os
import tomllib
import warnings
from dataclasses import dataclass, field
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import params
from .elements import kinematics
from ._errors import JaxclearError, ParameterError
from .model import AngleDriver, Mechanism
from .analysis.metrics import RUN_METRIC_KEYS, run_metrics
from ._errors import STATUS
from .integrate import SOLVERS, Settings, jit, simulate

#: Number of times the per-run function has been traced (compiled) in this process.
TRACE_COUNT = 0

CSV_NAME = "runs.csv"
MANIFEST_NAME = "manifest.json"
CHUNK_DIR = "chunks"
FORMAT_VERSION = 1

#: Poincare coordinates, in the order of the last axis of the ``poincare`` arrays.
POINCARE_COORDS = ("e_x", "e_y", "v_x", "v_y")

#: Allowed keys of a sweep configuration file, per table (see :func:`load_config`).
CONFIG_KEYS = {
    "mechanism": "preset and preset keyword overrides (law, friction, speed_rpm, clearance...)",
    "grid": "parameters swept as a Cartesian product: NAME = [values] or {start, stop, num, spacing}",
    "list": "parameters swept together (zipped, equal lengths): NAME = [values]",
    "run": "revolutions, transient_revolutions, samples_per_revolution, solver, rtol, atol, max_steps, "
           "ideal_reference",
    "output": "dir, chunk_size, trajectories, progress, devices",
}
RUN_KEYS = ("revolutions", "transient_revolutions", "samples_per_revolution", "solver", "rtol", "atol",
            "max_steps", "ideal_reference")
OUTPUT_KEYS = ("dir", "chunk_size", "trajectories", "progress", "devices")
RANGE_KEYS = ("start", "stop", "num", "spacing")

#: Bytes per output sample and per run assumed by :func:`auto_chunk_size` (state, derivatives,
#: reactions, contact outputs of the solution plus the ideal run and the metrics' temporaries).
BYTES_PER_SAMPLE = 4096
DEFAULT_RUNS_PER_DEVICE = 16


# --------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------


def _number(where: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{where}: expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{where}: values must be finite, got {value!r}")
    return v


def _values(name: str, spec) -> np.ndarray:
    """A parameter's values from a list, a single number or ``{start, stop, num, spacing}``."""
    where = f"parameter {name!r}"
    if isinstance(spec, dict):
        unknown = sorted(set(spec) - set(RANGE_KEYS))
        if unknown:
            raise ParameterError(f"{where}: unknown key(s) {unknown} in a range; allowed: {list(RANGE_KEYS)}")
        missing = [k for k in ("start", "stop", "num") if k not in spec]
        if missing:
            raise ParameterError(f"{where}: a range needs start, stop and num (missing {missing})")
        start, stop = _number(f"{where}.start", spec["start"]), _number(f"{where}.stop", spec["stop"])
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, (int, np.integer)) or num < 1:
            raise ParameterError(f"{where}.num = {num!r}: expected an integer >= 1")
        spacing = spec.get("spacing", "linear")
        if spacing == "linear":
            return np.linspace(start, stop, int(num))
        if spacing == "log":
            if start <= 0 or stop <= 0:
                raise ParameterError(f"{where}: a log range needs start, stop > 0 (got {start:g}, {stop:g})")
            return np.geomspace(start, stop, int(num))
        raise ParameterError(f"{where}.spacing = {spacing!r}: expected 'linear' or 'log'")
    if isinstance(spec, (list, tuple, np.ndarray)):
        arr = np.asarray(spec, dtype=object).ravel()
        if arr.size == 0:
            raise ParameterError(f"{where}: empty list of values (give at least one)")
        return np.array([_number(f"{where}, value #{i + 1}", v) for i, v in enumerate(arr)], dtype=float)
    return np.array([_number(where, spec)])


def _canonical(name: str) -> tuple:
    """What a name addresses (so that ``speed``/``speed_rpm`` and ``clearance``/``clearance@0``
    are recognised as the same leaf)."""
    base, joint, body = params._split(name)
    if base in ("speed", "speed_rpm"):
        return ("speed",)
    if base in ("mass", "inertia"):
        return (base, body)
    return (base, joint)


@dataclass(frozen=True)
class Plan:
    """The static part of a sweep: everything the compiled function depends on besides the
    mechanism's numbers (hashable; a jit static argument)."""

    names: tuple[str, ...]
    ideal_names: tuple[str, ...]
    revolutions: float
    n_out: int
    start: int
    section: tuple[int, ...]
    solver: str
    rtol: float
    atol: float
    max_steps: int
    trajectories: bool
    mesh: Any


@dataclass
class SweepConfig:
    """A sweep, validated when built (every check runs before anything is compiled).

    Args:
        grid: ``{name: values}`` swept as a Cartesian product (first name slowest), or
        list: ``{name: values}`` zipped (equal lengths); exactly one of the two. Values: a list of
            numbers, one number, or ``{"start", "stop", "num", "spacing": "linear" | "log"}``.
        preset: preset mechanism name (:func:`jaxclear.preset`), with keyword overrides
            ``preset_options`` (``law``, ``friction``, ``speed_rpm``...); or
        mechanism: a :class:`~jaxclear.Mechanism` (then ``ideal_mechanism``, optional, is its
            ideal-joint counterpart with the same bodies).
        revolutions: crank revolutions per run (> 0); ``t_end = revolutions * 2 pi / |omega|``.
        transient_revolutions: revolutions excluded from the metrics and the Poincare section
            (in [0, revolutions)).
        samples_per_revolution: output samples per revolution (>= 2; ``revolutions *
            samples_per_revolution`` must be an integer).
        solver, rtol, atol, max_steps: integration settings (:class:`jaxclear.Settings`).
        ideal_reference: also run the ideal-joint mechanism (acceleration deviation metrics).
        out: output folder; chunk_size: runs per chunk (``"auto"`` or an integer, rounded up to a
            multiple of the number of devices); trajectories: also store the time series;
        progress: tqdm bar over the chunks; devices: number of devices to use (``None``: all).
    """

    grid: dict | None = None
    list: dict | None = None
    preset: str | None = "flores-slider-crank"
    preset_options: dict = field(default_factory=dict)
    mechanism: Mechanism | None = None
    ideal_mechanism: Mechanism | None = None
    revolutions: float = 3.0
    transient_revolutions: float = 0.0
    samples_per_revolution: int = 200
    solver: str = "tsit5"
    rtol: float = 1e-6
    atol: float = 1e-9
    max_steps: int = 200_000
    ideal_reference: bool = True
    out: str = "sweep-out"
    chunk_size: int | str = "auto"
    trajectories: bool = False
    progress: bool = True
    devices: int | None = None
    source: str = "<python>"

    def __post_init__(self):
        self._check()

    # ---- validation -------------------------------------------------------------
    def _check(self):
        src = self.source
        if (self.grid is None) == (self.list is None):
            raise ParameterError(f"{src}: give exactly one of 'grid' (Cartesian product) or 'list' (zipped values)")
        table = self.grid if self.grid is not None else self.list
        if not isinstance(table, dict) or not table:
            raise ParameterError(f"{src}: the {'grid' if self.grid is not None else 'list'} has no parameters; "
                                 f"give at least one NAME = [values] (names: {params.parameter_names()})")
        # mechanism
        if self.mechanism is None:
            from .presets import PRESETS, preset

            if self.preset not in PRESETS:
                raise ParameterError(f"{src}: unknown preset {self.preset!r}; valid presets: {sorted(PRESETS)}")
            allowed = [k for k in inspect.signature(PRESETS[self.preset]).parameters if k != "ideal"]
            unknown = sorted(set(self.preset_options) - set(allowed))
            if unknown:
                raise ParameterError(f"{src}: unknown key(s) {unknown} for preset {self.preset!r} in [mechanism]; "
                                     f"allowed: {['preset'] + allowed}")
            try:
                self._mech = preset(self.preset, **self.preset_options)
                self._ideal = preset(self.preset, ideal=True, **self.preset_options) if self.ideal_reference else None
            except JaxclearError as err:
                raise ParameterError(f"{src}: [mechanism]: {err}") from None
        else:
            if not isinstance(self.mechanism, Mechanism):
                raise ParameterError(
                    f"{src}: mechanism must be a jaxclear Mechanism, got {type(self.mechanism).__name__}")
            self._mech = self.mechanism
            self._ideal = self.ideal_mechanism if self.ideal_reference else None
        if self._ideal is not None and self._mech.role("slider") is None:
            self._ideal = None  # the deviation metrics are defined for a slider only
        # parameters
        names = [str(n) for n in table]
        seen: dict[tuple, str] = {}
        for name in names:
            try:
                params.get(self._mech, name)  # unknown name, joint or body -> ParameterError
            except JaxclearError as err:
                raise ParameterError(f"{src}: {err}") from None
            key = _canonical(name)
            if key in seen:
                raise ParameterError(f"{src}: parameters {seen[key]!r} and {name!r} set the same quantity; keep one")
            seen[key] = name
        axes = {}
        for name in names:
            vals = _values(name, table[name])
            try:
                params.validate(self._mech, name, vals)
            except JaxclearError as err:
                raise ParameterError(f"{src}: {err}") from None
            if _canonical(name) == ("speed",) and np.any(vals == 0.0):
                raise ParameterError(f"{src}: {name} = 0: crank revolutions are undefined at zero speed")
            axes[name] = vals
        if self.grid is not None:
            mesh = np.meshgrid(*axes.values(), indexing="ij")
            values = np.stack([m.ravel() for m in mesh], axis=-1)
        else:
            lengths = {n: len(v) for n, v in axes.items()}
            if len(set(lengths.values())) != 1:
                raise ParameterError(f"{src}: the list's parameters have different lengths {lengths}; "
                                     "a list sweep zips them, so they must be equally long (use 'grid' for a product)")
            values = np.stack(list(axes.values()), axis=-1)
        self._names = tuple(names)
        self._axes = axes
        self._values = values
        if not any(_canonical(n) == ("speed",) for n in names):
            try:
                w = float(params.get(self._mech, "speed"))
            except JaxclearError as err:
                raise ParameterError(f"{src}: {err}; sweeps run whole crank revolutions") from None
            if w == 0.0:
                raise ParameterError(f"{src}: the crank speed is 0: crank revolutions are undefined")
        self._ideal_names = tuple(n for n in names if self._ideal is not None and _applies(self._ideal, n))
        # run settings
        r = _number(f"{src}: run.revolutions", self.revolutions)
        if not r > 0:
            raise ParameterError(f"{src}: run.revolutions = {r:g} is outside the allowed range (0, inf)")
        tr = _number(f"{src}: run.transient_revolutions", self.transient_revolutions)
        if not 0 <= tr < r:
            raise ParameterError(f"{src}: run.transient_revolutions = {tr:g} is outside the allowed range "
                                 f"[0, revolutions = {r:g})")
        spr = self.samples_per_revolution
        if isinstance(spr, bool) or not isinstance(spr, (int, np.integer)) or spr < 2:
            raise ParameterError(f"{src}: run.samples_per_revolution = {spr!r}: expected an integer >= 2")
        total = r * spr
        if abs(total - round(total)) > 1e-9 * max(total, 1.0):
            raise ParameterError(f"{src}: revolutions x samples_per_revolution = {total:g} must be an integer "
                                 "(so that samples fall on whole revolutions)")
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, (int, np.integer)):
            raise ParameterError(f"{src}: run.max_steps = {self.max_steps!r}: expected an integer >= 1")
        for key in ("rtol", "atol"):
            _number(f"{src}: run.{key}", getattr(self, key))
        if self.solver not in SOLVERS:
            raise ParameterError(f"{src}: unknown solver {self.solver!r}; valid: {sorted(SOLVERS)}")
        try:  # Settings' own range checks (rtol in (0, 1), atol > 0, max_steps >= 1)
            Settings(t_end=jnp.asarray(1.0), solver=self.solver, rtol=float(self.rtol), atol=float(self.atol),
                     max_steps=int(self.max_steps))
        except JaxclearError as err:
            raise ParameterError(f"{src}: run: {err}") from None
        for key in ("ideal_reference", "trajectories", "progress"):
            if not isinstance(getattr(self, key), bool):
                raise ParameterError(f"{src}: {key} = {getattr(self, key)!r}: expected true or false")
        if not isinstance(self.out, (str, os.PathLike)) or not str(self.out):
            raise ParameterError(f"{src}: output.dir = {self.out!r}: expected a folder name")
        cs = self.chunk_size
        if not (cs == "auto" or (isinstance(cs, (int, np.integer)) and not isinstance(cs, bool) and cs >= 1)):
            raise ParameterError(f"{src}: output.chunk_size = {cs!r}: expected 'auto' or an integer >= 1")
        available = len(jax.devices())
        if self.devices is not None:
            d = self.devices
            if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or not 1 <= d <= available:
                raise ParameterError(f"{src}: output.devices = {d!r}: expected an integer in [1, {available}] "
                                     f"(devices available: {available}) or 'all'")

    # ---- derived ----------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """Swept parameter names, in column order."""
        return self._names

    @property
    def values(self) -> np.ndarray:
        """(n_runs, n_params) parameter values, row ``i`` = run ``i``."""
        return self._values

    @property
    def axes(self) -> dict[str, np.ndarray]:
        """Each parameter's distinct values as given (the grid axes)."""
        return dict(self._axes)

    @property
    def n_runs(self) -> int:
        return int(self._values.shape[0])

    @property
    def base_mechanism(self) -> Mechanism:
        return self._mech

    @property
    def n_out(self) -> int:
        return int(round(self.revolutions * self.samples_per_revolution)) + 1

    @property
    def section(self) -> tuple[int, ...]:
        """Output sample indices of the Poincare section: every whole revolution after the transient."""
        s = self.samples_per_revolution
        first = math.ceil(self.transient_revolutions - 1e-12)
        last = math.floor(self.revolutions + 1e-12)
        return tuple(k * s for k in range(first, last + 1) if k * s < self.n_out)

    @property
    def window_start(self) -> int:
        """First output sample of the metrics window (after the transient)."""
        return int(math.ceil(self.transient_revolutions * self.samples_per_revolution - 1e-9))

    def describe(self) -> dict:
        """JSON-able definition (what the manifest stores and hashes)."""
        if self.mechanism is None:
            mech = {"preset": self.preset, **{k: _jsonable(v) for k, v in sorted(self.preset_options.items())}}
        else:
            mech = {"mechanism": self._mech.name, "leaves_sha256": _tree_hash(self._mech),
                    "ideal_leaves_sha256": None if self._ideal is None else _tree_hash(self._ideal)}
        return {
            "mechanism": mech,
            "mode": "grid" if self.grid is not None else "list",
            "parameters": {n: [float(v) for v in a] for n, a in self._axes.items()},
            "run": {"revolutions": float(self.revolutions), "transient_revolutions": float(self.transient_revolutions),
                    "samples_per_revolution": int(self.samples_per_revolution), "solver": self.solver,
                    "rtol": float(self.rtol), "atol": float(self.atol), "max_steps": int(self.max_steps),
                    "ideal_reference": self._ideal is not None},
            "trajectories": bool(self.trajectories),
        }

    def sweep_hash(self) -> str:
        """sha256 of the definition and of every run's parameter values (bit-exact)."""
        h = hashlib.sha256(json.dumps(self.describe(), sort_keys=True).encode())
        h.update(np.ascontiguousarray(self._values, dtype="<f8").tobytes())
        return h.hexdigest()


def _applies(mech: Mechanism, name: str) -> bool:
    try:
        params.get(mech, name)
        return True
    except JaxclearError:
        return False


def _jsonable(v):
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, (np.ndarray, jax.Array)):
        return np.asarray(v).tolist()
    return v


def _tree_hash(tree) -> str:
    h = hashlib.sha256()
    leaves, treedef = jax.tree_util.tree_flatten(eqx.filter(tree, eqx.is_array))
    h.update(str(treedef).encode())
    for leaf in leaves:
        h.update(np.ascontiguousarray(np.asarray(leaf, dtype=float)).tobytes())
    return h.hexdigest()


def load_config(path, **overrides) -> SweepConfig:
    """Read a TOML sweep configuration (see ``examples/sweep.toml``) and validate it.

    Tables: ``[mechanism]`` (``preset`` and preset keyword overrides), ``[grid]`` or ``[list]``
    (the swept parameters), ``[run]`` (:data:`RUN_KEYS`), ``[output]`` (:data:`OUTPUT_KEYS`).
    Unknown tables or keys are errors. ``overrides`` replace :class:`SweepConfig` fields
    (the command-line options). Relative ``output.dir`` is relative to the current folder.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except OSError as err:
        raise ParameterError(f"cannot read sweep configuration {path!r}: {err.strerror or err}") from None
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"{path}: not valid TOML: {err}") from None
    return config_from_dict(doc, source=path, **overrides)


def config_from_dict(doc: dict, source: str = "<dict>", **overrides) -> SweepConfig:
    """Build a :class:`SweepConfig` from the TOML layout (a dict of tables); unknown keys are
    errors naming the allowed ones."""
    unknown = sorted(set(doc) - set(CONFIG_KEYS))
    if unknown:
        raise ParameterError(f"{source}: unknown table(s) or key(s) {unknown}; allowed tables: {list(CONFIG_KEYS)}")
    for table in CONFIG_KEYS:
        if table in doc and not isinstance(doc[table], dict):
            raise ParameterError(f"{source}: '{table}' must be a table ([{table}]), got {doc[table]!r}")
    mech = dict(doc.get("mechanism", {}))
    run = dict(doc.get("run", {}))
    out = dict(doc.get("output", {}))
    for table, got, allowed in (("run", run, RUN_KEYS), ("output", out, OUTPUT_KEYS)):
        bad = sorted(set(got) - set(allowed))
        if bad:
            raise ParameterError(f"{source}: unknown key(s) {bad} in [{table}]; allowed: {list(allowed)}")
    kwargs: dict = {"source": source}
    kwargs["preset"] = mech.pop("preset", "flores-slider-crank")
    kwargs["preset_options"] = mech
    kwargs["grid"] = doc.get("grid")
    kwargs["list"] = doc.get("list")
    kwargs.update(run)
    for key in OUTPUT_KEYS:
        if key in out:
            kwargs["out" if key == "dir" else key] = out[key]
    if kwargs.get("devices") == "all":
        kwargs["devices"] = None
    kwargs.update({k: v for k, v in overrides.items() if v is not None})
    return SweepConfig(**kwargs)


# --------------------------------------------------------------------------------------
# The compiled function
# --------------------------------------------------------------------------------------


def _settings(plan: Plan, m: Mechanism) -> Settings:
    speed = [d for d in m.drivers if isinstance(d, AngleDriver)][0].speed
    t_end = plan.revolutions * 2.0 * jnp.pi / jnp.abs(speed)
    # stages="loop": under vmap one copy of the vector field serves every Runge-Kutta stage
    return Settings(t_end=t_end, n_out=plan.n_out, solver=plan.solver, rtol=plan.rtol, atol=plan.atol,
                    max_steps=plan.max_steps, throw=False, stages="loop")


def _clearance_run(plan: Plan, mech: Mechanism, row):
    """Phase 1 of a run: the mechanism with this row's parameters, integrated."""
    global TRACE_COUNT
    TRACE_COUNT += 1  # a Python side effect: counts traces, not calls
    m = params.replace_many(mech, {n: row[i] for i, n in enumerate(plan.names)})
    return simulate(m, _settings(plan, m))


def _ideal_run(plan: Plan, mech: Mechanism, ideal: Mechanism, row):
    """Phase 2: the ideal-joint mechanism at the same speed (and masses...), same time grid.
    Returns (slider acceleration (T,), status)."""
    m = params.replace_many(mech, {n: row[i] for i, n in enumerate(plan.names)})
    im = params.replace_many(ideal, {n: row[plan.names.index(n)] for n in plan.ideal_names})
    isol = simulate(im, _settings(plan, m))
    return isol.coordinate(im, im.role("slider"), "x", derivative=2), isol.status


def _after(ideal: Mechanism, sol) -> Mechanism:
    """``ideal`` with a data dependency on the clearance solution(s) ``sol``: its float leaves
    plus ``min(sum(status), 0)``, which is 0 at run time but not known to the compiler, so the
    ideal integration cannot start before every clearance run in ``sol`` has finished.

    Why: both integrations end with one large batched LU (the engine's post-processing solves
    the augmented system at every output sample). jaxlib 0.10's CPU LAPACK kernels split a large
    batch over the intra-op thread pool and block the calling pool thread until the pieces are
    done, so two of them running at once on a 2-thread pool wait for each other forever
    (observed: a 20-run chunk hung with zero CPU use; gdb showed both pool threads in
    ``jax::ParallelBatchMap`` under ``lapack_dgetrf_ffi``). An optimization barrier is not
    enough: XLA:CPU drops it before scheduling."""
    zero = jnp.minimum(jnp.sum(sol.status), 0).astype(float)
    return jax.tree_util.tree_map(lambda a: a + zero if eqx.is_inexact_array(a) else a, ideal)


def _finish(plan: Plan, mech: Mechanism, row, sol, ideal_acc, ideal_status):
    """Phase 3: metrics, Poincare points and optional time series of one run."""
    m = params.replace_many(mech, {n: row[i] for i, n in enumerate(plan.names)})
    met = run_metrics(m, sol, ideal_acc, plan.start)
    failed = sol.status != 0
    out = {}
    for key, value in met.items():
        if key in ("status", "num_steps", "num_accepted_steps", "num_rejected_steps"):
            out[key] = value
        else:
            value = jnp.where(failed, jnp.nan, value)
            if ideal_status is not None and key in ("peak_acc_deviation_m_s2", "rms_acc_deviation_m_s2"):
                value = jnp.where(ideal_status != 0, jnp.nan, value)
            out[key] = value
    if ideal_status is not None:
        out["ideal_status"] = ideal_status
    out["t_end_s"] = sol.ts[-1]
    # Poincare section: journal state once per crank revolution after the transient
    k = len(m.clearance_joints)
    idx = jnp.asarray(plan.section, dtype=jnp.int32)
    if k and len(plan.section):
        def state(q, qd):
            rows = []
            for joint in m.clearance_joints:
                kin = kinematics(m, joint, q, qd)
                rows.append(jnp.concatenate([kin.ecc, kin.journal_velocity - kin.bearing_velocity]))
            return jnp.stack(rows)

        out["poincare"] = jax.vmap(state)(sol.q[idx], sol.qdot[idx])
    else:
        out["poincare"] = jnp.zeros((len(plan.section), k, 4), sol.ts.dtype)
    if plan.trajectories:
        out["traj_ts"] = sol.ts
        out["traj_ecc"] = sol.ecc
        out["traj_normal_force"] = sol.normal_force
        out["traj_penetration"] = sol.penetration
        out["traj_mode"] = sol.mode
        slider = m.role("slider")
        if slider is not None:
            out["traj_slider_acc"] = sol.coordinate(m, slider, "x", derivative=2)
            if ideal_acc is not None:
                out["traj_ideal_slider_acc"] = ideal_acc
    return out


def _one_run(plan: Plan, mech: Mechanism, ideal: Mechanism | None, row):
    """One run, unbatched: the three phases in order (what :func:`_runs` vmaps)."""
    sol = _clearance_run(plan, mech, row)
    ideal_acc = ideal_status = None
    if ideal is not None:
        ideal_acc, ideal_status = _ideal_run(plan, mech, _after(ideal, sol), row)
    return _finish(plan, mech, row, sol, ideal_acc, ideal_status)


def _runs(plan: Plan, mech: Mechanism, ideal: Mechanism | None, rows):
    """A batch of runs (B, P) -> dict of (B, ...): each phase vmapped over the batch; the ideal
    runs start after all clearance runs of the batch (see :func:`_after`). An ideal mechanism
    that no swept parameter changes is integrated once, unbatched (vmap leaves it unbatched)."""
    sol = jax.vmap(lambda r: _clearance_run(plan, mech, r))(rows)
    ideal_acc = ideal_status = None
    if ideal is not None:
        later = _after(ideal, sol)
        ideal_acc, ideal_status = jax.vmap(lambda r: _ideal_run(plan, mech, later, r))(rows)
    return jax.vmap(lambda r, s, a, st: _finish(plan, mech, r, s, a, st))(rows, sol, ideal_acc, ideal_status)


@jit
def _run_chunk(values, mech: Mechanism, ideal: Mechanism | None, plan: Plan):
    """``values`` (B, P) sharded over ``plan.mesh`` -> dict of (B, ...) outputs."""
    from jax.sharding import PartitionSpec as P

    m_arr, m_static = eqx.partition(mech, eqx.is_array)
    i_arr, i_static = eqx.partition(ideal, eqx.is_array)

    def local(rows, m_arr, i_arr):
        m = eqx.combine(m_arr, m_static)
        i = None if ideal is None else eqx.combine(i_arr, i_static)
        return _runs(plan, m, i, rows)

    f = jax.shard_map(local, mesh=plan.mesh, in_specs=(P("batch"), P(), P()), out_specs=P("batch"),
                      check_vma=False)
    return f(values, m_arr, i_arr)


def make_mesh(devices: int | None = None):
    """A 1-D :class:`jax.sharding.Mesh` named ``"batch"`` over the first ``devices`` of
    ``jax.devices()`` (every device of every process by default)."""
    from jax.sharding import Mesh

    devs = jax.devices()
    if devices is not None:
        devs = devs[:devices]
    return Mesh(np.array(devs), ("batch",))


def auto_chunk_size(n_out: int, n_devices: int, n_runs: int, memory_bytes: int | None = None,
                    trajectories: bool = False) -> int:
    """Runs per chunk: :data:`DEFAULT_RUNS_PER_DEVICE` per device, fewer if the outputs of a
    chunk (:data:`BYTES_PER_SAMPLE` per sample and run, doubled with trajectories) would exceed
    a quarter of ``memory_bytes`` (default: the device's or the host's memory), and no more than
    the runs rounded up to a multiple of the devices."""
    if memory_bytes is None:
        memory_bytes = _memory_bytes()
    per_run = BYTES_PER_SAMPLE * n_out * (2 if trajectories else 1)
    fit = max(1, int(memory_bytes // 4 // per_run))
    size = min(DEFAULT_RUNS_PER_DEVICE * n_devices, fit)
    size = min(size, n_runs + (-n_runs) % n_devices)
    return max(n_devices, size - size % n_devices)


#: jaxlib 0.10's CPU LAPACK kernels split a batch of ``b`` matrices of size ``n`` over the intra-op
#: thread pool when ``b n^3`` reaches this (read from the LU kernel in jaxlib 0.10.2's ``_lapack.so``).
LAPACK_SPLIT_COST = 200_000


def _pool_threads() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def max_runs_per_device(cfg: SweepConfig, n_devices: int, platform: str | None = None,
                        pool_threads: int | None = None) -> int | None:
    """Largest number of runs per device that is safe from a jaxlib CPU deadlock (0: none is),
    or None when there is no limit.

    Every run ends with one batched LU over its output samples (the engine's post-processing
    solves the augmented system of size ``n = coordinates + constraints`` at every sample), so a
    device computing ``r`` runs factors ``r n_out`` matrices at once. jaxlib 0.10's CPU LAPACK
    kernels split a batch costing ``b n^3 >=`` :data:`LAPACK_SPLIT_COST` over the intra-op
    thread pool and block the calling pool thread until the pieces are done. With at least as
    many CPU devices as pool threads (e.g. 2 forced host devices on 2 cores) all pool threads
    can end up blocked in such calls at once and the sweep hangs with zero CPU use (observed,
    gdb: every pool thread in ``jax::ParallelBatchMap`` under ``lapack_dgetrf_ffi``). With fewer
    devices than pool threads one thread stays free and there is no limit; within one device the
    sweep never runs two such calls at once (:func:`_after`). Accelerators are not affected."""
    platform = platform or jax.devices()[0].platform
    if platform != "cpu" or n_devices < 2:
        return None
    if n_devices < (pool_threads or _pool_threads()):
        return None
    mechs = [cfg._mech] + ([cfg._ideal] if cfg._ideal is not None else [])
    size = max(m.n_coordinates + m.n_constraints for m in mechs)
    return (LAPACK_SPLIT_COST - 1) // (cfg.n_out * size**3)


def _memory_bytes() -> int:
    try:
        stats = jax.local_devices()[0].memory_stats() or {}
        if "bytes_limit" in stats:
            return int(stats["bytes_limit"])
    except Exception:  # noqa: BLE001 - CPU devices have no memory stats
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 4 << 30


def _put(values: np.ndarray, mesh):
    """Place a (B, P) host array on the mesh, batch axis split (works across processes)."""
    from jax.sharding import NamedSharding, PartitionSpec as P

    sharding = NamedSharding(mesh, P("batch"))
    if jax.process_count() == 1:
        return jax.device_put(values, sharding)
    return jax.make_array_from_callback(values.shape, sharding, lambda index: values[index])


def _fetch(tree) -> dict:
    if jax.process_count() == 1:
        return jax.tree_util.tree_map(np.asarray, tree)
    from jax.experimental import multihost_utils

    return jax.tree_util.tree_map(np.asarray, multihost_utils.process_allgather(tree, tiled=True))


# --------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------


def csv_columns(cfg: SweepConfig) -> list[str]:
    """Header of ``runs.csv``: run index, parameters, metrics, statuses and the status message."""
    keys = _metric_keys(cfg)
    cols = ["run", *cfg.names, "t_end_s"] + [k for k in keys if k != "status"]
    if cfg._ideal is not None:
        cols.append("ideal_status")
    return cols + ["status", "status_message"]


def _metric_keys(cfg: SweepConfig) -> list[str]:
    mech = cfg.base_mechanism
    keys = list(RUN_METRIC_KEYS)
    if not mech.clearance_joints:
        keys = [k for k in keys if k not in _CONTACT_KEYS]
    if mech.role("slider") is None:
        keys = [k for k in keys if "slider" not in k and "deviation" not in k]
    elif cfg._ideal is None:
        keys = [k for k in keys if "deviation" not in k]
    return keys


_CONTACT_KEYS = ("peak_contact_force_n", "rms_contact_force_n", "max_penetration_m", "impacts",
                 "fraction_free_flight", "fraction_impact", "fraction_continuous_contact",
                 "energy_dissipated_j", "energy_dissipated_per_rev_j")
_INT_COLUMNS = ("run", "impacts", "num_steps", "num_accepted_steps", "num_rejected_steps", "status", "ideal_status")


def _fmt(col: str, value) -> str:
    if col == "status_message":
        return str(value)
    v = float(value)
    if col in _INT_COLUMNS and math.isfinite(v):
        return str(int(round(v)))
    return repr(v)


def _fsync_write(path: str, text: str, mode: str = "a"):
    with open(path, mode, encoding="utf-8", newline="") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


def _atomic_json(path: str, obj):
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(obj, f, indent=2, sort_keys=True)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _atomic_npz(path: str, arrays: dict):
    tmp = path + ".tmp.npz"
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _repair_csv(path: str, columns: list[str]) -> set[int]:
    """Cut a partial last line (left by a kill), check the header and every row, return the run
    indices present. Raises :class:`ParameterError` for a header of another sweep, a malformed
    row that is not the last, or a repeated run index."""
    with open(path, "rb") as f:
        data = f.read()
    if data and not data.endswith(b"\n"):
        cut = data.rfind(b"\n") + 1
        with open(path, "r+b") as f:
            f.truncate(cut)
            f.flush()
            os.fsync(f.fileno())
        data = data[:cut]
    if not data:
        _fsync_write(path, ",".join(columns) + "\n", mode="w")
        return set()
    rows = list(csv.reader(_io.StringIO(data.decode("utf-8"))))
    if rows[0] != columns:
        raise ParameterError(f"{path}: its header {rows[0]} is not this sweep's {columns}; "
                             "use another output folder or restart=True (--restart)")
    done: set[int] = set()
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(columns):
            raise ParameterError(f"{path}, line {lineno}: {len(row)} fields, expected {len(columns)} (corrupt file)")
        i = int(row[0])
        if i in done:
            raise ParameterError(f"{path}, line {lineno}: run {i} appears twice (corrupt file)")
        done.add(i)
    return done


def _prepare_output(cfg: SweepConfig, out: str, restart: bool, layout: dict) -> set[int]:
    """Create or check the output folder; returns the run indices already done."""
    os.makedirs(os.path.join(out, CHUNK_DIR), exist_ok=True)
    manifest_path = os.path.join(out, MANIFEST_NAME)
    csv_path = os.path.join(out, CSV_NAME)
    columns = csv_columns(cfg)
    digest = cfg.sweep_hash()
    if restart:
        for name in (manifest_path, csv_path):
            if os.path.exists(name):
                os.remove(name)
        for name in os.listdir(os.path.join(out, CHUNK_DIR)):
            if name.startswith("chunk_") and name.endswith(".npz"):
                os.remove(os.path.join(out, CHUNK_DIR, name))
    if os.path.exists(manifest_path):
        with open(manifest_path, encoding="utf-8") as f:
            old = json.load(f)
        if old.get("sweep_hash") != digest:
            raise ParameterError(
                f"{out} holds a different sweep (manifest hash {str(old.get('sweep_hash'))[:12]}..., this one "
                f"{digest[:12]}...); use another output folder or restart=True (--restart) to discard it")
        for key in ("chunk_size", "devices"):
            if old.get("layout", {}).get(key) != layout[key]:
                warnings.warn(
                    f"resuming {out} with {key} = {layout[key]} (the sweep started with {old['layout'].get(key)}): "
                    "the runs still to do are batched differently, which changes their results in the last bits "
                    "(and the chaotic dynamics amplify that)", stacklevel=3)
    elif os.path.exists(csv_path):
        raise ParameterError(f"{csv_path} exists without {MANIFEST_NAME}: not a jaxclear sweep folder; "
                             "use another output folder or restart=True (--restart)")
    manifest = {
        "format_version": FORMAT_VERSION,
        "sweep_hash": digest,
        "n_runs": cfg.n_runs,
        "names": list(cfg.names),
        "columns": columns,
        "config": cfg.describe(),
        "layout": layout,
        "status_codes": {str(k): v for k, v in STATUS.items()},
        "poincare_coords": list(POINCARE_COORDS),
        "base_clearance_m": [float(c.clearance) for c in cfg.base_mechanism.clearance_joints],
        "section_samples": list(cfg.section),
    }
    _atomic_json(manifest_path, manifest)
    if not os.path.exists(csv_path):
        _fsync_write(csv_path, ",".join(columns) + "\n", mode="w")
        return set()
    return _repair_csv(csv_path, columns)


# --------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------


@dataclass
class SweepResult:
    """A finished sweep read back from its folder (rows sorted by run index).

    Attributes:
        out: the folder. table: column -> (n_runs,) array (``status_message`` as strings).
        names: swept parameters. poincare: (n_runs, n_section, n_joints, 4) journal states
            (:data:`POINCARE_COORDS`) at the whole revolutions after the transient.
        axes: each parameter's grid values. mode: ``"grid"`` or ``"list"``. computed: runs
            computed by this call (the others were already on disk). base_clearance: radial
            clearance [m] of each clearance joint of the unswept mechanism.
    """

    out: str
    table: dict
    names: tuple
    poincare: np.ndarray
    axes: dict
    mode: str
    computed: int = 0
    base_clearance: tuple = ()

    def grid(self, metric: str, x: str, y: str) -> np.ndarray:
        """Metric as a (len(y axis), len(x axis)) array over a two-parameter grid sweep."""
        return _grid(self, metric, x, y)

    def trajectories(self) -> dict:
        """The stored time series (``trajectories = true``): key -> (n_runs, ...) arrays."""
        return read_chunks(self.out, prefix="traj_")


def run_sweep(cfg: SweepConfig, out: str | None = None, restart: bool = False,
              progress: bool | None = None) -> SweepResult:
    """Run (or resume) a sweep; returns its results read back from disk.

    Args:
        cfg: a validated :class:`SweepConfig` (errors were raised when it was built).
        out: output folder (default ``cfg.out``).
        restart: discard results of a previous sweep in ``out`` instead of resuming.
        progress: tqdm bar over the chunks (default ``cfg.progress``).
    """
    from tqdm import tqdm

    out = os.fspath(out if out is not None else cfg.out)
    progress = cfg.progress if progress is None else progress
    mesh = make_mesh(cfg.devices)
    n_dev = mesh.devices.size
    if cfg.chunk_size == "auto":
        chunk = auto_chunk_size(cfg.n_out, n_dev, cfg.n_runs, trajectories=cfg.trajectories)
    else:
        chunk = int(cfg.chunk_size) + (-int(cfg.chunk_size)) % n_dev
    local = sum(1 for d in mesh.devices.flat if d.process_index == jax.process_index())
    cap = max_runs_per_device(cfg, local)
    if cap == 0:
        msg = (f"{n_dev} CPU devices on {_pool_threads()} cores can deadlock jaxlib's CPU LAPACK kernels with "
               f"{cfg.n_out} output samples per run (see jaxclear.sweep.max_runs_per_device)")
        if cfg.devices is not None:
            raise ParameterError(f"{msg}; use devices < {_pool_threads()} or fewer samples")
        n_dev = max(1, min(n_dev, _pool_threads() - 1))
        warnings.warn(f"{msg}: using {n_dev} device(s)", stacklevel=2)
        mesh = make_mesh(n_dev)
        chunk = chunk + (-chunk) % n_dev
        cap = None
    if cap is not None and chunk > cap * n_dev:
        if cfg.chunk_size != "auto":
            warnings.warn(
                f"chunk_size {chunk} lowered to {cap * n_dev} ({cap} run(s) per device): with {n_dev} CPU devices on "
                "as many cores, larger batches can deadlock jaxlib's CPU LAPACK kernels (see "
                "jaxclear.sweep.max_runs_per_device); use fewer devices than cores or fewer output samples",
                stacklevel=2)
        chunk = cap * n_dev
    layout = {"chunk_size": chunk, "devices": n_dev, "processes": jax.process_count(),
              "platform": jax.devices()[0].platform}
    lead = jax.process_index() == 0
    if lead:
        done = _prepare_output(cfg, out, restart, layout)
    else:
        done = set()
    if jax.process_count() > 1:  # every process must agree on the work left
        from jax.experimental import multihost_utils

        mask = np.zeros(cfg.n_runs, dtype=np.int32)
        mask[list(done)] = 1
        mask = np.asarray(multihost_utils.broadcast_one_to_all(mask))
        done = set(np.nonzero(mask)[0].tolist())
    plan = Plan(
        names=cfg.names, ideal_names=cfg._ideal_names, revolutions=float(cfg.revolutions), n_out=cfg.n_out,
        start=cfg.window_start, section=cfg.section, solver=cfg.solver, rtol=float(cfg.rtol),
        atol=float(cfg.atol), max_steps=int(cfg.max_steps), trajectories=bool(cfg.trajectories), mesh=mesh,
    )
    n_chunks = -(-cfg.n_runs // chunk)
    todo = [c for c in range(n_chunks)
            if any(i not in done for i in range(c * chunk, min((c + 1) * chunk, cfg.n_runs)))]
    columns = csv_columns(cfg)
    csv_path = os.path.join(out, CSV_NAME)
    computed = 0
    bar = tqdm(total=n_chunks, initial=n_chunks - len(todo), unit="chunk", desc="sweep",
               disable=not (progress and lead), dynamic_ncols=True)
    try:
        for c in todo:
            lo, hi = c * chunk, min((c + 1) * chunk, cfg.n_runs)
            rows = cfg.values[lo:hi]
            padded = np.concatenate([rows, np.repeat(rows[-1:], chunk - (hi - lo), axis=0)], axis=0)
            res = _fetch(_run_chunk(_put(padded, mesh), cfg._mech, cfg._ideal, plan))
            res = {k: v[: hi - lo] for k, v in res.items()}
            if lead:
                arrays = {"run": np.arange(lo, hi), "poincare": res["poincare"]}
                arrays.update({k: v for k, v in res.items() if k.startswith("traj_")})
                _atomic_npz(os.path.join(out, CHUNK_DIR, f"chunk_{c:06d}.npz"), arrays)
                lines = []
                for j, i in enumerate(range(lo, hi)):
                    if i in done:
                        continue
                    row = {"run": i, **{n: rows[j, p] for p, n in enumerate(cfg.names)}}
                    row.update({k: res[k][j] for k in columns if k in res})
                    row["status_message"] = STATUS.get(int(res["status"][j]), "unknown status")
                    lines.append(",".join(_csv_quote(_fmt(col, row[col])) for col in columns) + "\n")
                _fsync_write(csv_path, "".join(lines))
                computed += len(lines)
            bar.update(1)
    finally:
        bar.close()
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices("jaxclear-sweep-done")
    if not lead:
        return SweepResult(out, {}, cfg.names, np.zeros(0), cfg.axes, "grid" if cfg.grid is not None else "list",
                           computed)
    res = read_results(out)
    res.computed = computed
    return res


def _csv_quote(text: str) -> str:
    if any(ch in text for ch in ',"\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


# --------------------------------------------------------------------------------------
# Reading results back
# --------------------------------------------------------------------------------------


def read_results(out) -> SweepResult:
    """Read a sweep folder (complete or not): rows sorted by run index, Poincare points."""
    out = os.fspath(out)
    with open(os.path.join(out, MANIFEST_NAME), encoding="utf-8") as f:
        manifest = json.load(f)
    with open(os.path.join(out, CSV_NAME), encoding="utf-8", newline="") as f:
        text = f.read()
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    rows = list(csv.reader(_io.StringIO(text)))
    header, body = rows[0], rows[1:]
    body.sort(key=lambda r: int(r[0]))
    table: dict = {}
    for j, col in enumerate(header):
        vals = [r[j] for r in body]
        if col == "status_message":
            table[col] = np.array(vals, dtype=object)
        elif col in ("run", "num_steps", "num_accepted_steps", "num_rejected_steps", "status", "ideal_status"):
            table[col] = np.array([int(v) for v in vals], dtype=np.int64)
        else:
            table[col] = np.array([float(v) for v in vals], dtype=float)
    chunks = read_chunks(out, prefix="poincare")
    poincare = chunks.get("poincare", np.zeros((0,)))
    if "run" in chunks and len(table.get("run", [])):
        pos = {int(r): k for k, r in enumerate(chunks["run"])}
        poincare = poincare[[pos[int(r)] for r in table["run"]]]
    cfg = manifest["config"]
    axes = {n: np.asarray(v, dtype=float) for n, v in cfg["parameters"].items()}
    return SweepResult(out, table, tuple(manifest["names"]), poincare, axes, cfg["mode"],
                       base_clearance=tuple(manifest.get("base_clearance_m", ())))


def read_chunks(out, prefix: str = "") -> dict:
    """Concatenate the arrays of ``OUT/chunks/*.npz`` whose key starts with ``prefix`` (and the
    run indices, key ``run``), ordered by run index."""
    folder = os.path.join(os.fspath(out), CHUNK_DIR)
    names = sorted(n for n in os.listdir(folder) if n.startswith("chunk_") and n.endswith(".npz"))
    parts: dict[str, list] = {}
    for name in names:
        with np.load(os.path.join(folder, name)) as z:
            for key in z.files:
                if key == "run" or key.startswith(prefix):
                    parts.setdefault(key, []).append(z[key])
    if not parts:
        return {}
    merged = {k: np.concatenate(v, axis=0) for k, v in parts.items()}
    order = np.argsort(merged["run"], kind="stable")
    return {k: v[order] for k, v in merged.items()}


def _grid(res: SweepResult, metric: str, x: str, y: str) -> np.ndarray:
    if res.mode != "grid":
        raise ParameterError("a 2-D map needs a grid sweep (this one is a list)")
    for n in (x, y):
        if n not in res.axes:
            raise ParameterError(f"{n!r} is not a swept parameter; swept: {list(res.axes)}")
    if metric not in res.table:
        raise ParameterError(f"unknown metric {metric!r}; columns: {list(res.table)}")
    xs, ys = res.axes[x], res.axes[y]
    z = np.full((len(ys), len(xs)), np.nan)
    for r in range(len(res.table["run"])):
        i = int(np.argmin(np.abs(ys - res.table[y][r])))
        j = int(np.argmin(np.abs(xs - res.table[x][r])))
        z[i, j] = res.table[metric][r]
    return z


# --------------------------------------------------------------------------------------
# Figures (thin wrappers over jaxclear.plot)
# --------------------------------------------------------------------------------------

_UNITS = {"clearance": ("clearance [mm]", 1e3), "speed_rpm": ("crank speed [rpm]", 1.0),
          "speed": ("crank speed [rad/s]", 1.0), "restitution": ("restitution c_r [-]", 1.0),
          "friction": ("friction coefficient [-]", 1.0), "length": ("joint length [mm]", 1e3)}


def axis_label(name: str) -> tuple[str, float]:
    """(label, scale) of a parameter for plots: clearance in mm, others in SI."""
    base = name.split("@")[0]
    if base in _UNITS:
        return _UNITS[base]
    try:
        unit = params.info(name).unit
    except JaxclearError:
        unit = ""
    return (f"{name} [{unit or '-'}]", 1.0)


def metric_label(metric: str) -> str:
    unit = RUN_METRIC_KEYS.get(metric, "-")
    text = metric
    for suffix in ("_n", "_m", "_j", "_m_s2", "_s"):
        if text.endswith(suffix):
            text = text[: -len(suffix)]
            break
    return f"{text.replace('_', ' ')} [{unit}]"


def heatmap(res: SweepResult, metric: str, x: str, y: str, path=None, log: bool | None = None):
    """PNG heat map of ``metric`` over a 2-D grid sweep (``x`` and ``y`` swept parameters)."""
    from .plot import plot_heatmap

    z = res.grid(metric, x, y)
    (xl, xs), (yl, ys) = axis_label(x), axis_label(y)
    return plot_heatmap(path, res.axes[x] * xs, res.axes[y] * ys, z, xlabel=xl, ylabel=yl,
                        zlabel=metric_label(metric), log=log, title=f"{metric_label(metric)} over {x} x {y} ({metric})")


def bifurcation(res: SweepResult, parameter: str, coordinate: str = "e_x", joint: int = 0, path=None):
    """PNG bifurcation diagram: the Poincare coordinate (:data:`POINCARE_COORDS`, or ``e`` for
    the eccentricity magnitude) of every section point of every run against ``parameter``."""
    from .plot import plot_bifurcation

    values, label = poincare_coordinate(res.poincare, coordinate, joint)
    pl, ps = axis_label(parameter)
    ok = res.table["status"] == 0
    return plot_bifurcation(path, res.table[parameter][ok] * ps, values[ok], xlabel=pl, ylabel=label,
                            title=f"bifurcation diagram over {parameter} (one point per crank revolution)")


def poincare_coordinate(points: np.ndarray, coordinate: str, joint: int = 0) -> tuple[np.ndarray, str]:
    """(values (n_runs, n_section), axis label) of one Poincare coordinate; lengths in mm."""
    p = np.asarray(points)[..., joint, :]
    if coordinate == "e":
        return 1e3 * np.hypot(p[..., 0], p[..., 1]), "eccentricity |e| [mm]"
    if coordinate not in POINCARE_COORDS:
        raise ParameterError(f"unknown Poincare coordinate {coordinate!r}; valid: {list(POINCARE_COORDS) + ['e']}")
    i = POINCARE_COORDS.index(coordinate)
    sym = f"${coordinate[0]}_{coordinate[2]}$"
    if i < 2:
        return 1e3 * p[..., i], f"journal-centre eccentricity {sym} [mm]"
    return p[..., i], f"journal-centre velocity {sym} relative to the bearing [m/s]"


def poincare_plot(res: SweepResult, runs=None, joint: int = 0, path=None, color_by: str | None = None):
    """PNG Poincare sections of the given runs (default all): journal position in the clearance
    circle and the (e_x, v_x) plane, one point per crank revolution after the transient."""
    from .plot import plot_poincare

    runs = np.arange(len(res.table["run"])) if runs is None else np.asarray(runs)
    color_by = color_by or res.names[0]
    label, scale = axis_label(color_by)
    name = "clearance" if joint == 0 else f"clearance@{joint}"
    if name in res.table:
        clearance = res.table[name][runs]
    elif len(res.base_clearance) > joint:
        clearance = res.base_clearance[joint]
    else:
        clearance = None
    return plot_poincare(path, res.poincare[runs, :, joint, :], colors=res.table[color_by][runs] * scale,
                         color_label=label, clearance=clearance)


__all__ = [
    "SweepConfig",
    "SweepResult",
    "Plan",
    "load_config",
    "config_from_dict",
    "run_sweep",
    "read_results",
    "read_chunks",
    "make_mesh",
    "auto_chunk_size",
    "csv_columns",
    "heatmap",
    "bifurcation",
    "poincare_plot",
    "poincare_coordinate",
    "TRACE_COUNT",
    "POINCARE_COORDS",
]
