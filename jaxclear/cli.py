"""The ``jaxclear`` command line.

    jaxclear simulate [options]     simulate a preset, write CSV, JSON and PNG plots
    jaxclear presets                list the preset mechanisms
    jaxclear fit DATA.csv [options] fit contact parameters to a measured record

Subcommands are registered with :func:`subcommand`: each is a function that adds its
arguments to an :class:`argparse.ArgumentParser` and returns the function that runs it
(``run(args) -> exit code``). Errors of type :class:`jaxclear.JaxclearError` (bad parameters,
failed runs) are printed as ``error: ...`` on stderr with exit code 2 and no traceback;
command-line syntax errors also exit with 2 (argparse).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from typing import Callable

#: Registered subcommands: name -> (one-line help, description, configure function).
SUBCOMMANDS: dict[str, tuple[str, str, Callable]] = {}

SAMPLES_PER_REVOLUTION = 2000
DEFAULT_SAMPLES = 2001  # when the mechanism has no crank period


def subcommand(name: str, help: str, description: str = ""):
    """Register ``configure(parser) -> run`` as subcommand ``name`` (decorator)."""

    def deco(configure: Callable):
        SUBCOMMANDS[name] = (help, description or help, configure)
        return configure

    return deco


class _Formatter(argparse.RawDescriptionHelpFormatter):
    def __init__(self, prog):
        super().__init__(prog, max_help_position=30, width=100)


def build_parser() -> argparse.ArgumentParser:
    """The full parser, with one sub-parser per registered subcommand."""
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="jaxclear",
        description="Dynamics of planar mechanisms with revolute clearance joints (JAX, differentiable).",
        epilog="Run 'jaxclear COMMAND --help' for the options of a command (all in SI units).\n"
        "Example: jaxclear simulate --preset flores-slider-crank --clearance 0.5e-3 --revolutions 3",
        formatter_class=_Formatter,
    )
    parser.add_argument("--version", action="version", version=f"jaxclear {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    for name, (help_, description, configure) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=description, formatter_class=_Formatter)
        p.set_defaults(run=configure(p))
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxclear`` console script; returns the exit code."""
    from .errors import JaxclearError

    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors (code 2)
        return int(exc.code or 0) if not isinstance(exc.code, str) else 2
    if getattr(args, "run", None) is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args.run(args) or 0)
    except JaxclearError as err:
        text = str(err)
        text = text[len("jaxclear: "):] if text.startswith("jaxclear: ") else text
        print(f"error: {text}", file=sys.stderr)
        return 2
    except OSError as err:
        where = f" {err.filename!r}" if getattr(err, "filename", None) else ""
        print(f"error: cannot access{where}: {err.strerror or err}", file=sys.stderr)
        return 1


# --------------------------------------------------------------------------------------
# presets
# --------------------------------------------------------------------------------------


def _first_line(doc: str | None, width: int = 100) -> str:
    """The docstring's first paragraph on one line, shortened to ``width`` characters."""
    paragraph = " ".join((doc or "").strip().split("\n\n")[0].split())
    if len(paragraph) <= width:
        return paragraph
    return paragraph[: width - 3].rsplit(" ", 1)[0] + "..."


def _preset_defaults(fn) -> str:
    """``clearance 0.5 mm, c_r 0.9, mu 0, 5000 rpm`` from a preset function's defaults."""
    import inspect

    params = inspect.signature(fn).parameters
    d = {k: v.default for k, v in params.items() if v.default is not inspect.Parameter.empty}
    parts = []
    if "clearance" in d:
        parts.append(f"clearance {d['clearance'] * 1e3:g} mm")
    if "restitution" in d:
        parts.append(f"c_r {d['restitution']:g}")
    if "friction" in d:
        parts.append(f"mu {d['friction']:g}")
    if "speed_rpm" in d:
        parts.append(f"{d['speed_rpm']:g} rpm")
    return ", ".join(parts)


@subcommand("presets", "list the preset mechanisms", "List the preset mechanisms that --preset accepts.")
def _configure_presets(p: argparse.ArgumentParser):
    def run(args) -> int:
        from .presets import PRESETS

        width = max(len(n) for n in PRESETS)
        for name in sorted(PRESETS):
            print(f"{name:<{width}}  {_first_line(PRESETS[name].__doc__)}")
            defaults = _preset_defaults(PRESETS[name])
            if defaults:
                print(f"{'':<{width}}  defaults: {defaults}")
        return 0

    return run


