"""Sweep configuration: :class:`SweepConfig` (validated when built, before anything is
compiled), :func:`load_config` (TOML) and :func:`config_from_dict`.

Checks: unknown tables or keys, unknown or conflicting parameter names, empty or inconsistent
grids, values outside their physical range, bad run and output settings; every error is a
:class:`~jaxclear.errors.ParameterError` naming the source and the allowed values.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from dataclasses import dataclass, field

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import params
from .._storage import fingerprint, json_text, jsonable, read_toml
from .._errors import JaxclearError, ParameterError
from .._results import deprecated
from ..model import Mechanism
from ..mechanisms.files import load_mechanism
from ..mechanisms.presets import PRESETS, preset
from ..integrate import Settings, check_settings
from ..integrate import (MAX_OUT_SAMPLES, OPTION_KEYS, deprecated_keywords, option_values,
                                  settings_from_options)
from ..analysis.channels import unit as channel_unit
from ..analysis.sections import section_indices
from .labels import channel_key
from .values import MAX_RUNS, _canonical, _is_speed, _number, _values

#: Allowed keys of a sweep configuration file, per table (see :func:`load_config`).
CONFIG_KEYS = {
    "mechanism": "preset and preset keyword overrides (law, friction, speed_rpm, clearance...)",
    "grid": "parameters swept as a Cartesian product: NAME = [values] or {start, stop, num, spacing}",
    "list": "parameters swept together (zipped, equal lengths): NAME = [values]",
    "run": "revolutions, transient_revolutions, samples_per_revolution, ideal_reference (solver, rtol, atol, "
           "max_steps: deprecated, in [settings])",
    "settings": "how every run is integrated: " + ", ".join(OPTION_KEYS) + " (jaxclear.Settings by name)",
    "output": "dir, chunk_size, trajectories, progress, devices, channels",
}
RUN_KEYS = ("revolutions", "transient_revolutions", "samples_per_revolution", "solver", "rtol", "atol",
            "max_steps", "ideal_reference")
#: Keys of ``[run]`` that moved to ``[settings]`` (accepted with a ``DeprecationWarning`` for one release).
OLD_RUN_SETTINGS = ("solver", "rtol", "atol", "max_steps")
#: The step limit of a sweep's run when no settings are given: a failing run in a batch costs at
#: most this many steps (the batch waits for its slowest run), half of ``Settings``' default.
MAX_STEPS = 200_000
OUTPUT_KEYS = ("dir", "chunk_size", "trajectories", "progress", "devices", "channels")

#: Largest runs x output samples of a sweep that stores its time series (``trajectories``):
#: about 100 bytes per sample of a one-joint mechanism on disk and in ``SweepResult``, ~5 GB.
MAX_TRAJECTORY_SAMPLES = 50_000_000


@dataclass
class SweepConfig:
    """A sweep, validated when built (every check runs before anything is compiled).

    Args:
        grid: ``{name: values}`` swept as a Cartesian product (first name slowest), or
        list: ``{name: values}`` zipped (equal lengths); exactly one of the two. Values: a list of
            numbers, one number, or ``{"start", "stop", "num", "spacing": "linear" | "log"}``.
        preset: preset mechanism name (:func:`jaxclear.preset`), with keyword overrides
            ``preset_options`` (``law``, ``friction``, ``speed_rpm``...); or
        mechanism: a :class:`~jaxclear.Mechanism` (then ``ideal_mechanism`` is its ideal-joint
            counterpart with the same bodies; default ``mechanism.ideal()``).
        revolutions: crank revolutions per run (> 0); ``t_end = revolutions * 2 pi / |omega|``.
        transient_revolutions: revolutions excluded from the metrics and the Poincare section
            (in [0, revolutions)).
        samples_per_revolution: output samples per revolution (>= 2; ``revolutions *
            samples_per_revolution`` must be an integer).
        settings: how every run is integrated (:class:`jaxclear.Settings`: solver, tolerances,
            step limit, derivatives, onsets...); the sweep replaces only what it owns: ``t_end``
            (the revolutions of each run's swept speed), ``t_start`` (0), ``n_out``, ``throw``
            (False: a failed run is a status) and ``progress`` (False). Default None: the
            defaults of ``Settings`` with ``max_steps`` :data:`MAX_STEPS`. The derivatives
            (``Sensitivity(tolerance)``) are those of a derivative of the runs (the tolerance
            study's estimate from derivatives).
        solver, rtol, atol, max_steps: deprecated (one release, a ``DeprecationWarning``):
            ``settings=jc.settings(1.0, rtol=...)``; with ``settings`` too, a
            :class:`~jaxclear.ParameterError`.
        ideal_reference: also run the ideal-joint mechanism (acceleration deviation metrics).
        out: output folder; chunk_size: runs per chunk (``"auto"`` or an integer, rounded up to a
            multiple of the number of devices); trajectories: also store the time series;
        progress: tqdm bar over the chunks; devices: number of devices to use (``None``: all).
        channels: named output channels (:mod:`jaxclear.analysis.channels`, e.g.
            ``joint:0:min_film_thickness``, ``joint:0:film_force``, ``joint:0:rear_lower_normal_force``,
            ``joint:0:feature``, ``point:rod:P:acc:norm``) summarized per run over the metrics window:
            columns ``min__KEY``, ``max__KEY``, ``mean__KEY``, ``rms__KEY``
            (:func:`jaxclear.sweep.labels.channel_column`; units in the dataset's attributes) and,
            with ``trajectories``, the time series ``traj_KEY``.
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
    solver: str | None = None
    rtol: float | None = None
    atol: float | None = None
    max_steps: int | None = None
    ideal_reference: bool = True
    out: str = "sweep-out"
    chunk_size: int | str = "auto"
    trajectories: bool = False
    progress: bool = True
    devices: int | None = None
    channels: tuple | list = ()
    settings: Settings | None = None
    source: str = "<python>"

    def __post_init__(self):
        self._check()

    # ---- validation -------------------------------------------------------------
    def _check(self):
        if (self.grid is None) == (self.list is None):
            raise ParameterError(f"{self.source}: give exactly one of 'grid' (Cartesian product) or 'list' "
                                 "(zipped values)")
        table = self.grid if self.grid is not None else self.list
        if not isinstance(table, dict) or not table:
            raise ParameterError(f"{self.source}: the {'grid' if self.grid is not None else 'list'} has no "
                                 f"parameters; give at least one NAME = [values] (names: {params.parameter_names()})")
        self._mech, self._ideal = self._check_mechanism()
        if self._ideal is not None and self._mech.role("slider") is None:
            self._ideal = None  # the deviation metrics are defined for a slider only
        self._check_parameters(table)
        self._check_channels()
        self._check_run()
        self._check_output()

    def _check_mechanism(self) -> tuple[Mechanism, Mechanism | None]:
        """(mechanism, ideal-joint mechanism or None) from the preset or the given mechanism."""
        src = self.source
        if self.mechanism is not None:
            if not isinstance(self.mechanism, Mechanism):
                raise ParameterError(
                    f"{src}: mechanism must be a jaxclear Mechanism, got {type(self.mechanism).__name__}")
            if not self.ideal_reference:
                return self.mechanism, None
            return self.mechanism, self.ideal_mechanism if self.ideal_mechanism is not None else self.mechanism.ideal()
        if self.preset not in PRESETS:
            raise ParameterError(f"{src}: unknown preset {self.preset!r}; valid presets: {sorted(PRESETS)}")
        allowed = [k for k in inspect.signature(PRESETS[self.preset]).parameters if k != "ideal"]
        unknown = sorted(set(self.preset_options) - set(allowed))
        if unknown:
            raise ParameterError(f"{src}: unknown key(s) {unknown} for preset {self.preset!r} in [mechanism]; "
                                 f"allowed: {['preset'] + allowed}")
        try:
            mech = preset(self.preset, **self.preset_options)
            ideal = preset(self.preset, ideal=True, **self.preset_options) if self.ideal_reference else None
        except JaxclearError as err:
            raise ParameterError(f"{src}: [mechanism]: {err}") from None
        return mech, ideal

    def _check_names(self, names: list[str]):
        """Every name addresses a leaf of the mechanism, and no two the same one."""
        seen: dict[tuple, str] = {}
        for name in names:
            try:
                params.get(self._mech, name)  # unknown name, joint or body -> ParameterError
            except JaxclearError as err:
                raise ParameterError(f"{self.source}: {err}") from None
            key = _canonical(name, self._mech)
            if key in seen:
                raise ParameterError(f"{self.source}: parameters {seen[key]!r} and {name!r} set the same "
                                     "quantity; keep one")
            seen[key] = name

    def _check_parameters(self, table: dict):
        """Names, values and the (n_runs, n_params) layout of the runs."""
        src = self.source
        names = [str(n) for n in table]
        self._check_names(names)
        axes = {}
        for name in names:
            try:
                vals = _values(name, table[name])
                params.validate(self._mech, name, vals)
            except JaxclearError as err:
                raise ParameterError(f"{src}: {err}") from None
            if _is_speed(name, self._mech) and np.any(vals == 0.0):
                raise ParameterError(f"{src}: {name} = 0: crank revolutions are undefined at zero speed")
            axes[name] = vals
        sizes = [len(v) for v in axes.values()]
        n_runs = math.prod(sizes) if self.grid is not None else max(sizes)
        if n_runs > MAX_RUNS:
            raise ParameterError(f"{src}: the {'grid' if self.grid is not None else 'list'} has {n_runs} runs "
                                 f"(axes {dict(zip(names, sizes))}), outside the allowed range [1, {MAX_RUNS}] "
                                 "(jaxclear.sweep.config.MAX_RUNS); split the sweep or use fewer values")
        if self.grid is not None:
            mesh = np.meshgrid(*axes.values(), indexing="ij")
            values = np.stack([m.ravel() for m in mesh], axis=-1)
        else:
            lengths = {n: len(v) for n, v in axes.items()}
            if len(set(lengths.values())) != 1:
                raise ParameterError(f"{src}: the list's parameters have different lengths {lengths}; a list sweep "
                                     "zips them, so they must be equally long (use 'grid' for a product)")
            values = np.stack(list(axes.values()), axis=-1)
        self._names, self._axes, self._values = tuple(names), axes, values
        if not any(_is_speed(n, self._mech) for n in names):
            try:
                w = float(params.get(self._mech, "speed"))
            except JaxclearError as err:
                raise ParameterError(f"{src}: {err}; sweeps run whole crank revolutions") from None
            if w == 0.0:
                raise ParameterError(f"{src}: the crank speed is 0: crank revolutions are undefined")
        self._ideal_names = tuple(n for n in names if self._ideal is not None and _applies(self._ideal, n))

    def _check_channels(self):
        """Every channel name is a string the mechanism answers (its unit), no two share a column."""
        src, names = self.source, self.channels
        if isinstance(names, str) or not isinstance(names, (list, tuple)):
            raise ParameterError(f"{src}: output.channels = {names!r}: expected a list of channel names such as "
                                 "['joint:0:min_film_thickness'] (CLI: --channel NAME)")
        units, keys = {}, {}
        for name in names:
            if not isinstance(name, str) or not name.strip():
                raise ParameterError(f"{src}: output.channels: {name!r} is not a channel name")
            try:
                units[name] = channel_unit(self._mech, name)
            except JaxclearError as err:
                raise ParameterError(f"{src}: output.channels: {err}") from None
            key = channel_key(name)
            if key in keys:
                raise ParameterError(f"{src}: output.channels {keys[key]!r} and {name!r} share the column name "
                                     f"{key!r}; keep one")
            keys[key] = name
        self._channel_units = units

    def _check_run(self):
        """Revolutions, samples and integration settings."""
        src = self.source
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
        n_out = int(round(total)) + 1
        if n_out > MAX_OUT_SAMPLES:
            raise ParameterError(f"{src}: run.revolutions x run.samples_per_revolution + 1 = {n_out} output samples "
                                 f"per run, outside the allowed range [2, {MAX_OUT_SAMPLES}] "
                                 "(jaxclear.integrate.MAX_OUT_SAMPLES); use fewer revolutions or samples")
        self._settings = self._run_settings()

    def _run_settings(self) -> Settings:
        """The settings of every run: ``settings`` (or the sweep's default) with the old keywords."""
        src = self.source
        check_settings(src, self.settings)
        old = {key: getattr(self, key) for key in OLD_RUN_SETTINGS if getattr(self, key) is not None}
        if "max_steps" in old and (isinstance(self.max_steps, bool) or
                                   not isinstance(self.max_steps, (int, np.integer))):
            raise ParameterError(f"{src}: run.max_steps = {self.max_steps!r}: expected an integer >= 1")
        for key in ("rtol", "atol"):
            if key in old:
                _number(f"{src}: run.{key}", old[key])
        try:
            old = deprecated_keywords("SweepConfig", self.settings, stacklevel=7, **old)  # the line that builds the config
        except ParameterError as err:
            raise ParameterError(f"{src}: {err}") from None
        base = self.settings if self.settings is not None else Settings(t_end=jnp.asarray(1.0), max_steps=MAX_STEPS)
        try:  # Settings' own checks (the solver's name, rtol in (0, 1), atol > 0, max_steps >= 1)
            return dataclasses.replace(base, **{k: (float(v) if k in ("rtol", "atol") else v) for k, v in old.items()})
        except JaxclearError as err:
            raise ParameterError(f"{src}: run: {err}") from None

    def _check_output(self):
        """Flags, output folder, chunk size and device count."""
        src = self.source
        for key in ("ideal_reference", "trajectories", "progress"):
            if not isinstance(getattr(self, key), bool):
                raise ParameterError(f"{src}: {key} = {getattr(self, key)!r}: expected true or false")
        if not isinstance(self.out, (str, os.PathLike)) or not str(self.out):
            raise ParameterError(f"{src}: output.dir = {self.out!r}: expected a folder name")
        stored = self.n_runs * self.n_out
        if self.trajectories and stored > MAX_TRAJECTORY_SAMPLES:
            raise ParameterError(
                f"{src}: output.trajectories (CLI: --trajectories) stores runs x samples = {self.n_runs} x "
                f"{self.n_out} = {stored} time-series samples, outside the allowed range [0, "
                f"{MAX_TRAJECTORY_SAMPLES}] (jaxclear.sweep.config.MAX_TRAJECTORY_SAMPLES, ~100 bytes each); "
                "store fewer runs, revolutions or run.samples_per_revolution, or turn trajectories off")
        cs = self.chunk_size
        if not (cs == "auto" or (isinstance(cs, (int, np.integer)) and not isinstance(cs, bool) and cs >= 1)):
            raise ParameterError(f"{src}: output.chunk_size = {cs!r}: expected 'auto' or an integer >= 1")
        available = len(jax.devices())
        d = self.devices
        if d is not None and (isinstance(d, bool) or not isinstance(d, (int, np.integer)) or not 1 <= d <= available):
            raise ParameterError(f"{src}: output.devices = {d!r}: expected an integer in [1, {available}] "
                                 f"(devices available: {available}) or 'all'")

    # ---- derived ----------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """Swept parameter names, in column order."""
        return self._names

    @property
    def ideal_names(self) -> tuple[str, ...]:
        """Swept names that also apply to the ideal-joint mechanism (empty without one)."""
        return self._ideal_names

    @property
    def values(self) -> np.ndarray:
        """(n_runs, n_params) parameter values, row ``i`` = run ``i``."""
        return self._values

    @property
    def axes(self) -> dict[str, np.ndarray]:
        """Each parameter's distinct values as given (the grid axes)."""
        return dict(self._axes)

    @property
    def channel_units(self) -> dict[str, str]:
        """The summarized output channels, name -> unit."""
        return dict(self._channel_units)

    @property
    def run_settings(self) -> Settings:
        """How every run is integrated (``settings``, or the sweep's default, with the old
        keywords); ``t_end`` and ``n_out`` of a run are the sweep's (:func:`~.batch.run_settings`)."""
        return self._settings

    @property
    def n_runs(self) -> int:
        return int(self._values.shape[0])

    @property
    def base_mechanism(self) -> Mechanism:
        return self._mech

    @property
    def ideal(self) -> Mechanism | None:
        """The ideal-joint reference mechanism, or None (no reference run)."""
        return self._ideal

    @property
    def n_out(self) -> int:
        return int(round(self.revolutions * self.samples_per_revolution)) + 1

    @property
    def section(self) -> tuple[int, ...]:
        """Output sample indices of the Poincare section: every whole revolution after the transient."""
        s = self.samples_per_revolution
        first = math.ceil(self.transient_revolutions - 1e-12)
        return tuple(int(i) for i in section_indices(self.n_out, s, first * s)) if first * s < self.n_out else ()

    @property
    def window_start(self) -> int:
        """First output sample of the metrics window (after the transient)."""
        return int(math.ceil(self.transient_revolutions * self.samples_per_revolution - 1e-9))

    def describe(self) -> dict:
        """JSON-able definition (what the manifest stores and hashes)."""
        if self.mechanism is None:
            mech = {"preset": self.preset, **{k: jsonable(v) for k, v in sorted(self.preset_options.items())}}
        else:
            mech = {"mechanism": self._mech.name, "leaves_sha256": _tree_hash(self._mech),
                    "ideal_leaves_sha256": None if self._ideal is None else _tree_hash(self._ideal)}
        extra = {"channels": list(self._channel_units)} if self._channel_units else {}  # old hashes unchanged
        options = option_values(self._settings)
        defaults = option_values(Settings(t_end=jnp.asarray(1.0)))
        # the settings beyond the four of old, where they differ from the defaults (old hashes unchanged)
        changed = {k: v for k, v in options.items() if k not in OLD_RUN_SETTINGS and v != defaults[k]}
        baumgarte = [float(self._settings.baumgarte.alpha), float(self._settings.baumgarte.beta)]
        if baumgarte != [5.0, 5.0]:
            changed["baumgarte"] = baumgarte
        settings = {"settings": changed} if changed else {}
        return {
            **extra,
            "mechanism": mech,
            "mode": "grid" if self.grid is not None else "list",
            "parameters": {n: [float(v) for v in a] for n, a in self._axes.items()},
            "run": {"revolutions": float(self.revolutions), "transient_revolutions": float(self.transient_revolutions),
                    "samples_per_revolution": int(self.samples_per_revolution), "solver": options["solver"],
                    "rtol": float(options["rtol"]), "atol": float(options["atol"]),
                    "max_steps": int(options["max_steps"]), "ideal_reference": self._ideal is not None,
                    **settings},
            "trajectories": bool(self.trajectories),
        }

    def sweep_hash(self) -> str:
        """sha256 of the definition (:meth:`describe`, as sorted JSON) and of every run's
        parameter values (float64 bytes, bit-exact), via :func:`jaxclear._storage.fingerprint`."""
        return fingerprint(json_text(self.describe(), indent=None), np.asarray(self._values, dtype=float))


def _applies(mech: Mechanism, name: str) -> bool:
    try:
        params.get(mech, name)
        return True
    except JaxclearError:
        return False


def _tree_hash(tree) -> str:
    """sha256 of a pytree's array leaves (float64 bytes) and its structure."""
    return fingerprint(eqx.filter(tree, eqx.is_array))


def load_config(path, *, settings_options: dict | None = None, **overrides) -> SweepConfig:
    """Read a TOML sweep configuration (see ``examples/sweep.toml``) and validate it.

    Tables: ``[mechanism]`` (``preset`` and preset keyword overrides, or ``file = "M.toml"``, a
    mechanism file relative to the configuration's folder), ``[grid]`` or ``[list]``
    (the swept parameters), ``[run]`` (:data:`RUN_KEYS`), ``[settings]`` (how every run is
    integrated: :data:`~jaxclear.integrate.OPTION_KEYS`, ``Settings``' fields by name,
    converted by :func:`~jaxclear.integrate.settings_from_options` as the command line's
    are), ``[output]`` (:data:`OUTPUT_KEYS`). ``solver``, ``rtol``, ``atol``, ``max_steps`` in
    ``[run]`` are deprecated (a ``DeprecationWarning``, one release): write them in
    ``[settings]``. Unknown tables or keys are errors. ``overrides`` replace
    :class:`SweepConfig` fields (the command-line options); ``settings_options`` (names, as in
    ``[settings]``) replace the file's settings one by one (the command line's integration
    options). Relative ``output.dir`` is relative to the current folder.
    """
    path = os.fspath(path)
    return config_from_dict(read_toml(path, "sweep configuration"), source=path, settings_options=settings_options,
                            **overrides)


def settings_table(doc: dict, run: dict, source: str, given: dict | None = None) -> Settings | None:
    """The :class:`~jaxclear.Settings` of a file's ``[settings]`` table (``doc["settings"]``),
    with the deprecated ``solver``, ``rtol``, ``atol``, ``max_steps`` of ``run`` (its ``[run]``
    table, removed from it; a ``DeprecationWarning``) and the command line's ``given`` options
    over them; ``None`` when none is given (the driver's default). Base: ``Settings``' defaults
    with ``max_steps`` :data:`MAX_STEPS`."""
    table = dict(doc.get("settings") or {})
    old = {key: run.pop(key) for key in OLD_RUN_SETTINGS if key in run}
    both = sorted(set(old) & set(table))
    if both:
        raise ParameterError(f"{source}: {both} given both in [run] and in [settings]; keep [settings]")
    if old:
        deprecated(f"{source}: writing {sorted(old)} in [run]", "a [settings] table (the same keys)", stacklevel=3)
    options = {**old, **table, **(given or {})}
    if not options:
        return None
    base = Settings(t_end=jnp.asarray(1.0), max_steps=MAX_STEPS)
    where = "[settings]" if not old else "[run]" if not table else "[run]/[settings]"
    return settings_from_options(options, base, source=f"{source}: {where}")


def config_from_dict(doc: dict, source: str = "<dict>", *, settings_options: dict | None = None,
                     **overrides) -> SweepConfig:
    """Build a :class:`SweepConfig` from the TOML layout (a dict of tables); unknown keys are
    errors naming the allowed ones (``settings_options``: :func:`load_config`)."""
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
    settings = settings_table(doc, run, source, settings_options)
    kwargs: dict = {"source": source, "grid": doc.get("grid"), "list": doc.get("list"), "settings": settings, **run}
    if "file" in mech:  # a mechanism file, relative to the configuration's folder
        if set(mech) != {"file"}:
            raise ParameterError(f"{source}: [mechanism] with 'file' takes no other key (got {sorted(mech)}); "
                                 "set fixed values in the mechanism file, swept ones in [grid] or [list]")
        folder = os.path.dirname(source) if os.path.isfile(source) else ""
        kwargs.update(preset=None, mechanism=load_mechanism(os.path.join(folder, str(mech["file"]))))
    else:
        kwargs.update(preset=mech.pop("preset", "flores-slider-crank"), preset_options=mech)
    for key in OUTPUT_KEYS:
        if key in out:
            kwargs["out" if key == "dir" else key] = out[key]
    if kwargs.get("devices") == "all":
        kwargs["devices"] = None
    kwargs.update({k: v for k, v in overrides.items() if v is not None})
    return SweepConfig(**kwargs)
