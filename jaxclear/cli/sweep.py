"""``jaxclear sweep``: run a parameter sweep from a TOML file (CSV, NPZ, PNG)."""

from __future__ import annotations

import argparse
import dataclasses

import jax

from .._errors import ParameterError
from .._xla_flags import request_host_devices
from ..integrate import default_settings
from ..sweep import load_config, make_mesh, run_sweep
from ..sweep.config import MAX_STEPS
from .common import number_in
from .settings import add_settings_options, given_options

HELP = "run a parameter sweep from a TOML file (CSV, NetCDF, NPZ, PNG)"
DESCRIPTION = """\
Run a parameter sweep described by a TOML file (see examples/sweep.toml): a grid or a list
over any numeric parameters, split over all local devices (on CPU one device per core unless
XLA_FLAGS sets --xla_force_host_platform_device_count), compiled once, written chunk by chunk
to the output folder:
  runs.csv                one row per run: index, parameters, metrics, statistics of the
                          --channel channels (min__KEY, max__KEY, mean__KEY, rms__KEY), status
  manifest.json           the sweep's definition and hash (a re-run resumes the same sweep)
  chunks/chunk_NNNNNN.npz Poincare points (and time series with --trajectories)
  results.nc              everything as a labelled dataset (NetCDF; xarray.open_dataset reads it)
  heatmap_METRIC.png      2-parameter grids: heat maps of the main metrics
  bifurcation_NAME.png    1-parameter sweeps: bifurcation diagram (Poincare e_x per revolution)
  poincare.png            Poincare sections of every run
Running the same command again after an interruption resumes where it stopped."""

def sweep_settings():
    """A sweep's settings where its file has no ``[settings]``: ``Settings``' defaults with the
    sweep's step limit (:data:`jaxclear.sweep.config.MAX_STEPS`)."""
    return dataclasses.replace(default_settings(), max_steps=MAX_STEPS)


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear sweep``; returns its ``run(args) -> exit code``."""
    p.add_argument("config", metavar="CONFIG.toml", help="sweep configuration file (TOML)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: the file's output.dir, else ./sweep-out)")
    p.add_argument("--chunk-size", type=number_in(int, 1), metavar="N",
                   help="runs per chunk, >= 1, rounded up to a multiple of the devices "
                   "(default: the file's, else auto)")
    p.add_argument("--devices", type=number_in(int, 1), metavar="N",
                   help="number of local devices to use, >= 1 and at most the devices available (default: all)")
    p.add_argument("--trajectories", action="store_true", default=None,
                   help="also store the time series in the chunk files (default: the file's, else off)")
    p.add_argument("--channel", action="append", metavar="NAME",
                   help="a named output channel to summarize per run (min, max, mean, rms over the metrics "
                   "window; with --trajectories also its time series), e.g. joint:0:min_film_thickness, "
                   "joint:0:rear_lower_normal_force; repeatable; replaces the file's output.channels")
    p.add_argument("--restart", action="store_true", help="discard results already in the folder instead of resuming")
    p.add_argument("--no-plots", action="store_true", help="write CSV/NPZ/JSON only, no PNG (default: off)")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    add_settings_options(p, sweep_settings(), title="integration (each option given replaces the file's [settings] "
                         "value; defaults: a sweep's without one)")
    return run


def run(args) -> int:
    """Load the configuration, run (or resume) the sweep, draw its plots, print a summary. On
    CPU the process first asks XLA for one host device per usable core
    (:func:`jaxclear._xla_flags.request_host_devices`; before JAX starts, so only where nothing
    has computed yet: a fresh ``jaxclear sweep`` process)."""
    request_host_devices()
    available = len(jax.devices())
    if args.devices is not None and args.devices > available:
        raise ParameterError(f"--devices = {args.devices} is outside the allowed range [1, {available}] "
                             f"(devices available: {available})")
    cfg = load_config(args.config, out=args.out, chunk_size=args.chunk_size, devices=args.devices,
                      trajectories=args.trajectories, progress=False if args.no_progress else None,
                      channels=args.channel, settings_options=given_options(args))
    mode = "grid" if cfg.grid is not None else "list"
    mesh = make_mesh(cfg.devices)  # the devices the sweep runs on
    print(f"jaxclear sweep: {cfg.n_runs} runs ({mode} over {', '.join(cfg.names)}), {cfg.revolutions:g} revolutions "
          f"each, on {mesh.size} {mesh.devices.flat[0].platform.upper()} device{'s' if mesh.size > 1 else ''}, "
          f"output {cfg.out}", flush=True)
    res = run_sweep(cfg, restart=args.restart, write_dataset=False)  # results.nc written once, below
    table = res.table
    failed = int(sum(1 for s in table["status"] if s != 0))
    files = res.write(cfg.out, plots=not args.no_plots)
    before = len(table["run"]) - res.computed
    resumed = f", resumed with {before} already on disk" if before > 0 else ""
    print(f"done: {len(table['run'])} of {cfg.n_runs} runs on disk ({res.computed} computed now){resumed}, "
          f"{failed} failed")
    print("wrote " + ", ".join(files))
    return 0
