"""What the commands share: the help formatter, argument types, the mechanism option group
(preset, physical parameters, contact law and its hybrid-model options) and the conversion of
those options to :func:`jaxclear.presets.preset` keyword arguments."""

from __future__ import annotations

import argparse
import math
import re

from ..contact.hybrid import MAX_GAUSS_PER_ELEMENT, MAX_GAUSS_POINTS
from ..contact.registry import law_names
from .._errors import ParameterError
from .. import params
from ..mechanisms.files import load_mechanism
from ..model import Mechanism
from ..mechanisms.presets import preset, preset_names


#: What reads as a number after a flag, not as a flag: ``-5``, ``-.5``, ``-0.5e-3``, ``-1E+9``,
#: ``-inf``, ``-nan``. argparse's own pattern (``^-\d+$|^-\d*\.\d+$``, Python 3.11) misses the
#: exponent, so ``--clearance -0.5e-3`` was "expected one argument" instead of a range error.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


class Parser(argparse.ArgumentParser):
    """The parser of every command: a usage error is one line, ``error: argument --flag: ...``
    and where to find the options (exit code 2), like the library's errors. A negative number
    in any notation (:data:`NEGATIVE_NUMBER`) is a value, so that its flag's range check names
    it (argparse's pattern is a private attribute, set on every parser and sub-parser: the
    sub-parsers are made by this class too)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message):
        self.exit(2, f"error: {message} (options: {self.prog} --help)\n")


#: What an option whose argparse default is None means, by its ``dest``: the help's
#: ``%(default)s`` of these options shows it (see :class:`Formatter`).
UNSET_MEANS = {"placement": "arc", "damping": "joint", "geometry": "exact"}


class Formatter(argparse.RawDescriptionHelpFormatter):
    """Help layout of every command: descriptions kept as written, 100 columns. A help text's
    ``%(default)s`` is the option's argparse default, so a command that changes a shared
    option's default (``parser.set_defaults(model="hybrid")``) has a help that says so; a None
    default shows what it means (:data:`UNSET_MEANS`)."""

    def __init__(self, prog):
        super().__init__(prog, max_help_position=30, width=100)

    def _expand_help(self, action):
        if action.default is None and action.dest in UNSET_MEANS:
            action = argparse.Action(action.option_strings, action.dest, default=UNSET_MEANS[action.dest],
                                     help=action.help, choices=action.choices, metavar=action.metavar)
        return super()._expand_help(action)


def number_in(kind=float, low=None, high=None, low_open=False, high_open=False):
    """argparse type: a finite number (``kind`` float or int) in the interval the help states
    (``None`` bounds are open ends); else a usage error that argparse prefixes with the flag
    (``argument --rtol: ...``), exit code 2, before anything is built or compiled."""
    lo = "-inf" if low is None else f"{low:g}"
    hi = "inf" if high is None else f"{high:g}"
    interval = f"{'(' if (low is None or low_open) else '['}{lo}, {hi}{')' if (high is None or high_open) else ']'}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"expected {what} in the allowed range {interval}, got {text!r}") from None
        bad = not math.isfinite(value)
        bad |= low is not None and (value <= low if low_open else value < low)
        bad |= high is not None and (value >= high if high_open else value > high)
        if bad:
            raise argparse.ArgumentTypeError(f"{text} is outside the allowed range {interval}")
        return value

    return parse


def name_value(text: str) -> tuple[str, float]:
    """argparse type: ``NAME=VALUE`` with a numeric value -> ``(name, value)``."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name.strip()}: value {value!r} is not a number") from None


#: A reST role with its target: ``:func:`~jaxclear.presets.flores_slider_crank```.
_ROLE = re.compile(r":(?:py:)?[a-z]+:`~?([^`<]*?)(?:\s*<([^>]*)>)?`")


def plain_text(rst: str, names: dict | None = None) -> str:
    """A docstring's reST as plain text for a terminal: a role (``:func:`~a.b.f```,
    ``:class:`X```, ``:math:`x```) becomes its target's last part (``f``; ``names`` maps a
    target to another word, e.g. a preset function to its preset name), ````code```` and
    ``*emphasis*`` lose their marks, and white space runs become one space."""

    def role(m):
        target = (m.group(2) or m.group(1)).strip()
        short = target if m.group(0).startswith(":math:") else target.rsplit(".", 1)[-1]
        return (names or {}).get(short, short)

    text = _ROLE.sub(role, rst)
    text = re.sub(r"``(.+?)``", r"\1", text)
    text = re.sub(r"(?<![\w*])\*{1,2}([^*\s][^*]*?)\*{1,2}(?![\w*])", r"\1", text)
    return " ".join(text.split())


def fmt(value, unit: str = "", spec: str = ".4g") -> str:
    """``value`` with its unit for printing, ``n/a`` for None."""
    return "n/a" if value is None else f"{value:{spec}}{(' ' + unit) if unit else ''}"


