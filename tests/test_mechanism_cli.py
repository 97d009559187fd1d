"""The command line on mechanism files: check (structure, drawing), simulate FILE.toml, and a
sweep configuration naming a file."""

import json
from pathlib import Path

import equinox as eqx
import pytest

import jaxclear as jc
from jaxclear.cli import main
from jaxclear.sweep.config import config_from_dict

ROOT = Path(__file__).resolve().parents[1]
FOUR_BAR = ROOT / "examples" / "four-bar-rocker-pivot.toml"
PENDULUM = ROOT / "examples" / "pendulum.toml"
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("path, dof, mobility, driven", [
    # Gruebler at the assembled configuration: 3 x 3 coordinates - 3 revolutes x 2 - 1 driver = 2 (the
    # journal's eccentricity); ideal four-bar: 9 - 8 = 1, driven: 0
    (FOUR_BAR, 2, 1, 0),
    # a free bar on a clearance pivot: 3 coordinates, no constraint; ideal: a pendulum, 1 dof, undriven
    (PENDULUM, 3, 1, 1),
])
def test_check_reports_dof_and_draws(tmp_path, capsys, path, dof, mobility, driven):
    assert main(["check", str(path), "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    report = json.loads((tmp_path / "check.json").read_text())
    assert (report["dof"], report["mobility"], report["driven_mobility"]) == (dof, mobility, driven)
    assert f"degrees of freedom         {dof}" in text
    assert "clearance joint" in text and "c = 500 um" in text
    assert report["assembly_residual"] < 1e-10
    assert (tmp_path / "mechanism.png").read_bytes()[:8] == PNG


def test_check_needs_a_mechanism(capsys):
    assert main(["check"]) == 2
    assert "give a mechanism file" in capsys.readouterr().err


def test_simulate_a_file_errors(tmp_path, capsys):
    assert main(["simulate", str(PENDULUM), "--no-progress", "--out", str(tmp_path)]) == 2
    assert "--t-end" in capsys.readouterr().err
    assert main(["simulate", str(PENDULUM), "--model", "hertz", "--t-end", "0.01", "--out", str(tmp_path)]) == 2
    assert "set in the file" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "none.toml"), "--out", str(tmp_path)]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_sweep_config_names_a_file(tmp_path):
    (tmp_path / "m.toml").write_text(FOUR_BAR.read_text())
    doc = {"mechanism": {"file": "m.toml"}, "grid": {"clearance": [0.25e-3, 0.5e-3]}, "run": {"revolutions": 1}}
    cfg_path = tmp_path / "sweep.toml"
    cfg_path.write_text("")  # the file's folder resolves the relative mechanism path
    cfg = config_from_dict(doc, source=str(cfg_path))
    assert bool(eqx.tree_equal(cfg.base_mechanism, jc.load_mechanism(FOUR_BAR)))
    with pytest.raises(jc.ParameterError, match="takes no other key"):
        config_from_dict({**doc, "mechanism": {"file": "m.toml", "law": "hertz"}}, source=str(cfg_path))
