"""Archard wear on the hybrid model's contact field (jaxclear.wearing).

The rig: a ring (the bearing) turned about its fixed centre at a constant speed, a free pin (the
journal, 10 kg) pressed into it by gravity, frictionless contact (the pin does not turn). In the
steady state the contact force is the weight W = m g and the slip speed is omega R_B, so
Archard's law gives the closed form V = k_w W omega R_B t for the worn volume and, over a full
revolution, the same depth all round the bearing.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

import jaxclear as jc
from jaxclear import wearing
from jaxclear.cli import main
from conftest import assert_strict_json

M, G, RB, RJ, L = 10.0, 9.81, 0.010, 0.0095, 0.010
C = RB - RJ
OMEGA = 2 * math.pi * 100.0  # 100 rev/s
T = 2 * math.pi / OMEGA
SETTLE = 0.5 * T  # the pin falls 0.5 um onto the ring; its bounces have died out by then
KW = 1e-14
SETTINGS = jc.settings(SETTLE + T, n_out=1801, allow_free_dof=True)


def rig(omega=OMEGA):
    ring = jc.Body("ring", 1.0, 1e-4, {"c": (0.0, 0.0)})
    pin = jc.Body("pin", M, 1e-3, {"c": (0.0, 0.0)}, position=(0.0, -0.999 * C, 0.0))
    law = jc.HybridLaw(restitution=0.5, placement="fixed", n_elements=180, thickness=C)
    joint = jc.ClearanceJoint("ring", "c", "pin", "c", RB, RJ, length=L, law=law, initial_offset=(0.0, -0.999 * C),
                              name="ring-pin")
    return jc.Mechanism([ring, pin], [jc.Revolute(jc.GROUND, "o", "ring", "c")], [jc.AngleDriver("ring", omega, 0.0)],
                        clearance_joints=[joint], gravity=(0.0, -G), ground_points={"o": (0.0, 0.0)}, name="rig")


@pytest.fixture(scope="module")
def turning():
    mech = wearing.prepare(rig(), 0, 24)
    sol = jc.simulate(mech, SETTINGS)
    return mech, sol


def test_deposit_conserves_and_interpolates():
    rng = np.random.default_rng(0)
    beta = rng.uniform(-10, 10, 50)
    amount = rng.uniform(0, 1, 50)
    nodes = np.asarray(wearing.deposit(beta, amount, 36))
    assert nodes.sum() == pytest.approx(amount.sum(), rel=1e-13)
    one = np.asarray(wearing.deposit(np.array([2 * np.pi * 3.25 / 36 - 4 * np.pi]), np.array([1.0]), 36))
    np.testing.assert_allclose(one[3:5], [0.75, 0.25], atol=1e-12)  # linear hat: 3/4 to node 3, 1/4 to node 4


def test_fourier_of_nodes_is_exact_for_a_band_limited_field():
    beta = wearing.node_angles(64)
    field = 2e-6 + 1e-6 * np.cos(beta) - 3e-7 * np.sin(3 * beta)
    mean, cos, sin = wearing.fourier_of_nodes(field, 8)
    assert float(mean) == pytest.approx(2e-6, rel=1e-12)
    np.testing.assert_allclose(cos, [1e-6] + [0] * 7, atol=1e-18)
    np.testing.assert_allclose(sin, [0, 0, -3e-7] + [0] * 5, atol=1e-18)


@pytest.mark.extended
def test_archard_volume_and_uniform_wear_of_a_turning_bearing(turning):
    """Worn volume over one revolution: (1) against k_w * integral of F_N * slip dt from the
    output time series (the pressure integral equals F_N up to the contact arc's obliquity,
    1 - cos(theta_c) <= theta_c^2 / 2 with theta_c ~ sqrt(2 delta / c)), (2) against the closed
    form k_w W omega R_B t (the same, plus the slip speed omega * |point| vs omega R_B: relative
    R_B - |point| / R_B < c / R_B ... in fact ~ delta / R_B, 1e-5). The trapezoid rule on 1200
    samples per revolution of a steady integrand adds nothing measurable. The depth round the
    bearing is uniform to 3 %: the only non-uniformity is the residual settling oscillation of
    the force where the window starts (its amplitude there, measured: 0.6 % of W; the depth
    varies by up to +-2.5 % over the few nodes the patch crosses while it decays)."""
    mech, sol = turning
    ts = np.asarray(sol.ts)
    w = wearing.window_wear(mech, sol, 0, KW, 180, SETTLE)
    duration = float(w.duration)
    assert duration == pytest.approx(T, rel=1e-12)
    inside = ts >= SETTLE - 1e-12
    delta = float(np.asarray(sol.penetration)[inside, 0].max())
    theta_c = math.sqrt(2 * delta / C)
    obliquity = theta_c**2 / 2
    f_n = np.asarray(sol.normal_force)[inside, 0]
    e = np.linalg.norm(np.asarray(sol.ecc)[inside, 0], axis=-1)
    slip = OMEGA * (RJ + e)  # bearing material point under the pin's surface point (the pin does not turn)
    from_series = KW * np.trapezoid(f_n * slip, ts[inside])
    assert abs(float(w.volume) / from_series - 1) < obliquity + 1e-4
    closed = KW * M * G * OMEGA * RB * T
    assert abs(float(w.volume) / closed - 1) < obliquity + 1e-3
    depth = np.asarray(w.depth)
    assert depth.max() / depth.min() - 1 < 0.06
    assert abs(depth.mean() * 2 * math.pi * RB * L / float(w.volume) - 1) < 1e-12  # the depth holds the volume


@pytest.mark.extended
def test_worn_profile_changes_the_next_window(tmp_path, monkeypatch):
    """Half speed: one window wears half the circumference. After one update with an
    extrapolation factor, the next run's pin sits lower by the wear depth where it presses the
    worn arc (to 10 %: the profile's 24 Fourier terms smooth the worn arc, and the pin's elastic
    settling differs slightly on the curved worn arc). Then the run resumes for a second update,
    killed once between appending its row and replacing the state (the update is listed once
    after the resume), and a corrupt or damaged state is a named error."""
    mech = rig(OMEGA / 2)
    options = jc.WearOptions(coefficient=KW, updates=1, cycles_per_update=2e4, settle=SETTLE, n_nodes=180,
                             harmonics=24)
    out = tmp_path / "wear"
    h = jc.wear(mech, SETTINGS, options, out, progress=False)
    assert h.depth.shape == (1, 180) and h.resumed_from == 0
    assert 1e-6 < h.depth[-1].max() < 0.1 * C
    worn_nodes = h.depth[-1] > 0.01 * h.depth[-1].max()
    assert 0.4 < worn_nodes.mean() < 0.6  # half the circumference
    # the pin in the worn bearing against the unworn one, mid-window
    prepared = wearing.prepare(mech, 0, 24)
    fresh, aged = jc.simulate(prepared, SETTINGS), jc.simulate(h.mechanism, SETTINGS)
    ts = np.asarray(fresh.ts)
    k = np.argmin(np.abs(ts - (SETTLE + 0.5 * T)))
    e0 = np.linalg.norm(np.asarray(fresh.ecc)[k, 0])
    e1 = np.linalg.norm(np.asarray(aged.ecc)[k, 0])
    # the bearing angle the pin presses at that time: global -90 deg minus the ring's rotation
    beta = (-math.pi / 2 - OMEGA / 2 * ts[k]) % (2 * math.pi)
    angles, growth = wearing.bearing_deviation(h.mechanism, 0, prepared, n=3600)
    local = growth[np.argmin(np.abs(angles - beta))]
    assert local > 0.5 * h.depth[-1].max()  # it presses the middle of the worn arc
    assert e1 - e0 == pytest.approx(local, rel=0.1)
    # files written as it goes
    assert [p.name for p in out.glob("profile_*.csv")] == ["profile_0000.csv"]
    # the CSV files hold numbers that read back bit for bit (not "np.float64(...)" text)
    profile = pd.read_csv(out / "profile_0000.csv")
    assert list(profile.columns) == ["angle_rad", "depth_m"] and all(profile.dtypes == np.float64)
    np.testing.assert_array_equal(profile["angle_rad"], wearing.node_angles(180))
    np.testing.assert_array_equal(profile["depth_m"], h.depth[-1])
    updates = pd.read_csv(out / "updates.csv")
    assert all(dtype.kind in "if" for dtype in updates.dtypes), updates.dtypes
    assert (out / "profile.png").stat().st_size > 10_000
    # resume for 2 updates, killed after the second's row reached updates.csv but before wear.json
    two = jc.WearOptions(**{**options.__dict__, "updates": 2})
    replace_state = wearing.service.atomic_write_json

    def killed(path, *args, **kwargs):
        raise KeyboardInterrupt  # where a SIGKILL between the two writes stops the run

    monkeypatch.setattr(wearing.service, "atomic_write_json", killed)
    with pytest.raises(KeyboardInterrupt):
        jc.wear(mech, SETTINGS, two, out, progress=False)
    assert [r.split(",")[0] for r in (out / "updates.csv").read_text().splitlines()[1:]] == ["0", "1"]
    assert len(json.loads((out / "wear.json").read_text())["updates"]) == 1
    monkeypatch.setattr(wearing.service, "atomic_write_json", replace_state)
    # the same command again runs only the second update, and lists it once
    h2 = jc.wear(mech, SETTINGS, two, out, progress=False)
    assert h2.resumed_from == 1 and h2.depth.shape == (2, 180) and h2.volume[1] > 0
    np.testing.assert_array_equal(h2.depth[:1], h.depth)
    assert np.all(h2.depth[1] >= h2.depth[0]) and np.all(np.diff(h2.service_time) > 0)
    state = json.loads((out / "wear.json").read_text())
    assert len(state["updates"]) == 2 and "wear.json" in assert_strict_json(out)
    assert [r.split(",")[0] for r in (out / "updates.csv").read_text().splitlines()[1:]] == ["0", "1"]
    # the finished history is the state, and writes the files the run wrote as it went, byte for byte
    assert h2.to_dict() == state
    again = tmp_path / "again"
    written = {p.rsplit("/", 1)[-1] for p in h2.write(again)}
    assert written == {"wear.json", "updates.csv", "profile_0000.csv", "profile_0001.csv", "profile.png"}
    for name in written - {"profile.png"}:
        assert (again / name).read_bytes() == (out / name).read_bytes(), name
    # a damaged state (a record without a key, a NaN depth, no 'updates') is an error naming the
    # file, the record and the way out, before anything is computed
    for damage, words in (
        (lambda st: st["updates"][1].pop("peak_force_n"), r"update 1 misses the key\(s\) \['peak_force_n'\]"),
        (lambda st: st["updates"][1]["depth_m"].__setitem__(3, float("nan")), r"update 1: depth_m holds a value"),
        (lambda st: st.pop("updates"), r"unreadable \(key 'updates' missing\)"),
    ):
        broken = json.loads(json.dumps(state))
        damage(broken)
        (out / "wear.json").write_text(json.dumps(broken))
        with pytest.raises(jc.CheckpointError, match=r"wear\.json.*" + words + r".*--restart"):
            jc.wear(mech, SETTINGS, two, out, progress=False)
    # a corrupt state is an error naming the file and the way out
    (out / "wear.json").write_text("{not json")
    with pytest.raises(jc.CheckpointError, match=r"wear\.json.*restart"):
        jc.wear(mech, SETTINGS, options, out, progress=False)


@pytest.mark.parametrize("change,match", [
    ({"coefficient": -1e-15}, r"wear coefficient.*allowed range"),
    ({"cycles_per_update": 0.5}, r"extrapolation factor.*allowed range"),
    ({"updates": 0}, r"updates = 0"),
    ({"n_nodes": 4}, r"n_nodes = 4"),
    ({"harmonics": 90}, r"harmonics = 90"),
    ({"settle": 1.0}, r"settle.*allowed range"),
    ({"joint": "nope"}, r"joint = 'nope'"),
])
def test_bad_wear_input_is_named(change, match):
    options = jc.WearOptions(**{"coefficient": KW, "updates": 1, **change})
    with pytest.raises(jc.ParameterError, match=match):
        jc.wear(rig(), SETTINGS, options, progress=False)


def test_wear_needs_the_hybrid_law_at_fixed_points(tmp_path, capsys):
    with pytest.raises(jc.ParameterError, match="hybrid Gauss-point law"):
        jc.wear(jc.preset("flores-slider-crank"), SETTINGS, jc.WearOptions(coefficient=KW, updates=1), progress=False)
    assert main(["wear", "--model", "lankarani-nikravesh", "--out", str(tmp_path)]) == 2
    assert "--model hybrid" in capsys.readouterr().err
    assert main(["wear", "--wear-coefficient", "-1", "--out", str(tmp_path)]) == 2
    assert "argument --wear-coefficient" in capsys.readouterr().err
    assert main(["wear", "--harmonics", "90", "--out", str(tmp_path)]) == 2
    assert "--harmonics 90 is outside the allowed range" in capsys.readouterr().err


def test_the_command_prints_the_history_summary(tmp_path, monkeypatch, capsys):
    """``jaxclear wear`` prints the result's summary() (the run itself stands in: a hand-made history)."""
    from test_results_protocol import _wear_history

    import jaxclear.cli.wear as cli_wear

    h = _wear_history()
    monkeypatch.setattr(cli_wear, "wear", lambda *args, **kwargs: h)
    assert main(["wear", "--updates", "2", "--out", str(tmp_path / "w")]) == 0
    out = capsys.readouterr().out
    assert "\n".join("  " + line for line in h.summary().splitlines()) in out and "written to" in out


