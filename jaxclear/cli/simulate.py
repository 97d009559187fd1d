"""``jaxclear simulate``: simulate a preset mechanism and write CSV, JSON and PNG plots."""

from __future__ import annotations

import argparse
import os

import jax

from .. import io, plot
from ..analysis import channels, metrics
from ..integrate import SAMPLES_PER_REVOLUTION, revolution_settings, revolutions_of, simulate_with_ideal
from .._errors import ParameterError, check_range
from .._numbers import as_typed
from ..model import crank_driver

from ..integrate import MAX_OUT_SAMPLES
from . import cache
from .settings import add_settings_options, settings_from_args
from .common import (add_mechanism_file_option, add_mechanism_options, fmt, load_mechanism_file, mechanism_file,
                     mechanism_overrides, number_in, preset_from_args)

HELP = "simulate a preset or a mechanism file (CSV, NetCDF, JSON, PNG)"
DESCRIPTION = """\
Simulate a preset mechanism or a mechanism file (jaxclear simulate FILE.toml) and write to the
output folder:
  timeseries.csv          sampled time series (SI units in the column names)
  timeseries.nc           the same as NetCDF (xarray): units per variable, the run's settings
                          as attributes
  summary.json            peak contact force, impacts, penetration, solver statistics, wall time
  slider_acceleration.png slider acceleration vs crank angle, ideal joint overlaid (slider only)
  orbit.png               journal-centre orbit inside the clearance circle (clearance joint only)
  contact_force.png       contact force vs crank angle (clearance joint only)

Physical parameters left out keep the preset's values (see 'jaxclear presets' and the
preset's docstring); e.g. flores-slider-crank: clearance 0.5e-3 m, restitution 0.9,
friction 0, 5000 rpm."""


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear simulate``; returns its ``run(args) -> exit code``."""
    add_mechanism_file_option(p)
    add_mechanism_options(p)
    add_integration_options(p)
    out = p.add_argument_group("output")
    out.add_argument("--out", default="./jaxclear-out", metavar="DIR",
                     help="output folder, created if missing (default: ./jaxclear-out)")
    out.add_argument("--output", action="append", metavar="CHANNEL",
                     help="output channel(s) for timeseries.csv (and one PNG each), repeatable or comma-separated, "
                     "e.g. body:rocker:phi:acc, point:rocker:B:acc:x:frame=rocker, reaction:0:norm, "
                     "joint:0:normal_force (names: docs/mechanism-files.md; default: the legacy columns, plus the "
                     "output link's motion with its ideal-joint overlay for a mechanism without a slider)")
    out.add_argument("--no-plots", action="store_true", help="write CSV and JSON only, no PNG (default: off)")
    out.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown when the compilation cache is off)")
    return run


def add_integration_options(p: argparse.ArgumentParser, revolutions: float = 3.0):
    """The integration options (time span, samples, solver, tolerances) of simulate and animate
    (``revolutions``: the default of ``--revolutions``)."""
    run_ = p.add_argument_group("integration")
    run_.add_argument("--revolutions", type=number_in(float, 0.0, low_open=True), default=float(revolutions),
                      metavar="N", help=f"simulated time in crank revolutions [-], > 0 (default: {revolutions:g})")
    run_.add_argument("--t-end", type=number_in(float, 0.0, low_open=True), metavar="S",
                      help="simulated time [s], > 0; overrides --revolutions (default: unset)")
    run_.add_argument("--n-out", type=number_in(int, 2, MAX_OUT_SAMPLES), metavar="N",
                      help=f"number of output samples [-], in [2, {MAX_OUT_SAMPLES}], uniform in time (default: "
                      f"{SAMPLES_PER_REVOLUTION} per crank revolution + 1, i.e. "
                      f"{3 * SAMPLES_PER_REVOLUTION + 1} for 3 revolutions)")
    add_settings_options(run_)
    add_free_dof_option(run_)


def add_free_dof_option(group):
    """``--allow-free-dof`` (:attr:`Settings.allow_free_dof <jaxclear.Settings>`), of the commands
    that assemble a driven mechanism (check, simulate, animate, wear)."""
    group.add_argument("--allow-free-dof", action="store_true",
                       help="allow a driven mechanism motion that no joint or driver determines, e.g. a pendulum "
                       "hanging from a driven crank (default: off, such a mechanism is an error naming the "
                       "missing constraints)")


def load(args):
    """``(mechanism, path or None, overrides)`` from a mechanism file or the preset options."""
    path = mechanism_file(args)
    if path is None:
        overrides = mechanism_overrides(args)
        return preset_from_args(args, ideal=args.ideal), None, overrides
    return load_mechanism_file(args, path, ideal=args.ideal), path, {"mechanism_file": path}


def settings_from(args, mech):
    """The run's :class:`~jaxclear.integrate.Settings` from the integration options (checked first
    under their flag names)."""
    if args.t_end is not None:
        check_range("--t-end", args.t_end, low=0.0, low_open=True, unit="s")
    else:
        check_range("--revolutions", args.revolutions, low=0.0, low_open=True)
        if crank_driver(mech) is None:
            raise ParameterError(f"{mech.name!r} has no crank (AngleDriver): give --t-end [s] instead of --revolutions")
    base = revolution_settings(mech, args.revolutions, t_end=args.t_end, n_out=args.n_out,
                               progress=cache.progress_allowed(args), allow_free_dof=args.allow_free_dof)
    return settings_from_args(args, base)  # the integration options given (cli/settings.py)


def run(args) -> int:
    """Simulate, write timeseries.csv and .nc, the plots and summary.json, print the summary."""
    mech, path, overrides = load(args)
    s = settings_from(args, mech)
    t_end, n_out = float(s.t_end), int(s.n_out)
    revolutions = revolutions_of(mech, t_end)
    os.makedirs(args.out, exist_ok=True)

    joint = mech.clearance_joints[0] if mech.clearance_joints else None
    what = "ideal joints" if joint is None else f"{plot.joint_label(joint)}, mu = {float(joint.friction.coefficient):g}"
    revs = f" ({revolutions:g} crank revolution(s))" if revolutions is not None else ""
    print(f"jaxclear: {mech.name}, {what}; t_end = {t_end:.6g} s{revs}, {n_out} samples, "
          f"{args.solver} rtol={args.rtol:g} atol={args.atol:g}", flush=True)
    chosen = [c.strip() for text in (args.output or []) for c in text.split(",") if c.strip()]
    names = chosen or (channels.default_channels(mech) if path is not None or mech.role("slider") is None else [])
    for name in names:
        channels.unit(mech, name)  # a bad name is an error before any compute
    wants_overlay = any(channels.parse(n).kind in channels.OVERLAY_KINDS for n in names)
    overlay = bool(mech.clearance_joints) and (wants_overlay or (not args.no_plots and mech.role("slider") is not None))
    print("compiling and integrating (the first run includes JIT compilation)"
          + (", then the ideal-joint mechanism for the overlay" if overlay else "") + "...", flush=True)
    r = simulate_with_ideal(mech, s, ideal=overlay)
    # host (NumPy) copies: indexing and plotting them runs no small JAX programs, each of which a
    # new process would compile or load from the cache
    r = r._replace(sol=jax.device_get(r.sol), ideal_sol=jax.device_get(r.ideal_sol))

    summary = metrics.summary(mech, r.sol, wall_time_s=r.wall_time_s)
    summary["inputs"] = inputs(args, path, overrides, t_end, revolutions, n_out)
    if r.ideal_sol is not None:
        summary["ideal_wall_time_s"] = r.ideal_wall_time_s
        summary["ideal_peak_slider_acc_m_s2"] = metrics.peak_slider_acceleration(r.ideal_mech, r.ideal_sol)
    table = channels.channel_table(mech, r.sol, names, r.ideal_mech, r.ideal_sol)
    base = {"time_s": r.sol.ts} if chosen else io.timeseries_table(mech, r.sol)
    files = [io.write_table_csv(os.path.join(args.out, "timeseries.csv"), {**base, **table}),
             io.write_timeseries_netcdf(os.path.join(args.out, "timeseries.nc"), {**base, **table},
                                        netcdf_attributes(mech, summary))]
    if not args.no_plots:
        files += plot.plot_simulation(args.out, mech, r.sol, r.ideal_sol, r.ideal_mech)
        files += _plot_channels(args.out, mech, r, chosen or names[-1:])
    files.append(io.write_json(os.path.join(args.out, "summary.json"), summary))
    _print_summary(summary, files)
    return 0


def netcdf_attributes(mech, summary: dict) -> dict:
    """Global attributes of timeseries.nc: what wrote it, the mechanism, the run's settings (the
    summary's ``inputs``: preset or mechanism file, overrides, t_end, samples, solver,
    tolerances) and its status."""
    from .. import __version__

    return {"title": f"jaxclear simulate: {mech.name}", "source": f"jaxclear {__version__}",
            "mechanism": mech.name, **summary["inputs"], "status": summary["status"],
            "status_message": summary["status_message"]}


def inputs(args, path, overrides: dict, t_end: float, revolutions: float | None, n_out: int) -> dict:
    """``summary.json``'s ``inputs``: what the user gave, and what follows from it (``t_end_s``
    from the revolutions, the revolutions from ``--t-end``) without the noise of the arithmetic
    between (:func:`~jaxclear._numbers.as_typed`: 3, not 3.0000000000000004)."""
    return {"preset": args.preset if path is None else None, "ideal": bool(args.ideal), **overrides,
            "t_end_s": as_typed(t_end), "revolutions": as_typed(revolutions), "n_out": n_out, "solver": args.solver,
            "rtol": args.rtol, "atol": args.atol, "max_steps": args.max_steps}


def _plot_channels(folder: str, mech, r, names: list[str]) -> list[str]:
    """One PNG per channel (ideal-joint overlay where it applies): ``channel_<name>.png``."""
    paths = []
    for name in names:
        values, unit = channels.channel_with_unit(mech, r.sol, name)
        ideal = None
        if r.ideal_sol is not None and channels.parse(name).kind in channels.OVERLAY_KINDS:
            ideal = channels.channel(r.ideal_mech, r.ideal_sol, name)
        safe = "".join(ch if ch.isalnum() else "_" for ch in name)
        paths.append(os.path.join(folder, f"channel_{safe}.png"))
        plot.plot_channel(paths[-1], mech, r.sol, name, values, unit, ideal)
    return paths


def _print_summary(s: dict, files: list[str]):
    """Print the main numbers of summary.json and the files written."""
    lines = [f"done in {s['wall_time_s']:.2f} s wall (incl. compilation); status {s['status']}: {s['status_message']}"]
    if s["impacts"] is not None:
        pen = s["max_penetration_m"]
        lines += [
            f"  impacts (contact onsets)   {s['impacts']}",
            f"  peak contact force         {fmt(s['peak_contact_force_n'], 'N')}",
            f"  max penetration            {fmt(pen * 1e6 if pen is not None else None, 'um')}",
            f"  free / impact / continuous {s['fraction_free_flight']:.1%} / {s['fraction_impact']:.1%} / "
            f"{s['fraction_continuous_contact']:.1%} of samples",
            f"  energy dissipated          {fmt(s['energy_dissipated_j'], 'J')}",
        ]
    if s["peak_slider_acc_m_s2"] is not None:
        ideal = s.get("ideal_peak_slider_acc_m_s2")
        extra = f" (ideal joint: {fmt(ideal, 'm/s^2')})" if ideal is not None else ""
        lines.append(f"  peak slider acceleration   {fmt(s['peak_slider_acc_m_s2'], 'm/s^2')}{extra}")
    lines += [
        f"  max constraint drift       {fmt(s['max_constraint_drift'], spec='.3g')}",
        f"  solver steps               {s['num_steps']} ({s['num_accepted_steps']} accepted, "
        f"{s['num_rejected_steps']} rejected)",
        "wrote " + ", ".join(files),
    ]
    print("\n".join(lines))
