r"""Parameter sweeps: many simulations of one mechanism, batched with ``jax.vmap``, sharded over
the devices with :mod:`jax.sharding`, compiled once, written to disk chunk by chunk and
resumable.

A sweep is a grid (Cartesian product) or a list (zipped values) over any numeric parameters
that :mod:`jaxclear.params` names: ``clearance``, ``restitution``, ``friction``, ``stiffness``,
``exponent``, ``length``, ``speed`` / ``speed_rpm``, ``mass:BODY``, ``inertia:BODY``
(``NAME@J`` for clearance joint J). Each run simulates ``revolutions`` crank revolutions, so
``t_end = revolutions * 2 pi / |omega|`` follows the swept speed; the output grid has
``samples_per_revolution`` samples per revolution (the same number of samples for every run).

Modules:

* :mod:`~jaxclear.sweep.config`: :class:`SweepConfig`, :func:`load_config`,
  :func:`config_from_dict` (every input checked before anything is compiled);
  :mod:`~jaxclear.sweep.values`: parsing one parameter's values;
* :mod:`~jaxclear.sweep.plan`: :class:`Plan`, the static part of the compiled function;
* :mod:`~jaxclear.sweep.batch`: the compiled chunk function ``values (B, P) -> outputs``
  (clearance runs, ideal-joint runs, metrics, each vmapped, inside ``jax.shard_map``), jitted
  once per sweep structure (``TRACES.value`` counts the traces);
* :mod:`~jaxclear.sweep.devices`: the mesh, chunk sizing, moving chunks on and off the devices;
* :mod:`~jaxclear.sweep.lanes`: the one lane runner under every batch of jaxclear (sweeps,
  design evaluations, samplers, :func:`jaxclear.lyapunov_map`): the map-or-vmap rule
  (:func:`lanes_one_by_one`, :func:`over_lanes`), devices (:func:`on_devices`), chunks and resume
  (:func:`run_lanes`);
* :mod:`~jaxclear.sweep.store`: ``runs.csv``, ``manifest.json``, ``chunks/*.npz``;
* :mod:`~jaxclear.sweep.driver`: :func:`run_sweep`;
* :mod:`~jaxclear.sweep.results`: :class:`SweepResult`, :func:`read_results`;
* :mod:`~jaxclear.sweep.labels`: units and names of the columns;
* :mod:`~jaxclear.sweep.dataset`: the results as an ``xarray.Dataset`` / ``pandas.DataFrame``,
  ``OUT/results.nc`` (:func:`open_dataset`; loaded on first use, like the figures);
* :mod:`~jaxclear.sweep.figures`: :func:`heatmap`, :func:`bifurcation`, :func:`poincare_plot`
  (loaded on first use, so that ``import jaxclear`` does not import matplotlib).

``Settings(throw=False)``: a failed run gets a non-zero ``status`` and NaN metrics, the others
are unaffected.

Metrics per run: :func:`jaxclear.analysis.metrics.run_metrics` over the window after
``transient_revolutions``, the slider-acceleration deviation against the ideal-joint mechanism
(``jc.preset(..., ideal=True)`` or ``Mechanism.ideal()``, same speed, same time grid, vmapped
alongside). Poincare points: the journal state (eccentricity ``e_x, e_y`` [m] and its rate
``v_x, v_y`` [m/s], journal centre relative to bearing centre,
:func:`jaxclear.elements.journal_state`) at every whole crank revolution after the transient.

No LAPACK in the compiled chunk (measured 2026-11-23, jax 0.10.2, 2 shared CPU cores). Earlier
versions ran the ideal-joint runs only after every clearance run of the batch had finished and
capped the runs per CPU device, because jaxlib 0.10's batched CPU LAPACK kernels split a large
batch over the intra-op thread pool and block the calling pool thread, so two concurrent ones
could deadlock (a 20-run chunk on 2 forced host devices once hung with every pool thread in
``lapack_dgetrf_ffi``). The engine's solves are now unrolled eliminations
(``dynamics.spd_solve``), also in the assembly of the initial conditions. Measured:

* custom calls of the compiled chunk (flores-slider-crank, 4 runs, ideal reference on, 1 device;
  :func:`compiled_hlo`, i.e. ``jit(...).lower(...).compile()`` as text): before the assembly
  change ``lapack_dgesdd_ffi`` (the assembly's ``pinv``) and ``xla_ffi_python_cpu_callback``;
  after it only ``xla_ffi_python_cpu_callback``;
* with both workarounds removed, on 2 forced host devices
  (``XLA_FLAGS=--xla_force_host_platform_device_count=2``), ideal reference on, Bogacki-Shampine:
  a 24-run chunk (12 per device, 0.5 revolution, 101 samples) completes in 9.5 s (compilation
  included; 16.0 s before the assembly change); a 600-run chunk (300 per device: ``300 x 9^3``
  is above the 200,000 at which jaxlib 0.10 split its batched LU kernel over the pool; 0.25
  revolution, 2 samples) in 12.1 s (24.8 s before the assembly change, which also completed).
  Timings on a shared machine (load average about 5), so they vary.

``tests/test_sweep.py::test_compiled_chunk_has_no_lapack_call`` keeps the compiled chunk free of
LAPACK calls, so the deadlock cannot come back unnoticed.

Several hosts: call ``jax.distributed.initialize()`` in every process before
:func:`run_sweep`; the mesh then spans every device of every process, each process feeds its
own shards (``jax.make_array_from_callback``), the metrics are gathered
(``multihost_utils.process_allgather``) and process 0 alone writes the files (see docs/theory/sweep.md).
"""

