"""Reliability, names and ranges: every range a command's help states is what its parser
enforces (read from the help texts), usage errors name the flag typed, bounds that depend on the
mechanism or the machine name the flag too, and every unknown name in the public API is a
:class:`jaxclear.JaxclearError` subclass. Nothing here compiles a simulation."""

from __future__ import annotations

import argparse
import math
import re

import jax
import jax.numpy as jnp
import pytest

import jaxclear as jc
from jaxclear import params
from jaxclear.cli import main

MECH = jc.preset("flores-slider-crank")

# ---- 7. the command line: every stated range is enforced, errors name the flag -------------

_RANGE = re.compile(r"in ([\(\[])(-?[0-9.e+-]+), (-?[0-9.e+-]+|inf)([\)\]])|(>=|>) (-?[0-9.e+-]+)")
_POSITIONAL = {"sweep": ["sweep.toml"], "fit": ["record.csv"], "design": ["--vary", "clearance=1e-4:6e-4"],
               "tolerance": ["study.toml"]}


def _stated_ranges():
    """(command, flag, integer?, low, high, low_open, high_open) of every option whose help
    states a numeric range ("in (0, 1]", ">= 1", "> 0")."""
    parser = jc.cli.build_parser()
    out = []
    for command, sub in parser._subparsers._group_actions[0].choices.items():
        for action in sub._actions:
            m = _RANGE.search(action.help or "") if action.option_strings else None
            if m is None:
                continue
            if m.group(1):
                low, high = float(m.group(2)), float(m.group(3))
                low_open, high_open = m.group(1) == "(", m.group(4) == ")"
            else:
                low, high, low_open, high_open = float(m.group(6)), math.inf, m.group(5) == ">", True
            try:  # an integer option refuses a fraction
                action.type("2.5")
                integer = False
            except argparse.ArgumentTypeError as err:
                integer = "integer" in str(err)
            out.append((command, action.option_strings[0], integer, low, high, low_open, high_open))
    return out


def _parses(capsys, command, flag, value) -> tuple[bool, str]:
    try:
        jc.cli.build_parser().parse_args([command, *_POSITIONAL.get(command, []), f"{flag}={value}"])
    except SystemExit as exit_:
        assert exit_.code == 2
        return False, capsys.readouterr().err
    return True, ""


def test_every_stated_cli_range_is_enforced_by_the_parser(capsys):
    """For each option whose help states a range, the parser accepts exactly that range: the
    bounds themselves as the help says (open or closed), a step inside, a step outside, NaN and
    infinity; a refused value is a usage error (exit 2) naming the flag."""
    ranges = _stated_ranges()
    flags = {(c, f) for c, f, *_ in ranges}
    # the audit covers every numeric option with a range (a help without one would drop out here)
    assert {("simulate", "--rtol"), ("simulate", "--n-out"), ("simulate", "--clearance"), ("fit", "--windows"),
            ("fit", "--sensor-cutoff-hz"), ("sweep", "--chunk-size"), ("sweep", "--devices"),
            ("animate", "--frames"), ("check", "--magnify"), ("simulate", "--gauss-points")} <= flags
    assert len(ranges) >= 30
    for command, flag, integer, low, high, low_open, high_open in ranges:
        step_low = 1 if integer else max(abs(low) * 1e-9, 1e-300)
        cases = [(low, not low_open), (low - step_low, False), (low + step_low, True), ("nan", False),
                 ("inf", False)]
        if math.isfinite(high):
            step_high = 1 if integer else abs(high) * 1e-9
            cases += [(high, not high_open), (high + step_high, False), (high - step_high, True)]
        for value, accepted in cases:
            text = str(int(value)) if integer and isinstance(value, float) else repr(value) if isinstance(
                value, float) else value
            ok, err = _parses(capsys, command, flag, text)
            assert ok == accepted, f"{command} {flag}={text}: accepted {ok}, the help says {accepted}"
            if not ok:
                assert f"argument {flag}" in err and "allowed range" in err, err