# --------------------------------------------------------------------------------------
# simulate
# --------------------------------------------------------------------------------------

SIMULATE_DESCRIPTION = """\
Simulate a preset mechanism and write to the output folder:
  timeseries.csv          sampled time series (SI units in the column names)
  summary.json            peak contact force, impacts, penetration, solver statistics, wall time
  slider_acceleration.png slider acceleration vs crank angle, ideal joint overlaid (slider only)
  orbit.png               journal-centre orbit inside the clearance circle (clearance joint only)
  contact_force.png       contact force vs crank angle (clearance joint only)

Physical parameters left out keep the preset's values (see 'jaxclear presets' and the
preset's docstring); e.g. flores-slider-crank: clearance 0.5e-3 m, restitution 0.9,
friction 0, 5000 rpm."""


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"must be at least 2, got {value}")
    return value


@subcommand("simulate", "simulate a preset mechanism (CSV, JSON, PNG)", SIMULATE_DESCRIPTION)
def _configure_simulate(p: argparse.ArgumentParser):
    from . import SOLVERS, law_names, preset_names

    mech = p.add_argument_group("mechanism")
    mech.add_argument("--preset", default="flores-slider-crank", metavar="NAME",
                      help=f"preset mechanism, one of {', '.join(preset_names())} (default: flores-slider-crank)")
    mech.add_argument("--clearance", type=float, metavar="M",
                      help="radial clearance c = R_B - R_J [m], > 0 and < the bearing radius "
                      "(default: the preset's, 0.5e-3 m)")
    mech.add_argument("--restitution", type=float, metavar="CR",
                      help="coefficient of restitution c_r [-], in (0, 1] (default: the preset's, 0.9)")
    mech.add_argument("--friction", type=float, metavar="MU",
                      help="friction coefficient mu [-], >= 0 (default: the preset's; 0 for "
                      "flores-slider-crank and four-bar, 0.01 for flores-2011-rig)")
    mech.add_argument("--speed-rpm", type=float, metavar="RPM",
                      help="crank speed [rev/min] (default: the preset's; 5000 for flores-slider-crank, "
                      "200 for flores-2011-rig, 500 for four-bar)")
    mech.add_argument("--model", default="lankarani-nikravesh", metavar="LAW",
                      help=f"normal contact force law [-], one of {', '.join(law_names())} "
                      "(default: lankarani-nikravesh)")
    mech.add_argument("--stiffness", type=float, metavar="K",
                      help="contact stiffness, > 0: K [N/m^n] of the Hertz-family laws (n = 1.5), the "
                      "stiffness parameter of the others (default: from steel, E = 207 GPa, nu = 0.3, and "
                      "the radii; K = 6.61e10 N/m^1.5 for R_B = 10 mm, c = 0.5 mm)")
    mech.add_argument("--ideal", action="store_true",
                      help="replace the clearance joint by an ideal revolute joint (default: off)")
    _add_hybrid_options(p)

    run_ = p.add_argument_group("integration")
    run_.add_argument("--revolutions", type=float, default=3.0, metavar="N",
                      help="simulated time in crank revolutions [-], > 0 (default: 3)")
    run_.add_argument("--t-end", type=float, metavar="S",
                      help="simulated time [s], > 0; overrides --revolutions (default: unset)")
    run_.add_argument("--n-out", type=_positive_int, metavar="N",
                      help=f"number of output samples [-], >= 2, uniform in time (default: "
                      f"{SAMPLES_PER_REVOLUTION} per crank revolution + 1, i.e. 6001 for 3 revolutions)")
    run_.add_argument("--solver", default="tsit5", metavar="NAME",
                      help=f"explicit/implicit Runge-Kutta solver, one of {', '.join(SOLVERS)} (default: tsit5)")
    run_.add_argument("--rtol", type=float, default=1e-6, metavar="TOL",
                      help="relative tolerance of the adaptive step [-], in (0, 1) (default: 1e-6)")
    run_.add_argument("--atol", type=float, default=1e-9, metavar="TOL",
                      help="absolute tolerance of the adaptive step [m, rad, m/s, rad/s], > 0 (default: 1e-9)")
    run_.add_argument("--max-steps", type=int, default=400_000, metavar="N",
                      help="maximum number of solver steps [-], >= 1 (default: 400000)")

    out = p.add_argument_group("output")
    out.add_argument("--out", default="./jaxclear-out", metavar="DIR",
                     help="output folder, created if missing (default: ./jaxclear-out)")
    out.add_argument("--no-plots", action="store_true", help="write CSV and JSON only, no PNG (default: off)")
    out.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    return _run_simulate


