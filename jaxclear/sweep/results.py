"""Reading a sweep folder back: :class:`SweepResult` (the CSV table, the Poincare points, the
grid axes; as labelled data with :meth:`SweepResult.to_xarray` and
:meth:`SweepResult.to_dataframe`; an :class:`~jaxclear.AbstractResult`: ``to_dict``, ``write``,
``summary``, ``plot``) and :func:`read_chunks` (the NPZ arrays, e.g. the time series)."""

from __future__ import annotations

import importlib
import os
import zipfile
from dataclasses import dataclass, field

import numpy as np

from .._errors import STATUS, CheckpointError, ParameterError
from .._results import AbstractResult
from .._storage import jsonable
from .labels import column_records
from .store import _INT_READ, CHUNK_DIR, CSV_NAME, MANIFEST_NAME, NETCDF_NAME, damaged, parse_rows, read_manifest



@dataclass
class SweepResult(AbstractResult):
    """A finished sweep read back from its folder (rows sorted by run index); :meth:`to_dict`,
    :meth:`write`, :meth:`summary`, :meth:`plot` (:class:`~jaxclear.AbstractResult`).

    Attributes:
        out: the folder. table: column -> (n_runs,) array (``status_message`` as strings).
        names: swept parameters. poincare: (n_runs, n_section, n_joints, 4) journal states
            (:data:`~jaxclear.sweep.POINCARE_COORDS`: [m, m, m/s, m/s]) at the whole revolutions
            after the transient.
        axes: each parameter's grid values. mode: ``"grid"`` or ``"list"``. computed: runs
            computed by this call (the others were already on disk). base_clearance: radial
            clearance [m] of each clearance joint of the unswept mechanism. manifest: the
            folder's ``manifest.json`` (the sweep's definition).
    """

    out: str
    table: dict
    names: tuple
    poincare: np.ndarray
    axes: dict
    mode: str
    computed: int = 0
    base_clearance: tuple = ()
    manifest: dict = field(default_factory=dict)

    def grid(self, metric: str, x: str, y: str) -> np.ndarray:
        """Metric as a (len(y axis), len(x axis)) array over a two-parameter grid sweep (NaN
        where no run is on disk). Unlabelled; ``to_xarray()[metric]`` is the same map with its
        axes, values and units attached."""
        if self.mode != "grid":
            raise ParameterError("a 2-D map needs a grid sweep (this one is a list)")
        for n in (x, y):
            if n not in self.axes:
                raise ParameterError(f"{n!r} is not a swept parameter; swept: {list(self.axes)}")
        if metric not in self.table:
            raise ParameterError(f"unknown metric {metric!r}; columns: {list(self.table)}")
        xs, ys = self.axes[x], self.axes[y]
        z = np.full((len(ys), len(xs)), np.nan)
        for r in range(len(self.table["run"])):
            i = int(np.argmin(np.abs(ys - self.table[y][r])))
            j = int(np.argmin(np.abs(xs - self.table[x][r])))
            z[i, j] = self.table[metric][r]
        return z

    def to_xarray(self):
        """The results as an :class:`xarray.Dataset`: for a grid sweep the swept parameters are
        dimensions (their values the coordinates), for a list sweep the dimension is ``run``;
        the metrics, ``status`` and the Poincare points are variables with ``units`` and
        ``long_name`` attributes (:mod:`jaxclear.sweep.dataset`)."""
        return _dataset().to_dataset(self.table, self.names, self.axes, self.mode, self.poincare, self.manifest)

    def to_dataframe(self):
        """The results as a :class:`pandas.DataFrame`: one row per run (index ``run``), the
        parameters and metrics as columns, ``df.attrs["units"]`` their units."""
        return _dataset().to_dataframe(self.table, self.names, column_records(self.manifest))

    def trajectories(self) -> dict:
        """The stored time series (``trajectories = true``): key -> (n_runs, ...) arrays."""
        return read_chunks(self.out, prefix="traj_")

    def _statuses(self) -> dict:
        """status code -> runs with it."""
        codes, counts = np.unique(np.asarray(self.table.get("status", []), dtype=np.int64), return_counts=True)
        return {int(c): int(n) for c, n in zip(codes, counts)}

    def to_dict(self) -> dict:
        """JSON-ready (NaN as None): the folder, the swept parameters and their axes, the runs on
        disk, computed now and failed (per :class:`~jaxclear.RESULTS` code), the table (column ->
        list, one entry a run) and the manifest (the sweep's definition)."""
        statuses = self._statuses()
        return jsonable({"folder": self.out, "mode": self.mode, "names": list(self.names), "axes": self.axes,
                         "runs_on_disk": len(self.table.get("run", [])), "computed": self.computed,
                         "failed": sum(n for c, n in statuses.items() if c != 0), "statuses": statuses,
                         "table": self.table, "manifest": self.manifest})

    def write(self, folder=None, *, plots: bool = True) -> list[str]:
        """The labelled dataset ``results.nc`` (:meth:`to_xarray`) and, with ``plots``, the
        figures (:func:`~jaxclear.sweep.figures.write_figures`: heat maps, bifurcation diagram,
        Poincare sections) in ``folder`` (default: the sweep's own folder); returns their paths,
        after ``runs.csv`` and ``manifest.json`` where ``folder`` is the sweep's own (those and
        ``chunks/`` are the sweep's store, written as it ran, and stay there)."""
        folder = self.out if folder is None else os.fspath(folder)
        os.makedirs(folder, exist_ok=True)
        own = os.path.abspath(folder) == os.path.abspath(self.out)
        paths = [os.path.join(folder, CSV_NAME), os.path.join(folder, MANIFEST_NAME)] if own else []
        paths.append(_dataset().write_netcdf(self.to_xarray(), os.path.join(folder, NETCDF_NAME)))
        if plots:
            paths += _figures().write_figures(self, folder)
        return paths

    def summary(self) -> str:
        """The runs on disk and how many failed (each status with its message), the swept
        parameters' ranges, and the range of the main metrics over the runs that succeeded."""
        n = len(self.table.get("run", []))
        total = self.manifest.get("n_runs", n)
        statuses = self._statuses()
        failed = sum(k for c, k in statuses.items() if c != 0)
        lines = [f"{n} of {total} runs on disk ({self.computed} computed now), {failed} failed; {self.mode} over "
                 + ", ".join(f"{name} [{np.min(self.axes[name]):.4g}, {np.max(self.axes[name]):.4g}]"
                             if len(self.axes.get(name, ())) else name for name in self.names)]
        lines += [f"  status {c}: {k} run(s): {STATUS.get(c, 'unknown status')}" for c, k in statuses.items() if c != 0]
        ok = np.asarray(self.table.get("status", []), dtype=np.int64) == 0
        for metric in _figures().PLOT_METRICS:
            values = np.asarray(self.table.get(metric, []), dtype=float)
            values = values[ok & np.isfinite(values)] if values.size == ok.size else values[:0]
            if values.size:
                lines.append(f"  {metric}: {values.min():.4g} .. {values.max():.4g}")
        return "\n".join(lines)

    def plot(self, path=None):
        """The main figure: over a 2-parameter grid the heat map of the first metric of
        :data:`~jaxclear.sweep.figures.PLOT_METRICS` in the table, over one parameter the
        bifurcation diagram, else the Poincare sections: the figure, or ``path`` once saved there."""
        figures = _figures()
        metrics = [m for m in figures.PLOT_METRICS if m in self.table]
        if self.mode == "grid" and len(self.names) == 2 and metrics:
            fig = figures.heatmap(self, metrics[0], x=self.names[0], y=self.names[1], path=path)
        elif len(self.names) == 1 and self.poincare.size:
            fig = figures.bifurcation(self, self.names[0], path=path)
        else:
            fig = figures.poincare_plot(self, path=path)
        return fig if path is None else os.fspath(path)