def test_dynamic_cli_bounds_name_the_flag(capsys, tmp_path):
    """Bounds that depend on the mechanism or the machine are checked before any compilation and
    name the flag: --clearance below the bearing radius, --devices at most those available."""
    assert main(["simulate", "--clearance", "0.02", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith("error: --clearance: clearance = 0.02")
    assert main(["sweep", "missing.toml", "--devices", str(len(jax.devices()) + 1)]) == 2
    assert "--devices" in capsys.readouterr().err
    assert main(["simulate", "--rtol", "2"]) == 2
    assert "argument --rtol: 2 is outside the allowed range (0, 1)" in capsys.readouterr().err


UNKNOWN_NAMES = {
    "preset name": lambda: jc.preset("nope"),
    "preset keyword": lambda: jc.preset("four-bar", bogus=1),
    "preset law": lambda: jc.preset("flores-slider-crank", law="nope"),
    "law option": lambda: jc.preset("flores-slider-crank", law="hybrid", law_options={"bogus": 1}),
    "law name": lambda: jc.make_law("nope"),
    "law keyword": lambda: jc.make_law("flores", bogus=1),
    "friction model": lambda: jc.Friction(0.1, model="nope"),
    "preset file": lambda: jc.preset_file("nope"),
    "parameter": lambda: params.get(MECH, "nope"),
    "parameter body": lambda: params.get(MECH, "mass:nobody"),
    "parameter joint index": lambda: params.get(MECH, "restitution@5"),
    "parameter joint suffix": lambda: params.get(MECH, "restitution@x"),
    "replace parameter": lambda: params.replace(MECH, "nope", 1.0),
    "replace body": lambda: params.replace(MECH, "inertia:nobody", 1.0),
    "validate parameter": lambda: params.validate(MECH, "nope", 1.0),
    "channel kind": lambda: jc.analysis.channels.unit(MECH, "nope:x"),
    "channel body": lambda: jc.analysis.channels.unit(MECH, "body:nobody:x"),
    "channel point": lambda: jc.analysis.channels.unit(MECH, "point:crank:nope:pos"),
    "channel joint": lambda: jc.analysis.channels.unit(MECH, "joint:nope:penetration"),
    "channel quantity": lambda: jc.analysis.channels.unit(MECH, "joint:0:nope"),
    "channel reaction": lambda: jc.analysis.channels.unit(MECH, "reaction:nope"),
    "sweep parameter": lambda: jc.sweep.config_from_dict({"grid": {"nope": [1.0]}}),
    "sweep body": lambda: jc.sweep.config_from_dict({"grid": {"mass:nobody": [1.0]}}),
    "sweep preset": lambda: jc.sweep.config_from_dict({"grid": {"restitution": [0.5]}, "mechanism": {"preset": "x"}}),
    "sweep preset keyword": lambda: jc.sweep.config_from_dict({"grid": {"restitution": [0.5]},
                                                               "mechanism": {"bogus": 1}}),
    "solver": lambda: jc.Settings(t_end=jnp.asarray(1.0), solver="nope"),
    "body": lambda: MECH.body_index("nobody"),
    "point": lambda: MECH.point("crank", "nope"),
    "fit free parameter": lambda: jc.fitting.parameters.check_free(MECH, ["nope"], {}),
    "solution coordinate": lambda: jc.Solution.coordinate(None, MECH, "crank", "z"),
}


@pytest.mark.parametrize("what", sorted(UNKNOWN_NAMES))
def test_every_unknown_name_is_a_jaxclear_error(what):
    """An unknown name anywhere in the public API is a JaxclearError subclass (never a KeyError,
    TypeError or AttributeError) whose message repeats the name."""
    with pytest.raises(jc.JaxclearError) as info:
        UNKNOWN_NAMES[what]()
    assert any(bad in str(info.value) for bad in ("nope", "nobody", "bogus", "@5", "@x", "'x'", "'z'"))


# ---- a misspelt parameter: the closest names first, not every name ------------------------------

@pytest.mark.parametrize("call", [
    lambda: params.get(MECH, "clearence"),
    lambda: params.replace(MECH, "clearence", 1e-4),
    lambda: params.validate(MECH, "clearence", [1e-4]),
    lambda: jc.derivatives.check_names(MECH, ["clearence"]),
    lambda: jc.designing.check_variables(MECH, {"clearence": (1e-4, 2e-4)}),
    lambda: jc.sweep.config_from_dict({"grid": {"clearence": [1e-4]}}),
])
def test_misspelt_parameter_suggests_the_closest_name(call):
    """Every API that looks a name up in the registry (one place: params._accessor) answers a
    misspelling with the closest name and where to list them all, in under 250 characters (it
    listed every name, about 1,300 characters for the benchmark, more for a larger mechanism)."""
    with pytest.raises(jc.ParameterError) as info:
        call()
    text = str(info.value)
    n = len(params.names(MECH))
    assert text.endswith(f"unknown parameter 'clearence'; did you mean 'clearance'? ({n} names: "
                         "jc.params.names(mech))"), text
    assert len(text) < 250 and "velocity_x" not in text


def test_closest_names_of_a_suffixed_name_and_without_a_mechanism():
    with pytest.raises(jc.ParameterError, match=r"unknown parameter 'mas:rod'; did you mean 'mass:rod'\?"):
        params.get(MECH, "mas:rod")
    with pytest.raises(jc.MechanismError, match=r"unknown body 'rdo'.*; did you mean 'mass:rod'"):
        params.get(MECH, "mass:rdo")
    with pytest.raises(jc.ParameterError, match=r"^unknown parameter 'model' \(39 names: jc.params.names\(mech\)\)$"):
        params.get(MECH, "model")  # nothing close: no guess
    with pytest.raises(jc.ParameterError, match=r"did you mean 'restitution'\? \(51 names: "
                                                 r"jc.params.parameter_names\(\)\)$"):
        params.info("restitutoin")
    assert params.names(MECH) == jc.differentiable_names(MECH) and len(params.names(MECH)) == 39


def test_cli_design_misspelt_variable_is_one_short_line(tmp_path, capsys):
    assert main(["design", "--vary", "clearence=1e-4:2e-4", "--no-progress", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == ("error: design variable 'clearence' is not a number of mechanism 'flores-slider-crank': unknown "
                       "parameter 'clearence'; did you mean 'clearance'? (39 names: jc.params.names(mech))"), err