def _add_hybrid_options(p: argparse.ArgumentParser):
    """Options of the hybrid Gauss-point model (``--model hybrid``), shared by simulate and fit."""
    h = p.add_argument_group("hybrid model (--model hybrid)")
    h.add_argument("--placement", choices=("arc", "fixed"), default=None,
                   help="where the Gauss points sit: 'arc' (on the current contact arc, exact with few "
                   "points) or 'fixed' (body-fixed over the whole pin circumference, as in the paper) "
                   "(default: arc)")
    h.add_argument("--elements", type=_positive_int, metavar="N_E",
                   help="number of elements N_e [-], >= 1 (default: 2 for arc, 180 for fixed)")
    h.add_argument("--gauss-points", type=_positive_int, metavar="N_G",
                   help="Gauss-Legendre points per element N_g [-], >= 1 (default: 4)")
    h.add_argument("--layer-thickness", type=float, metavar="H",
                   help="compliant layer thickness h [m], > 0 (default: the clearance c)")
    h.add_argument("--damping", choices=("joint", "point"), default=None,
                   help="Qin-Lu damping applied to the joint resultant or to every point (default: joint)")
    h.add_argument("--geometry", choices=("exact", "small-gap"), default=None,
                   help="point penetration from the exact circles or the small-gap profile e cos(theta) - c "
                   "(default: exact)")


def _hybrid_options(args) -> dict:
    keys = {"placement": "placement", "elements": "n_elements", "gauss_points": "n_gauss",
            "layer_thickness": "thickness", "damping": "damping", "geometry": "geometry"}
    opts = {key: getattr(args, attr) for attr, key in keys.items() if getattr(args, attr, None) is not None}
    if opts and args.model != "hybrid":
        from .errors import ParameterError

        raise ParameterError(f"--{', --'.join(k.replace('_', '-') for k in opts)} apply only to --model hybrid "
                             f"(got --model {args.model})")
    return opts


def _overrides(args) -> dict:
    names = {"clearance": "clearance", "restitution": "restitution", "friction": "friction",
             "speed_rpm": "speed_rpm", "stiffness": "stiffness"}
    out = {key: getattr(args, attr) for attr, key in names.items() if getattr(args, attr) is not None}
    out["law"] = args.model
    opts = _hybrid_options(args)
    if opts:
        out["law_options"] = opts
    return out


@subcommand("models", "list the contact force laws", "List every normal contact force law that --model "
            "accepts, with its parameters (defaults) and reference, and the friction laws.")
def _configure_models(p: argparse.ArgumentParser):
    p.add_argument("--json", action="store_true", help="print JSON instead of text (default: text)")

    def run(args) -> int:
        import json

        from .contact.friction import FRICTION_MODELS
        from .contact.registry import describe_laws

        laws = describe_laws()
        if args.json:
            print(json.dumps({"laws": laws, "friction": list(FRICTION_MODELS)}, indent=2))
            return 0
        for law in laws:
            print(f"{law['name']}")
            print(f"    {law['formula']}")
            print(f"    reference: {law['reference']}")
            params = ", ".join(f"{k}={v}" for k, v in law["parameters"].items())
            print(f"    parameters: {params}")
            print(f"    --stiffness sets: {law['stiffness_parameter']}")
        print("friction laws (per joint): " + ", ".join(FRICTION_MODELS)
              + " (ambrosio: Ambrosio 2003 modified Coulomb; smooth: mu F_N tanh(v_T / v_s))")
        return 0

    return run


