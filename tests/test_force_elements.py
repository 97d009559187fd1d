"""Force elements among the loads (springs, dampers, bushings; issue 43 items 1-2) against closed
forms. Every run is float64 at rtol 1e-10 unless said; each tolerance says where its size comes
from."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.analysis.channels import channel
from jaxclear.mechanism_files import loads_mechanism

M, K, C, L0 = 2.0, 800.0, 4.0, 0.5  # kg, N/m, N s/m, m
TIGHT = dict(rtol=1e-10, atol=1e-13, allow_free_dof=True)


def oscillator(stiffness=K, damping=C, preload=0.0, y0=-(L0 + 0.01), gravity=0.0, curve=None):
    """A block on a vertical guide hung from the ground point O by a spring-damper (1 dof: y)."""
    block = jc.Body("block", M, 0.01, points={"P": (0.0, 0.0)}, position=(0.0, y0, 0.0))
    guide = jc.Translational("ground", "O", "block", "P", axis=(0.0, 1.0))
    spring = jc.TranslationalSpringDamper("s", "ground", "O", "block", "P", stiffness=stiffness, damping=damping,
                                          rest_length=L0, preload=preload, curve=curve)
    return jc.Mechanism([block], joints=[guide], loads=[spring], ground_points={"O": (0.0, 0.0)},
                        gravity=(0.0, -gravity), name="oscillator")


#: Samples of the oscillator's runs below (five damped periods at 400 a period): one compiled
#: program for all of them (their spans differ only in t_end, a traced value).
SAMPLES = 5 * 400 + 1


def crossings(t, x):
    """Times where ``x`` changes sign (linear interpolation between samples)."""
    i = np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def test_mass_on_a_spring_damper_has_the_closed_form_frequency_and_logarithmic_decrement():
    """Damped natural frequency omega_d = omega_n sqrt(1 - zeta^2) and logarithmic decrement
    delta = 2 pi zeta / sqrt(1 - zeta^2) of m x'' + c x' + k x = 0 (omega_n = 20 rad/s, zeta =
    0.05). The frequency from 9 zero crossings: linear interpolation between samples 1/400 of a
    period apart errs by about (h^2/8) |x''/x'| at a crossing, where x'' = -2 zeta omega x' (2e-8 of
    a period), so 1e-6. The decrement from x(t)/x(t + T_d) = exp(-zeta omega_n T_d), exact for
    the free damped response at every t: samples a damped period apart, errors of the run only
    (rtol 1e-10 on amplitudes down to 1e-3 of the start), so 1e-6."""
    wn, zeta = np.sqrt(K / M), C / (2 * np.sqrt(K * M))
    wd = wn * np.sqrt(1 - zeta**2)
    td = 2 * np.pi / wd
    n_per = 400
    mech = oscillator()
    sol = jc.simulate(mech, jc.settings(5 * td, n_out=SAMPLES, **TIGHT))
    assert int(sol.status) == 0
    t, x = np.asarray(sol.ts), np.asarray(sol.q[:, 1]) + L0  # deflection from the rest length
    zeros = crossings(t, x)
    assert len(zeros) >= 9
    period = 2 * np.mean(np.diff(zeros))
    assert period == pytest.approx(td, rel=1e-6)
    ratio = x[:-n_per] / x[n_per:]
    keep = np.abs(x[n_per:]) > 1e-3 * np.abs(x).max()
    delta = np.log(ratio[keep])
    assert delta == pytest.approx(2 * np.pi * zeta / np.sqrt(1 - zeta**2), rel=1e-6)
    # the whole response against the closed form x(t) = e^{-zeta wn t}(x0 cos wd t + zeta wn x0/wd sin wd t)
    x0 = -0.01
    exact = np.exp(-zeta * wn * t) * (x0 * np.cos(wd * t) + zeta * wn * x0 / wd * np.sin(wd * t))
    np.testing.assert_allclose(x, exact, rtol=0, atol=1e-10)  # 1e-8 of the 1e-2 m amplitude (1e-11 measured)
    # the channels: length, rate, tension and power as the formulas give them
    length = np.asarray(channel(mech, sol, "load:s:length"))
    rate = np.asarray(channel(mech, sol, "load:s:rate"))
    np.testing.assert_allclose(length, -np.asarray(sol.q[:, 1]), rtol=1e-14)
    np.testing.assert_allclose(rate, -np.asarray(sol.qdot[:, 1]), rtol=0, atol=1e-14)
    force = np.asarray(channel(mech, sol, "load:s:force"))
    np.testing.assert_allclose(force, K * (length - L0) + C * rate, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(channel(mech, sol, "load:0:power")), -force * rate, rtol=0, atol=1e-12)


def pendulum(kt=3.0, ct=0.0, angle=0.0, l=0.3, m=1.5, j=0.02, g=9.81):
    """A rod pinned at its end A to the ground point O, its centroid l below A at rest, with a
    torsional spring between the ground and the rod."""
    rod = jc.Body("rod", m, j, points={"A": (0.0, l)}, position=(l * np.sin(angle), -l * np.cos(angle), angle))
    pin = jc.Revolute("ground", "O", "rod", "A")
    spring = jc.RotationalSpringDamper("t", "ground", "rod", stiffness=kt, damping=ct, drawn_at="A")
    return jc.Mechanism([rod], joints=[pin], loads=[spring], ground_points={"O": (0.0, 0.0)}, gravity=(0.0, -g),
                        name="pendulum")


def test_pendulum_with_a_torsional_spring_has_the_small_angle_frequency():
    """omega^2 = (k_t + m g l)/(J + m l^2) for small angles. At an amplitude of 1e-3 rad the
    nonlinear period shift is about theta^2/16 (gravity's part; the spring is linear), 6e-8; the
    crossing interpolation (400 samples a period) is below 1e-7: tolerance 1e-6."""
    kt, l, m, j, g = 3.0, 0.3, 1.5, 0.02, 9.81
    w = np.sqrt((kt + m * g * l) / (j + m * l**2))
    mech = pendulum(kt=kt, angle=1e-3, l=l, m=m, j=j, g=g)
    period = 2 * np.pi / w
    sol = jc.simulate(mech, jc.settings(6 * period, n_out=6 * 400 + 1, **TIGHT))
    phi = np.asarray(channel(mech, sol, "load:t:angle"))
    np.testing.assert_array_equal(phi, np.asarray(sol.q[:, 2]))
    zeros = crossings(np.asarray(sol.ts), phi)
    assert 2 * np.mean(np.diff(zeros)) == pytest.approx(period, rel=1e-6)
    np.testing.assert_allclose(np.asarray(channel(mech, sol, "load:t:moment")), kt * phi, rtol=1e-14, atol=1e-18)


def simpson(t, y):
    """Composite Simpson integral of samples at equal spacing (an odd count)."""
    h = t[1] - t[0]
    return h / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


def test_energy_balance_with_the_dissipated_work_of_all_three_elements():
    """A free body (no joints) under gravity held by a spring-damper with preload and a cubic
    curve, a rotational spring-damper and a bushing, all to the ground: kinetic + gravity +
    stored energy + dissipated work is constant, the stored energy in closed form (F0 x + k x^2/2 +
    a3 x^4/4; k_t theta^2/2; d^T K d / 2 with d in the ground's frame) and the dissipation the
    integral of c Ldot^2 + c_t thetadot^2 + ddot^T C ddot (Simpson on 4001 samples: error
    h^4/180 max|f''''| below 1e-9 of the scale). Also the element's power channels: the sum of
    their integrals is the change of kinetic + gravity energy. Tolerance 1e-8 of the energy that
    moves (1.66 J, of which 1.43 J dissipated in 1 s; measured: 2.5e-10 J)."""
    mech = three_elements()
    sol = jc.simulate(mech, jc.settings(1.0, n_out=4001, **TIGHT))
    assert int(sol.status) == 0
    t = np.asarray(sol.ts)
    ch = {n: np.asarray(channel(mech, sol, f"load:{n}")) for n in (
        "s:length", "s:rate", "s:power", "t:angle", "t:rate", "t:power", "u:dx", "u:dy", "u:angle",
        "u:rate_x", "u:rate_y", "u:rate_angle", "u:power")}
    x = ch["s:length"] - 0.2
    stored = (4.0 * x + 150.0 * x**2 + 2e4 * x**4 / 4 + 1.0 * (ch["t:angle"] - 0.1) ** 2
              + 0.5 * (500.0 * ch["u:dx"] ** 2 + 800.0 * ch["u:dy"] ** 2 + 1.0 * ch["u:angle"] ** 2))
    rate = 1.5 * ch["s:rate"] ** 2 + 0.01 * ch["t:rate"] ** 2 + (
        2.0 * ch["u:rate_x"] ** 2 + 3.0 * ch["u:rate_y"] ** 2 + 0.005 * ch["u:rate_angle"] ** 2)
    dissipated = np.array([0.0] + [simpson(t[: 2 * k + 1], rate[: 2 * k + 1]) for k in range(1, len(t) // 2 + 1)])
    motion = np.array([float(jc.energy(mech, q, qd)) for q, qd in zip(sol.q[::2], sol.qdot[::2])])
    total = motion + stored[::2] + dissipated
    scale = np.ptp(motion)
    assert scale > 1.0 and dissipated[-1] > 0.1 * scale  # the balance is not trivially kept
    np.testing.assert_allclose(total, total[0], rtol=0, atol=1e-8 * scale)
    power = ch["s:power"] + ch["t:power"] + ch["u:power"]
    work = np.array([0.0] + [simpson(t[: 2 * k + 1], power[: 2 * k + 1]) for k in range(1, len(t) // 2 + 1)])
    np.testing.assert_allclose(motion - motion[0], work, rtol=0, atol=1e-8 * scale)


def test_a_preloaded_spring_holds_the_block_at_the_static_equilibrium():
    """A block hung on a spring with preload F0 under gravity rests at L = L0 + (m g - F0)/k, where
    the tension is m g; started there it stays (drift of the run at rtol 1e-10: 1e-12 m). A
    preload larger than the weight lifts the equilibrium above the rest length."""
    g = 9.81
    for f0 in (5.0, 30.0):
        length = L0 + (M * g - f0) / K
        mech = oscillator(preload=f0, y0=-length, gravity=g)
        sol = jc.simulate(mech, jc.settings(0.5, n_out=SAMPLES, **TIGHT))
        np.testing.assert_allclose(np.asarray(sol.q[:, 1]), -length, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(channel(mech, sol, "load:s:force")), M * g, rtol=1e-10)
    assert length < L0


def test_derivative_with_respect_to_a_spring_constant_against_central_differences():
    """d y(t_end)/d k and d y(t_end)/d c by the error-controlled sensitivities against central
    differences of runs at rtol 1e-10 (step 1e-4 of the value: truncation h^2/6 times the third
    derivative, about 1e-9 relative; the runs' errors, 1e-12 m on y ~ 1e-2 m, over a difference
    of 5e-6 m: 2e-7): to 1e-6 relative (measured 2.5e-8 and 3.4e-9)."""
    mech = oscillator()
    s = jc.settings(0.4, n_out=2, **TIGHT)
    runs = jc.settings(0.4, n_out=SAMPLES, **TIGHT)  # (the same end state as on 2 samples)

    def y_end(m):
        return float(jc.simulate(m, runs).q[-1, 1])

    _, d = jc.sensitivities(mech, ["spring_stiffness:s", "spring_damping:s"], s,
                            output=lambda sol, m: sol.q[-1, 1])
    for name, h in (("spring_stiffness:s", 1e-4 * K), ("spring_damping:s", 1e-4 * C)):
        v = jc.params.get(mech, name)
        fd = (y_end(jc.params.replace(mech, name, v + h)) - y_end(jc.params.replace(mech, name, v - h))) / (2 * h)
        assert abs(fd) > 1e-6
        assert float(d[name]) == pytest.approx(fd, rel=1e-6)


def test_nonlinear_curves_add_their_force_to_the_linear_tension():
    """The table curve of a cubic's samples is its PCHIP interpolant (exact at the points,
    continuous slope, the end tangent beyond); the polynomial is evaluated by Horner."""
    poly = jc.PolynomialCurve([10.0, 0.0, 3e4])
    x = jnp.linspace(-0.02, 0.02, 9)
    np.testing.assert_allclose(np.asarray(jnp.stack([poly.force(v) for v in x])), 10 * x + 3e4 * x**3, rtol=1e-14)
    pts = np.linspace(-0.01, 0.01, 11)
    table = jc.TableCurve(pts, 10 * pts + 3e4 * pts**3)
    np.testing.assert_allclose([float(table.force(v)) for v in pts], 10 * pts + 3e4 * pts**3, rtol=1e-12, atol=1e-14)
    end_slope = 10 + 9e4 * 0.01**2
    beyond = float(table.force(0.02))
    assert beyond == pytest.approx(float(table.force(0.01)) + 0.01 * end_slope, rel=0.05)
    with pytest.raises(jc.ParameterError, match="deflection must increase strictly"):
        jc.TableCurve([0.0, 0.0], [1.0, 2.0])
    mech = oscillator(curve=table)
    sol = jc.simulate(mech, jc.settings(0.05, n_out=6, **TIGHT))
    length = np.asarray(channel(mech, sol, "load:s:length"))
    rate = np.asarray(channel(mech, sol, "load:s:rate"))
    want = K * (length - L0) + C * rate + np.array([float(table.force(v)) for v in length - L0])
    np.testing.assert_allclose(np.asarray(channel(mech, sol, "load:s:force")), want, rtol=1e-12)


@pytest.mark.parametrize("kwargs, said", [
    (dict(stiffness=-1.0), r"stiffness \(spring_stiffness:s\) = -1 N/m is outside the allowed range \[0, inf\)"),
    (dict(damping=float("nan")), r"damping \(spring_damping:s\) must be finite"),
    (dict(rest_length=-0.1), r"rest_length \(spring_length:s\) = -0.1 m is outside"),
    (dict(curve="cubic"), r"curve must be a force-deflection curve"),
])
def test_bad_spring_numbers_are_named_with_their_range(kwargs, said):
    with pytest.raises(jc.ParameterError, match=said):
        jc.TranslationalSpringDamper("s", "ground", "O", "block", "P", **kwargs)


def test_a_traced_bad_constant_is_the_run_status_and_named_eagerly():
    """A constant set by params.replace is not checked there (it may be traced): the run's
    status is invalid_parameter and Mechanism.failed_check names it."""
    mech = jc.params.replace(oscillator(), "spring_damping:s", -2.0)
    sol = jc.simulate(mech, jc.settings(0.01, n_out=2, throw=False, **TIGHT))
    assert jc.STATUS[int(sol.status)].startswith("invalid parameter")
    assert "damping (spring_damping:s) = -2 N s/m" in mech.failed_check()
    with pytest.raises(jc.MechanismError, match="force element names .* must be unique"):
        jc.Mechanism(mech.bodies, mech.joints, loads=(*mech.loads, *mech.loads), ground_points={"O": (0.0, 0.0)})


def three_elements():
    """A free body (no joints) under gravity held to the ground by a preloaded spring-damper with
    a cubic curve, a rotational spring-damper and a bushing."""
    body = jc.Body("b", 1.2, 0.015, points={"P": (0.05, 0.02), "Q": (-0.04, 0.0)}, position=(0.02, -0.25, 0.3),
                   velocity=(0.4, -0.3, 2.0))
    spring = jc.TranslationalSpringDamper("s", "ground", "O", "b", "P", stiffness=300.0, damping=1.5,
                                          rest_length=0.2, preload=4.0, curve=jc.PolynomialCurve([0.0, 0.0, 2e4]))
    torsion = jc.RotationalSpringDamper("t", "ground", "b", stiffness=2.0, damping=0.01, rest_angle=0.1, drawn_at="Q")
    bushing = jc.Bushing("u", "ground", "R", "b", "Q", 500.0, 800.0, 1.0, 2.0, 3.0, 0.005)
    return jc.Mechanism([body], loads=[spring, torsion, bushing], ground_points={"O": (0.0, 0.0),
                        "R": (-0.03, -0.2)}, gravity=(0.0, -9.81), name="three elements")


def test_force_elements_saved_to_a_file_and_loaded_back_run_bit_for_bit_the_same(tmp_path):
    """Every number (the curves' tables too) is written as Python's float repr, which reads back
    exactly: the loaded mechanism equals the original leaf by leaf and runs bit for bit the same."""
    table = jc.TableCurve([-0.05, 0.0, 0.02, 0.05], [-9.0, 0.0, 5.0, 30.0])
    mech = three_elements()
    mech = eqx.tree_at(lambda m: m.loads, mech, (*mech.loads, jc.TranslationalSpringDamper(
        "table", "ground", "R", "b", "P", stiffness=50.0, rest_length=0.1, curve=table)))
    back = jc.load_mechanism(jc.save_mechanism(mech, tmp_path / "m.toml"))
    assert eqx.tree_equal(back, mech)
    s = jc.settings(0.2, n_out=21, allow_free_dof=True)
    np.testing.assert_array_equal(np.asarray(jc.simulate(back, s).q), np.asarray(jc.simulate(mech, s).q))
    text = (tmp_path / "m.toml").read_text()
    for key in ('type = "spring-damper"', 'type = "rotational-spring-damper"', 'type = "bushing"',
                'kind = "polynomial"', 'kind = "table"'):
        assert key in text
    with pytest.raises(jc.ParameterError, match=r"loads\[2\]: Bushing 'u': damping_y \(bushing_cy:u\) = -3"):
        loads_mechanism(text.replace("damping_y = 3.0", "damping_y = -3.0"))
    with pytest.raises(jc.ParameterError, match=r"loads\[0\].curve.kind: 'spline' is not a curve kind"):
        loads_mechanism(text.replace('kind = "polynomial"', 'kind = "spline"'))


def test_check_draws_each_force_element(tmp_path):
    """jaxclear check's drawing: a zigzag between a spring's points, a line to a bushing's square,
    a spiral of two turns at a rotational spring's drawn_at point."""
    mech = three_elements()
    q, _ = mech.guess()
    fig = jc.plot_mechanism(tmp_path / "m.png", mech, q)
    lines = {line.get_label(): np.asarray(line.get_xydata()) for line in fig.axes[0].get_lines()}
    spring, coil, bushing = (lines[load.label] for load in mech.loads)
    ends = [np.asarray(mech.point_position(q, b, p)) for b, p in mech.loads[0].points()]
    np.testing.assert_allclose(spring[[0, -1]], ends, atol=1e-12)
    assert len(spring) == 17 and len(bushing) == 2 and len(coil) == 60
    np.testing.assert_allclose(coil.mean(0), np.asarray(mech.point_position(q, "b", "Q")), atol=0.02)
    assert (tmp_path / "m.png").stat().st_size > 10_000


@pytest.mark.slow  # 86 s on a shared 2-core machine (compilation of the fit's programs)
def test_a_spring_constant_is_fitted_like_any_other(tmp_path):
    """The slider-crank of Flores with a stiff return spring on its slider: the spring's
    stiffness, started 50 % high, is fitted from 2 ms of the slider's acceleration (a noiseless
    record at 50 kHz). Measured: 199999.998 N/m for 2e5 (1e-8)."""
    base = jc.preset("flores-slider-crank")
    ground = {**base.ground_points, "wall": jnp.array([0.5, 0.05])}
    spring = jc.TranslationalSpringDamper("return", "ground", "wall", "slider", "B", stiffness=2e5, damping=5.0,
                                          rest_length=0.2)
    mech = eqx.tree_at(lambda m: (m.ground_points, m.loads), base, (ground, (*base.loads, spring)))
    rec = jc.synthetic_record(mech, 2e-3, 50e3, snr_db=None)
    res = jc.fit(rec, mech, free=("spring_stiffness:return",), start={"spring_stiffness:return": 3e5}, window=2e-3,
                 horizons=(1.0,), rtol=1e-6, atol=1e-9, progress=False, max_iter=15)
    assert res.estimates["spring_stiffness:return"] == pytest.approx(2e5, rel=1e-4)


def test_between_two_free_bodies_the_elements_keep_momentum_and_energy():
    """Two free bodies joined only by the three elements (the bushing in the turning first body's
    frame), no gravity: the elements' forces are internal, so linear momentum sum(m v) and angular
    momentum sum(m r x v + J omega) keep their start values (action and reaction, the bushing's
    lever moment included: linear momentum is a linear invariant, which a Runge-Kutta method keeps
    to round-off, 1e-12; the angular one to the run's error at rtol 1e-10, 1e-9), and without
    damping kinetic + stored energy is constant (to 1e-9 of it; measured 1.2e-10)."""
    a = jc.Body("a", 0.8, 0.004, points={"P": (0.03, 0.01), "Q": (0.05, -0.02)}, position=(0.0, 0.0, 0.2),
                velocity=(0.1, 0.2, 3.0))
    b = jc.Body("b", 1.1, 0.006, points={"P": (-0.02, 0.0), "Q": (-0.01, 0.02)}, position=(0.12, 0.01, -0.1),
                velocity=(-0.3, 0.1, -2.0))
    loads = [jc.TranslationalSpringDamper("s", "a", "P", "b", "P", stiffness=400.0, rest_length=0.06),
             jc.RotationalSpringDamper("t", "a", "b", stiffness=1.5, rest_angle=-0.2),
             jc.Bushing("u", "a", "Q", "b", "Q", 300.0, 600.0, 0.8)]
    mech = jc.Mechanism([a, b], loads=loads, gravity=(0.0, 0.0), name="two bodies")
    sol = jc.simulate(mech, jc.settings(0.5, n_out=201, **TIGHT))
    q, qd = np.asarray(sol.q).reshape(-1, 2, 3), np.asarray(sol.qdot).reshape(-1, 2, 3)
    m, j = np.array([0.8, 1.1]), np.array([0.004, 0.006])
    momentum = (m[None, :, None] * qd[:, :, :2]).sum(1)
    spin = (m * (q[:, :, 0] * qd[:, :, 1] - q[:, :, 1] * qd[:, :, 0]) + j * qd[:, :, 2]).sum(1)
    np.testing.assert_allclose(momentum, momentum[:1].repeat(len(q), 0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(spin, spin[0], rtol=1e-9)  # quadratic: kept to the run's error (2e-12 of 0.0165)
    ch = {n: np.asarray(channel(mech, sol, f"load:{n}")) for n in ("s:length", "t:angle", "u:dx", "u:dy", "u:angle")}
    stored = (200.0 * (ch["s:length"] - 0.06) ** 2 + 0.75 * (ch["t:angle"] + 0.2) ** 2
              + 0.5 * (300.0 * ch["u:dx"] ** 2 + 600.0 * ch["u:dy"] ** 2 + 0.8 * ch["u:angle"] ** 2))
    kinetic = np.array([float(jc.energy(mech, qq, vv)) for qq, vv in zip(sol.q, sol.qdot)])
    assert np.ptp(stored) > 0.1 * kinetic[0]  # the elements exchange energy
    np.testing.assert_allclose(kinetic + stored, kinetic[0] + stored[0], rtol=1e-9)  # measured 1.2e-10 of 1.07 J