def _read_table(out: str) -> dict:
    """``runs.csv`` as column -> array, rows sorted by run index (a partial last line ignored;
    a damaged file is an error naming it and the line, :func:`~jaxclear.sweep.store.parse_rows`)."""
    path = os.path.join(out, CSV_NAME)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as err:
        raise CheckpointError(f"cannot read {path}: {err.strerror or err}") from None
    if data and not data.endswith(b"\n"):
        data = data[: data.rfind(b"\n") + 1]
    header, body = parse_rows(path, data)
    body.sort(key=lambda r: int(r[0]))
    table: dict = {}
    for j, col in enumerate(header):
        vals = [r[j] for r in body]
        if col == "status_message":
            table[col] = np.array(vals, dtype=object)
        elif col in _INT_READ:
            table[col] = np.array([int(v) for v in vals], dtype=np.int64)
        else:
            table[col] = np.array([float(v) for v in vals], dtype=float)
    return table


def read_results(out) -> SweepResult:
    """Read a sweep folder (complete or not): rows sorted by run index, Poincare points. A
    damaged file (``runs.csv``, ``manifest.json``, a chunk) is a :class:`~jaxclear.CheckpointError`
    naming it."""
    out = os.fspath(out)
    manifest = read_manifest(out)
    table = _read_table(out)
    n_runs = manifest.get("n_runs")
    if isinstance(n_runs, int) and len(table["run"]) and int(table["run"].max()) >= n_runs:
        raise damaged(os.path.join(out, CSV_NAME), f"run index {int(table['run'].max())} is outside this sweep's "
                      f"[0, {n_runs})")
    chunks = read_chunks(out, prefix="poincare")
    poincare = chunks.get("poincare", np.zeros((0,)))
    if "run" in chunks and len(table.get("run", [])):
        pos = {int(r): k for k, r in enumerate(chunks["run"])}
        missing = [int(r) for r in table["run"] if int(r) not in pos]
        if missing:
            raise damaged(os.path.join(out, CHUNK_DIR), f"runs {missing[:5]} of {CSV_NAME} have no chunk file")
        poincare = poincare[[pos[int(r)] for r in table["run"]]]
    cfg = manifest["config"]
    axes = {n: np.asarray(v, dtype=float) for n, v in cfg["parameters"].items()}
    return SweepResult(out, table, tuple(manifest["names"]), poincare, axes, cfg.get("mode", "grid"),
                       base_clearance=tuple(manifest.get("base_clearance_m", ())), manifest=manifest)


