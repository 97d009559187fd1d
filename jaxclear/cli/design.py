"""``jaxclear design``: minimise an objective of simulations over named design variables within
bounds and under constraints, with gradients through the simulations, resumable."""

from __future__ import annotations

import argparse

from .._errors import ParameterError
from ..designing import METHODS, OBJECTIVES, Ensemble, OperatingPoint, SteadyOperation, design
from ..designing.problem import SAMPLES_PER_REVOLUTION
from .common import add_mechanism_file_option, add_mechanism_options, name_value, number_in
from .settings import add_settings_options, settings_from_args
from .simulate import load

HELP = "optimal design through impacts: minimise an objective over named variables, resumable"
DESCRIPTION = f"""\
Minimise an objective of simulations of a mechanism (a mechanism file or --preset) over named
design variables (--vary NAME=LOW:HIGH, names of jaxclear.params: masses mass:BODY, centroid
shifts centroid_x:BODY, point coordinates point_x:BODY.POINT, clearance, restitution, friction,
stiffness, speed_rpm...) within their ranges and under constraints (--constraint), with
gradients through the simulations (error-controlled forward sensitivities) and SciPy's L-BFGS-B
(bounds) or SLSQP (constraints). Objectives: {', '.join(OBJECTIVES)} (docs/theory/design.md).

Every evaluation is written to the output folder as it is made (a killed design resumes where
it stopped, with the same result):
  design_evaluations.jsonl  the journal the design resumes from
  design.json               status, design, objective, constraints, gradient, sensitivity
  design_history.csv        one row per iteration
  design.toml               the optimum as a mechanism file
  design.png                start design against the optimum, convergence

Exit code 0: a design that meets the constraints (converged, or stopped on --max-iter: see
its status); 3: no design found that meets them (the least violation is printed); 2: bad input.

Example: jaxclear design --preset flores-slider-crank --vary clearance=0.1e-3:0.6e-3
         --objective peak-force --revolutions 0.5 --out design-out"""


def variable_range(text: str) -> tuple[str, tuple[float, float]]:
    """argparse type: ``NAME=LOW:HIGH`` -> ``(name, (low, high))`` (a name may hold ``:``)."""
    name, sep, rest = text.partition("=")
    low, sep2, high = rest.partition(":")
    if not sep or not sep2 or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=LOW:HIGH, got {text!r}")
    try:
        return name.strip(), (float(low), float(high))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name.strip()}: range {rest!r} is not two numbers LOW:HIGH") from None


