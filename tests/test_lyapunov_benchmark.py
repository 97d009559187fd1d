"""Lyapunov exponents of the benchmark slider-crank (jaxclear.chaos) against truths that hold
whatever the code: a Hamiltonian motion's spectrum sums to zero and pairs as +-lambda, and the
largest exponent of a periodic orbit is ln|mu_1|/T of the largest Floquet multiplier of its
monodromy matrix (here from forward-mode differentiation of one period's flow map, a derivative
that does not go through the Lyapunov code's tangents, projections or renormalisations)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.chaos import lyapunov, manifold
from jaxclear.integrate import _solve as solve
from jaxclear.integrate._system import MechanismSystem


@pytest.mark.extended
def test_undamped_hertz_spectrum_sums_to_zero_and_pairs_at_the_defaults():
    """Frictionless, purely elastic Hertz contact (law "hertz": no damping, so no force reads the
    approach speed) at 5000 rpm: a Hamiltonian motion on the 4-dimensional constraint manifold
    (the crank is driven at a constant speed: a time-periodic Hamiltonian), whose tangent map is
    symplectic, so its volume is kept (the exponents sum to 0) and they pair as +-lambda.

    At the defaults (one revolution a reporting interval, the renormalisation steps adapted to
    max_growth = ln(0.01/rtol) = 9.2) over 8 counted revolutions. Measured: sum -0.0015 to
    -0.004 1/s (at max_growth 3, 6, 9; 10 revolutions), against +899 renormalised once a
    revolution and +7.9 every eighth (whose steps still spread the growths by up to e^16 in a
    contact). Tolerances: the sum is the growth of the tangents' volume, which the integration
    keeps to its tolerance: |sum| t < 0.01 (the volume after t = 8 revolutions is 1 to 1 %), i.e.
    |sum| < 0.1 1/s, 1e-4 of lambda_1 and 10,000 times below the fixed interval's error. The
    pairs of finite-time exponents from a QR factorisation meet only as 1/t (the angle between the
    QR basis and the symplectic pairs is bounded, not zero): lambda_1 + lambda_4 and lambda_2 +
    lambda_3 within 10 % of lambda_1 (measured 1.5 to 4 % over 10 revolutions; the fixed interval's
    lambda_1 + lambda_4 was 900 1/s, 61 % of its lambda_1)."""
    mech = jc.preset("flores-slider-crank", law="hertz", friction=0.0)
    period = jc.crank_period(mech)
    r = lyapunov(mech, jc.settings(10 * period), transient=2 * period, count=4, samples=1, keep=False)
    lam = np.asarray(r.exponents)
    print("exponents", lam, "sum", float(r.sum), "renormalisations", np.asarray(r.renormalisations))
    assert int(r.status) == 0
    assert lam[0] > 500.0  # chaotic: the pairing is not 0 = 0
    assert abs(float(r.sum)) * 8 * period < 0.01
    assert abs(lam[0] + lam[3]) < 0.1 * lam[0] and abs(lam[1] + lam[2]) < 0.1 * lam[0]


#: The Lyapunov runs of the two tests below (the benchmark's mechanism at two operating points: the
#: same structure) share their static arguments (five intervals, the first discarded, all four
#: exponents, one sample an interval), so that both use one compiled program.
SHARED = dict(count=4, discard=1, samples=1)


@pytest.mark.extended
def test_periodic_point_exponent_is_its_floquet_multiplier():
    """The chaos notebook's periodic point (1000 rpm, friction 0.2, c_r 0.3): after a transient the
    journal stays in one contact and the motion repeats every revolution T = 60 ms. Its largest
    Floquet multiplier mu_1, the largest eigenvalue of the monodromy matrix restricted to the
    constraint manifold, B^T W (dy(T)/dy(0)) W^-1 B (B an orthonormal basis of the manifold's
    tangent space in the metric W), is found by jax.jacfwd through one period's solve (diffrax's
    forward mode through the Runge-Kutta steps, rtol 1e-10): mu_1 = -0.225 (real: the perturbation
    flips sign every revolution), ln|mu_1|/T = -24.87 1/s (-24.72 from revolution 20; at rtol 1e-8
    the derivative of the adaptive step sizes, which forward mode through the solver includes,
    moved it by 3 %). The
    approach speed stored at the contact's onset is constant while it lasts: it is not changed by
    a perturbation of (q, qdot) (its row of the monodromy is (0, ..., 0, 1)), so the 4 x 4 block is
    the map of such perturbations. jc.lyapunov's lambda_1 (one revolution an interval; the largest
    of all four, as with count 1) is the same to 2 %: the two derivatives' errors at their
    tolerances (measured -24.83 at the default rtol 1e-6, 0.2 % from the multiplier's, with count
    1 and with all four; the multiplier itself moves by 0.6 % between
    revolutions 8 and 20). Two nearby trajectories gave -10.6 instead when their distance was
    measured and rescaled in the full state: off the constraint manifold the pair's separation
    decays only at the Baumgarte stabilisation's rates (-5 1/s at the default gains), and once the
    part on the manifold has decayed it dominates. Measured and rescaled on the manifold's tangent
    space (manifold.projector) every half revolution, the pair gives -24.74 (distance 1e-6) and
    -24.79 (1e-4) over revolutions 25-30 (rtol 1e-10)."""
    mech = jc.preset("flores-slider-crank", speed_rpm=1000.0, friction=0.2, restitution=0.3)
    period = float(jc.crank_period(mech))
    n = mech.n_coordinates
    s = jc.settings(10 * period, rtol=1e-10, atol=1e-14, adjoint="forward", max_steps=200_000)
    system = MechanismSystem(mech, s.baumgarte)

    def flow(t0, t1, y):
        return solve.integrate_system(system, s, t0, t1, jnp.asarray([t1]), y).samples[-1]

    t0 = 8 * period
    y = jax.jit(flow)(0.0, t0, solve.start_run(mech, s, None).packed)
    jac = np.asarray(jax.jit(jax.jacfwd(lambda v: flow(t0, t0 + period, v)))(y))
    w = np.asarray(manifold.weights(mech, manifold.time_scale(mech)))
    basis = np.asarray(manifold.tangent_basis(mech, t0, y[:n], y[n:2 * n], jnp.asarray(w), 4))
    monodromy = basis.T @ (w[:, None] * jac[:2 * n, :2 * n]) @ (basis / w[:, None])
    mu = np.linalg.eigvals(monodromy)
    floquet = math.log(np.max(np.abs(mu))) / period
    r = lyapunov(mech, jc.settings(t0 + 5 * period), transient=t0, **SHARED)
    print("multipliers", mu, "Floquet exponent", floquet, "lyapunov", float(r.exponents[0]))
    assert -30.0 < floquet < -20.0
    assert abs(float(r.exponents[0]) - floquet) < 0.02 * abs(floquet)


@pytest.mark.extended
def test_full_spectrum_volume_is_the_tangent_maps_determinant():
    """The sum of the log growths of all four directions over an interval is the log of the
    volume the tangent map gives the manifold's unit cube, ln sqrt(det(X^T X)), X = P W (dy(t+h)/dy(t))
    W^-1 B, whatever the renormalisations within it: here on the benchmark at 5000 rpm over
    eighths of a revolution that begin at 3.25 and 3.5 revolutions (5 and 1 contact onsets inside:
    the stored approach speed's saltation and the damping it sets act), against jax.jacfwd
    through one solve of the interval (rtol 1e-10, diffrax's forward mode; the memory held at the
    interval's start, as the Lyapunov run's first interval holds it). Measured: -0.77298 and
    -0.77298, -17.15790 and -17.15781 (and from 4 revolutions -23.91547 and -23.91575: to 2e-5
    relative). Tolerance 1e-3 of
    the volume's log plus 1e-3: the Lyapunov run's tolerance rtol 1e-6 over a growth spread of up
    to e^23. Intervals whose smallest direction contracts by more than e^25 relative to the
    largest are beyond the forward-mode derivative's resolution at rtol 1e-10 and are not used
    (the Lyapunov run's adaptive steps resolve them: ln det -430 to -480 in an eighth of a
    revolution in a contact entered at a very small approach speed, where jacfwd gives -40)."""
    from jaxclear.integrate import State

    mech = jc.preset("flores-slider-crank")
    period = float(jc.crank_period(mech))
    n, h = mech.n_coordinates, period / 8
    sf = jc.settings(period, rtol=1e-10, atol=1e-14, adjoint="forward", max_steps=400_000)
    system = MechanismSystem(mech, sf.baumgarte)
    jac = jax.jit(jax.jacfwd(lambda t0, y: solve.integrate_system(system, sf, t0, t0 + h, jnp.asarray([t0 + h]),
                                                            y).samples[-1], argnums=1))
    w = np.asarray(manifold.weights(mech, manifold.time_scale(mech)))
    for k in (10, 12):
        ta = 2 * period + k * h
        r = lyapunov(mech, jc.settings(ta + 5 * h), interval=h, transient=ta, **SHARED)
        sol = jc.simulate(mech, jc.settings(ta, n_out=2))  # the state the Lyapunov run starts from
        y = State(sol.q[-1], sol.qdot[-1], jax.tree_util.tree_map(lambda x: x[-1], sol.element_states)).pack()
        assert float(r.packed[0][2 * n + 2] - y[2 * n + 2]) >= 1  # an onset inside
        basis = np.asarray(manifold.tangent_basis(mech, ta, y[:n], y[n:2 * n], jnp.asarray(w), 4))
        end = r.packed[0]
        proj = np.asarray(manifold.projector(mech, ta + h, end[:n], end[n:2 * n], jnp.asarray(w)))
        x = proj @ (w[:, None] * np.asarray(jac(ta, y))[:2 * n, :2 * n] @ (basis / w[:, None]))
        volume = float(np.sum(np.log(np.linalg.svd(x, compute_uv=False))))
        benettin = float(np.sum(np.asarray(r.log_growth[0])))
        print(k, benettin, volume)
        assert abs(benettin - volume) < 1e-3 * abs(volume) + 1e-3
