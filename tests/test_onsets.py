"""Exact contact onsets (Settings.exact_onsets): the step that crosses into contact ends just past
the onset, so the dissipative laws use the approach speed at the onset; output samples inside a
crossing step carry the new memory; the accuracy benchmark runs.

Truths: an independent SciPy integration of a 1-DOF impact with event restarts at every onset
(exact approach speed), the mode definition applied to the penetration series, central
differences, and per-member runs for vmap.
"""

import jaxclear  # noqa: F401  (float64 first)

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import jaxclear as jc
from conftest import free_journal
from jaxclear import params

G = 2000.0  # [m/s^2] constant acceleration pushing the journal towards +x
K = 1e10  # [N/m^1.5]
CLEARANCE = 0.5e-3
T_END = 1.6e-3  # one impact, then continuous contact


def falling_journal(restitution=0.3, law="flores"):
    """A 1 kg journal, centred and at rest in a ground bearing (c = 0.5 mm), accelerated along +x
    by a body force G: it reaches the wall at sqrt(2 c / G) = 0.71 ms with 1.41 m/s and bounces
    (with c_r = 0.3 it then stays in contact). Its approach speed changes during a step, so a stale impact speed shows."""
    body = jc.Body("pin", 1.0, 1e-3, {"c": (0.0, 0.0)})
    joint = jc.ClearanceJoint(jc.GROUND, "hole", "pin", "c", bearing_radius=0.010, journal_radius=0.010 - CLEARANCE,
                              law=jc.make_law(law, restitution=restitution, stiffness=K))
    return jc.Mechanism([body], clearance_joints=[joint], gravity=(G, 0.0), ground_points={"hole": (0, 0)},
                        name="falling-journal")


def scipy_bouncing(restitution, ts, rtol=1e-11, atol=1e-15):
    """x(t) of the same journal by SciPy: x'' = G - F(delta, delta'), delta = x - c, with the Flores
    law F = K delta^1.5 (1 + chi delta' / v0), chi = 8 (1 - c_r) / (5 c_r), F >= 0, and v0 the
    approach speed at the onset (Flores, Machado, Silva, Martins, Multibody Syst. Dyn. 25 (2011)
    357): the integration stops at every onset and restarts with v0 set to x' there."""
    chi = 8 * (1 - restitution) / (5 * restitution)

    def rhs(t, y, v0):
        d = y[0] - CLEARANCE
        f = max(K * d**1.5 * (1 + chi * y[1] / v0), 0.0) if d > 0 else 0.0
        return [y[1], G - f]

    t0, y0, v0, contact, out = 0.0, [0.0, 0.0], 1.0, False, []
    while True:
        def ev(t, y):
            return y[0] - CLEARANCE + (1e-13 if contact else 0.0)
        ev.terminal, ev.direction = True, (-1 if contact else 1)
        sel = ts[(ts >= t0) & (ts <= ts[-1])]
        sol = solve_ivp(lambda t, y: rhs(t, y, v0), (t0, ts[-1]), y0, method="DOP853", t_eval=sel, events=ev,
                        rtol=rtol, atol=atol)
        out.extend(sol.y[0])
        if sol.status != 1:
            break
        t0, y0 = float(sol.t_events[0][0]), sol.y_events[0][0].copy()
        if not contact:
            v0 = y0[1]
        contact = not contact
    return np.asarray(out)


def _run(mech, rtol, exact, n_out=161):
    return jc.simulate(mech, jc.settings(T_END, n_out=n_out, rtol=rtol, atol=1e-12, exact_onsets=exact))


