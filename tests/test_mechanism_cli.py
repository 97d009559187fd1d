"""The command line on mechanism files: check (structure, drawing), simulate FILE.toml, and a
sweep configuration naming a file."""

import json
from pathlib import Path

import equinox as eqx
import pytest

import jaxclear as jc
from jaxclear.cli import main
from jaxclear.sweep.config import config_from_dict
from conftest import assert_strict_json

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
    assert "check.json" in assert_strict_json(tmp_path)
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


# ---- the new force elements in files: lubricated, pin-in-slot, translational clearance --------

PRESET_FILES = ROOT / "jaxclear" / "mechanisms"


def _element_file(tmp_path, kind: str) -> Path:
    """A mechanism file with one force element of ``kind``: the shipped preset files and the
    lubricated benchmark of examples/."""
    if kind == "lubricated":
        return ROOT / "examples" / "lubricated-slider-crank.toml"
    return PRESET_FILES / f"{kind}.toml"


@pytest.mark.parametrize("kind, words", [
    ("lubricated", ["c = 500 um", "viscosity 0.4 Pa s", "film width (length) 10 mm"]),
    ("slider-crank-pin-slot", ["c = 500 um", "slot length 1 mm"]),
    ("slider-crank-guide-clearance", ["translational clearance joint guide", "c = 100 um per side",
                                      "guide width 30.2 mm"]),
])
def test_check_a_file_with_each_new_element(tmp_path, capsys, kind, words):
    """Each slider-crank keeps its slider's two coordinates free beside the crank's driven one: the
    journal's eccentricity (2) or, for the guide clearance, the block's lateral offset and tilt (2)."""
    path = _element_file(tmp_path, kind)
    assert main(["check", str(path), "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    report = json.loads((tmp_path / "check.json").read_text())
    assert (report["dof"], report["mobility"], report["driven_mobility"]) == (2, 1, 0)
    assert report["assembly_residual"] < 1e-10
    for w in words:
        assert w in text, (w, text)
    assert (tmp_path / "mechanism.png").read_bytes()[:8] == PNG


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["lubricated", "slider-crank-pin-slot", "slider-crank-guide-clearance"])
def test_simulate_a_file_with_each_new_element(tmp_path, kind):
    """`jaxclear simulate FILE.toml` on 2 ms of each mechanism (about 2 minutes each on 2 cores,
    mostly compilation): status ok, the element's columns in the time series."""
    out = tmp_path / "out"
    assert main(["simulate", str(_element_file(tmp_path, kind)), "--t-end", "0.002", "--n-out", "5", "--no-plots",
                 "--no-progress", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] in (0, "ok"), summary
    assert_strict_json(out)
    assert len((out / "timeseries.csv").read_text().strip().splitlines()) == 1 + 5


@pytest.mark.parametrize("kind", ["lubricated", "slider-crank-pin-slot", "slider-crank-guide-clearance"])
def test_sweep_config_names_a_file_with_each_new_element(tmp_path, kind):
    path = _element_file(tmp_path, kind)
    (tmp_path / "m.toml").write_text(path.read_text())
    doc = {"mechanism": {"file": "m.toml"}, "grid": {"restitution": [0.5, 0.9]}, "run": {"revolutions": 1}}
    cfg_path = tmp_path / "sweep.toml"
    cfg_path.write_text("")
    cfg = config_from_dict(doc, source=str(cfg_path))
    assert bool(eqx.tree_equal(cfg.base_mechanism, jc.load_mechanism(path)))


@pytest.mark.slow
def test_sweep_over_a_guide_clearance_file(tmp_path):
    """`jaxclear sweep` with [mechanism] file = the guide-clearance slider-crank: two restitutions,
    0.05 revolutions (3 ms), both runs ok in runs.csv, with one corner's force as a channel
    (``--channel``: its largest value >= its mean >= 0, a compressive contact force)."""
    (tmp_path / "m.toml").write_text(_element_file(tmp_path, "slider-crank-guide-clearance").read_text())
    (tmp_path / "sweep.toml").write_text(
        '[mechanism]\nfile = "m.toml"\n[grid]\nrestitution = [0.5, 0.9]\n'
        "[run]\nrevolutions = 0.05\nsamples_per_revolution = 100\nideal_reference = false\n[output]\nchunk_size = 2\n")
    out = tmp_path / "out"
    assert main(["sweep", str(tmp_path / "sweep.toml"), "--out", str(out), "--no-plots",
                 "--channel", "joint:0:rear_lower_normal_force"]) == 0
    rows = (out / "runs.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + 2
    assert "manifest.json" in assert_strict_json(out)
    header = rows[0].split(",")
    status = [r.split(",")[header.index("status")] for r in rows[1:]]
    assert status == ["0", "0"], rows
    for r in rows[1:]:
        col = lambda s: float(r.split(",")[header.index(f"{s}__joint_0_rear_lower_normal_force")])  # noqa: E731
        assert col("max") >= col("mean") >= col("min") >= 0.0
