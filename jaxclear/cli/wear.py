"""``jaxclear wear``: wear the bearing of a clearance joint over a long service (Archard's law on
the hybrid model's contact pressures), window by window, resumable."""

from __future__ import annotations

import argparse
import textwrap

from .._errors import ParameterError, check_range
from ..integrate import revolutions_of
from ..wearing import WearOptions, wear
from ..wearing.service import MAX_NODES, ONSETS_WHY
from .common import add_mechanism_file_option, add_mechanism_options, number_in
from .settings import given_options
from .simulate import add_integration_options, load, settings_from

HELP = "wear a clearance joint's bearing over a long service (Archard), resumable"
DESCRIPTION = """\
Wear the bearing of a clearance joint with Archard's law (wear depth rate = k_w p v_s) from the
hybrid Gauss-point model's contact pressures: simulate a window (--revolutions or --t-end,
the first --settle seconds discarded), multiply its wear by --cycles-per-update, update the
bearing profile, run the next window on the worn bearing; --updates times. The contact law is
the hybrid model with body-fixed points (--model hybrid --placement fixed, the defaults here).

Written to the output folder after every update (a killed run resumes where it stopped):
  profile_NNNN.csv   node angle in the bearing [rad], cumulative wear depth [m]
  updates.csv        service time, worn volume, largest and mean depth, peak force per update
  wear.json          the state the run resumes from
  profile.png        the worn bearing (polar) and the depth after the updates"""


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear wear``; returns its ``run(args) -> exit code``."""
    add_mechanism_file_option(p)
    add_mechanism_options(p, ideal=False)
    # the command's own defaults, which a mechanism file (whose law is its own) must not read as given options
    defaults = {"model": "hybrid", "placement": "fixed"}
    p.set_defaults(**defaults, ideal=False, mechanism_defaults=defaults)
    add_integration_options(p)
    w = p.add_argument_group("wear")
    w.add_argument("--wear-coefficient", type=number_in(float, 0.0, low_open=True), default=1e-15, metavar="K_W",
                   help="Archard's dimensional wear coefficient [m^2/N], > 0 (default: 1e-15)")
    w.add_argument("--updates", type=number_in(int, 1), default=10, metavar="N",
                   help="number of profile updates (windows) [-], >= 1 (default: 10)")
    w.add_argument("--cycles-per-update", type=number_in(float, 1.0), default=1.0, metavar="F",
                   help="extrapolation factor: each window's wear is multiplied by it [-], >= 1 (default: 1)")
    w.add_argument("--settle", type=number_in(float, 0.0), default=0.0, metavar="S",
                   help="start of each window discarded [s], >= 0 and below the window (default: 0)")
    w.add_argument("--joint", default=None, metavar="NAME",
                   help="the clearance joint to wear, by name or index (default: the only one)")
    w.add_argument("--nodes", type=number_in(int, 8, MAX_NODES), default=180, metavar="N",
                   help=f"bearing nodes [-], in [8, {MAX_NODES}] (default: 180)")
    w.add_argument("--harmonics", type=number_in(int, 1), default=24, metavar="M",
                   help="Fourier terms of the worn profile [-], >= 1 and below --nodes / 2 (default: 24)")
    o = p.add_argument_group("output")
    o.add_argument("--out", default="./jaxclear-wear", metavar="DIR",
                   help="output folder, created if missing, locked while running (default: ./jaxclear-wear)")
    o.add_argument("--restart", action="store_true", help="discard a previous run in --out and start over")
    o.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    return run


def run(args) -> int:
    """Run the wear windows and print a summary."""
    if args.model != "hybrid":
        raise ParameterError(f"jaxclear wear needs --model hybrid (got --model {args.model}): Archard's law needs "
                             "the contact pressure point by point")
    if given_options(args).get("onsets") == "exact":
        raise ParameterError(f"--onsets exact: jaxclear wear runs with step onsets (--onsets step, the only allowed "
                             f"value here, and what it uses when --onsets is not given): {ONSETS_WHY}")
    if not args.harmonics < args.nodes / 2:
        raise ParameterError(f"--harmonics {args.harmonics} is outside the allowed range [1, --nodes / 2 = "
                             f"{args.nodes / 2:g})")
    mech, _, _ = load(args)
    s = settings_from(args, mech)
    check_range("--settle", args.settle, low=0.0, high=float(s.t_end) - s.t_start, high_open=True, unit="s")
    joint = args.joint
    if joint is not None and joint.isdigit():
        joint = int(joint)
    options = WearOptions(coefficient=args.wear_coefficient, updates=args.updates,
                          cycles_per_update=args.cycles_per_update, settle=args.settle, joint=joint,
                          n_nodes=args.nodes, harmonics=args.harmonics)
    revs = revolutions_of(mech, float(s.t_end))
    print(f"jaxclear wear: {mech.name}, {args.updates} update(s) of {float(s.t_end):.6g} s"
          + (f" ({revs:g} revolution(s))" if revs is not None else "")
          + f" x {args.cycles_per_update:g} cycles; k_w = {args.wear_coefficient:g} m^2/N; the first update compiles",
          flush=True)
    h = wear(mech, s, options, args.out, restart=args.restart, progress=not args.no_progress)
    print(textwrap.indent(h.summary(), "  "))
    # the files were written by wear as it went (resumable); a finished history writes the same through h.write
    print(f"  written to {args.out} (profile_NNNN.csv, updates.csv, wear.json, profile.png)")
    return 0