@pytest.mark.extended
def test_exact_onsets_match_an_event_restart_integration():
    """At rtol = 1e-6 the position history of the falling journal (one Flores impact with c_r = 0.3,
    after which it stays in contact) matches the event-restart SciPy solution, and the stored
    approach speed is the closed form sqrt(2 G c); with the onset found only after the
    step (exact_onsets=False) the stale approach speed of the crossing step costs much more.
    The approach speed: to 1e-7 (measured 1e-15 to 1.3e-8 over the six runs; the interpolant of
    the crossing step is exact for the free flight's parabola, and the step ends inside the
    contact, where the force has begun to act).

    The error in contact depends on the step sequence (at rtol 1e-6 it is a few nm either way:
    over initial steps of 0.1-0.7 ms, 1.1e-7 to 5.0e-6 of the clearance with exact onsets and
    2.8e-6 to 2.6e-5 without, measured 2026-11-25), so six runs of slightly different lengths
    (their own grids, so their own steps) are compared: every exact-onset error below 1e-5 of the
    clearance (measured 1.1e-7 to 5.2e-6), and the median error without exact onsets more than
    10x the median with them (measured 2.3e-5 against 1.8e-7)."""
    mech = falling_journal()
    factors = np.array([1.0, 1.02, 1.05, 1.08, 1.11, 1.14])
    refs = [scipy_bouncing(0.3, np.linspace(0.0, T_END * f, 161)) for f in factors]
    assert all(r.max() > CLEARANCE for r in refs)
    errs = {}
    for exact in (True, False):
        s = jc.settings(T_END, n_out=161, rtol=1e-6, atol=1e-12, exact_onsets=exact)
        run = jax.jit(jax.vmap(lambda te: jc.simulate(mech, dataclasses.replace(s, t_end=te))))
        sol = run(jnp.asarray(T_END * factors))
        assert np.all(np.asarray(sol.impacts[:, 0]) == 1)
        errs[exact] = np.array([np.max(np.abs(np.asarray(x) - r)) for x, r in zip(sol.q[:, :, 0], refs)]) / CLEARANCE
        if exact:
            v0 = np.asarray(sol.memory.impact_velocity[:, -1, 0])
            assert np.all(np.abs(v0 - math.sqrt(2 * G * CLEARANCE)) < 1e-7 * v0), v0
    assert np.all(errs[True] < 1e-5), errs
    assert np.median(errs[False]) > 10 * np.median(errs[True]), errs


def test_every_sample_of_a_contact_reads_the_same_onset():
    """One central impact of a free journal at 1 m/s (onset at 0.5 ms): every output sample from
    the step that crossed into contact on, those before the onset inside that step included,
    reads the same contact_start, bit for bit. (The crossing step's dense output used to add the
    jump from the -1e9 s sentinel to the old value, keeping ~1e-7 s of the onset: such a sample
    read 0.49996 ms here, 43 ns off on the benchmark at 3000 rpm.)"""
    mech = free_journal(restitution=0.9, speed=1.0)
    sol = jc.simulate(mech, jc.settings(0.8e-3, n_out=801, rtol=1e-9, atol=1e-13))
    cs = np.asarray(sol.memory.contact_start[:, 0])
    seen = cs[cs > -1.0]
    assert len(seen) > 100 and np.unique(seen).size == 1, np.unique(seen)
    assert seen[0] == pytest.approx(0.5e-3, rel=1e-6)


def test_four_bar_samples_inside_the_onset_step_read_the_impact_mode():
    """Four-bar preset: every in-contact output sample within the first 2e-4 s of a contact (minus
    one sample spacing, since the onset lies between samples) reads mode 1 (impact), every one
    later than 2e-4 s plus a spacing reads mode 2 (continuous contact): the output samples of the
    step that crossed into contact carry the new onset time."""
    mech = jc.preset("four-bar")
    n_out = 801
    t_end = 0.03
    sol = jc.simulate(mech, jc.settings(t_end, n_out=n_out))
    ts, pen, mode = np.asarray(sol.ts), np.asarray(sol.penetration[:, 0]), np.asarray(sol.mode[:, 0])
    dt = ts[1] - ts[0]
    assert dt < 1e-4
    inside, start, checked = pen > 0, None, 0
    for i in range(len(ts)):
        if not inside[i]:
            start = None
            assert mode[i] == 0
            continue
        start = ts[i] if start is None else start
        age = ts[i] - start
        if age < 2e-4 - dt:
            assert mode[i] == 1, (i, ts[i], age)
            checked += 1
        elif age > 2e-4 + dt:
            assert mode[i] == 2, (i, ts[i], age)
    assert checked >= 3


