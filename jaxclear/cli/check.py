"""``jaxclear check``: assemble a mechanism file, report its structure, draw it."""

from __future__ import annotations

import argparse
import os

from .. import io
from .._errors import ParameterError
from ..analysis.structure import check_mechanism
from ..plot.drawing import plot_mechanism
from ..plot.profiles import plot_profiles
from .common import add_mechanism_file_option, mechanism_file, number_in
from ..mechanisms.files import load_mechanism
from ..mechanisms.presets import preset, preset_names
from .simulate import add_free_dof_option

HELP = "assemble a mechanism file, report its degrees of freedom, draw it (PNG)"
DESCRIPTION = """\
Assemble a mechanism (a file, or --preset NAME) at t = 0 and report: bodies, joints, drivers,
clearance joints, degrees of freedom (dof: what the dynamics integrates, 2 per revolute clearance
joint included; mobility: of the ideal-joint mechanism without drivers; driven mobility: with
drivers, 0 when kinematically driven). Writes to the output folder:
  mechanism.png   the assembled configuration: bodies as lines between their points, joints,
                  clearance joints magnified (the factor is printed on the figure)
  check.json      the same report
  profiles.png    the time profiles, if any: each speed-profile driver's angle, speed and
                  acceleration, each load's time factor (the profiles are checked when the
                  file is read: a bad value names its key and the allowed range)"""


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear check``; returns its ``run(args) -> exit code``."""
    add_mechanism_file_option(p)
    p.add_argument("--preset", metavar="NAME", help=f"a preset instead of a file, one of {', '.join(preset_names())}")
    p.add_argument("--out", default="./jaxclear-out", metavar="DIR",
                   help="output folder, created if missing (default: ./jaxclear-out)")
    p.add_argument("--magnify", type=number_in(float, 0.0, low_open=True), metavar="X",
                   help="drawing factor of the clearances [-], > 0 (default: the largest clearance drawn as "
                   "30 %% of the bearing circle)")
    add_free_dof_option(p)
    return run


def run(args) -> int:
    path = mechanism_file(args)
    if path is None and args.preset is None:
        raise ParameterError("give a mechanism file (jaxclear check FILE.toml) or --preset NAME")
    mech = load_mechanism(path) if path is not None else preset(args.preset)
    report = check_mechanism(mech, allow_free_dof=args.allow_free_dof)
    os.makedirs(args.out, exist_ok=True)
    png = os.path.join(args.out, "mechanism.png")
    plot_mechanism(png, mech, report["q"], magnify=args.magnify)
    js = io.write_json(os.path.join(args.out, "check.json"), report)
    profiles = os.path.join(args.out, "profiles.png")
    wrote = [png, js] + ([profiles] if plot_profiles(profiles, mech) is not None else [])
    lines = [
        f"{mech.name}: {len(report['bodies'])} bodies, {report['coordinates']} coordinates, "
        f"{report['constraint_equations']} constraint equations (joints and drivers)",
        f"  degrees of freedom         {report['dof']} (integrated: ideal joints and drivers removed "
        f"{report['coordinates'] - report['dof']}; clearance joints free)",
        f"  mobility (ideal joints)    {report['mobility']} without drivers, {report['driven_mobility']} with drivers"
        + (" (kinematically driven)" if report["driven_mobility"] == 0 else ""),
        f"  assembly residual |Phi|    {report['assembly_residual']:.3g}",
        "  bodies: " + ", ".join(f"{b['name']} ({b['mass_kg']:g} kg, points {', '.join(b['points']) or '-'})"
                                 for b in report["bodies"]),
        "  joints: " + (", ".join(report["joints"]) or "none"),
        "  drivers: " + (", ".join(report["drivers"]) or "none"),
        "  clearance joints: " + ("none" if not report["clearance_joints"] else ""),
        *[f"    {text}" for text in report["clearance_joints"]],
        "  loads: " + (", ".join(report["loads"]) or "none") + f"; gravity {report['gravity_m_s2']} m/s^2",
        f"wrote {', '.join(wrote)}",
    ]
    print("\n".join(lines))
    return 0
