"""One JSON writer and one TOML reader (jaxclear/_storage.py).

Every JSON file jaxclear writes goes through :func:`jaxclear._storage.json_text`: strict JSON,
NaN and infinities (of floats, NumPy and JAX scalars and arrays) as ``null``. The files the
command line writes are parsed with a strict parser (``tests/conftest.py``'s
:func:`assert_strict_json`) by the tests that already run each command: ``simulate``
(test_cli.py), ``check`` and ``sweep`` (test_mechanism_cli.py), ``design`` and its journal
(test_design.py), ``fit`` (test_fit.py, test_fit_verdict.py, test_channel_fit.py), ``fit
--posterior`` and ``tolerance`` (test_uncertainty.py), ``wear`` (test_wear.py), ``chaos``
(test_cli_chaos.py); ``models --json`` here. Readers of files written before the change still
read them (a design journal's ``"nan"`` strings)."""

import ast
import json
import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from conftest import assert_strict_json, strict_json
from jaxclear._storage import atomic_write_json, json_text, parse_toml, read_toml
from jaxclear.cli import main
from jaxclear.designing.journal import JOURNAL_NAME, Journal
from jaxclear.tolerance.config import load_study

ROOT = Path(__file__).resolve().parents[1]

#: Modules that still call ``json.dumps`` themselves, each with the reason; all of them hash or
#: normalise settings (fingerprints of a resumable run, which must not change), none writes a file.
#: jaxclear/fitting/ is being edited by another change: routing these through
#: ``jaxclear._storage.json_text`` is left to it.
JSON_DUMPS_PENDING = {
    "jaxclear/fitting/posterior.py": "the posterior checkpoint's key (a fingerprint of the settings)",
    "jaxclear/fitting/state.py": "the fit checkpoint's key and its copy of the settings",
    "jaxclear/fitting/problem.py": "the settings normalised to JSON values",
}
#: Modules that still parse TOML themselves (same reason as above).
TOML_PENDING = {"jaxclear/fitting/targets.py": "the channels file of a fit"}


def test_json_text_writes_nonfinite_numbers_of_every_kind_as_null():
    value = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf, "np": np.float64("nan"), "f32": np.float32("-inf"),
             "jax": jnp.asarray(jnp.inf), "arr": np.array([1.0, np.nan, np.inf]), "jarr": jnp.asarray([[jnp.nan, 2.0]]),
             "ints": (np.int64(3), np.int32(-1)), "flag": np.bool_(False), "nested": [{"x": (math.nan,)}], 7: "key"}
    text = json_text(value)
    assert "NaN" not in text and "Infinity" not in text
    assert strict_json(text) == {
        "nan": None, "inf": None, "-inf": None, "np": None, "f32": None, "jax": None, "arr": [1.0, None, None],
        "jarr": [[None, 2.0]], "ints": [3, -1], "flag": False, "nested": [{"x": [None]}], "7": "key"}


def test_json_text_keeps_finite_floats_exact_and_refuses_what_is_not_json():
    x = [0.1, 1 / 3, 5e-324, 1.7976931348623157e308, -0.0]
    assert json.loads(json_text(x)) == x and str(json.loads(json_text(-0.0))) == "-0.0"
    with pytest.raises(TypeError):
        json_text({"a": object()})
    assert strict_json(json_text({"a": Path("p")}, default=str)) == {"a": "p"}


def test_atomic_write_json_is_strict_with_sorted_keys(tmp_path):
    path = atomic_write_json(tmp_path / "a.json", {"b": np.nan, "a": [np.inf]})
    text = Path(path).read_text()
    assert text == '{\n  "a": [\n    null\n  ],\n  "b": null\n}\n'
    assert assert_strict_json(tmp_path) == ["a.json"]


def test_strict_parser_of_the_tests_refuses_bare_nan(tmp_path):
    """The check the command-line tests use is not vacuous: Python's default output is refused."""
    (tmp_path / "bad.json").write_text(json.dumps({"a": math.nan}))
    with pytest.raises(AssertionError, match="bad.json: NaN is not JSON"):
        assert_strict_json(tmp_path)
    (tmp_path / "bad.json").unlink()
    (tmp_path / "bad.jsonl").write_text('{"a": 1}\n{"a": Infinity}\n')
    with pytest.raises(AssertionError, match="bad.jsonl: Infinity is not JSON"):
        assert_strict_json(tmp_path)