def _timed_simulate(mech, s):
    import jax

    from .solve import simulate

    t = time.perf_counter()
    sol = jax.block_until_ready(simulate(mech, s))
    return sol, time.perf_counter() - t


def _run_simulate(args) -> int:
    from . import io, metrics, plot
    from .errors import JaxclearError, check_range
    from .presets import preset
    from .solve import crank_period, settings

    overrides = _overrides(args)
    mech = preset(args.preset, ideal=args.ideal, **overrides)
    period = None
    if args.t_end is not None:
        check_range("--t-end", args.t_end, low=0.0, low_open=True, unit="s")
        t_end = float(args.t_end)
        try:
            period = crank_period(mech)
        except JaxclearError:  # no constant-speed crank: revolutions undefined, t_end suffices
            period = None
    else:
        check_range("--revolutions", args.revolutions, low=0.0, low_open=True)
        period = crank_period(mech)
        t_end = args.revolutions * period
    revolutions = t_end / period if period else None
    if args.n_out is not None:
        n_out = args.n_out
    elif revolutions is not None:
        n_out = max(int(round(SAMPLES_PER_REVOLUTION * revolutions)), 100) + 1
    else:
        n_out = DEFAULT_SAMPLES
    s = settings(t_end, n_out=n_out, solver=args.solver, rtol=args.rtol, atol=args.atol,
                 max_steps=args.max_steps, progress=not args.no_progress)
    os.makedirs(args.out, exist_ok=True)

    joint = mech.clearance_joints[0] if mech.clearance_joints else None
    what = "ideal joints" if joint is None else (
        f"{plot.joint_label(joint)}, mu = {float(joint.friction.coefficient):g}")
    revs = f" ({revolutions:g} crank revolution(s))" if revolutions is not None else ""
    print(f"jaxclear: {mech.name}, {what}; t_end = {t_end:.6g} s{revs}, {n_out} samples, "
          f"{args.solver} rtol={args.rtol:g} atol={args.atol:g}", flush=True)
    print("compiling and integrating (the first run includes JIT compilation)...", flush=True)
    sol, wall = _timed_simulate(mech, s)
    summary = metrics.summary(mech, sol, wall_time_s=wall)
    summary["inputs"] = {
        "preset": args.preset, "ideal": bool(args.ideal), **overrides, "t_end_s": t_end,
        "revolutions": revolutions, "n_out": n_out, "solver": args.solver, "rtol": args.rtol,
        "atol": args.atol, "max_steps": args.max_steps,
    }

    files = [io.write_timeseries_csv(os.path.join(args.out, "timeseries.csv"), mech, sol)]
    if not args.no_plots:
        if mech.role("slider") is not None:
            ideal_sol, ideal_mech = None, None
            if mech.clearance_joints:
                print("integrating the ideal-joint mechanism for the overlay...", flush=True)
                ideal_mech = preset(args.preset, ideal=True, **overrides)
                ideal_sol, ideal_wall = _timed_simulate(ideal_mech, s)
                summary["ideal_wall_time_s"] = ideal_wall
                summary["ideal_peak_slider_acc_m_s2"] = metrics.peak_slider_acceleration(ideal_mech, ideal_sol)
            path = os.path.join(args.out, "slider_acceleration.png")
            plot.plot_slider_acceleration(path, mech, sol, ideal_sol, ideal_mech)
            files.append(path)
        if mech.clearance_joints:
            for name, fn in (("orbit.png", plot.plot_orbit), ("contact_force.png", plot.plot_contact_force)):
                fn(os.path.join(args.out, name), mech, sol)
                files.append(os.path.join(args.out, name))
    files.append(io.write_json(os.path.join(args.out, "summary.json"), summary))
    _print_summary(summary, files)
    return 0


def _fmt(value, unit="", spec=".4g"):
    return "n/a" if value is None else f"{value:{spec}}{(' ' + unit) if unit else ''}"


