"""``jaxclear chaos``: how chaotic a mechanism's motion is: its Lyapunov spectrum from the tangent
dynamics, and on named channels the Poincare section's period, the 0-1 test and the spectrum."""

from __future__ import annotations

import argparse
import math
import os

from .._errors import ParameterError
from ..chaos.lyapunov import MIN_INTERVALS, check_count, check_length, interval_count
from ..chaos.report import ZERO_ONE_PER_REVOLUTION, characterise
from ..chaos.signals import ZERO_ONE_MIN_SAMPLES
from ..model import crank_driver
from .common import add_mechanism_file_option, add_mechanism_options, number_in
from .simulate import add_integration_options, load, settings_from

#: The defaults of ``jaxclear chaos``: crank revolutions in all, of them without tangents first,
#: and renormalisation intervals that do not count. 60 - 4 = 56 revolutions after the transient
#: give the 0-1 test 112 samples (it needs ZERO_ONE_MIN_SAMPLES = 100 at 2 a revolution).
REVOLUTIONS, TRANSIENT, DISCARD = 60, 4, 4

HELP = "Lyapunov exponents, Poincare section, 0-1 test and spectrum of a mechanism's motion"
DESCRIPTION = f"""\
Characterise the motion of a mechanism (a file or a preset) at one operating point: its Lyapunov
exponents by Benettin's method on the tangent dynamics (over the tangent space of the constraint
manifold, reported --per-revolution times a crank revolution and renormalised at least as often,
more often where the tangents' growth asks for it), and, for each --channel, the
Poincare section once per revolution and its period (period-n), the 0-1 test for chaos
(Gottwald and Melbourne) and the Welch power spectral density. The first --transient
revolutions are integrated without tangents, the next --discard intervals do not count.
The defaults (--revolutions {REVOLUTIONS}, --transient {TRANSIENT}, --discard {DISCARD}) leave the 0-1 test
the {ZERO_ONE_MIN_SAMPLES} samples it needs ({ZERO_ONE_PER_REVOLUTION} a revolution after the transient); the
first run also compiles the tangent program.

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
    add_integration_options(p, revolutions=REVOLUTIONS)
    c = p.add_argument_group("chaos")
    c.add_argument("--per-revolution", type=number_in(int, 1), default=1, metavar="N",
                   help="reporting intervals per crank revolution, each renormalised at its end and within it as "
                        "often as the tangents' growth asks [-], >= 1 (default: 1)")
    c.add_argument("--transient", type=number_in(int, 0), default=TRANSIENT, metavar="N",
                   help="crank revolutions integrated without tangents first, part of --revolutions [-], >= 0 "
                   f"(default: {TRANSIENT})")
    c.add_argument("--discard", type=number_in(int, 0), default=DISCARD, metavar="N",
                   help=f"renormalisation intervals that do not count [-], >= 0 (default: {DISCARD})")
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


def check_run(args, mech, s) -> int:
    """The options that depend on the mechanism and on each other, checked under their flags
    before anything compiles: ``--count`` against the phase space, ``--transient`` against the
    run, at least :data:`~jaxclear.chaos.lyapunov.MIN_INTERVALS` counted intervals. Returns the
    revolutions after the transient whose 0-1 test is too short to run (0 when it runs)."""
    check_count(mech, args.count, "--count")
    found = crank_driver(mech)
    if found is None or float(found[1].speed) == 0.0:
        raise ParameterError(f"jaxclear chaos runs whole crank revolutions: mechanism {mech.name!r} has no turning "
                             "crank (AngleDriver with a non-zero speed)")
    span = "--t-end" if args.t_end is not None else "--revolutions"
    revolutions = float(s.t_end) * abs(float(found[1].speed)) / (2 * math.pi)
    if not args.transient < revolutions:
        raise ParameterError(f"--transient = {args.transient} revolution(s) is outside the allowed range [0, "
                             f"{revolutions:g}) (the run, {span}); raise {span} or lower --transient")
    after = revolutions - args.transient
    windows = interval_count(after, 1.0 / args.per_revolution)
    fewest = args.transient + math.ceil((MIN_INTERVALS + args.discard) / args.per_revolution)
    given = (f"--t-end {args.t_end:g} s = {revolutions:g} revolutions" if args.t_end is not None
             else f"--revolutions {revolutions:g}")
    least = (f"{fewest * float(s.t_end) / revolutions:.6g} s ({fewest} revolutions)" if args.t_end is not None
             else f"{fewest}")
    check_length(windows, args.discard, f"({given} - --transient {args.transient}) x --per-revolution "
                 f"{args.per_revolution} = {windows} interval(s), less --discard {args.discard},",
                 f"raise {span} to {least} or more, or --per-revolution")
    return args.transient + math.ceil(ZERO_ONE_MIN_SAMPLES / ZERO_ONE_PER_REVOLUTION) if (
        after * ZERO_ONE_PER_REVOLUTION < ZERO_ONE_MIN_SAMPLES) else 0


def run(args) -> int:
    """Run the operating point and print its spectrum and channels."""
    mech, _, _ = load(args)
    s = settings_from(args, mech)
    zero_one_needs = check_run(args, mech, s)
    channels = args.channel or _default_channels(mech)
    print(f"jaxclear chaos: {mech.name}, {float(s.t_end):.6g} s; compiling the tangent run (a minute or more)",
          flush=True)
    report = characterise(mech, s, channels, per_revolution=args.per_revolution,
                          transient_revolutions=args.transient, discard=args.discard, count=args.count,
                          samples=args.samples, tol=args.tol)
    files = report.write(args.out)
    print(report.summary())
    if any(c.k != c.k for c in report.channels):
        print(f"  (the 0-1 test needs --revolutions {zero_one_needs} or more)")
    print(f"  written to {args.out} ({', '.join(os.path.basename(f) for f in files)})")
    return 0