@pytest.mark.slow
def test_vmap_of_exact_onsets_equals_single_runs():
    """A batch of restitutions under vmap gives each member's single run (each member keeps its own
    step sequence, the onset rejection included) to 1e-9 of the clearance."""
    mech = falling_journal()
    s = jc.settings(T_END, n_out=5, rtol=1e-6, atol=1e-12)
    crs = jnp.asarray([0.3, 0.6, 0.9])
    batch = jax.vmap(lambda c: jc.simulate(params.replace(mech, "restitution", c), s).q[:, 0])(crs)
    for k, c in enumerate(crs):
        single = jc.simulate(params.replace(mech, "restitution", c), s).q[:, 0]
        np.testing.assert_allclose(np.asarray(batch[k]), np.asarray(single), rtol=0, atol=1e-9 * CLEARANCE)


@pytest.mark.slow
def test_gradient_through_exact_onsets_matches_central_differences():
    """d x(T) / d c_r and d x(T) / d K after the first impact, reverse mode through the onset
    rejections (step-size decisions are not differentiated), against central differences
    (relative step 1e-4; at rtol 1e-10 the loss noise is ~1e-10, so the difference is good to
    ~1e-5; allowed 1e-3 as in tests/test_gradients.py)."""
    mech = falling_journal()
    s = jc.settings(0.9e-3, n_out=3, rtol=1e-10, atol=1e-14)

    def f(x):
        m = params.replace_many(mech, {"restitution": x[0], "stiffness": x[1] * 1e10})
        return jc.simulate(m, s).qdot[-1, 0]

    x0 = np.array([0.3, 1.0])
    g = np.asarray(jax.jit(jax.grad(f))(jnp.asarray(x0)))
    ff = jax.jit(f)
    assert np.all(np.isfinite(g))
    for i in range(2):
        h = 1e-4 * x0[i]
        e = np.zeros(2)
        e[i] = h
        fd = (float(ff(jnp.asarray(x0 + e))) - float(ff(jnp.asarray(x0 - e)))) / (2 * h)
        assert abs(g[i] - fd) <= 1e-3 * abs(fd), (i, g[i], fd)
    assert abs(g[0]) > 0


@pytest.mark.parametrize("name", ["slider-crank-guide-clearance", "slider-crank-pin-slot", "lubricated"])
def test_onset_fraction_of_every_element_kind(name):
    """Each element kind's ``onset`` finds the crossing of a step that enters contact: along the
    straight path q(t) = qa + (t / h) (qb - qa) (velocities (qb - qa) / h at both ends) from a free
    state off the centre to one in contact, its fraction matches the root of the penetration
    found by bisection to 0.02 (the cubic Hermite estimate over a step much longer than a real
    one), and it reports no onset for a step that stays free."""
    mech = jc.preset("flores-slider-crank", viscosity=0.4) if name == "lubricated" else jc.preset(name)
    element = mech.clearance_joints[0]
    q0 = jnp.asarray(jc.assemble(mech, 0.0).q)
    state = element.state_init()
    depth = lambda q: float(jnp.max(jnp.atleast_1d(_penetrations(mech, element, q))))
    rng = np.random.default_rng(0)
    found = False
    for _ in range(200):
        v = jnp.asarray(rng.normal(size=q0.shape[0]))
        for scale in (1e-4, 3e-4, 1e-3, 3e-3):
            qa, qb = q0 + 0.3 * scale * v, q0 + scale * v
            if depth(qa) <= 0 < depth(qb):
                found = True
                break
        if found:
            break
    assert found
    lo, hi = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if depth(qa + mid * (qb - qa)) <= 0 else (lo, mid)
    h = 1e-3
    qd = (qb - qa) / h
    s, crossed = element.onset(mech, 0.0, qa, qd, h, qb, qd, state)
    assert bool(crossed)
    assert abs(float(s) - lo) < 0.02, (float(s), lo)
    s_free, crossed_free = element.onset(mech, 0.0, q0 + 0.1 * scale * v, qd, h, qa, qd, state)
    assert not bool(crossed_free) and float(s_free) == 1.0


