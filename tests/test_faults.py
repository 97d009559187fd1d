"""Bad input and faults, round two: every case answers with one line naming the file, key or
option and what is allowed (the command line exits 2), or with a named status; never a
traceback, a hang, a silent wrong answer or a repeated record.

Sections follow the families of checks of docs/errors.md: files that are not what they claim
(binary, damaged, cut), values of the wrong kind in mechanism files, sizes bounded before
anything is allocated, damaged caches, and wrong answers about a mechanism's structure. Wear
states (damaged, killed between its two writes) are fed in tests/test_wear.py, whose wear run
they reuse. Every test here is cheap: nothing is integrated.
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path

import numpy as np
import pytest

import jaxclear as jc
from jaxclear.cli import main
from jaxclear.integrate import _programs as programs
from jaxclear.sweep import driver as sweep_driver, store as sweep_store

ROOT = Path(__file__).resolve().parents[1]
FOUR_BAR = ROOT / "examples" / "four-bar-rocker-pivot.toml"
#: bytes that are not UTF-8 (a binary file: a compressed archive's first bytes)
BINARY = b"\x1f\x8b\x08\x00\xd5\xff\xfe" + bytes(range(256))


def _one_line_error(capsys, *words) -> str:
    """The command's stderr: one line, ``error: ...``, no traceback, holding ``words``."""
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


# ---- files that are not text -------------------------------------------------------------