def add_mechanism_options(p: argparse.ArgumentParser, title: str = "mechanism", ideal: bool = True,
                          needs_slider: bool = False):
    """The mechanism options (``--preset``, the physical parameters, ``--model`` and its hybrid
    options) of simulate and fit, in a group named ``title``; ``--ideal`` only if ``ideal``;
    ``needs_slider``: the command needs a preset with a slider (said in the help)."""
    mech = p.add_argument_group(title)
    which = "preset mechanism with a slider" if needs_slider else "preset mechanism"
    mech.add_argument("--preset", default="flores-slider-crank", metavar="NAME",
                      help=f"{which}, one of {', '.join(preset_names())} (default: flores-slider-crank)")
    mech.add_argument("--clearance", type=number_in(float, 0.0, low_open=True), metavar="M",
                      help="radial clearance c = R_B - R_J [m], > 0 and < the bearing radius "
                      "(default: the preset's, 0.5e-3 m)")
    mech.add_argument("--restitution", type=number_in(float, 0.0, 1.0, low_open=True), metavar="CR",
                      help="coefficient of restitution c_r [-], in (0, 1] (default: the preset's, 0.9)")
    mech.add_argument("--friction", type=number_in(float, 0.0), metavar="MU",
                      help="friction coefficient mu [-], >= 0 (default: the preset's; 0 for "
                      "flores-slider-crank and four-bar, 0.01 for flores-2011-rig)")
    mech.add_argument("--speed-rpm", type=number_in(float), metavar="RPM",
                      help="crank speed [rev/min] (default: the preset's; 5000 for flores-slider-crank, "
                      "200 for flores-2011-rig, 500 for four-bar)")
    mech.add_argument("--model", default="lankarani-nikravesh", metavar="LAW",
                      help=f"normal contact force law [-], one of {', '.join(law_names())} "
                      "(default: %(default)s)")
    mech.add_argument("--stiffness", type=number_in(float, 0.0, low_open=True), metavar="K",
                      help="contact stiffness, > 0: K [N/m^n] of the Hertz-family laws (n = 1.5), the "
                      "stiffness parameter of the others (default: from steel, E = 207 GPa, nu = 0.3, and "
                      "the radii; K = 6.61e10 N/m^1.5 for R_B = 10 mm, c = 0.5 mm)")
    if ideal:
        mech.add_argument("--ideal", action="store_true",
                          help="replace the clearance joint by an ideal revolute joint (default: off)")
    _add_hybrid_options(p)


#: Hybrid-model option (argparse attribute) -> keyword of the hybrid law.
HYBRID_OPTIONS = {"placement": "placement", "elements": "n_elements", "gauss_points": "n_gauss",
                  "layer_thickness": "thickness", "damping": "damping", "geometry": "geometry"}


def _add_hybrid_options(p: argparse.ArgumentParser):
    """Options of the hybrid Gauss-point model (``--model hybrid``)."""
    h = p.add_argument_group("hybrid model (--model hybrid)")
    h.add_argument("--placement", choices=("arc", "fixed"), default=None,
                   help="where the Gauss points sit: 'arc' (on the current contact arc, exact with few "
                   "points) or 'fixed' (body-fixed over the whole pin circumference, the model's original "
                   "formulation) (default: %(default)s)")
    h.add_argument("--elements", type=number_in(int, 1, MAX_GAUSS_POINTS), metavar="N_E",
                   help=f"number of elements N_e [-], in [1, {MAX_GAUSS_POINTS}] and N_e x N_g <= {MAX_GAUSS_POINTS} "
                   "(default: 2 for arc, 180 for fixed)")
    h.add_argument("--gauss-points", type=number_in(int, 1, MAX_GAUSS_PER_ELEMENT), metavar="N_G",
                   help=f"Gauss-Legendre points per element N_g [-], in [1, {MAX_GAUSS_PER_ELEMENT}] (default: 4)")
    h.add_argument("--layer-thickness", type=number_in(float, 0.0, low_open=True), metavar="H",
                   help="compliant layer thickness h [m], > 0 (default: the clearance c)")
    h.add_argument("--damping", choices=("joint", "point"), default=None,
                   help="Qin-Lu damping applied to the joint resultant or to every point (default: %(default)s)")
    h.add_argument("--geometry", choices=("exact", "small-gap"), default=None,
                   help="point penetration from the exact circles or the small-gap profile e cos(theta) - c "
                   "(default: %(default)s)")


def _hybrid_options(args) -> dict:
    """``law_options`` of the hybrid law from its options; an error naming the options given
    without ``--model hybrid``."""
    given = [attr for attr in HYBRID_OPTIONS if getattr(args, attr, None) is not None]
    if given and args.model != "hybrid":
        flags = ", ".join("--" + attr.replace("_", "-") for attr in given)
        raise ParameterError(f"{flags} apply only to --model hybrid (got --model {args.model})")
    return {HYBRID_OPTIONS[attr]: getattr(args, attr) for attr in given}


