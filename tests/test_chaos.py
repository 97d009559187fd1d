"""Lyapunov exponents (jaxclear.chaos) against truths not from jaxclear's code: closed-form decay
rates of a forced linear oscillator, the time average of the vector field's divergence
(computed by hand on the run's samples), an independent SciPy implementation of Benettin's method
(solve_ivp of the state and its variational equation, QR by NumPy), Rosenstein's time-series
estimate (nolds), and independence of the renormalisation interval and the tolerance.

The oscillators are a body on a slide (a Translational joint to the ground: 3 coordinates, 2
constraints, a 2-dimensional phase space) with a PointForce whose function is the spring, the
damper and the forcing: :math:`m\\ddot x + c(x)\\dot x + a x + b x^3 = f\\cos\\omega t`."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.chaos import LyapunovError, lyapunov, trajectory


def oscillator(m=1.0, c0=0.3, c2=0.0, a=-1.0, b=1.0, f=0.5, w=1.2, x0=0.5):
    """:math:`m\\ddot x + (c_0 + c_2 x^2)\\dot x + a x + b x^3 = f\\cos\\omega t` on a slide
    (Duffing 1918; the chaotic case a = -1, b = 1, c = 0.3, f = 0.5, w = 1.2 is the twin-well
    oscillator of Guckenheimer and Holmes 1983, sec. 2.2)."""

    def load(t, q, qdot):
        x, v = q[0], qdot[0]
        return jnp.stack([-(c0 + c2 * x**2) * v - a * x - b * x**3 + f * jnp.cos(w * t), 0.0 * x])

    body = jc.Body("mass", m, 1.0, {"P": (0.0, 0.0)}, position=(x0, 0.0, 0.0))
    return jc.Mechanism([body], joints=[jc.Translational(jc.GROUND, "o", "mass", "P")],
                        loads=[jc.PointForce("mass", "P", function=load)], gravity=(0.0, 0.0),
                        ground_points={"o": (0.0, 0.0)}, name="oscillator")


def scipy_benettin(m, c0, c2, a, b, f, w, x0, t_end, interval, transient=0.0, rtol=1e-10):
    """Benettin's method written independently: scipy.integrate.solve_ivp (DOP853) of the state
    (x, v) and the 2x2 variational equation dS/dt = J S, the basis orthonormalised by NumPy's QR
    every ``interval``, the start basis the identity in (x, v) (jaxclear's, for a body on a
    slide, with the metric's time scale 1 s). Returns the exponents and the finite-time rows."""
    from scipy.integrate import solve_ivp

    def rhs(t, y):
        x, v = y[0], y[1]
        s = y[2:].reshape(2, 2)
        acc = (-(c0 + c2 * x**2) * v - a * x - b * x**3 + f * math.cos(w * t)) / m
        jac = np.array([[0.0, 1.0], [(-2 * c2 * x * v - a - 3 * b * x**2) / m, -(c0 + c2 * x**2) / m]])
        return np.concatenate([[v, acc], (jac @ s).ravel()])

    y = np.array([x0, 0.0])
    if transient > 0:
        y = solve_ivp(lambda t, y: rhs(t, np.concatenate([y, np.eye(2).ravel()]))[:2], (0, transient), y,
                      method="DOP853", rtol=rtol, atol=1e-12).y[:, -1]
    basis = np.eye(2)
    windows = round((t_end - transient) / interval)
    logs = []
    for k in range(windows):
        ta = transient + k * interval
        sol = solve_ivp(rhs, (ta, ta + interval), np.concatenate([y, basis.ravel()]), method="DOP853", rtol=rtol,
                        atol=1e-12)
        end = sol.y[:, -1]
        y = end[:2]
        q, r = np.linalg.qr(end[2:].reshape(2, 2))
        sign = np.sign(np.diag(r))
        basis = q * sign
        logs.append(np.log(np.abs(np.diag(r))))
    logs = np.array(logs)
    return logs.sum(axis=0) / (windows * interval), logs


# the forced linear oscillator (overdamped: m = 1 kg, c = 3 N s/m, k = 2 N/m): its exponents are the
# real parts of the roots of m s^2 + c s + k, -1 and -2 1/s, whatever the forcing
LINEAR = dict(m=1.0, c0=3.0, c2=0.0, a=2.0, b=0.0, f=0.5, w=1.2, x0=0.1)


@pytest.fixture(scope="module")
def linear_run():
    mech = oscillator(**LINEAR)
    return mech, lyapunov(mech, jc.settings(40.0, rtol=1e-9, atol=1e-12), interval=1.0, discard=8)


def test_linear_oscillator_exponents_are_its_decay_rates(linear_run):
    """Closed form: -c/(2m) +- sqrt((c/2m)^2 - k/m) = -1, -2 1/s. The finite-time estimate over
    T = 32 s after 8 discarded intervals differs from them by the logarithm of the basis'
    misalignment with the eigenvectors divided by T (the eigenvectors (1, -1) and (1, -2) are
    not orthogonal): measured 2e-4; allowed 1e-3 1/s. Both negative: a stable periodic response."""
    _, r = linear_run
    assert int(r.status) == 0
    np.testing.assert_allclose(np.asarray(r.exponents), [-1.0, -2.0], atol=1e-3)
    assert np.all(np.asarray(r.exponents) < 0)


def test_linear_oscillator_sum_is_the_divergence(linear_run):
    """The sum of the exponents is the phase-space contraction rate, the divergence -c/m of the
    vector field (x, v) -> (v, (F(t) - c v - k x)/m), exactly at every time (Liouville): the
    spurious Baumgarte directions of the constrained y and phi are not in the spectrum. Allowed
    1e-6 1/s (the integration tolerance 1e-9 over 1 s intervals)."""
    _, r = linear_run
    assert float(r.sum) == pytest.approx(-LINEAR["c0"] / LINEAR["m"], abs=1e-6)
    # the running estimate of the sum is the divergence after every interval, not only at the end
    np.testing.assert_allclose(np.asarray(r.running).sum(axis=1), -3.0, atol=1e-6)


def test_bad_input_is_named():
    mech = oscillator(**LINEAR)
    s = jc.settings(10.0)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(jc.ParameterError, match=r"interval = .*renormalisation interval.*\(0, inf\)"):
            lyapunov(mech, s, interval=bad)
    with pytest.raises(jc.ParameterError, match=r"too short for a converged estimate.*raise t_end"):
        lyapunov(mech, s, interval=4.0)
    with pytest.raises(jc.ParameterError, match=r"count = 3 exponents.*\[1, 2\]"):
        lyapunov(mech, s, interval=1.0, count=3)
    with pytest.raises(jc.ParameterError, match=r"interval: .*no turning crank"):
        lyapunov(mech, s)
    with pytest.raises(jc.ParameterError, match=r"tol = .*\(0, inf\)"):
        lyapunov(mech, s, interval=1.0, tol=-1.0)
    crank = jc.preset("flores-slider-crank")
    with pytest.raises(jc.ParameterError, match=r"output channel 'joint:3:ecc_x': '3' is no clearance joint"):
        jc.lyapunov_map(crank, s, ["clearance"], [[1e-4]], revolutions=8, channels=["joint:3:ecc_x"])
    with pytest.raises(jc.ParameterError, match=r"too short for a converged estimate"):
        jc.lyapunov_map(crank, s, ["clearance"], [[1e-4]], revolutions=2)
    with pytest.raises(jc.ParameterError, match=r"no_such"):
        jc.lyapunov_map(crank, s, ["no_such"], [[1e-4]], revolutions=8)


def test_missed_convergence_is_a_named_error(linear_run):
    """A tolerance the run cannot meet: LyapunovError naming tol and the spread."""
    mech, _ = linear_run
    with pytest.raises(LyapunovError, match=r"did not converge to tol = 1e-12 1/s"):
        lyapunov(mech, jc.settings(40.0, rtol=1e-9, atol=1e-12), interval=1.0, discard=8, tol=1e-12)


# ---- the chaotic Duffing oscillator (slow: long runs, compiled anew) -----------------------

DUFFING = dict(m=1.0, c0=0.25, c2=0.1, a=-1.0, b=1.0, f=0.5, w=1.2, x0=0.5)
PERIOD = 2 * math.pi / 1.2


@pytest.mark.slow
def test_duffing_against_an_independent_scipy_benettin():
    """The same oscillator, start state and start basis, QR every forcing period over 15 periods:
    the two codes follow the same trajectory (a chaotic run separates two solutions integrated
    at rtol 1e-10: here their finite-time growths differ by 1e-3 after 18 periods, 94 s; this run
    is 79 s) and must give the same growth over every period and the same exponents. Allowed:
    1e-5 per period and 1e-6 1/s (the two integrations' errors, amplified by the chaos)."""
    mech = oscillator(**DUFFING)
    t_end = 15 * PERIOD
    r = lyapunov(mech, jc.settings(t_end, rtol=1e-10, atol=1e-12), interval=PERIOD)
    ref, logs = scipy_benettin(**DUFFING, t_end=t_end, interval=PERIOD)
    print("jaxclear", np.asarray(r.exponents), "scipy", ref, "largest growth difference",
          np.max(np.abs(np.asarray(r.log_growth) - logs)))
    np.testing.assert_allclose(np.asarray(r.log_growth), logs, atol=1e-5)
    np.testing.assert_allclose(np.asarray(r.exponents), ref, atol=1e-6)


def test_unstable_equilibrium_is_resolved_by_adaptive_renormalisation():
    """An inverted oscillator (k = -100 N/m, no damping, no forcing) resting at its unstable
    equilibrium: the state stays 0 and the tangent map is exp(t [[0, 1], [100, 0]]), whose
    exponents are +-sqrt(100) = +-10 1/s. Over a 70 s interval its tangents grow by e^700 > 1e250
    (a fixed interval overflowed: status 2); the renormalisation steps shorten until the log
    growths of a step spread by no more than max_growth, and the exponents come out as the closed
    form over the run's 280 s: the start vector e_x (metric time scale 1 s) grows to
    (cosh 10t, 10 sinh 10t), of length e^(10t) sqrt(101)/2 (e^(-10t) terms below rounding), so
    lambda_1 = 10 + ln(sqrt(101)/2)/280, and lambda_2 = -lambda_1 (the map's determinant is 1). To
    1e-6 of their size: 2.8e-3 in a log growth of 2800, the tangents integrated at rtol 1e-8 over
    about 600 renormalisation steps."""
    mech = oscillator(m=1.0, c0=0.0, c2=0.0, a=-100.0, b=0.0, f=0.0, x0=0.0)
    r = lyapunov(mech, jc.settings(280.0, rtol=1e-8, atol=1e-12), interval=70.0)
    assert int(r.status) == 0 and int(r.run_status) == 0
    lam = 10.0 + math.log(math.sqrt(101.0) / 2.0) / 280.0
    np.testing.assert_allclose(np.asarray(r.exponents), [lam, -lam], rtol=1e-6)
    # the log growths spread at 20 1/s, a step by at most ln(0.01/rtol) = 13.8: at least 102 steps an interval
    assert np.all(np.asarray(r.renormalisations) >= 70.0 * 20.0 / math.log(0.01 / 1e-8))


def test_tangent_overflow_is_a_status():
    """The same oscillator over intervals of 6.5e7 s: the shortest renormalisation step
    (benettin.SHORTEST of the interval, 65 s) grows the tangents by e^650 > 1e250 (and below the
    largest float, so the state stays finite): the status RESULTS.tangent_overflow (the tangents
    overflowed within the shortest step; a member of the one status family, jc.STATUS its
    message) and a named LyapunovError, never an exponent reported as ok; the run itself is fine
    (run_status 0)."""
    mech = oscillator(m=1.0, c0=0.0, c2=0.0, a=-100.0, b=0.0, f=0.0, x0=0.0)
    s = jc.settings(2.6e8, rtol=1e-8, atol=1e-12, throw=False)
    r = lyapunov(mech, s, interval=6.5e7)
    assert int(r.status) == int(jc.RESULTS.tangent_overflow._value) and int(r.run_status) == 0
    assert jc.STATUS[int(r.status)].startswith("the tangents overflowed")
    assert np.all(np.isnan(np.asarray(r.exponents)))
    with pytest.raises(LyapunovError, match=r"tangents overflowed within the shortest renormalisation step"):
        lyapunov(mech, jc.settings(2.6e8, rtol=1e-8, atol=1e-12), interval=6.5e7)


@pytest.mark.slow
def test_sum_of_exponents_is_the_mean_divergence():
    """Liouville: the sum of all exponents is the time average of the divergence of the
    vector field, here -(c0 + c2 x^2)/m, averaged by hand (Simpson's rule on 32 samples a
    period of the run's x) over the counted intervals of a chaotic run (150 periods). Allowed
    1e-4 1/s (the quadrature of x^2 on the samples; measured below 1e-5)."""
    from scipy.integrate import simpson

    mech = oscillator(**DUFFING)
    s = jc.settings(160 * PERIOD, rtol=1e-9, atol=1e-12)
    r = lyapunov(mech, s, interval=PERIOD, transient=10 * PERIOD, samples=32, discard=1)
    sol = trajectory(mech, s, r)
    # the counted intervals start at the end of the first (discarded) one: its last sample
    ts, x = np.asarray(sol.ts)[31:], np.asarray(sol.q[31:, 0])
    assert ts[0] == pytest.approx(11 * PERIOD)
    d = DUFFING
    mean_div = -simpson(d["c0"] + d["c2"] * x**2, x=ts) / (ts[-1] - ts[0]) / d["m"]
    assert float(r.exponents[0]) > 0.05  # chaotic
    assert float(r.sum) == pytest.approx(mean_div, abs=1e-4)


@pytest.mark.slow
def test_periodic_exponents_do_not_depend_on_interval_or_tolerance():
    """A nonlinear oscillator on a stable periodic orbit (Duffing, weak forcing f = 0.1): both
    exponents negative, and the same to 2 digits (|difference| < 5e-3 1/s, measured ~1e-5)
    whether the basis is renormalised every half, one or two forcing periods and at rtol 1e-7
    or 1e-10."""
    mech = oscillator(**dict(DUFFING, f=0.1))
    runs = []
    for per, rtol in ((2.0, 1e-10), (1.0, 1e-10), (0.5, 1e-10), (1.0, 1e-7)):
        s = jc.settings(60 * PERIOD, rtol=rtol, atol=1e-12)
        r = lyapunov(mech, s, interval=PERIOD * per, transient=20 * PERIOD, discard=int(4 / per))
        runs.append(np.asarray(r.exponents))
    runs = np.array(runs)
    assert np.all(runs < 0)
    np.testing.assert_allclose(runs, runs[[1]].repeat(4, 0), atol=5e-3)


@pytest.fixture(scope="module")
def chaotic_runs():
    mech = oscillator(**DUFFING)
    out = {}
    for per, rtol in ((1.0, 1e-10), (0.5, 1e-10), (1.0, 1e-8)):
        s = jc.settings(1500 * PERIOD, rtol=rtol, atol=1e-12)
        out[per, rtol] = lyapunov(mech, s, interval=PERIOD * per, transient=20 * PERIOD, discard=int(10 / per),
                                  samples=int(16 * per))
    return mech, out


@pytest.mark.slow
def test_chaotic_exponent_does_not_depend_on_interval_or_tolerance(chaotic_runs):
    """The chaotic Duffing oscillator over 1480 periods: the largest exponent with the basis
    renormalised every period or half period, at rtol 1e-10 or 1e-8. The runs separate after
    ~200 s (chaos amplifies the different step sequences), so they are different samples of
    the attractor and agree only within the statistical error of a finite run: allowed 3
    combined batch-means standard errors (and 2 digits, 0.005 1/s, where those are smaller)."""
    _, runs = chaotic_runs
    values = {k: (float(r.exponents[0]), float(r.stderr[0])) for k, r in runs.items()}
    ref, ref_se = values[1.0, 1e-10]
    assert ref > 0.05
    for key, (v, se) in values.items():
        assert abs(v - ref) <= max(3 * math.hypot(se, ref_se), 5e-3), (key, v, ref, se, ref_se)


@pytest.mark.slow
def test_tangent_exponent_against_rosenstein(chaotic_runs):
    """Rosenstein's time-series estimate (nolds.lyap_r on x sampled 16 times a period, delay
    embedding of dimension 4, neighbours at least a period apart, a fit over 32 samples) on the
    same run. Its known bias: the fitted divergence curve bends over towards the attractor's size
    inside the fit range, so it falls short of the true exponent; Rosenstein et al. (1993)
    report errors of about 10 % and more with short series. Allowed: 0.6 to 1.1 times the
    tangent exponent (measured about 0.8-0.9)."""
    from jaxclear.chaos.signals import rosenstein

    mech, runs = chaotic_runs
    r = runs[1.0, 1e-10]
    sol = trajectory(mech, jc.settings(1500 * PERIOD), r)
    x = np.asarray(sol.q[:, 0])
    estimate = rosenstein(x, float(sol.ts[1] - sol.ts[0]), emb_dim=4, min_tsep=16, trajectory_len=32)
    ratio = estimate / float(r.exponents[0])
    assert 0.6 <= ratio <= 1.1, (estimate, float(r.exponents[0]))


@pytest.mark.slow
def test_map_row_equals_the_single_run():
    """lyapunov_map's row for a speed is lyapunov at that speed (the same transient, intervals
    and start). The benchmark at 5000 rpm is chaotic (~450 1/s): the two programs' interval ends
    differ by rounding (the period computed traced or in Python), which the motion amplifies by
    e^(450 t), so they agree bit-close only early: the Poincare section's first two revolutions to
    1e-6 relative, and the exponents after 6 revolutions within 3 combined standard errors."""
    mech = jc.preset("flores-slider-crank")
    period = jc.crank_period(mech)
    mp = jc.lyapunov_map(mech, jc.settings(1.0), ["speed_rpm"], [[5000.0]], revolutions=6, transient_revolutions=1,
                         count=1, channels=["joint:0:ecc_x"])
    s = jc.settings(7 * period, throw=False)
    r = lyapunov(mech, s, interval=period, transient=period, count=1)
    assert int(mp.status[0]) == 0 and int(r.status) == 0
    sol = trajectory(mech, s, r)
    ecc = np.asarray(jc.channel(mech, sol, "joint:0:ecc_x"))[7::8]
    print("map", np.asarray(mp.sections[0, :, 0]), "single", ecc)
    np.testing.assert_allclose(np.asarray(mp.sections[0, :2, 0]), ecc[:2], rtol=1e-6)
    se = math.hypot(float(mp.stderr[0, 0]), float(r.stderr[0]))
    assert abs(float(mp.exponents[0, 0]) - float(r.exponents[0])) <= 3 * se


def test_tangent_tolerance_grows_with_the_tangents():
    """The Lyapunov run's tangents solve a linear equation, so their error control is invariant
    under a scaling of the tangents (TangentSystem.weigh_error): above the reference size the
    error the controller scales (by atol + rtol |y|) is that of tangents measured against
    atol times their size over the reference; scaling the tangents and their errors by 1e6 leaves
    the scaled error unchanged to rounding, and leaves it alone below the reference (or without
    one: the sensitivities' system). Without it, a component that the constraints hold near zero
    was asked for atol absolutely while the tangent grew 1e10-fold in a revolution of the
    benchmark slider-crank, whose steps then shrank to the floor (400,000 not enough)."""
    from jaxclear.integrate import _solve as solve
    from jaxclear.integrate._sensitivity import Rebuild, TangentSystem

    mech = oscillator()
    s = jc.settings(1.0)
    size = solve.start_run(mech, s, None).packed.shape[0]
    count, rtol, atol = 2, 1e-8, 1e-12
    leaves, treedef = __import__("jax").tree_util.tree_flatten((mech, s, None))
    ref = 0.5

    def system(reference):
        return TangentSystem(mech, s.baumgarte, Rebuild(leaves, treedef, ()), (), (), jnp.asarray(1e-12), size,
                             count, None if reference is None else jnp.asarray(reference))

    rng = np.random.default_rng(0)
    y0, y1, ey = rng.normal(size=(3, size))
    t0, t1, et = rng.normal(size=(3, count, size)) * 1e3
    t0[:, 1] = t1[:, 1] = 1e-9  # a component the constraints hold near zero

    def scaled(sys_, c):
        v0, v1 = np.concatenate([y0, c * t0.ravel()]), np.concatenate([y1, c * t1.ravel()])
        e = np.concatenate([ey * 1e-9, c * et.ravel() * 1e-9])
        w = np.asarray(sys_.weigh_error(jnp.asarray(v0), jnp.asarray(v1), jnp.asarray(e), rtol, atol))
        return w / (atol + rtol * np.maximum(np.abs(v0), np.abs(v1))), e

    big, _ = scaled(system(ref), 1.0)
    bigger, _ = scaled(system(ref), 1e6)
    np.testing.assert_allclose(bigger, big, rtol=1e-12)
    # below the reference, and without one, the error is left as it is
    small, e = scaled(system(1e9), 1.0)
    plain, _ = scaled(system(None), 1.0)
    np.testing.assert_array_equal(small, plain)
    np.testing.assert_array_equal(np.asarray(system(None).weigh_error(0.0, 0.0, jnp.asarray(e), rtol, atol)), e)


@pytest.mark.slow
def test_long_intervals_on_the_chaotic_benchmark_do_not_stall():
    """The benchmark slider-crank at 5000 rpm (chaotic, lambda ~ 450 1/s: the tangent grows
    about 1e10-fold over some revolutions), renormalised once a revolution at rtol 1e-8 over 90
    revolutions: every interval finishes within the default 400,000 steps (before the tangents'
    tolerance grew with them, the interval starting at revolution 86 did not; measured after:
    459,618 steps in all, about 5,000 a revolution, lambda 458 1/s, 31 s)."""
    mech = jc.preset("flores-slider-crank", speed_rpm=5000.0)
    period = jc.crank_period(mech)
    r = lyapunov(mech, jc.settings(91 * period, rtol=1e-8, atol=1e-11, throw=False), interval=period,
                 transient=period, count=1, samples=1, keep=False)
    assert int(r.status) == 0 and int(r.run_status) == 0
    assert int(r.num_steps) < 90 * 20_000
    assert 200 < float(r.exponents[0]) < 900


@pytest.mark.extended
def test_only_the_memory_the_motion_reads_is_carried():
    """A basis vector carries the tangents of the memory entries the vector field reads
    (chaos.manifold.live_memory), and no others: the revolute joint's memory is
    [impact_velocity, contact_start, impacts, work, peak_force, peak_penetration]. At the
    benchmark's periodic point (1000 rpm, friction 0.2, c_r 0.3: the journal in one lasting
    contact) the Lankarani-Nikravesh law damps with the approach speed, so it is read; the onset
    time, the count, the work and the peaks are outputs (never read). Under the elastic Hertz law,
    and out of contact (the journal centred at the start), nothing is read. Carried by the
    renormalisations' R^-1 without acting back, an unread entry grew like e^(-lambda_min t) and
    overflowed (the work's tangent: 1e117, then inf, after 20-35 revolutions)."""
    import equinox as eqx
    import jax

    from jaxclear.chaos import manifold
    from jaxclear.integrate import State, _solve as solve

    # compiled once per law for both of its points (called eagerly, each call compiled its own
    # derivative of the vector field: twice the compilation)
    live_memory = eqx.filter_jit(manifold.live_memory)
    for law, expected in (("lankarani-nikravesh", [1, 0, 0, 0, 0, 0]), ("hertz", [0] * 6)):
        mech = jc.preset("flores-slider-crank", law=law, speed_rpm=1000.0, friction=0.2, restitution=0.3)
        s = jc.settings(0.12, n_out=1201)
        begin = solve.start_run(mech, s, None)
        np.testing.assert_array_equal(np.asarray(live_memory(mech, s.baumgarte, jnp.zeros(()), begin.packed)), [0] * 6)
        # the deepest sample of the second revolution: inside a contact
        sol = jc.simulate(mech, s)
        k = 600 + int(np.argmax(np.asarray(sol.penetration[600:, 0])))
        assert float(sol.penetration[k, 0]) > 1e-7
        y = State(sol.q[k], sol.qdot[k], jax.tree_util.tree_map(lambda x: x[k], sol.element_states)).pack()
        live = live_memory(mech, s.baumgarte, sol.ts[k], y)
        np.testing.assert_array_equal(np.asarray(live), expected)