def _penetrations(mech, element, q):
    qd = jnp.zeros_like(q)
    if hasattr(element, "corner_kinematics"):
        return jax.vmap(element.law.penetration)(element.corner_kinematics(mech, q, qd))
    return element.law.penetration(element.kinematics(mech, q, qd))


def test_accuracy_benchmark_quick(tmp_path):
    """benchmarks/bench_accuracy.py runs end to end on a tiny window (no cached reference): a table,
    a JSON file and a PNG, finite errors, one speed-up row for the one SciPy run."""
    import bench_accuracy

    res = bench_accuracy.main(["--quick", "--t-end", "4e-4", "--n-out", "21", "--no-cache", "--rtols", "1e-6",
                                "--out", str(tmp_path)])
    assert (tmp_path / "accuracy_quick.json").exists() and (tmp_path / "accuracy_quick.png").exists()
    errs = [r["error"] for r in res["rows"] if r["code"] == "jaxclear"]
    assert all(math.isfinite(e) for e in errs)
    assert len(res["speedups"]) == 1 and len(res["interpolated_speedups"]) == 1


def test_accuracy_benchmark_interpolates_on_the_front():
    """The interpolated equal-accuracy time: on a front with time proportional to error^-1/4
    (a fourth-order method), log-linear interpolation is exact; a dominated run is ignored; a
    SciPy error above the fastest run's error takes that run's time (no extrapolation to
    faster); one below every jaxclear error gets none."""
    import bench_accuracy

    def row(code, err, t, rtol=1e-6):
        return dict(code=code, case="c", solver="x", rtol=rtol, error=err, steady_s=t)

    jax_rows = [row("jaxclear", e, 0.01 * e ** -0.25) for e in (1e-2, 1e-4, 1e-6)]
    jax_rows.append(row("jaxclear", 1e-3, 1.0))  # dominated: slower than the 1e-4 run
    scipy_rows = [row("scipy", 1e-3, 5.0), row("scipy", 1e-1, 1.0), row("scipy", 1e-8, 9.0)]
    ups = bench_accuracy.interpolated_speedups(jax_rows + scipy_rows)
    assert abs(ups[0]["jaxclear_s"] - 0.01 * 1e-3 ** -0.25) < 1e-12
    assert abs(ups[1]["jaxclear_s"] - 0.01 * 1e-2 ** -0.25) < 1e-12
    assert ups[2]["speedup"] is None


def test_contact_switches_match_the_roots_of_the_cubic():
    """The sign changes of the cubic Hermite interpolant found between its extrema equal the real
    roots in (0, 1) of the same cubic found by numpy.roots (companion matrix eigenvalues, an
    independent method): count, first and last root to 1e-9 (of the step), and the rate at the
    last root to 1e-8 of the cubic's rate scale."""
    from jaxclear.elements.memory import contact_switches

    rng = np.random.default_rng(3)
    h = 1e-5
    checked = {0: 0, 1: 0, 2: 0, 3: 0}
    for _ in range(400):
        roots = np.sort(rng.uniform(-0.5, 1.5, 3))
        scale = rng.choice([-1.0, 1.0]) * 1e-6
        coeffs = scale * np.poly(roots)  # a s^3 + b s^2 + c s + d
        val = lambda s: np.polyval(coeffs, s)
        dval = lambda s: np.polyval(np.polyder(coeffs), s)
        p0, p1, r0, r1 = val(0.0), val(1.0), dval(0.0) / h, dval(1.0) / h
        inside = np.sort([r.real for r in np.roots(coeffs) if abs(r.imag) < 1e-12 and 0 < r.real < 1])
        # keep draws whose roots are clear of the ends and of each other (no double roots)
        if np.any(np.abs(np.concatenate([inside, inside - 1])) < 1e-3) or np.any(np.diff(inside) < 1e-3):
            continue
        sw = contact_switches(jnp.asarray(p0), jnp.asarray(p1), r0, r1, h)
        assert int(sw.count) == len(inside), (roots, inside)
        checked[len(inside)] += 1
        if len(inside):
            assert abs(float(sw.first) - inside[0]) < 1e-9
            assert abs(float(sw.last) - inside[-1]) < 1e-9
            # a root error of 1e-9 moves the rate by 1e-9 times the slope's derivative: bound it by
            # the cubic's rate scale sum(|coefficients|) / h
            assert abs(float(sw.last_rate) - dval(inside[-1]) / h) < 1e-8 * np.abs(coeffs).sum() / h
    assert min(checked.values()) >= 10, checked


