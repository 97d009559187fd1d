"""``jaxclear presets``: list the preset mechanisms with their default parameters."""

from __future__ import annotations

import argparse
import inspect
import textwrap

from ..mechanisms.presets import PRESETS
from .common import plain_text

HELP = "list the preset mechanisms"
DESCRIPTION = "List the preset mechanisms that --preset accepts."


def _summary(doc: str | None) -> str:
    """The docstring's first paragraph as plain text (:func:`~jaxclear.cli.common.plain_text`;
    a preset function it names is called by its preset name)."""
    names = {fn.__name__: f"'{name}'" for name, fn in PRESETS.items()}
    return plain_text((doc or "").strip().split("\n\n")[0], names)


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
    """Print every preset's name, docstring summary (wrapped to 100 columns) and default parameters."""
    width = max(len(n) for n in PRESETS)
    indent = " " * (width + 2)
    for name in sorted(PRESETS):
        print(textwrap.fill(_summary(PRESETS[name].__doc__), 100, initial_indent=f"{name:<{width}}  ",
                            subsequent_indent=indent, break_on_hyphens=False))
        defaults = _preset_defaults(PRESETS[name])
        if defaults:
            print(f"{indent}defaults: {defaults}")
    return 0