def _print_summary(s: dict, files: list[str]):
    lines = [f"done in {s['wall_time_s']:.2f} s wall (incl. compilation); status {s['status']}: {s['status_message']}"]
    if s["impacts"] is not None:
        lines += [
            f"  impacts (contact onsets)   {s['impacts']}",
            f"  peak contact force         {_fmt(s['peak_contact_force_n'], 'N')}",
            f"  max penetration            {_fmt(s['max_penetration_m'] * 1e6 if s['max_penetration_m'] is not None else None, 'um')}",
            f"  free / impact / continuous {s['fraction_free_flight']:.1%} / {s['fraction_impact']:.1%} / "
            f"{s['fraction_continuous_contact']:.1%} of samples",
            f"  energy dissipated          {_fmt(s['energy_dissipated_j'], 'J')}",
        ]
    if s["peak_slider_acc_m_s2"] is not None:
        ideal = s.get("ideal_peak_slider_acc_m_s2")
        extra = f" (ideal joint: {_fmt(ideal, 'm/s^2')})" if ideal is not None else ""
        lines.append(f"  peak slider acceleration   {_fmt(s['peak_slider_acc_m_s2'], 'm/s^2')}{extra}")
    lines += [
        f"  max constraint drift       {_fmt(s['max_constraint_drift'], spec='.3g')}",
        f"  solver steps               {s['num_steps']} ({s['num_accepted_steps']} accepted, "
        f"{s['num_rejected_steps']} rejected)",
        "wrote " + ", ".join(files),
    ]
    print("\n".join(lines))


# --------------------------------------------------------------------------------------
# sweep
# --------------------------------------------------------------------------------------

SWEEP_DESCRIPTION = """\
Run a parameter sweep described by a TOML file (see examples/sweep.toml): a grid or a list
over any numeric parameters, batched with jax.vmap over all local devices, compiled once,
written chunk by chunk to the output folder:
  runs.csv                one row per run: index, parameters, metrics, status, status message
  manifest.json           the sweep's definition and hash (a re-run resumes the same sweep)
  chunks/chunk_NNNNNN.npz Poincare points (and time series with --trajectories)
  heatmap_METRIC.png      2-parameter grids: heat maps of the main metrics
  bifurcation_NAME.png    1-parameter sweeps: bifurcation diagram (Poincare e_x per revolution)
  poincare.png            Poincare sections of every run
Running the same command again after an interruption resumes where it stopped."""

SWEEP_PLOT_METRICS = ("peak_contact_force_n", "energy_dissipated_per_rev_j", "rms_acc_deviation_m_s2", "impacts")


@subcommand("sweep", "run a parameter sweep from a TOML file (CSV, NPZ, PNG)", SWEEP_DESCRIPTION)
def _configure_sweep(p: argparse.ArgumentParser):
    p.add_argument("config", metavar="CONFIG.toml", help="sweep configuration file (TOML)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: the file's output.dir, else ./sweep-out)")
    p.add_argument("--chunk-size", type=int, metavar="N",
                   help="runs per chunk, >= 1, rounded up to a multiple of the devices (default: the file's, else auto)")
    p.add_argument("--devices", type=int, metavar="N", help="number of local devices to use, >= 1 (default: all)")
    p.add_argument("--trajectories", action="store_true", default=None,
                   help="also store the time series in the chunk files (default: the file's, else off)")
    p.add_argument("--restart", action="store_true", help="discard results already in the folder instead of resuming")
    p.add_argument("--no-plots", action="store_true", help="write CSV/NPZ/JSON only, no PNG (default: off)")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    return _run_sweep


def _run_sweep(args) -> int:
    from . import sweep

    cfg = sweep.load_config(args.config, out=args.out, chunk_size=args.chunk_size, devices=args.devices,
                            trajectories=args.trajectories, progress=False if args.no_progress else None)
    mode = "grid" if cfg.grid is not None else "list"
    print(f"jaxclear sweep: {cfg.n_runs} runs ({mode} over {', '.join(cfg.names)}), {cfg.revolutions:g} revolutions "
          f"each, output {cfg.out}", flush=True)
    res = sweep.run_sweep(cfg, restart=args.restart)
    table = res.table
    failed = int(sum(1 for s in table["status"] if s != 0))
    files = [os.path.join(cfg.out, sweep.CSV_NAME), os.path.join(cfg.out, sweep.MANIFEST_NAME)]
    if not args.no_plots and len(table["run"]):
        if mode == "grid" and len(cfg.names) == 2:
            for metric in SWEEP_PLOT_METRICS:
                if metric in table:
                    path = os.path.join(cfg.out, f"heatmap_{metric}.png")
                    sweep.heatmap(res, metric, x=cfg.names[0], y=cfg.names[1], path=path)
                    files.append(path)
        if res.poincare.size:
            if len(cfg.names) == 1:
                path = os.path.join(cfg.out, f"bifurcation_{cfg.names[0].replace(':', '_')}.png")
                sweep.bifurcation(res, cfg.names[0], path=path)
                files.append(path)
            path = os.path.join(cfg.out, "poincare.png")
            sweep.poincare_plot(res, path=path)
            files.append(path)
    print(f"done: {len(table['run'])} of {cfg.n_runs} runs on disk ({res.computed} computed now), {failed} failed")
    print("wrote " + ", ".join(files))
    return 0