def test_design_journal_writes_null_and_reads_null_and_the_old_strings(tmp_path):
    """A failed evaluation's values are null on disk and NaN when resumed; a journal written
    before (values as the strings "nan", "inf", "-inf") still resumes."""
    journal = Journal(tmp_path, "k1")
    journal.add([0.25, 0.5], [math.nan, 1.5], [0, 1], 0.1, jacobian=[[math.inf, 0.0], [1.0, -math.inf]])
    journal.add([0.5, 0.5], [2.0, 3.0], [0, 0], 0.2)
    lines = (tmp_path / JOURNAL_NAME).read_text().splitlines()
    assert len(lines) == 3 and '"values":[null,1.5]' in lines[1] and '"jacobian":[[null,0.0],[1.0,null]]' in lines[1]
    assert_strict_json(tmp_path)
    again = Journal(tmp_path, "k1")
    assert again.loaded == 2
    entry = again.find([0.25, 0.5], gradient=True)
    assert math.isnan(entry["values"][0]) and entry["values"][1] == 1.5
    assert math.isnan(entry["jacobian"][0][0]) and math.isnan(entry["jacobian"][1][1])
    assert again.find([0.5, 0.5], gradient=False)["values"] == [2.0, 3.0]
    old = tmp_path / "old"
    old.mkdir()
    (old / JOURNAL_NAME).write_text(
        '{"key": "k2", "format": 1}\n'
        '{"kind":"gradient","u":[0.25],"values":["nan",1.0],"status":[1],"wall_s":0.1,"jacobian":[["inf"],["-inf"]]}\n')
    entry = Journal(old, "k2").find([0.25], gradient=True)
    assert math.isnan(entry["values"][0]) and entry["jacobian"] == [[math.inf], [-math.inf]]


def test_models_json_is_strict_json(capsys):
    assert main(["models", "--json"]) == 0
    doc = strict_json(capsys.readouterr().out)
    assert {law["name"] for law in doc["laws"]} == set(jc.law_names()) and doc["friction"]


def test_one_toml_reader(tmp_path):
    """Every TOML file (mechanism, sweep, tolerance study) is read by jaxclear._storage.read_toml /
    parse_toml: a syntax error names the file and the line, in the error class of its caller."""
    bad = tmp_path / "bad.toml"
    bad.write_text("[run]\nrevolutions = = 1\n")
    with pytest.raises(jc.ParameterError, match=r"bad.toml: not valid TOML: .*line 2"):
        read_toml(bad, "sweep configuration")
    with pytest.raises(jc.MechanismError, match="m.toml: not valid TOML"):
        parse_toml("a = [", "m.toml", jc.MechanismError)
    with pytest.raises(jc.ParameterError, match="bad.toml: not valid TOML"):
        load_study(str(bad))
    with pytest.raises(jc.ParameterError, match="bad.toml: not valid TOML"):
        jc.load_config(bad)
    with pytest.raises(jc.MechanismError, match="bad.toml: not valid TOML"):
        jc.load_mechanism(bad)
    (tmp_path / "ok.toml").write_text("[a]\nb = 1\n")
    assert read_toml(tmp_path / "ok.toml", "x") == {"a": {"b": 1}}


def _calls(tree, names: set[str]) -> list[int]:
    """Lines of ``json.NAME(...)`` calls, NAME in ``names``."""
    return [node.lineno for node in ast.walk(tree) if isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute) and node.func.attr in names
            and isinstance(node.func.value, ast.Name) and node.func.value.id == "json"]


def _imports(tree, module: str) -> list[int]:
    return [node.lineno for node in ast.walk(tree)
            if (isinstance(node, ast.Import) and any(a.name == module for a in node.names))
            or (isinstance(node, ast.ImportFrom) and node.module == module)]


def test_json_is_written_and_toml_read_in_one_place():
    """Only jaxclear/_storage.py calls json.dump/json.dumps and imports tomllib (the modules of
    the pending lists above excepted, each still doing so: the lists do not go stale)."""
    dumps, toml = {}, {}
    for path in sorted((ROOT / "jaxclear").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        if rel != "jaxclear/_storage.py":
            if _calls(tree, {"dump", "dumps"}):
                dumps[rel] = _calls(tree, {"dump", "dumps"})
            if _imports(tree, "tomllib") or _imports(tree, "tomli"):
                toml[rel] = _imports(tree, "tomllib") + _imports(tree, "tomli")
    assert set(dumps) == set(JSON_DUMPS_PENDING), f"json.dump(s) outside jaxclear/_storage.py: {dumps}"
    assert set(toml) == set(TOML_PENDING), f"TOML read outside jaxclear/_storage.py: {toml}"