def test_separating_steps_keep_the_approach_speed_of_their_contact():
    """A bouncing journal (Lankarani-Nikravesh, c_r = 0.9: the law's force is positive throughout
    a contact, chi = 3 (1 - c_r^2) / 4 < 1 / c_r): every output sample with a positive penetration
    has a positive normal force, also the samples inside the steps that separate (their memory
    is the onset's approach speed, not the separating rate), and the run bounces more than once."""
    mech = falling_journal(restitution=0.9, law="lankarani-nikravesh")
    sol = jc.simulate(mech, jc.settings(4e-3, n_out=4001, rtol=1e-6, atol=1e-12))
    pen, force = np.asarray(sol.penetration[:, 0]), np.asarray(sol.normal_force[:, 0])
    assert int(sol.impacts[0]) >= 2
    touching = pen > 1e-12
    assert touching.sum() > 50
    assert np.all(force[touching] > 0.0)


@pytest.mark.parametrize("h", [1e-9, 1e-7, 1e-5])
def test_approach_speed_derivative_on_short_steps(h):
    """The approach speed stored at an onset, differentiated (forward mode) with respect to the
    wall's position, against the closed form of a uniformly accelerated approach: the
    penetration is ``X(t) - W`` with ``X = X0 + v t + a t^2 / 2`` (X0 = 0.35 m, so the
    penetrations carry the rounding of coordinates, ~1e-17 m) and ``W = X0 + w``; the crossing
    t_c solves ``v t + a t^2 / 2 = w``, so ``d delta'(t_c) / dw = a / (v + a t_c)``. The cubic
    Hermite interpolant is exact for this quadratic, so only rounding separates them: measured
    below 4e-8 (relative) for steps of 1 ns to 10 us and crossings at 2, 50 and 98 % of the
    step; allowed 1e-6. (With the curvature term differentiated through the crossing fraction,
    the rounding of the penetrations divided by h^2 made it 60 % off on the 1 ns step and 5e-4
    on the 100 ns one: the exact-onset steps are that short, and a fit's Jacobian came out 10 to
    600 times too large.) The value itself is off by the rounding of the penetrations divided by
    the step (measured 5e-9 m/s on the 1 ns step)."""
    from jaxclear.elements.memory import contact_switches

    x0, v, a = 0.35, 0.16, 33.5
    for frac in (0.02, 0.5, 0.98):
        tc = frac * h

        def rate(w):
            wall = x0 + w
            p0 = x0 - wall
            p1 = (x0 + v * h + 0.5 * a * h * h) - wall
            return contact_switches(p0, p1, v, v + a * h, h).last_rate

        r, dr = jax.jvp(rate, (jnp.asarray(v * tc + 0.5 * a * tc**2),), (jnp.asarray(1.0),))
        # the value: the penetrations' rounding (eps X0) divided by the step bounds its error
        assert abs(float(r) - (v + a * tc)) < 10 * np.finfo(float).eps * x0 / h + 1e-12, (frac, float(r))
        exact = a / (v + a * tc)
        assert abs(float(dr) / exact - 1.0) < 1e-6, (frac, float(dr), exact)