# --------------------------------------------------------------------------------------
# fit
# --------------------------------------------------------------------------------------

FIT_DESCRIPTION = """\
Fit contact parameters of a preset to a measured slider acceleration (CSV of spec section 8:
time_s, slider_acc_m_s2, optional crank_angle_rad, slider_pos_m, slider_vel_m_s) and write:
  fit.json              estimates, std (Gauss-Newton), loss, iterations, wall time, diagnostics
  fit.png               measured vs fitted acceleration and the residuals
  fit_checkpoint.json   the fit's state after every iteration: the same command resumes it
The first sample is the preset's start (crank angle 0, journal centred, velocities from the
ideal kinematics). The loss is on short windows from that state (see jaxclear.fit).
Example: jaxclear fit data.csv --free stiffness,restitution --start stiffness=2e11 \\
         --start restitution=0.6 --sensor-cutoff-hz 20000 --out fit-out"""


def _name_value(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name.strip()}: value {value!r} is not a number") from None


@subcommand("fit", "fit contact parameters to a measured record (JSON, PNG)", FIT_DESCRIPTION)
def _configure_fit(p: argparse.ArgumentParser):
    from . import law_names, preset_names

    p.add_argument("data", metavar="DATA.csv", help="measured record (spec section 8)")
    mech = p.add_argument_group("model (known values; free parameters start from them unless --start)")
    mech.add_argument("--preset", default="flores-slider-crank", metavar="NAME",
                      help=f"preset mechanism with a slider, one of {', '.join(preset_names())} "
                      "(default: flores-slider-crank)")
    mech.add_argument("--model", default="lankarani-nikravesh", metavar="LAW",
                      help=f"contact law fitted, one of {', '.join(law_names())} (default: lankarani-nikravesh)")
    mech.add_argument("--clearance", type=float, metavar="M", help="radial clearance [m] (default: the preset's)")
    mech.add_argument("--friction", type=float, metavar="MU", help="friction coefficient [-] (default: the preset's)")
    mech.add_argument("--speed-rpm", type=float, metavar="RPM", help="crank speed [rev/min] (default: the preset's)")
    mech.add_argument("--restitution", type=float, metavar="CR", help="restitution c_r [-] (default: the preset's)")
    mech.add_argument("--stiffness", type=float, metavar="K",
                      help="stiffness [N/m^1.5 for the LN family] (default: from steel and the radii)")
    _add_hybrid_options(p)
    f = p.add_argument_group("fit")
    f.add_argument("--free", default="stiffness,restitution", metavar="NAMES",
                   help="comma-separated free parameters: stiffness [N/m^1.5 for the LN family], restitution, "
                   "friction, clearance [m], mass:BODY, ..., sensor_gain, sensor_bias (default: stiffness,restitution)")
    f.add_argument("--start", type=_name_value, action="append", default=[], metavar="NAME=VALUE",
                   help="start value of a free parameter (SI), repeatable (default: the model's value)")
    f.add_argument("--window", type=float, metavar="S",
                   help="length of a fit window [s], > 0 (default: a quarter crank revolution)")
    f.add_argument("--windows", type=int, default=1, metavar="N",
                   help="back-to-back windows; windows after the first estimate their journal state (default: 1)")
    f.add_argument("--starts", type=int, default=1, metavar="N", help="number of starts, >= 1 (default: 1)")
    f.add_argument("--optimizer", default="levenberg-marquardt", metavar="NAME",
                   help="levenberg-marquardt (optax transformation, default) or adam[:LR]")
    f.add_argument("--max-iter", type=int, default=30, metavar="N",
                   help="iterations of the last stage, >= 1; earlier stages get half (default: 30)")
    f.add_argument("--align", choices=("time", "crank"), default="time",
                   help="first sample = simulation start ('time') or simulation time from crank_angle_rad "
                   "('crank') (default: time)")
    f.add_argument("--rtol", type=float, default=1e-8, metavar="TOL",
                   help="relative tolerance of the model's integration (default: 1e-8)")
    f.add_argument("--atol", type=float, default=1e-11, metavar="TOL",
                   help="absolute tolerance of the model's integration [m, rad, m/s] (default: 1e-11)")
    s = p.add_argument_group("sensor model")
    s.add_argument("--sensor-cutoff-hz", type=float, metavar="HZ",
                   help="accelerometer low-pass cut-off (2nd-order Butterworth) [Hz] (default: none)")
    s.add_argument("--sensor-gain", type=float, default=1.0, metavar="G", help="accelerometer gain [-] (default: 1)")
    s.add_argument("--sensor-bias", type=float, default=0.0, metavar="B",
                   help="accelerometer bias [m/s^2] (default: 0)")
    s.add_argument("--oversample", type=int, default=4, metavar="N",
                   help="model grid points per record sample, >= 1 (default: 4)")
    out = p.add_argument_group("output")
    out.add_argument("--out", default="./jaxclear-fit", metavar="DIR",
                     help="output folder, created if missing (default: ./jaxclear-fit)")
    out.add_argument("--restart", action="store_true", help="ignore a checkpoint in --out instead of resuming")
    out.add_argument("--no-plots", action="store_true", help="write fit.json only (default: off)")
    out.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    return _run_fit


