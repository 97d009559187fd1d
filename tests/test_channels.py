"""Named output channels against closed forms: a crank driven at constant speed under gravity
(centripetal point acceleration, an accelerometer in the crank's frame, the pin reaction and the
driving torque from Newton-Euler), central differences on a four-bar, name errors, traceability,
and ``simulate --output``."""

import csv
import math
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.analysis import channels as ch
from jaxclear.cli import main

ROOT = Path(__file__).resolve().parents[1]
L, M, W, PHI0, G = 0.2, 1.5, 30.0, 0.4, 9.81


@pytest.fixture(scope="module")
def crank():
    body = jc.Body("crank", M, M * L**2 / 12, {"O": (-L / 2, 0.0), "A": (L / 2, 0.0)},
                   position=(L / 2 * math.cos(PHI0), L / 2 * math.sin(PHI0), PHI0))
    mech = jc.Mechanism([body], [jc.Revolute(jc.GROUND, "O", "crank", "O")], [jc.AngleDriver("crank", W, PHI0)],
                        gravity=(0.0, -G), ground_points={"O": (0.0, 0.0)}, name="crank")
    sol = jc.simulate(mech, jc.settings(0.1, n_out=2001, rtol=1e-10, atol=1e-12))
    return mech, sol


def test_crank_closed_forms(crank):
    mech, sol = crank
    t = np.asarray(sol.ts)
    phi = PHI0 + W * t
    e = np.stack([np.cos(phi), np.sin(phi)], 1)
    get = lambda name: np.asarray(ch.channel(mech, sol, name))  # noqa: E731
    tol = 1e-6  # relative; Baumgarte-stabilized constraints at rtol 1e-10
    # angle and speed of the driven body
    np.testing.assert_allclose(get("body:crank:phi:vel"), W, rtol=tol)
    # centripetal acceleration of A: -w^2 L e (global), (-w^2 L, 0) in the crank's frame
    np.testing.assert_allclose(get("point:crank:A:acc:x"), -W**2 * L * e[:, 0], atol=tol * W**2 * L)
    np.testing.assert_allclose(get("point:crank:A:acc:x:frame=crank"), -W**2 * L, rtol=tol)
    np.testing.assert_allclose(get("point:crank:A:acc:y:frame=crank"), 0.0, atol=tol * W**2 * L)
    np.testing.assert_allclose(get("point:crank:A:acc:norm"), W**2 * L, rtol=tol)
    # an accelerometer (specific force a - g) at the pivot reads -g in the crank's axes: +g "up"
    np.testing.assert_allclose(get("point:crank:O:acc:x:frame=crank:specific"), G * np.sin(phi), atol=1e-5)
    np.testing.assert_allclose(get("point:crank:O:acc:y:frame=crank:specific"), G * np.cos(phi), atol=1e-5)
    # Newton: pin force on the crank F = m (a_G - g), a_G = -w^2 (L/2) e
    f = M * (-W**2 * L / 2 * e - np.array([0.0, -G]))
    np.testing.assert_allclose(get("reaction:0:x"), f[:, 0], atol=tol * np.abs(f).max())
    np.testing.assert_allclose(get("reaction:Revolute(ground-crank):y:on=crank"), f[:, 1], atol=tol * np.abs(f).max())
    # Euler about G with alpha = 0: tau + (r_O - r_G) x F = 0, r_O - r_G = -(L/2) e
    arm = -L / 2 * e
    tau = -(arm[:, 0] * f[:, 1] - arm[:, 1] * f[:, 0])
    np.testing.assert_allclose(get("reaction:1:moment"), tau, atol=tol * np.abs(tau).max())
    # the pin force in the crank's frame: radial component only plus gravity's share
    fx_body = f[:, 0] * np.cos(phi) + f[:, 1] * np.sin(phi)
    np.testing.assert_allclose(get("reaction:0:x:frame=crank"), fx_body, atol=tol * np.abs(f).max())


def test_crank_point_kinematics_match_central_differences(crank):
    mech, sol = crank
    t = np.asarray(sol.ts)
    for comp in ("x", "y"):
        pos, vel, acc = (np.asarray(ch.channel(mech, sol, f"point:crank:A:{d}:{comp}")) for d in ("pos", "vel", "acc"))
        # central differences, h = 5e-5 s: relative error ~ (h w)^2 / 6 = 4e-7
        np.testing.assert_allclose(np.gradient(vel, t)[2:-2], acc[2:-2], atol=1e-5 * np.abs(acc).max())
        np.testing.assert_allclose(np.gradient(pos, t)[2:-2], vel[2:-2], atol=1e-5 * np.abs(vel).max())


