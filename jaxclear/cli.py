"""The ``jaxclear`` command line.

    jaxclear simulate [options]     simulate a preset, write CSV, JSON and PNG plots
    jaxclear presets                list the preset mechanisms

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


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