from __future__ import annotations

import importlib
import warnings

from .batch import TRACES, TraceCounter, compiled_hlo, run_chunk, run_outputs
from .config import CONFIG_KEYS, OUTPUT_KEYS, RUN_KEYS, SweepConfig, config_from_dict, load_config
from .devices import (
    BYTES_PER_SAMPLE,
    DEFAULT_RUNS_PER_DEVICE,
    auto_chunk_size,
    chunk_size,
    fetch_chunk,
    make_mesh,
    put_chunk,
)
from .driver import run_sweep
from .lanes import lanes_one_by_one, on_devices, over_lanes, run_lanes
from .plan import Plan, make_plan
from .results import SweepResult, read_chunks, read_results
from .store import (
    CHUNK_DIR,
    CSV_NAME,
    FORMAT_VERSION,
    MANIFEST_NAME,
    NETCDF_NAME,
    POINCARE_COORDS,
    csv_columns,
    repair_csv,
)
from .labels import column_records, column_unit, long_name
from .values import RANGE_KEYS

#: Names served by :mod:`jaxclear.sweep.figures`, imported on first access (matplotlib).
_FIGURES = ("heatmap", "bifurcation", "poincare_plot", "poincare_coordinate", "axis_label", "metric_label")
#: Names served by :mod:`jaxclear.sweep.dataset`, imported on first access (xarray, pandas).
_DATASET = ("open_dataset", "write_netcdf")
#: The old private spellings of the chunk helpers, still served (with a DeprecationWarning) for
#: code written against them (benchmarks/bench_sweep.py): old name -> public name.
_RENAMED = {"_run_chunk": "run_chunk", "_put": "put_chunk", "_fetch": "fetch_chunk", "_repair_csv": "repair_csv"}


def __getattr__(name):
    if name in _FIGURES:
        return getattr(importlib.import_module(".figures", __name__), name)
    if name in _DATASET:
        return getattr(importlib.import_module(".dataset", __name__), name)
    if name == "TRACE_COUNT":  # the old spelling: a number read from the module
        warnings.warn("jaxclear.sweep.TRACE_COUNT is deprecated; read jaxclear.sweep.TRACES.value",
                      DeprecationWarning, stacklevel=2)
        return TRACES.value
    if name in _RENAMED:
        warnings.warn(f"jaxclear.sweep.{name} is deprecated; use jaxclear.sweep.{_RENAMED[name]}", DeprecationWarning,
                      stacklevel=2)
        return globals()[_RENAMED[name]]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "SweepConfig",
    "SweepResult",
    "Plan",
    "make_plan",
    "load_config",
    "config_from_dict",
    "run_sweep",
    "read_results",
    "read_chunks",
    "make_mesh",
    "run_chunk",
    "put_chunk",
    "fetch_chunk",
    "compiled_hlo",
    "run_outputs",
    "repair_csv",
    "auto_chunk_size",
    "chunk_size",
    "csv_columns",
    "heatmap",
    "bifurcation",
    "poincare_plot",
    "poincare_coordinate",
    "axis_label",
    "metric_label",
    "open_dataset",
    "write_netcdf",
    "NETCDF_NAME",
    "column_unit",
    "column_records",
    "long_name",
    "TRACES",
    "TraceCounter",
    "POINCARE_COORDS",
    "CSV_NAME",
    "MANIFEST_NAME",
    "CHUNK_DIR",
    "FORMAT_VERSION",
    "CONFIG_KEYS",
    "RUN_KEYS",
    "OUTPUT_KEYS",
    "RANGE_KEYS",
    "BYTES_PER_SAMPLE",
    "DEFAULT_RUNS_PER_DEVICE",
    "lanes_one_by_one",
    "over_lanes",
    "on_devices",
    "run_lanes",
]