class _Stop(Exception):
    pass


def test_wear_runs_with_step_onsets_and_the_command_refuses_exact_ones(tmp_path, monkeypatch, capsys):
    """Wear's windows run with step onsets (``wearing.service.ONSETS_WHY``): the default exact
    onsets of ``Settings`` (which cannot be told apart from asked ones) are replaced, another
    strategy is used as given; ``jaxclear wear --onsets exact`` is an error naming the option,
    the allowed value and why, ``--onsets step`` reaches the run."""
    import jaxclear.cli.wear as cli_wear

    seen = []

    def window(mech, settings, *args):
        seen.append(settings.onsets)
        raise _Stop

    monkeypatch.setattr(wearing.service, "_window", window)
    options = jc.WearOptions(coefficient=KW, updates=1, settle=SETTLE)
    for given in (SETTINGS, jc.settings(SETTLE + T, n_out=1801, allow_free_dof=True, onsets="exact")):
        assert given.onsets == jc.ExactOnsets()
        with pytest.raises(_Stop):
            jc.wear(rig(), given, options, progress=False)
        assert seen[-1] == jc.StepOnsets()

    class Mine(jc.StepOnsets):
        """A user's onsets strategy (here: step onsets under another name)."""

    with pytest.raises(_Stop):
        jc.wear(rig(), jc.settings(SETTLE + T, n_out=1801, allow_free_dof=True, onsets=Mine()), options, progress=False)
    assert type(seen[-1]) is Mine
    # the command line
    assert main(["wear", "--onsets", "exact", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--onsets exact: jaxclear wear runs with step onsets (--onsets step, the only allowed value" in err
    assert "Gauss points" in err
    got = []
    monkeypatch.setattr(cli_wear, "wear", lambda mech, s, *args, **kwargs: got.append(s.onsets) or _raise(_Stop()))
    with pytest.raises(_Stop):
        main(["wear", "--onsets", "step", "--updates", "1", "--out", str(tmp_path / "w")])
    assert got == [jc.StepOnsets()]


def _raise(err):
    raise err