def test_binary_mechanism_file_is_named(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_bytes(BINARY)
    with pytest.raises(jc.MechanismError, match=r"mechanism file .*m\.toml' is not UTF-8 text \(byte 0x8b at offset 1"):
        jc.load_mechanism(path)
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2
    _one_line_error(capsys, "m.toml", "not UTF-8 text", "allowed: a UTF-8 text file")


def test_binary_record_is_named(tmp_path, capsys):
    path = tmp_path / "rec.csv"
    path.write_bytes(b"time_s,slider_acc_m_s2\n0,1\n" + BINARY)  # text first, binary after
    with pytest.raises(jc.ParameterError, match=r"measurements file .*rec\.csv' is not UTF-8 text .*offset 28"):
        jc.read_measurements(path)
    assert main(["fit", str(path), "--no-progress", "--no-plots", "--out", str(tmp_path / "fit")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("error: measurements file")


def test_binary_sweep_configuration_and_channels_file_are_named(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_bytes(BINARY)
    assert main(["sweep", str(path)]) == 2
    _one_line_error(capsys, "sweep configuration", "s.toml", "not UTF-8 text")
    from jaxclear.fitting.targets import read_channels_toml

    with pytest.raises(jc.ParameterError, match=r"channels file .*s\.toml' is not UTF-8 text"):
        read_channels_toml(path)


def test_text_inputs_are_bounded_in_size(tmp_path, monkeypatch):
    from jaxclear import _storage

    path = tmp_path / "m.toml"
    path.write_text(FOUR_BAR.read_text())
    monkeypatch.setattr(_storage, "MAX_TEXT_BYTES", 100)  # the default of read_text is bound at import
    with pytest.raises(jc.MechanismError, match=r"bytes, outside the allowed range \[0, 100\] bytes"):
        _storage.read_text(path, "mechanism file", jc.MechanismError, max_bytes=_storage.MAX_TEXT_BYTES)


# ---- values of the wrong kind in mechanism files -------------------------------------------


@pytest.mark.parametrize("old, new, key, allowed", [
    ("mass = 0.2\n", "mass = [1.0, 2.0]\n", "bodies[0].mass", "must be a number, got [1.0, 2.0]"),
    ("restitution = 0.9\n", 'restitution = "high"\n', "clearance_joints[0].law.restitution",
     "must be a number, got 'high'"),
    ("length = 0.01\n", "length = [0.01]\n", "clearance_joints[0].length", "must be a number"),
    ("speed = 52.35987755982988\n", 'speed = "fast"\n', "drivers[0].speed", "must be a number"),
    ("coefficient = 0.0\n", "coefficient = [0.1]\n", "clearance_joints[0].friction.coefficient",
     "must be a number"),
    ('model = "ambrosio"\n', "model = 3\n", "clearance_joints[0].friction.model", "must be a string"),
    ("poisson = 0.3\n", 'poisson = "steel"\n', "clearance_joints[0].law.bearing_material.poisson",
     "must be a number"),
    ('name = "lankarani-nikravesh"\n', 'name = "hybrid"\nn_gauss = 2.5\n', "clearance_joints[0].law.n_gauss",
     "must be an integer, got 2.5"),
    ('name = "lankarani-nikravesh"\n', 'name = "hybrid"\nplacement = 1\n', "clearance_joints[0].law.placement",
     "must be a string"),
])
def test_wrong_kind_of_value_in_a_mechanism_file_is_named(tmp_path, capsys, old, new, key, allowed):
    text = FOUR_BAR.read_text()
    assert old in text
    path = tmp_path / "m.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(jc.JaxclearError) as err:
        jc.load_mechanism(path)
    assert f"{path}: {key}: {allowed}" in str(err.value)
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2
    _one_line_error(capsys, key)


# ---- sizes bounded before anything is allocated ---------------------------------------------


def test_sweep_axis_size_is_checked_before_its_values_are_made(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text('[grid]\nclearance = { start = 1e-4, stop = 5e-4, num = 1000000000 }\n')
    start = time.perf_counter()
    assert main(["sweep", str(path)]) == 2
    assert time.perf_counter() - start < 10.0  # before: 10 GB of values and 35 s
    _one_line_error(capsys, "s.toml", "'clearance'.num = 1000000000", "allowed range [1, 10000000]")


@pytest.mark.parametrize("kwargs, words", [
    (dict(n_gauss=10**9), "n_gauss = 1000000000 is outside the allowed range: an integer in [1, 64]"),
    (dict(n_elements=10**9), "n_elements = 1000000000 is outside the allowed range: an integer in [1, 100000]"),
    (dict(n_elements=50_000, n_gauss=4), "200000 Gauss points, outside the allowed range [1, 100000]"),
])
def test_gauss_point_counts_are_bounded(kwargs, words):
    start = time.perf_counter()
    with pytest.raises(jc.ParameterError) as err:
        jc.HybridLaw(placement="fixed", **kwargs)
    assert words in str(err.value)
    with pytest.raises(jc.ParameterError) as err:
        jc.LubricatedJoint(jc.GROUND, "o", "b", "c", **kwargs)
    assert words in str(err.value)
    assert time.perf_counter() - start < 5.0


def test_wear_nodes_and_cli_counts_are_bounded(capsys, tmp_path):
    with pytest.raises(jc.ParameterError, match=r"n_nodes = 1000000000 .*\[8, 100000\]"):
        jc.WearOptions(coefficient=1e-15, updates=1, n_nodes=10**9).check(jc.settings(0.01))
    assert main(["wear", "--nodes", "1000000000", "--out", str(tmp_path)]) == 2
    assert "argument --nodes: 1000000000 is outside the allowed range [8, 100000]" in capsys.readouterr().err
    assert main(["simulate", "--model", "hybrid", "--gauss-points", "100000", "--out", str(tmp_path)]) == 2
    assert "argument --gauss-points: 100000 is outside the allowed range [1, 64]" in capsys.readouterr().err


# ---- a resumed sweep whose folder is damaged ------------------------------------------------


@pytest.fixture
def sweep_folder(tmp_path):
    """A sweep configuration and its output folder as a first run leaves it (manifest, CSV
    header, one row), made without computing anything."""
    cfg_path = tmp_path / "s.toml"
    out = tmp_path / "out"
    cfg_path.write_text(f'[grid]\nclearance = [2e-4, 5e-4]\n[run]\nrevolutions = 1\n[output]\ndir = "{out}"\n')
    cfg = jc.load_config(cfg_path)
    _, _, layout = sweep_driver._layout(cfg)
    sweep_store.prepare_output(cfg, str(out), False, layout)
    columns = sweep_store.csv_columns(cfg)
    row = ["0"] + ["1" if c in sweep_store._INT_READ else "1.0" for c in columns[1:-1]] + ["ok"]
    with open(out / "runs.csv", "a") as f:
        f.write(",".join(row) + "\n")
    return cfg_path, out


@pytest.mark.parametrize("damage, words", [
    (lambda out: (out / "runs.csv").write_bytes((out / "runs.csv").read_bytes().replace(b"ok", b"o\xff")),
     ["runs.csv is damaged", "line 2: byte 0xff is not UTF-8 text"]),
    (lambda out: (out / "runs.csv").write_text((out / "runs.csv").read_text().replace("\n0,", "\nx0,")),
     ["runs.csv is damaged", "line 2: run index 'x0' is not an integer"]),
    (lambda out: (out / "runs.csv").write_text((out / "runs.csv").read_text().replace("\n0,", "\n7,")),
     ["runs.csv is damaged", "run index 7 is outside this sweep's [0, 2)"]),
    (lambda out: (out / "runs.csv").write_text((out / "runs.csv").read_text().replace(",1.0,", ",1.0x,", 1)),
     ["runs.csv is damaged", "line 2, column", "'1.0x' is not a number"]),
    (lambda out: (out / "manifest.json").write_text((out / "manifest.json").read_text()[:100]),
     ["manifest.json is damaged", "not valid JSON"]),
    (lambda out: (out / "manifest.json").write_text("[1, 2]"),
     ["manifest.json is damaged", "not a jaxclear sweep manifest"]),
    (lambda out: (out / "manifest.json").write_bytes(BINARY),
     ["manifest.json is damaged", "is not UTF-8 text"]),
])
def test_damaged_sweep_folder_names_the_file_and_offers_restart(sweep_folder, capsys, damage, words):
    cfg_path, out = sweep_folder
    damage(out)
    assert main(["sweep", str(cfg_path), "--no-plots"]) == 2  # before anything is compiled
    _one_line_error(capsys, *words, "--restart")
    with pytest.raises(jc.CheckpointError, match="damaged"):
        jc.read_results(out)


def test_damaged_chunk_file_is_named_when_read(sweep_folder):
    _, out = sweep_folder
    (out / "chunks" / "chunk_000000.npz").write_bytes(b"PK\x03\x04 cut short")
    with pytest.raises(jc.CheckpointError, match=r"chunk_000000\.npz is damaged \(not a readable NPZ file"):
        jc.read_results(out)


# ---- the compilation cache -------------------------------------------------------------------


@pytest.fixture
def store(tmp_path):
    yield programs.enable(tmp_path / "programs")
    programs.enable(None)


def _double(x):
    return {"y": 2.0 * x}


def _call(x):
    return programs.call("double", _double, (x,), lambda: __import__("jax").tree_util.tree_structure({"y": 0}))


def test_stored_program_with_flipped_bytes_is_a_miss(store):
    """A flipped byte inside the serialized program may still deserialize (then XLA fails to
    parse it at the call): the file's checksum makes it a miss, traced again and replaced."""
    x = np.arange(3.0)
    np.testing.assert_array_equal(_call(x)["y"], 2 * x)
    (path,) = store.glob(f"*{programs.SUFFIX}")
    good = path.read_bytes()
    bad = bytearray(good)
    bad[len(good) // 2] ^= 0x01
    path.write_bytes(bytes(bad))
    programs.enable(None)  # a new process: nothing loaded yet (enabling the same folder again keeps
    programs.enable(store)  # what was loaded)
    np.testing.assert_array_equal(_call(x)["y"], 2 * x)
    again = path.read_bytes()
    assert again != bytes(bad) and programs._unpack(again) is not None  # replaced by a sound file


def test_enabling_the_same_store_again_keeps_the_loaded_programs(store):
    """The command line's ``main`` enables the store on every call: in one process (the tests
    call it in-process) the same folder keeps the programs it loaded (not read and compiled
    again); another folder forgets them."""
    x = np.arange(3.0)
    _call(x)
    before = programs.counts()
    for folder in (store, store):
        programs.enable(folder)
        np.testing.assert_array_equal(_call(x)["y"], 2 * x)
    assert programs.counts() == before  # nothing loaded, nothing traced
    other = programs.enable(store.parent / "other")
    assert programs.folder() == other
    _call(x)
    assert programs.counts()["traced"] == before["traced"] + 1  # a new folder: read (here: traced) anew


def test_unwritable_program_store_goes_on_without_it(store, monkeypatch):
    """mkstemp failing (a read-only folder; tests run as root, which ignores file modes) leaves
    the store off with a warning, and the call still answers."""

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(programs.tempfile, "mkstemp", refuse)
    with pytest.warns(UserWarning, match=r"cannot write to the program cache .*Permission denied"):
        np.testing.assert_array_equal(_call(np.ones(2))["y"], [2.0, 2.0])
    assert programs.folder() is None


def test_cache_folder_that_cannot_hold_programs_is_left_off(tmp_path, capsys):
    from jaxclear.cli import cache

    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "programs").write_text("a file where the folder belongs")
    assert cache.enable(tmp_path / "c") is None
    err = capsys.readouterr().err
    assert err.startswith("warning: the compilation cache folder") and "programs" in err
    assert "running without the compilation cache" in err and len(err.strip().splitlines()) == 1
    assert programs.folder() is None
    assert main(["--cache-dir", str(tmp_path / "c"), "presets"]) == 0  # the command runs on


# ---- wrong answers about a mechanism's structure --------------------------------------------


def _four_bar_text(drop_joint_b: bool = False) -> str:
    text = FOUR_BAR.read_text()
    if drop_joint_b:  # the coupler-rocker pin removed: the rocker hangs on its clearance pivot alone
        line = '    { type = "revolute", body_i = "coupler", point_i = "B", body_j = "rocker", point_j = "B" },\n'
        assert line in text
        text = text.replace(line, "")
    return text


def test_clearance_joint_names_are_unique(tmp_path, capsys):
    """Two clearance joints of one name: refused where the mechanism is built (outputs and
    parameters address a joint by name; before, an output request failed with a list of twins)."""
    text = _four_bar_text(drop_joint_b=True)
    block = text[text.index("[[clearance_joints]]"):]
    second = (block.replace('bearing_body = "ground"', 'bearing_body = "rocker"')
              .replace('bearing_point = "O4"', 'bearing_point = "B"').replace('journal_body = "rocker"', 'journal_body = "coupler"')
              .replace('journal_point = "O"', 'journal_point = "B"'))
    path = tmp_path / "twins.toml"
    path.write_text(text + "\n" + second)
    with pytest.raises(jc.MechanismError, match=r"clearance joint names must be unique .* got 'rocker-pivot' twice"):
        jc.load_mechanism(path)
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2
    _one_line_error(capsys, "twins.toml", "'rocker-pivot' twice")
    path.write_text(text + "\n" + second.replace('name = "rocker-pivot"', 'name = "coupler-rocker"'))
    mech = jc.load_mechanism(path)
    assert [c.name for c in mech.clearance_joints] == ["rocker-pivot", "coupler-rocker"]


def test_second_driver_on_a_one_dof_four_bar_is_named_redundant(tmp_path, capsys):
    """A driver on the rocker of the crank-driven four-bar: 8 equations of joints and drivers and
    2 of the clearance joint held centred for 9 coordinates. Before, the count left out the
    clearance joint's 2 and the run reported a Newton failure (improve the position guesses)."""
    path = tmp_path / "two-drivers.toml"
    path.write_text(_four_bar_text() + '\n[[drivers]]\ntype = "angle"\nbody = "rocker"\nspeed = 10.0\n'
                    "angle0 = 1.312988228135458\n")
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2
    line = _one_line_error(capsys, "redundant or conflicting constraints: 10 equations for 9 coordinates",
                           "2 of the clearance joints ['rocker-pivot']", "AngleDriver(rocker-ground)")
    assert "Newton" not in line


def test_under_driven_mechanism_names_the_command_line_option_and_check_agrees(tmp_path, capsys):
    """The same file fails in check as it would in simulate (one function, check_assembly),
    and the remedy names the option a command-line user can give."""
    path = tmp_path / "under.toml"
    path.write_text(_four_bar_text(drop_joint_b=True))
    mech = jc.load_mechanism(path)
    with pytest.raises(jc.MechanismError, match=r"too few constraints .* --allow-free-dof on the command line"):
        jc.check_mechanism(mech)
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2
    _one_line_error(capsys, "too few constraints for the drivers: 9 coordinates but only 7",
                    "Settings(allow_free_dof=True)", "--allow-free-dof")
    assert main(["check", str(path), "--allow-free-dof", "--out", str(tmp_path)]) == 0
    assert "degrees of freedom         4" in capsys.readouterr().out
    for command in ("simulate", "animate", "wear"):
        args = jc.cli.build_parser().parse_args([command, str(path), "--allow-free-dof"])
        assert args.allow_free_dof is True


def test_lugre_bristle_stiffness_gets_its_own_status_message():
    """A NaN bristle stiffness (a traced value: no eager check) gets a status whose message
    names it, not the friction coefficient's alone."""
    import equinox as eqx
    import jax.numpy as jnp

    from jaxclear._errors import STATUS

    mech = jc.preset("flores-slider-crank")
    mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction, mech, jc.Friction(0.1, model="lugre"))
    bad = eqx.tree_at(lambda m: m.clearance_joints[0].friction.bristle_stiffness, mech, jnp.asarray(np.nan))
    message = STATUS[int(bad.check()._value)]
    assert "bristle_stiffness sigma_0 > 0" in message and "coefficient" in message
    with pytest.raises(jc.ParameterError, match="bristle_stiffness"):
        jc.Friction(0.1, model="lugre", bristle_stiffness=np.nan)


def _record(path, rate_hz: float, span_s: float):
    t = np.arange(int(round(span_s * rate_hz)) + 1) / rate_hz
    path.write_text("time_s,slider_acc_m_s2\n" + "".join(f"{a!r},{1.0 + math.sin(2e3 * a)!r}\n" for a in t.tolist()))
    return path


def _problem(path, window, windows=1, rtol=1e-6):
    from jaxclear.fitting.problem import build_problem

    settings = dict(max_iter=3, ftol=1e-8, xtol=1e-8, rtol=rtol, atol=rtol * 1e-3, max_steps=1000, align="time",
                    time_offset=0.0, optimizer="lm")
    return build_problem(str(path), jc.preset("flores-slider-crank"), ["stiffness"], None, None, window, windows,
                         (1.0,), None, 1, settings)


def test_fit_model_runs_its_sensitivities_at_its_own_tolerance_where_it_is_tight(tmp_path):
    """The fit's window model asks for the sensitivity solve at its own tolerance
    (``derivative_tolerance`` 1) where its rtol is 1e-7 or tighter (the fits' 1e-8: smooth
    derivatives already, and the tenth cost their Jacobians about 1.2x), at Settings' default
    tenth where it is looser."""
    rec = _record(tmp_path / "r.csv", 20000.0, 0.004)
    assert _problem(rec, 0.002, rtol=1e-8).model.settings.derivative_tolerance == 1.0
    assert _problem(rec, 0.002, rtol=1e-7).model.settings.derivative_tolerance == 1.0
    assert _problem(rec, 0.002, rtol=1e-6).model.settings.derivative_tolerance == jc.Settings.derivative_tolerance == 0.1


def test_fit_window_against_short_records(tmp_path, capsys):
    """A 13-sample record (2 kHz over 6 ms) is long enough for a 1 ms window, which holds 3
    samples: the error says so (before: 'record shorter than the fit windows'). A record shorter
    than the default window (a quarter revolution, 3 ms at 5000 rpm) gets a window that fits it."""
    short = _record(tmp_path / "13.csv", 2000.0, 0.006)
    with pytest.raises(jc.ParameterError) as err:
        _problem(short, 0.001)
    assert "a window of 0.001 s holds 3 sample(s) of the record (one every 0.0005 s); at least 4" in str(err.value)
    assert "shorter than" not in str(err.value)
    assert main(["fit", str(short), "--window", "0.001", "--no-progress", "--no-plots",
                 "--out", str(tmp_path / "fit")]) == 2
    assert "holds 3 sample(s)" in capsys.readouterr().err
    assert _problem(short, None).win.length == pytest.approx(0.003, rel=1e-9)  # the default fits
    brief = _record(tmp_path / "2ms.csv", 20000.0, 0.002)  # shorter than the default window
    assert _problem(brief, None).win.length == pytest.approx(0.002, rel=1e-9)
    two = _problem(brief, None, windows=2).win
    assert two.length == pytest.approx(0.001, rel=1e-9) and two.starts[1] == pytest.approx(0.001, rel=1e-9)
    with pytest.raises(jc.ParameterError, match=r"record shorter than the fit windows"):
        _problem(brief, 0.003)  # a window given is not shortened
    with pytest.raises(jc.ParameterError, match=r"3 samples over 0.001 s .* holding 3 sample\(s\) each; at least 4"):
        _problem(_record(tmp_path / "tiny.csv", 2000.0, 0.001), None)


def test_wear_reads_a_hybrid_file_without_its_own_defaults_as_options(tmp_path, capsys):
    """jaxclear wear sets --model hybrid --placement fixed as its defaults; a mechanism file's
    law is its own, and those defaults are not options the user gave."""
    path = tmp_path / "hybrid.toml"
    jc.save_mechanism(jc.preset("flores-slider-crank", law="hybrid", law_options={"placement": "fixed"}), path)
    assert main(["wear", str(path), "--settle", "10", "--out", str(tmp_path / "w")]) == 2
    _one_line_error(capsys, "--settle = 10 s is outside the allowed range")  # the file was read
    assert main(["wear", str(path), "--placement", "arc", "--out", str(tmp_path / "w")]) == 2
    _one_line_error(capsys, "--placement applies to presets only", "set in the file")


# ---- large mechanisms: validation in linear time, size bounded ------------------------------


def _chain_text(n: int) -> str:
    """A mechanism file of ``n`` bars pinned end to end (a hanging chain)."""
    parts = ['format = 1\nname = "chain"\n[ground_points]\nO = [0.0, 0.0]\n']
    parts += [f'[[bodies]]\nname = "b{i}"\nmass = 0.1\ninertia = 1e-4\nposition = [{0.1 * i + 0.05}, 0.0, 0.0]\n'
              '[bodies.points]\nL = [-0.05, 0.0]\nR = [0.05, 0.0]\n' for i in range(n)]
    parts += ['[[joints]]\ntype = "revolute"\nbody_i = "ground"\npoint_i = "O"\nbody_j = "b0"\npoint_j = "L"\n']
    parts += [f'[[joints]]\ntype = "revolute"\nbody_i = "b{i - 1}"\npoint_i = "R"\nbody_j = "b{i}"\npoint_j = "L"\n'
              for i in range(1, n)]
    return "".join(parts)


@pytest.fixture(scope="module")
def chain_parts():
    n = jc.model.mechanism.MAX_BODIES
    bodies = [jc.Body(f"b{i}", 0.1, 1e-4, {"L": (-0.05, 0.0), "R": (0.05, 0.0)}) for i in range(n + 1)]
    joints = [jc.Revolute(jc.GROUND, "O", "b0", "L")] + [jc.Revolute(f"b{i - 1}", "R", f"b{i}", "L")
                                                        for i in range(1, n + 1)]
    return bodies, joints


def test_validation_of_the_largest_mechanism_is_fast(chain_parts):
    """1000 bodies and 1000 joints: validated in well under a second (the name and point lookups
    were quadratic: 500 bodies took 14 s, 2000 more than 145 s)."""
    bodies, joints = chain_parts
    start = time.perf_counter()
    mech = jc.Mechanism(bodies[:-1], joints[:-1], ground_points={"O": (0.0, 0.0)})
    assert time.perf_counter() - start < 2.0  # measured 0.14 s on 2 shared cores; before: minutes
    assert mech.n_bodies == 1000
    with pytest.raises(jc.MechanismError, match=r"unknown point 'X' on body 'b999'"):
        jc.Mechanism(bodies[:-1], [*joints[:-1], jc.Revolute("b998", "R", "b999", "X")], ground_points={"O": (0, 0)})


def test_too_large_mechanisms_are_named(chain_parts, tmp_path, capsys):
    bodies, joints = chain_parts
    with pytest.raises(jc.MechanismError, match=r"bodies: 1001 items, outside the allowed range \[0, 1000\]"):
        jc.Mechanism(bodies, joints, ground_points={"O": (0.0, 0.0)})
    path = tmp_path / "chain.toml"
    path.write_text(_chain_text(1001))
    start = time.perf_counter()
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2  # before any body is built
    assert time.perf_counter() - start < 5.0
    _one_line_error(capsys, "chain.toml: bodies: 1001 items, outside the allowed range [0, 1000]", "MAX_BODIES")


def test_damaged_fit_checkpoint_is_named(tmp_path):
    """A checkpoint whose key matches but whose numbers are damaged (NaN, another shape, a
    negative counter) is named before the fit continues from it, as the wear state is."""
    from jaxclear.fitting.driver import _check_resumed
    from jaxclear.fitting.run import fresh_state

    problem = _problem(_record(tmp_path / "r.csv", 20000.0, 0.004), None)
    good = fresh_state(problem)
    _check_resumed(problem, good, "ck.json")
    theta = list(good.theta)
    for change, words in ((dict(theta=[math.nan] * len(theta)), "theta holds a value that is not finite"),
                          (dict(theta=theta + [1.0]), "theta has shape (2,), this fit's is (1,)"),
                          (dict(states=[[0.0]]), "states has shape"),
                          (dict(iteration=-1), "iteration = -1 is not an integer >= 0"),
                          (dict(stage=99), "stage = 99 is beyond"),
                          (dict(x=("a",)), "x is not an array of numbers")):
        with pytest.raises(jc.CheckpointError, match=r"fit checkpoint 'ck\.json' is damaged \(" + re.escape(words)):
            _check_resumed(problem, good.replace(**change), "ck.json")


def test_lock_owner_file_that_is_not_text(tmp_path):
    from jaxclear._storage import LOCK_NAME, locked_folder

    with locked_folder(tmp_path):
        (tmp_path / (LOCK_NAME + ".owner")).write_bytes(BINARY)
        with pytest.raises(jc.OutputLockedError, match=r"in use by another process \(unknown\)"):
            with locked_folder(tmp_path):
                pass