@pytest.mark.slow
def test_point_acceleration_matches_central_differences():
    mech = jc.preset("four-bar", ideal=True)
    sol = jc.simulate(mech, jc.settings(0.01, n_out=1001, rtol=1e-10, atol=1e-12))
    t = np.asarray(sol.ts)
    for comp in ("x", "y"):
        vel = np.asarray(ch.channel(mech, sol, f"point:coupler:B:vel:{comp}"))
        acc = np.asarray(ch.channel(mech, sol, f"point:coupler:B:acc:{comp}"))
        pos = np.asarray(ch.channel(mech, sol, f"point:coupler:B:pos:{comp}"))
        # second-order central differences, h = 1e-5 s: error ~ h^2 |a'''| / 6, far below 1e-5 relative
        np.testing.assert_allclose(np.gradient(vel, t)[2:-2], acc[2:-2], atol=1e-5 * np.abs(acc).max())
        np.testing.assert_allclose(np.gradient(pos, t)[2:-2], vel[2:-2], atol=1e-5 * np.abs(vel).max())


def test_channels_are_traceable(crank):
    mech, sol = crank
    f = jax.jit(lambda s: ch.channel(mech, s, "point:crank:A:acc:x:frame=crank"))
    np.testing.assert_allclose(np.asarray(f(sol)), -W**2 * L, rtol=1e-6)


@pytest.mark.parametrize("name, words", [
    ("bodies:crank:phi", ["first field", "body"]),
    ("body:crank:theta", ["body:BODY:x|y|phi"]),
    ("body:arm:phi", ["unknown body 'arm'", "crank"]),
    ("point:crank:Z:acc", ["'Z'", "['A', 'O']"]),
    ("point:crank:A:acc:z", ["component 'z'", "norm"]),
    ("point:crank:A:jerk", ["pos|vel|acc"]),
    ("point:crank:A:vel:x:specific", ["acc only"]),
    ("reaction:7", ["outside [0, 1]", "AngleDriver"]),
    ("reaction:0:x:on=ground", ["acts on ['crank']"]),
    ("joint:0:penetration", ["no clearance joint"]),
    ("body:crank:phi:acc:frame=crank", ["unknown option"]),
])
def test_bad_names_are_clear_errors(crank, name, words):
    mech, _ = crank
    with pytest.raises(jc.JaxclearError) as err:
        ch.unit(mech, name)
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_default_channels_follow_roles():
    assert ch.default_channels(jc.preset("four-bar"))[-1] == "body:rocker:phi:acc"
    assert ch.default_channels(jc.preset("flores-slider-crank"))[-1] == "body:slider:x:acc"
    assert ch.default_channels(jc.load_mechanism(ROOT / "examples" / "pendulum.toml"))[0] == "body:bar:phi:pos"


def test_simulate_output_option(tmp_path, capsys):
    code = main(["simulate", str(ROOT / "examples" / "pendulum.toml"), "--t-end", "0.01", "--n-out", "11",
                 "--restitution", "0.5",
                 "--output", "body:bar:phi:acc,joint:pivot:normal_force", "--output", "point:bar:tip:acc:y:frame=bar",
                 "--no-plots", "--no-progress", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    assert "c_r = 0.5" in capsys.readouterr().out  # --restitution applied to the file's joint
    with open(tmp_path / "timeseries.csv", newline="") as fh:
        header = next(csv.reader(fh))
    assert header == ["time_s", "body:bar:phi:acc [rad/s^2]", "body:bar:phi:acc:ideal [rad/s^2]",
                      "joint:pivot:normal_force [N]", "point:bar:tip:acc:y:frame=bar [m/s^2]",
                      "point:bar:tip:acc:y:frame=bar:ideal [m/s^2]"]
    assert main(["simulate", str(ROOT / "examples" / "pendulum.toml"), "--t-end", "0.01", "--output", "body:x",
                 "--out", str(tmp_path)]) == 2
    assert "output channel 'body:x'" in capsys.readouterr().err
