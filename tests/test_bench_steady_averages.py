"""benchmarks/bench_steady_averages.py's own pieces (the long runs are the benchmark's): the
ideal slider's acceleration against central differences of its closed-form position, and the
regression's slope, interval and lack-of-fit test on data of known shape."""

import math

import numpy as np

import bench_steady_averages as bench  # benchmarks/ is on sys.path (conftest.py)


def test_ideal_slider_acceleration_is_the_second_difference_of_the_position():
    """x(phi) = r cos phi + sqrt(l^2 - r^2 sin^2 phi) (the ideal slider-crank with the preset's
    r = 0.05 m, l = 0.12 m); the closed-form acceleration at 5000 rpm against the central second
    difference of x(omega t) with h = 1e-6 s: truncation h^2 x''''/12, about 1e-4 relative of
    the 1.7e4 m/s^2 scale, rounding 1e-16 * 0.17 m / h^2 = 2e-5 m/s^2; 1e-3 relative allowed."""
    omega = 5000 * 2 * math.pi / 60
    r, l = bench.CRANK, bench.ROD

    def x(t):
        phi = 0.3 + omega * t
        return r * np.cos(phi) + np.sqrt(l**2 - r**2 * np.sin(phi) ** 2)

    t = np.linspace(0.0, 0.012, 97)
    h = 1e-6
    fd = (x(t + h) - 2 * x(t) + x(t - h)) / h**2
    exact = bench.slider_crank_exact(0.3 + omega * t, omega)[2]
    assert np.max(np.abs(fd - exact)) < 1e-3 * np.max(np.abs(exact))


def test_regression_finds_a_known_slope_and_flags_a_curve():
    """Averages on a line y = 2 + 3 x with Gaussian errors of known size: the slope within its
    interval and a lack of fit that is not significant; on a parabola whose curvature is 30
    standard errors over the band, the line's p-value below 1e-6 and the parabola's slope at x0
    the derivative there (within 4 of its standard errors)."""
    rng = np.random.default_rng(0)
    x = np.linspace(0.9, 1.1, 10)
    se = np.full(10, 0.01)
    y = 2 + 3 * x + se * rng.standard_normal(10)
    f = bench.regression(x, y, se, 1.0)
    assert f["slope_95"][0] < 3.0 < f["slope_95"][1]
    assert f["line_p"] > 0.01
    curved = 2 + 3 * x + 30 * (x - 1.0) ** 2 / 0.01 * 0.01 + se * rng.standard_normal(10)
    g = bench.regression(x, curved, se, 1.0)
    assert g["line_p"] < 1e-6
    assert abs(g["parabola_slope"] - 3.0) < 4 * g["parabola_slope_se"]


def test_members_on_different_attractors_are_told_apart():
    """Four motions' averages within their errors agree (p well above the benchmark's 1e-3);
    one of them 20 errors off, as a motion settled on another attractor (0.534 mm: 8,010 against
    14,200-14,800 m/s^2 with errors of about 300), gives p below 1e-6."""
    ses = [100.0, 120.0, 110.0, 100.0]
    assert bench.members_agree([15000.0, 15100.0, 14950.0, 15050.0], ses) > 0.01
    assert bench.members_agree([15000.0, 15100.0, 14950.0, 13000.0], ses) < 1e-6
    assert bench.members_agree([15000.0], [100.0]) == 1.0


def test_the_shadowing_benchmarks_objective_is_the_squared_deviation_from_the_closed_form():
    """benchmarks/bench_shadowing.py's traced objective (jax.numpy through ``xp``) against the
    NumPy closed form at a few states: the same formula, to rounding."""
    import jax.numpy as jnp

    import bench_shadowing
    import jaxclear as jc

    mech = bench_shadowing.mechanism(None)
    objective = bench_shadowing.deviation_squared(mech)
    i = 3 * mech.body_index("slider")
    omega, angle0 = float(jc.params.get(mech, "speed")), float(jc.params.get(mech, "angle0"))
    n = mech.n_coordinates
    for t, a in ((0.0, 100.0), (0.0031, -2.5e4), (0.0107, 7.0e3)):
        qddot = jnp.zeros(n).at[i].set(a)
        got = float(objective(t, jnp.zeros(n), jnp.zeros(n), qddot, mech))
        want = (a - bench.slider_crank_exact(angle0 + omega * t, omega)[2]) ** 2
        assert math.isclose(got, want, rel_tol=1e-12)


def test_the_shadowing_benchmarks_force_objective_is_the_runs_normal_force():
    """benchmarks/bench_shadowing.py's peak-force objective (the clearance joint's force law on the
    memory handed to the objective's sixth parameter) at a run's samples against the normal force
    the run reports there (``sol.normal_force``): in contact at the first onset's sample and at the
    largest sample, and out of contact; the same law on the same memory, to rounding."""
    import jax

    import bench_shadowing
    import jaxclear as jc

    mech = bench_shadowing.mechanism(None)
    sol = jc.simulate(mech, jc.settings(0.012, n_out=121))  # one revolution at 5000 rpm
    force = np.asarray(sol.normal_force)[:, 0]
    objective = bench_shadowing.normal_force(mech)
    for k in (int(np.flatnonzero(force > 0)[0]), int(np.argmax(force)), int(np.flatnonzero(force == 0)[0])):
        memory = jax.tree.map(lambda a: a[k, 0], sol.memory)
        got = float(objective(sol.ts[k], sol.q[k], sol.qdot[k], sol.qddot[k], mech, (memory,)))
        assert math.isclose(got, force[k], rel_tol=1e-12, abs_tol=1e-9)
