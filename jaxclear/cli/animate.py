"""``jaxclear animate``: simulate a mechanism file or preset and write a GIF or MP4 of it moving."""

from __future__ import annotations

import argparse
import os

from ..plot.drawing import animate
from ..integrate import timed_simulate
from .common import add_mechanism_file_option, add_mechanism_options, number_in
from .simulate import add_integration_options, load, settings_from

HELP = "animate a mechanism file or preset (GIF, or MP4 with ffmpeg)"
DESCRIPTION = """\
Simulate a mechanism (a file, jaxclear animate FILE.toml, or --preset NAME) and write an
animation: the bodies moving, the clearance joints magnified (the factor is in the title), and
the journal-centre orbit of a clearance joint at true scale in an inset. GIF needs nothing
beyond matplotlib (Pillow); MP4 needs ffmpeg (pip install imageio-ffmpeg, or a system ffmpeg)."""


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear animate``; returns its ``run(args) -> exit code``."""
    add_mechanism_file_option(p)
    add_mechanism_options(p)
    add_integration_options(p)
    a = p.add_argument_group("animation")
    a.add_argument("--to", default="./jaxclear-out/animation.gif", metavar="FILE",
                   help="animation file, .gif or .mp4 (default: ./jaxclear-out/animation.gif)")
    a.add_argument("--frames", type=number_in(int, 1), default=120, metavar="N",
                   help="frames, spread uniformly over the output samples [-], >= 1 (default: 120)")
    a.add_argument("--fps", type=number_in(int, 1), default=25, metavar="N", help="frames per second, >= 1 (default: 25)")
    a.add_argument("--magnify", type=number_in(float, 0.0, low_open=True), metavar="X",
                   help="drawing factor of the clearances [-], > 0 (default: 30 %% of the drawn bearing)")
    a.add_argument("--joint", type=number_in(int, 0), default=0, metavar="K",
                   help="clearance joint whose orbit the inset shows, >= 0 (default: 0)")
    a.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    return run


def run(args) -> int:
    mech, _, _ = load(args)
    s = settings_from(args, mech)
    print(f"jaxclear: {mech.name}: simulating {float(s.t_end):.6g} s ({int(s.n_out)} samples)...", flush=True)
    sol, wall = timed_simulate(mech, s)
    folder = os.path.dirname(os.path.abspath(args.to))
    os.makedirs(folder, exist_ok=True)
    path = animate(mech, sol, args.to, fps=args.fps, frames=args.frames, magnify=args.magnify, joint=args.joint)
    print(f"simulated in {wall:.2f} s wall (incl. compilation); wrote {path}")
    return 0