def operating_point(text: str) -> OperatingPoint:
    """argparse type: ``NAME=VALUE,...[,weight=W]`` -> :class:`OperatingPoint`."""
    values, weight = {}, 1.0
    for item in (part for part in text.split(",") if part.strip()):
        name, value = name_value(item)
        if name == "weight":
            weight = value
        else:
            values[name] = value
    return OperatingPoint(values, weight)


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear design``; returns its ``run(args) -> exit code``."""
    add_mechanism_file_option(p)
    add_mechanism_options(p, ideal=False)
    p.set_defaults(ideal=False)
    d = p.add_argument_group("design")
    d.add_argument("--vary", type=variable_range, action="append", required=True, metavar="NAME=LOW:HIGH",
                   help="a design variable and its range (SI; speed_rpm in rpm), repeatable, at least one")
    d.add_argument("--start", type=name_value, action="append", default=[], metavar="NAME=VALUE",
                   help="start value of a variable (default: the mechanism's; 0 for centroid shifts)")
    d.add_argument("--objective", default="rms-deviation", metavar="SPEC",
                   help=f"objective, one of {', '.join(OBJECTIVES)}, with options NAME:OPT=V,... (e.g. "
                   "rms-deviation:skip=0.5, peak-force:p=16) (default: rms-deviation)")
    d.add_argument("--constraint", action="append", default=[], metavar="SPEC",
                   help="constraint, repeatable: total-mass, total-mass<=KG, assembles, assembles:margin=F, "
                   "peak-force<=N, penetration<=M (default: none)")
    d.add_argument("--point", type=operating_point, action="append", default=None, metavar="NAME=V,...,weight=W",
                   help="an operating point (parameter values, a weight), repeatable; the objective is their "
                   "weighted mean (default: the mechanism as given)")
    d.add_argument("--ensemble", type=number_in(int, 1), default=1, metavar="N",
                   help="runs per operating point, averaged: periodic starts spread over a revolution (or "
                   "journal offsets, --ensemble-kind offsets) [-], >= 1 (default: 1)")
    d.add_argument("--ensemble-kind", choices=("angles", "offsets"), default="angles",
                   help="what the ensemble's members differ in (default: angles)")
    d.add_argument("--method", choices=METHODS, default="auto",
                   help="optimiser; auto: L-BFGS-B without constraints, SLSQP with them; differential-evolution: "
                        "no gradients, --max-iter generations of 5 members per variable (default: auto)")
    d.add_argument("--max-iter", type=number_in(int, 1), default=30, metavar="N",
                   help="iteration limit [-], >= 1 (default: 30)")
    d.add_argument("--ftol", type=number_in(float, 0.0, low_open=True), default=1e-6, metavar="TOL",
                   help="relative decrease of the objective that stops [-], > 0 (default: 1e-6)")
    d.add_argument("--gtol", type=number_in(float, 0.0, low_open=True), default=1e-5, metavar="TOL",
                   help="projected gradient norm that stops (unit ranges, relative objective) [-], > 0 "
                   "(default: 1e-5)")
    r = p.add_argument_group("runs")
    r.add_argument("--revolutions", type=number_in(float, 0.0, low_open=True), default=1.0, metavar="N",
                   help="each run's length in crank revolutions [-], > 0 (default: 1)")
    r.add_argument("--samples-per-revolution", type=number_in(int, 8), default=SAMPLES_PER_REVOLUTION, metavar="N",
                   help=f"output samples per revolution [-], >= 8 (default: {SAMPLES_PER_REVOLUTION})")
    r.add_argument("--steady", type=number_in(int, 0), default=0, metavar="N",
                   help="design on steady operation: the objective averaged over N crank revolutions after "
                   "--transient, gradients by least-squares shadowing (rms-deviation only; no --point, "
                   "--ensemble) [-], >= 0, 0 is off (default: 0)")
    r.add_argument("--transient", type=number_in(int, 0), default=20, metavar="N",
                   help="with --steady: revolutions left out first [-], >= 0 (default: 20)")
    r.add_argument("--n-unstable", type=number_in(int, 1), default=1, metavar="N",
                   help="with --steady: the shadowing's homogeneous tangents, at least the positive Lyapunov "
                   "exponents [-], >= 1 (default: 1)")
    add_settings_options(r)
    o = p.add_argument_group("output")
    o.add_argument("--out", default="./jaxclear-design", metavar="DIR",
                   help="output folder, created if missing, locked while running (default: ./jaxclear-design)")
    o.add_argument("--restart", action="store_true", help="discard a previous design's journal in --out")
    o.add_argument("--no-chaos-check", action="store_true",
                   help="skip the chaos checks at the start: the derivative horizon (one sensitivity solve) and "
                   "the objective's roughness (6 runs per variable at +-1e-10..1e-6 of its range)")
    o.add_argument("--no-sensitivity", action="store_true",
                   help="skip the +-1 %% runs around the optimum (the sensitivity table)")
    o.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    return run


def run(args) -> int:
    """Run the design and print its summary; exit code 0 only for a converged, feasible design."""
    mech, _, _ = load(args)
    variables = {}
    for name, bounds in args.vary:
        if name in variables:
            raise ParameterError(f"--vary {name}: given twice")
        variables[name] = bounds
    settings = settings_from_args(args)  # the integration options given, over Settings' defaults
    print(f"jaxclear design: {mech.name}, {len(variables)} variable(s), objective {args.objective}; the first "
          "evaluations compile", flush=True)
    steady = SteadyOperation(revolutions=args.steady, transient_revolutions=args.transient,
                             n_unstable=args.n_unstable) if args.steady else None
    if steady is not None and args.ensemble > 1:
        raise ParameterError("--ensemble: does not apply with --steady (the steady average holds every start)")
    res = design(mech, variables, args.objective, args.constraint, start=dict(args.start), settings=settings,
                 points=args.point, ensemble=None if steady else Ensemble(args.ensemble, args.ensemble_kind),
                 steady=steady,
                 revolutions=args.revolutions, samples_per_revolution=args.samples_per_revolution,
                 method=args.method, max_iter=args.max_iter, ftol=args.ftol, gtol=args.gtol, out=args.out,
                 resume=not args.restart, progress=not args.no_progress, check_chaos=not args.no_chaos_check,
                 report_sensitivity=not args.no_sensitivity)
    print(res.summary())
    print(f"  written to {args.out} (design.json, design_history.csv, design.toml, design.png, "
          "design_evaluations.jsonl)")
    if res.status == "infeasible":
        print("error: no design meets the constraints (the least violation is above)", flush=True)
        return 3
    return 0
