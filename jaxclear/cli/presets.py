"""``jaxclear presets``: list the preset mechanisms with their default parameters."""

from __future__ import annotations

import argparse
import inspect

from ..presets import PRESETS

HELP = "list the preset mechanisms"
DESCRIPTION = "List the preset mechanisms that --preset accepts."


def _first_line(doc: str | None, width: int = 100) -> str:
    """The docstring's first paragraph on one line, shortened to ``width`` characters."""
    paragraph = " ".join((doc or "").strip().split("\n\n")[0].split())
    if len(paragraph) <= width:
        return paragraph
    return paragraph[: width - 3].rsplit(" ", 1)[0] + "..."


def _preset_defaults(fn) -> str:
    """``clearance 0.5 mm, c_r 0.9, mu 0, 5000 rpm`` from a preset function's defaults."""
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


def configure(p: argparse.ArgumentParser):
    """No options; returns the command's ``run(args) -> exit code``."""
    return run


def run(args) -> int:
    """Print every preset's name, docstring summary and default parameters."""
    width = max(len(n) for n in PRESETS)
    for name in sorted(PRESETS):
        print(f"{name:<{width}}  {_first_line(PRESETS[name].__doc__)}")
        defaults = _preset_defaults(PRESETS[name])
        if defaults:
            print(f"{'':<{width}}  defaults: {defaults}")
    return 0
