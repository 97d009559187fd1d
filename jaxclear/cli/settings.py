"""The integration options of every command that integrates (simulate, animate, chaos, wear,
design, fit and its posterior, sweep, tolerance): one option group, :func:`add_settings_options`,
whose defaults are read from :class:`~jaxclear.Settings` (a command's own default settings where
it has them, the fit's tolerances), never written here; and one function,
:func:`settings_from_args`, that turns the options given into a ``Settings`` through
:func:`~jaxclear.integrate.settings_from_options`, the conversion a sweep's or a tolerance
study's ``[settings]`` table goes through too."""

from __future__ import annotations

import argparse

from ..integrate import Settings, default_settings, option_values, settings_from_options
from ..integrate import ADJOINTS, ONSETS, OUTPUTS, SOLVERS
from .common import number_in

#: The group's options: flag -> ``Settings`` field by name
#: (:data:`~jaxclear.integrate.OPTION_KEYS`); the parsed value's ``dest`` is the flag's.
FLAGS = {
    "--solver": "solver",
    "--rtol": "rtol",
    "--atol": "atol",
    "--max-steps": "max_steps",
    "--derivatives": "derivatives",
    "--derivative-tolerance": "derivative_tolerance",
    "--output-sampling": "output",
    "--onsets": "onsets",
}
#: The attribute of the parsed arguments naming the options given on the command line.
GIVEN = "settings_given"


class _Given(argparse.Action):
    """Store the value and remember that the option was given (a default is not a choice: the
    command's own settings, a file's ``[settings]``, keep what the command line leaves out)."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        given = set(getattr(namespace, GIVEN, None) or ())
        setattr(namespace, GIVEN, given | {self.dest})


def _dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def number_text(x: float) -> str:
    """A default as ``--help`` shows it: ``1e-8``, not ``1e-08``."""
    return f"{x:g}".replace("e-0", "e-")


def add_settings_options(group, defaults: Settings | None = None, *, shown: dict | None = None,
                         title: str | None = None):
    """Add the integration options (:data:`FLAGS`) to ``group`` (a parser or an argument group;
    with ``title``, a new group of that parser). Their defaults, shown by ``--help``, are
    ``defaults``' fields (default: ``Settings``' own defaults, read from a default
    ``Settings``); ``shown``: flag -> the text shown instead (a default the command chooses at
    run time, as the fit's step limit; the parser's default is then None). Returns the group."""
    if title is not None:
        group = group.add_argument_group(title)
    values = option_values(defaults if defaults is not None else default_settings())
    shown = dict(shown or {})

    def default(flag):
        text = shown.get(flag, values[FLAGS[flag]])
        return number_text(text) if isinstance(text, float) else str(text)

    def add(flag, help, **kw):
        # an option whose default the command chooses at run time has none in the parser
        group.add_argument(flag, action=_Given, default=None if flag in shown else values[FLAGS[flag]],
                           help=f"{help} (default: {default(flag)})", **kw)

    add("--solver", f"Runge-Kutta solver, one of {', '.join(SOLVERS)}", metavar="NAME")
    add("--rtol", "relative tolerance of the adaptive step [-], in (0, 1)",
        type=number_in(float, 0.0, 1.0, True, True), metavar="TOL")
    add("--atol", "absolute tolerance of the adaptive step [m, rad, m/s, rad/s], > 0",
        type=number_in(float, 0.0, low_open=True), metavar="TOL")
    add("--max-steps", "maximum number of solver steps per run [-], >= 1", type=number_in(int, 1), metavar="N")
    add("--derivatives", "how derivatives of a run are taken: 'sensitivity' (the error-controlled forward "
        "sensitivities) or through diffrax's loop ('recursive', 'forward', 'direct')", choices=ADJOINTS)
    add("--derivative-tolerance", "the sensitivities' tolerance as a fraction of rtol and atol [-], in (0, 1] "
        "(jaxclear.Sensitivity(tolerance))", type=number_in(float, 0.0, 1.0, True, False), metavar="F")
    add("--output-sampling", "how the output samples are written: 'loop' (diffrax's saving) or 'block' (a "
        "step's samples at once)", choices=tuple(OUTPUTS))
    add("--onsets", "contact onsets: 'exact' (the step crossing into contact ends just past the onset) or "
        "'step'", choices=tuple(ONSETS))
    return group


def given_options(args) -> dict:
    """The integration options given on the command line, by ``Settings`` field name
    (:data:`FLAGS`): what :func:`~jaxclear.integrate.settings_from_options` and a file's
    ``settings_options`` take."""
    given = getattr(args, GIVEN, None) or ()
    return {FLAGS[flag]: getattr(args, _dest(flag)) for flag in FLAGS if _dest(flag) in given}


def settings_from_args(args, base: Settings | None = None, *, none_if_unset: bool = False) -> Settings | None:
    """The :class:`~jaxclear.Settings` of the parsed options: ``base`` (default ``Settings``'
    defaults) with the options given on the command line replaced; with ``none_if_unset`` and no
    option given, None (the command's driver chooses its own settings)."""
    options = given_options(args)
    if none_if_unset and not options:
        return None
    return settings_from_options(options, base, source="command line")