def _run_fit(args) -> int:
    from . import fitting
    from .errors import ParameterError
    from .presets import preset
    from .sensor import Accelerometer

    for name, value in (("--windows", args.windows), ("--starts", args.starts), ("--max-iter", args.max_iter),
                        ("--oversample", args.oversample)):
        if value < 1:
            raise ParameterError(f"{name} = {value} must be >= 1")
    mech = preset(args.preset, **_overrides(args))
    free = [n.strip() for n in args.free.split(",") if n.strip()]
    start = dict(args.start)
    sensor = Accelerometer(args.sensor_cutoff_hz, gain=args.sensor_gain, bias=args.sensor_bias,
                           oversample=args.oversample)
    os.makedirs(args.out, exist_ok=True)
    print(f"jaxclear fit: {args.data}, {mech.name} with {args.model}, free {', '.join(free)}; sensor: "
          f"{sensor.describe()}", flush=True)
    print("compiling the forward-mode model (about 20 to 40 s), then fitting...", flush=True)
    import warnings

    with warnings.catch_warnings():  # the fit's warnings are printed below, once
        warnings.simplefilter("ignore", UserWarning)
        res = fitting.fit(args.data, mech, free, start, sensor=sensor, window=args.window, windows=args.windows,
                          starts=args.starts, optimizer=args.optimizer, max_iter=args.max_iter, rtol=args.rtol,
                          atol=args.atol, align=args.align, out=args.out, resume=not args.restart,
                          progress=not args.no_progress)
    files = [res.write_json(os.path.join(args.out, "fit.json"))]
    if not args.no_plots:
        path = os.path.join(args.out, "fit.png")
        res.plot(path)
        files.append(path)
    width = max(len(n) for n in res.estimates)
    print(f"done in {res.wall_time_s:.1f} s wall, {res.iterations} iterations ({res.stop_reason}); "
          f"loss {res.loss:.4g}, residual lag-1 autocorrelation {res.residual_autocorrelation:.2f}")
    print(f"  {'parameter':<{width}}  {'start':>12}  {'estimate':>12}  {'std':>10}")
    for name, value in res.estimates.items():
        print(f"  {name:<{width}}  {res.start[name]:>12.6g}  {value:>12.6g}  {res.std[name]:>10.3g}")
    for w in res.warnings:
        print(f"warning: {w}")
    print("wrote " + ", ".join(files))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