@pytest.mark.parametrize("h", [1e-5, 1e-4])
def test_approach_speed_derivative_on_long_steps_with_jerk(h):
    """The onset time's part of the approach speed's derivative takes the penetration's
    acceleration at the onset, not its mean over the step: an approach with jerk, ``X = X0 + v t
    + a t^2/2 + j t^3/6`` against a wall at ``X0 + w``, has ``d delta'(t_c)/dw = delta''(t_c) /
    delta'(t_c) = (a + j t_c) / (v + a t_c + j t_c^2/2)`` (implicit function theorem on
    ``X(t_c) = X0 + w``). The cubic Hermite interpolant is exact for a cubic, so its curvature
    term (differentiated through the crossing fraction where it is resolved) recovers it:
    measured 1e-10 - 5e-8 (relative; rounding of the penetrations over the step); allowed 1e-6.
    With the mean acceleration ``(r1 - r0)/h = a + j h/2`` (the curvature term's weight held
    fixed, as before 2026-11-26) it was 10 - 19 % off here (j h = 20 m/s^2 against a = 33.5), and the translational clearance joint's sensitivities 2 % off after its fourth
    onset (benchmarks/bench_gradients.py)."""
    from jaxclear.elements.memory import contact_switches

    x0, v, a, j = 0.35, 0.16, 33.5, 2e5 * (1e-4 / h)
    X = lambda t: x0 + v * t + a * t**2 / 2 + j * t**3 / 6
    V = lambda t: v + a * t + j * t**2 / 2
    for frac in (0.3, 0.9999):
        tc = frac * h

        def rate(w):
            wall = x0 + w
            return contact_switches(x0 - wall, X(h) - wall, v, V(h), h).last_rate

        r, dr = jax.jvp(rate, (jnp.asarray(X(tc) - x0),), (jnp.asarray(1.0),))
        assert abs(float(r) / V(tc) - 1.0) < 1e-9, (frac, float(r))
        exact = (a + j * tc) / V(tc)
        assert abs(float(dr) / exact - 1.0) < 1e-6, (frac, float(dr), exact)


@pytest.mark.parametrize("h", [1e-13, 1e-12, 1e-11])
def test_approach_speed_derivative_with_the_vector_fields_acceleration(h):
    """The sensitivity solve approaches an onset in steps of 1e-14 - 1e-12 s, where the rates'
    change over the step, ``(r1 - r0)/h``, is the rounding of velocities: here each rate is the
    difference of two velocities of order 20 m/s (``(U + V(t)) - U``), as a journal's
    penetration rate is. With the penetration's accelerations at the step's ends (``accel``,
    from the vector field) the approach speed's derivative with respect to the wall's position
    is the closed form ``delta''(t_c) / delta'(t_c) = a / (v + a t_c)`` (implicit function
    theorem on ``X(t_c) = X0 + w``, uniformly accelerated approach): measured 1e-12 - 3e-9
    (relative); allowed 1e-8. From the rates' change alone it is 1.2e-6 (h = 1e-11 s) to
    6.2e-5 (1e-13 s) off here, and at an onset where the onset time's part nearly cancels the
    rate's tangent that error is multiplied (bench_gradients.py: the approach speed's
    derivative 7e-3 m/s off at the benchmark's onset at 1.57 ms); asserted above 1e-5 on the
    two shorter steps, so this test would see it come back."""
    from jaxclear.elements.memory import contact_switches

    x0, v, a, U = 0.35, 0.16, 33.5, 20.0
    r0, r1 = (U + v) - U, (U + (v + a * h)) - U  # rounded like a journal's penetration rate
    for frac in (0.5, 0.9999):
        tc = frac * h
        exact = a / (v + a * tc)
        errors = {}
        for accel in ((a, a), None):
            def rate(w):
                wall = x0 + w
                return contact_switches(x0 - wall, (x0 + v * h + 0.5 * a * h * h) - wall, r0, r1, h, accel).last_rate

            _, dr = jax.jvp(rate, (jnp.asarray(v * tc + 0.5 * a * tc**2),), (jnp.asarray(1.0),))
            errors[accel is None] = abs(float(dr) / exact - 1.0)
        assert errors[False] < 1e-8, (frac, errors)
        assert h > 1e-12 or errors[True] > 1e-5, (frac, errors)
