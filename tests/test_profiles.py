"""Time profiles of drivers and loads (jaxclear.model.profiles), in Python and in mechanism
files: each profile against its closed form written out here (ramp, harmonic) or SciPy's own
PCHIP evaluation and quadrature (table); a driven crank following the prescribed angle; the
crank period of a constant-speed crank (host, traced, its derivative); files
read back equal; bad input named by key with the allowed range; the drawing of jaxclear check."""

from __future__ import annotations

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.interpolate import PchipInterpolator

import jaxclear as jc
from jaxclear.cli import main
from jaxclear.integrate._kinematics import kinematic_solution
from jaxclear.mechanism_files import dumps_mechanism, loads_mechanism

T = jnp.linspace(0.0, 0.03, 61)


def _all(fn):
    return np.asarray(jax.vmap(fn)(T))


def test_ramp_closed_form():
    """Cubic smooth step v0 (3 tau^2 - 2 tau^3), its integral v0 T (tau^3 - tau^4/2) then
    v0 (t - T/2), its slope 6 v0 tau (1 - tau)/T (1e-12: closed forms on both sides)."""
    v0, ramp = 523.6, 0.01
    p = jc.RampProfile(v0, ramp)
    t = np.asarray(T)
    tau = np.clip(t / ramp, 0, 1)
    np.testing.assert_allclose(_all(p.value), v0 * (3 * tau**2 - 2 * tau**3), rtol=1e-12, atol=1e-9)
    angle = np.where(t <= ramp, v0 * ramp * (tau**3 - tau**4 / 2), v0 * (t - ramp / 2))
    np.testing.assert_allclose(_all(p.integral), angle, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(_all(p.derivative), 6 * v0 * tau * (1 - tau) / ramp, rtol=1e-12, atol=1e-6)


def test_harmonic_closed_form_and_derivatives():
    """v0 + a sin(2 pi f t + psi): the integral against quad, value and slope by hand; jax.grad of
    the integral is the value and of the value the slope (1e-10)."""
    p = jc.HarmonicProfile(300.0, 20.0, 50.0, 0.4)
    t = np.asarray(T)
    np.testing.assert_allclose(_all(p.value), 300 + 20 * np.sin(2 * math.pi * 50 * t + 0.4), rtol=1e-12)
    np.testing.assert_allclose(_all(p.derivative), 20 * 2 * math.pi * 50 * np.cos(2 * math.pi * 50 * t + 0.4),
                               rtol=1e-12, atol=1e-9)
    ref = [quad(lambda s: 300 + 20 * math.sin(2 * math.pi * 50 * s + 0.4), 0, x, epsabs=1e-13)[0] for x in t]
    np.testing.assert_allclose(_all(p.integral), ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(_all(jax.grad(p.integral)), _all(p.value), rtol=1e-10)
    np.testing.assert_allclose(_all(jax.grad(p.value)), _all(p.derivative), rtol=1e-10, atol=1e-6)


def test_table_is_scipys_pchip_and_holds_its_end_value():
    """The table's value and slope equal SciPy's PchipInterpolator (1e-12), its integral SciPy's
    antiderivative (1e-12) and quadrature (1e-10, split at the knots); after the last point the value is held (slope 0, integral linear);
    monotone data give a monotone speed (no overshoot)."""
    t_k, v_k = [0.0, 0.005, 0.01, 0.02], [0.0, 150.0, 420.0, 520.0]
    p = jc.TableProfile(t_k, v_k)
    ref = PchipInterpolator(t_k, v_k)
    t = np.asarray(T)
    inside = t <= 0.02
    np.testing.assert_allclose(_all(p.value)[inside], ref(t[inside]), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(_all(p.derivative)[inside], ref.derivative()(t[inside]), rtol=1e-12, atol=1e-6)
    anti = ref.antiderivative()
    ints = [anti(min(x, 0.02)) + 520.0 * max(x - 0.02, 0.0) for x in t]
    np.testing.assert_allclose(_all(p.integral), ints, rtol=1e-12, atol=1e-15)
    ints = [quad(ref, 0, min(x, 0.02), points=t_k[1:-1], epsabs=1e-14, epsrel=1e-13)[0] + 520.0 * max(x - 0.02, 0.0)
            for x in t]
    np.testing.assert_allclose(_all(p.integral), ints, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(_all(p.value)[~inside], 520.0, rtol=1e-12)
    assert np.all(_all(p.derivative)[~inside] == 0.0)
    assert np.all(np.diff(_all(p.value)) >= -1e-9)


@pytest.mark.parametrize("make,match", [
    (lambda: jc.RampProfile(100.0, 0.0), r"ramp_time.*\(0, inf\) s"),
    (lambda: jc.HarmonicProfile(1.0, 0.1, -2.0), r"frequency.*\(0, inf\) Hz"),
    (lambda: jc.TableProfile([0.0, 0.02, 0.01], [0, 1, 2]), "start at 0 s and increase strictly"),
    (lambda: jc.TableProfile([0.01, 0.02], [0, 1]), "start at 0 s"),
    (lambda: jc.TableProfile([0.0], [1.0]), "same length >= 2"),
    (lambda: jc.ConstantProfile(float("nan")), "value"),
    (lambda: jc.ProfileDriver("crank", 5.0), "time profile"),
])
def test_bad_profiles_are_named(make, match):
    with pytest.raises(jc.ParameterError, match=match):
        make()


def _driven(profile):
    mech = jc.preset("flores-slider-crank", ideal=True)
    return eqx_tree_drivers(mech, (jc.ProfileDriver("crank", profile),))


def eqx_tree_drivers(mech, drivers):
    import equinox as eqx

    return eqx.tree_at(lambda m: m.drivers, mech, drivers)


def test_driven_crank_follows_the_ramp():
    """The ideal slider-crank driven by a ramp-up to 5000 rpm over 10 ms: the crank's angle,
    speed and acceleration at every sample are the profile's (1e-9 rad, the assembly's Newton
    tolerance; the speed and acceleration from the exact derivatives of the constraint)."""
    prof = jc.RampProfile(5000 * 2 * math.pi / 60, 0.01)
    mech = _driven(prof)
    sol = kinematic_solution(mech, jc.settings(0.02, n_out=41))
    assert int(sol.status) == 0
    t = sol.ts
    np.testing.assert_allclose(sol.coordinate(mech, "crank", "phi"), jax.vmap(prof.integral)(t), atol=1e-9)
    np.testing.assert_allclose(sol.coordinate(mech, "crank", "phi", 1), jax.vmap(prof.value)(t), rtol=1e-8, atol=1e-7)
    np.testing.assert_allclose(sol.coordinate(mech, "crank", "phi", 2), jax.vmap(prof.derivative)(t), rtol=1e-7,
                               atol=1e-3)



def test_crank_period_on_the_host_traced_and_named():
    """jc.crank_period (jaxclear.model.drivers), the one crank period T = N 2 pi/|omega| [s]: on
    the host the float written out before; under jax.jit and jax.vmap the same numbers; under
    jax.grad dT/domega = -2 pi/omega^2 (omega > 0, the closed form at rtol 1e-12); a named
    ParameterError for a mechanism without a crank driver (a speed profile: no constant period)
    and for a crank at rest."""
    from jaxclear import params
    from jaxclear.model import crank_driver

    mech = jc.preset("flores-slider-crank", ideal=True)
    w = float(crank_driver(mech)[1].speed)
    assert float(jc.crank_period(mech)) == 2.0 * math.pi / abs(w)
    assert float(jc.crank_period(mech, 3)) == 3 * 2.0 * math.pi / abs(w)
    assert float(jc.crank_period(params.replace(mech, "speed", -w))) == 2.0 * math.pi / abs(w)

    def period(v):
        return jc.crank_period(params.replace(mech, "speed", v))

    assert float(jax.jit(period)(w)) == float(jc.crank_period(mech))
    np.testing.assert_allclose(np.asarray(jax.vmap(period)(jnp.array([10.0, -20.0]))),
                               2.0 * math.pi / np.array([10.0, 20.0]), rtol=1e-15)
    for v in (w, 12.5, 1.0e3):
        np.testing.assert_allclose(float(jax.grad(period)(v)), -2.0 * math.pi / v**2, rtol=1e-12)
        np.testing.assert_allclose(float(jax.jit(jax.grad(period))(v)), -2.0 * math.pi / v**2, rtol=1e-12)
    with pytest.raises(jc.ParameterError, match="has no crank driver"):
        jc.crank_period(_driven(jc.RampProfile(100.0, 0.01)))
    with pytest.raises(jc.ParameterError, match="speed is 0 rad/s"):
        jc.crank_period(params.replace(mech, "speed", 0.0))

PROFILE_TEXT = '''
[drivers.profile]
kind = "{kind}"
{body}
'''


def _file_text(profile_body: str, kind: str, load: str = "") -> str:
    text = dumps_mechanism(jc.preset("flores-slider-crank"))
    text = re.sub(r'type = "angle"\nbody = "crank"\nspeed = [0-9.e+-]+\n(.*?)\n\n',
                  lambda m: 'type = "speed-profile"\nbody = "crank"\n' + m.group(1) + "\n"
                  + PROFILE_TEXT.format(kind=kind, body=profile_body) + "\n", text, count=1, flags=re.S)
    return text.replace("[[clearance_joints]]", load + "[[clearance_joints]]", 1)


TORQUE = '''[[loads]]
type = "torque"
body = "crank"
torque = 2.0

[loads.profile]
kind = "harmonic"
value = 1.0
amplitude = 0.5
frequency = 200.0
phase = 0.0

'''


def test_file_profiles_read_write_and_csv(tmp_path):
    """A ramp in rpm, a harmonic torque factor and a CSV table (relative to the file's folder,
    header row) read as the profiles, and a file written back reads equal."""
    mech = loads_mechanism(_file_text("value = 5000\nunit = \"rpm\"\nramp_time = 0.01", "ramp", TORQUE))
    d, load = mech.drivers[0], mech.loads[0]
    assert isinstance(d, jc.ProfileDriver) and isinstance(d.profile, jc.RampProfile)
    assert float(d.profile.value0) == pytest.approx(5000 * 2 * math.pi / 60, rel=1e-15)
    assert isinstance(load.profile, jc.HarmonicProfile) and float(load.torque) == 2.0
    back = loads_mechanism(dumps_mechanism(mech))
    assert float(back.drivers[0].profile.ramp_time) == 0.01 and float(back.loads[0].profile.frequency) == 200.0
    (tmp_path / "speed.csv").write_text("time_s,speed_rpm\n0,0\n0.01,3000\n0.02,5000\n")
    path = tmp_path / "m.toml"
    path.write_text(_file_text('file = "speed.csv"\nunit = "rpm"', "table"))
    table = jc.load_mechanism(path).drivers[0].profile
    np.testing.assert_allclose(np.asarray(table.values), np.array([0, 3000, 5000]) * 2 * math.pi / 60, rtol=1e-15)
    again = loads_mechanism(dumps_mechanism(jc.load_mechanism(path)))
    np.testing.assert_array_equal(np.asarray(again.drivers[0].profile.time), [0, 0.01, 0.02])


@pytest.mark.parametrize("body,kind,words", [
    ("value = 100", "sinus", ["drivers[0].profile.kind", "'sinus'", "allowed", "harmonic", "table"]),
    ("value = 100\nramp_time = -0.01", "ramp", ["drivers[0].profile", "ramp_time", "(0, inf) s"]),
    ('value = "100 * 2"', "constant", ["drivers[0].profile.value", "must be a number"]),
    ("value = 100\nunit = \"rps\"", "constant", ["drivers[0].profile.unit", "'rps'", "'rpm'"]),
    ("value = 100\nspeed = 3", "constant", ["drivers[0].profile.speed", "unknown key"]),
    ("time = [0, 0.01]", "table", ["drivers[0].profile.values", "needs time and values"]),
    ("time = [0, 0.02, 0.01]\nvalues = [0, 1, 2]", "table", ["drivers[0].profile", "increase strictly"]),
    ('file = "missing.csv"', "table", ["drivers[0].profile.file", "does not exist"]),
])
def test_bad_file_profiles_name_key_and_range(tmp_path, body, kind, words):
    path = tmp_path / "bad.toml"
    path.write_text(_file_text(body, kind))
    with pytest.raises((jc.ParameterError, jc.MechanismError)) as err:
        jc.load_mechanism(path)
    message = str(err.value)
    assert str(path) in message and "Traceback" not in message
    for w in words:
        assert w in message, (w, message)


def test_check_draws_the_profiles(tmp_path, capsys):
    """jaxclear check writes profiles.png (a PNG) for a file with a profile driver and a profiled
    load, and none for a file without profiles."""
    path = tmp_path / "m.toml"
    path.write_text(_file_text("value = 5000\nunit = \"rpm\"\nramp_time = 0.01", "ramp", TORQUE))
    assert main(["check", str(path), "--out", str(tmp_path / "out")]) == 0
    png = tmp_path / "out" / "profiles.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "profiles.png" in capsys.readouterr().out
    assert main(["check", "--preset", "four-bar", "--out", str(tmp_path / "plain")]) == 0
    assert not (tmp_path / "plain" / "profiles.png").exists()