def _dataset():
    """:mod:`jaxclear.sweep.dataset`, imported on first use (xarray and pandas add about 1 s to
    ``import jaxclear``)."""
    return importlib.import_module(".dataset", __package__)


def _figures():
    """:mod:`jaxclear.sweep.figures`, imported on first use (matplotlib; it imports this module)."""
    return importlib.import_module(".figures", __package__)


def read_chunks(out, prefix: str = "") -> dict:
    """Concatenate the arrays of ``OUT/chunks/*.npz`` whose key starts with ``prefix`` (and the
    run indices, key ``run``), ordered by run index."""
    folder = os.path.join(os.fspath(out), CHUNK_DIR)
    names = sorted(n for n in os.listdir(folder) if n.startswith("chunk_") and n.endswith(".npz"))
    parts: dict[str, list] = {}
    for name in names:
        try:
            with np.load(os.path.join(folder, name)) as z:
                for key in z.files:
                    if key == "run" or key.startswith(prefix):
                        parts.setdefault(key, []).append(z[key])
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as err:
            raise damaged(os.path.join(folder, name), f"not a readable NPZ file: {err}") from None
    if not parts:
        return {}
    merged = {k: np.concatenate(v, axis=0) for k, v in parts.items()}
    order = np.argsort(merged["run"], kind="stable")
    return {k: v[order] for k, v in merged.items()}
