"""``jaxclear chaos``: how chaotic a mechanism's motion is: its Lyapunov spectrum from the tangent
dynamics, and on named channels the Poincare section's period, the 0-1 test and the spectrum."""

from __future__ import annotations

import argparse

from ..analysis.sections import period_name
from ..chaos.report import characterise, write_report
from .common import add_mechanism_file_option, add_mechanism_options, fmt, number_in
from .simulate import add_integration_options, load, settings_from

HELP = "Lyapunov exponents, Poincare section, 0-1 test and spectrum of a mechanism's motion"
DESCRIPTION = """\
Characterise the motion of a mechanism (a file or a preset) at one operating point: its Lyapunov
exponents by Benettin's method on the tangent dynamics (over the tangent space of the constraint
manifold, renormalised --per-revolution times a crank revolution), and, for each --channel, the
Poincare section once per revolution and its period (period-n), the 0-1 test for chaos
(Gottwald and Melbourne) and the Welch power spectral density. The first --transient
revolutions are integrated without tangents, the next --discard intervals do not count.

Written to the output folder:
  exponents.csv   the exponents [1/s], standard error, spread, e-folding time 1/lambda [s]
  running.csv     the running estimates after every counted interval
  channels.csv    per channel: the section's period, the 0-1 statistic K, the PSD's peak
  summary.json    all of it
  running.png, spectrum.png, poincare.png"""


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear chaos``; returns its ``run(args) -> exit code``."""
    add_mechanism_file_option(p)
    add_mechanism_options(p, ideal=False)
    p.set_defaults(ideal=False)
    add_integration_options(p)
    c = p.add_argument_group("chaos")
    c.add_argument("--per-revolution", type=number_in(int, 1), default=1, metavar="N",
                   help="renormalisations (QR) per crank revolution [-], >= 1 (default: 1)")
    c.add_argument("--transient", type=number_in(int, 0), default=0, metavar="N",
                   help="crank revolutions integrated without tangents first [-], >= 0 (default: 0)")
    c.add_argument("--discard", type=number_in(int, 0), default=0, metavar="N",
                   help="renormalisation intervals that do not count [-], >= 0 (default: 0)")
    c.add_argument("--count", type=number_in(int, 1), default=None, metavar="N",
                   help="how many exponents, the largest first [-], >= 1 (default: all, 2(n - m))")
    c.add_argument("--samples", type=number_in(int, 4), default=32, metavar="N",
                   help="output samples per renormalisation interval [-], >= 4 (default: 32)")
    c.add_argument("--tol", type=number_in(float, 0.0, low_open=True), default=None, metavar="TOL",
                   help="convergence asked for [1/s]: the running estimate's spread over the last half of the run "
                   "(default: none)")
    c.add_argument("--channel", action="append", default=None, metavar="NAME",
                   help="a named channel for the section, 0-1 test and spectrum, repeatable (default: "
                   "body:SLIDER:x:vel and joint:0:ecc_x where they exist)")
    o = p.add_argument_group("output")
    o.add_argument("--out", default="./jaxclear-chaos", metavar="DIR",
                   help="output folder, created if missing (default: ./jaxclear-chaos)")
    return run


def _default_channels(mech) -> list[str]:
    out = []
    slider = mech.role("slider")
    if slider:
        out.append(f"body:{slider}:x:vel")
    if mech.clearance_joints:
        out.append("joint:0:ecc_x")
    return out or [f"body:{mech.body_names[-1]}:x:pos"]


def run(args) -> int:
    """Run the operating point and print its spectrum and channels."""
    mech, _, _ = load(args)
    s = settings_from(args, mech)
    channels = args.channel or _default_channels(mech)
    print(f"jaxclear chaos: {mech.name}, {float(s.t_end):.6g} s; compiling the tangent run (a minute or more)",
          flush=True)
    result, reports = characterise(mech, s, channels, per_revolution=args.per_revolution,
                                   transient_revolutions=args.transient, discard=args.discard, count=args.count,
                                   samples=args.samples, tol=args.tol)
    summary = write_report(args.out, mech, result, reports)
    for i, (v, se) in enumerate(zip(summary["exponents"], summary["stderr"])):
        print(f"  lambda_{i + 1:<2d} {fmt(v, '1/s'):>16} +- {se:.2g}")
    print(f"  sum       {fmt(summary['sum'], '1/s'):>16} (phase-space contraction)")
    if summary["e_folding_time"] is not None:
        print(f"  e-folding time 1/lambda_1 = {fmt(summary['e_folding_time'], 's')}: a derivative through the run "
              "loses its meaning after a few of these")
    for c in reports:
        print(f"  {c.name}: Poincare section {c.period and f'period-{c.period}' or 'not periodic'}, "
              + (f"0-1 test K = {c.k:.2f} (on {c.k_on})" if c.k == c.k else
                 "0-1 test not run (fewer than 100 samples: run longer)")
              + f", PSD peak {c.peak_frequency:.4g} Hz")
    print(f"  written to {args.out} (exponents.csv, running.csv, channels.csv, summary.json, running.png, "
          "spectrum.png, poincare.png)")
    return 0