#: preset keyword -> the command-line flag that sets it.
FLAGS = {"clearance": "--clearance", "restitution": "--restitution", "friction": "--friction",
         "speed_rpm": "--speed-rpm", "stiffness": "--stiffness", "law": "--model", "n_elements": "--elements",
         "n_gauss": "--gauss-points", "thickness": "--layer-thickness", "placement": "--placement",
         "damping": "--damping", "geometry": "--geometry"}


def preset_from_args(args, **kwargs) -> Mechanism:
    """The preset ``args.preset`` with the mechanism options applied (``kwargs``: more preset
    keywords, e.g. ``ideal``); a range error names the flag the user typed (``--clearance:
    clearance = 0.02 m must be smaller than ...``)."""
    overrides = mechanism_overrides(args)
    try:
        return preset(args.preset, **kwargs, **overrides)
    except ParameterError as err:
        text = str(err)
        given = list(overrides) + list(overrides.get("law_options", {}))
        named = [FLAGS[k] for k in given if k in FLAGS and text.startswith((f"{k} ", f"{k}="))]
        if named and not text.startswith("--"):
            raise ParameterError(f"{named[0]}: {text}") from None
        raise


def mechanism_overrides(args) -> dict:
    """Keyword arguments of :func:`jaxclear.presets.preset` from the mechanism options: the
    physical parameters given (SI, crank speed in rpm), ``law`` and ``law_options``."""
    names = ("clearance", "restitution", "friction", "speed_rpm", "stiffness")
    out = {name: getattr(args, name) for name in names if getattr(args, name) is not None}
    out["law"] = args.model
    opts = _hybrid_options(args)
    if opts:
        out["law_options"] = opts
    return out


# ---- mechanism files -------------------------------------------------------------------

#: Mechanism options that apply to a file's every clearance joint (argparse attribute -> parameter).
FILE_OVERRIDES = {"clearance": "clearance", "restitution": "restitution", "friction": "friction",
                  "stiffness": "stiffness"}


def add_mechanism_file_option(p: argparse.ArgumentParser):
    """The mechanism file: a positional ``FILE.toml`` or ``--mechanism FILE``."""
    p.add_argument("file", nargs="?", metavar="FILE.toml",
                   help="mechanism file (TOML, docs/mechanism-files.md); instead of --preset")
    p.add_argument("--mechanism", metavar="FILE",
                   help="mechanism file, the same as the positional FILE.toml (default: use --preset)")


def mechanism_file(args) -> str | None:
    """The mechanism file given (positional or ``--mechanism``), or None."""
    given = [f for f in (getattr(args, "file", None), getattr(args, "mechanism", None)) if f]
    if len(given) == 2 and given[0] != given[1]:
        raise ParameterError(f"two mechanism files given ({given[0]!r} and --mechanism {given[1]!r}); give one")
    return given[0] if given else None


def preset_options_given(args) -> list[str]:
    """The preset-only options (``--model``, the hybrid options) the user gave, as flags: those
    whose value differs from the command's default (``lankarani-nikravesh`` and none, unless the
    command names others in ``args.mechanism_defaults``, as ``jaxclear wear`` does)."""
    defaults = {"model": "lankarani-nikravesh", **getattr(args, "mechanism_defaults", {})}
    return ["--" + attr.replace("_", "-") for attr in ("model", *HYBRID_OPTIONS)
            if hasattr(args, attr) and getattr(args, attr) != defaults.get(attr)]


def load_mechanism_file(args, path: str, ideal: bool = False) -> Mechanism:
    """A mechanism file with the physical options given on the command line applied to every
    clearance joint (``--clearance``, ``--restitution``, ``--friction``, ``--stiffness``) and to
    the crank (``--speed-rpm``); ``ideal``: its ideal-joint counterpart. The contact law is the
    file's (``--model`` and the hybrid options are for presets)."""
    mech = load_mechanism(path)
    given = preset_options_given(args)
    if given:
        raise ParameterError(f"{', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to presets only (like "
                             f"--model and every hybrid option); the contact law of {path!r} is set in the file "
                             "([clearance_joints.law] name = ...)")
    values = {}
    for attr, name in FILE_OVERRIDES.items():
        if getattr(args, attr, None) is not None:
            values.update({f"{name}@{k}": getattr(args, attr) for k in range(len(mech.clearance_joints))})
            if not mech.clearance_joints:
                raise ParameterError(f"--{attr} needs a clearance joint; {path!r} has none")
    if getattr(args, "speed_rpm", None) is not None:
        values["speed_rpm"] = args.speed_rpm
    for name, value in values.items():
        params.validate(mech, name, value)
    mech = params.replace_many(mech, values)
    return mech.ideal() if ideal else mech
