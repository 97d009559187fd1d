"""NILSAS (jaxclear.shadowing.nilsas, issue 44): the adjoint form of least-squares shadowing.

Truths that do not come from the adjoint code:

* Lorenz 63's d<z>/d rho against the slope of <z> over 7 values of rho in [25, 31] (plain runs,
  tests/test_shadowing.py's regression), and all three parameters (sigma, rho, beta) against NILSS,
  whose tangents share nothing with the adjoints but the least squares;
* van der Pol's limit cycle against central differences of weighted Birkhoff averages (the time
  dilation, which the adjoint's flow component carries, is half the answer there);
* a forced linear oscillator against its closed form, two parameters at once;
* the adjoint is the same whatever the parameters: 12 parameters cost what 3 do (the same steps),
  and their derivative is the 3 forcings' derivative times the weights (exact linearity).

Measured here (docs/theory/shadowing.md, "NILSAS"): Lorenz 63 over 4 x 200 time units, NILSAS
(0.1335, 1.0172, -1.651) +- (0.0003, 0.002, 0.009) against NILSS (0.1332, 1.0166, -1.646) +-
(0.0004, 0.0006, 0.011); van der Pol equal to NILSS to 1e-8 relative.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxclear._errors import SolverError
from jaxclear.shadowing import nilsas, nilss
from test_shadowing import (SHADOWING_GAP, U0, _birkhoff_mean, forced_oscillator, oscillator_exact, regression_slope,
                            skewed, van_der_pol)

S3 = jnp.array([10.0, 28.0, 8.0 / 3.0])


def lorenz3(u, s):
    sigma, rho, beta = s
    x, y, z = u
    return jnp.stack([sigma * (y - x), x * (rho - z) - y, x * y - beta * z])


def height(u, s):
    return u[2]


RUN = dict(n_unstable=1, segment_time=0.25, segments=800, members=4, transient=20.0, rtol=1e-7, atol=1e-7)


@pytest.mark.extended
def test_lorenz_three_parameters_agree_with_nilss_and_the_slope_of_long_runs():
    slope, slope_se, _, _ = regression_slope(np.linspace(25.0, 31.0, 7))
    adjoint = nilsas(lorenz3, U0, S3, height, discard=8, **RUN)
    tangent = nilss(lorenz3, U0, S3, height, discard=8, **RUN)
    d, e = np.asarray(adjoint.derivative), np.asarray(adjoint.derivative_error)
    d_t, e_t = np.asarray(tangent.derivative), np.asarray(tangent.derivative_error)
    print(f"\nNILSAS {d} +- {e}\nNILSS  {d_t} +- {e_t}\nslope d<z>/drho {slope:.4f} +- {slope_se:.4f}")
    assert adjoint.method == "NILSAS" and adjoint.derivative.shape == (3,) and "NILSAS" in adjoint.summary()
    # rho: the independent regression, with the shadowing gap of test_shadowing.py
    assert abs(d[1] - slope) <= 3.0 * np.hypot(e[1], slope_se) + SHADOWING_GAP
    # every parameter: NILSS, within 4 combined standard errors (3 parameters: a 4-sigma band
    # keeps a false alarm below 2e-4) plus 0.5 % for the finite runs' O(1/T) terms, which the two
    # algorithms make at opposite ends of the run
    assert np.all(np.abs(d - d_t) <= 4.0 * np.hypot(e, e_t) + 5e-3 * np.abs(d_t))
    assert np.all(e < 0.02 * np.abs(d))
    # the adjoints' growth backwards is Lorenz 63's largest exponent, 0.906
    assert abs(float(np.mean(adjoint.exponents)) - 0.906) < 0.05
    assert abs(float(adjoint.average) - float(tangent.average)) < 3.0 * np.hypot(float(adjoint.average_error),
                                                                               float(tangent.average_error)) + 0.05


def test_limit_cycle_gives_the_ordinary_derivative_with_its_time_dilation():
    exact = float((jax.jit(_birkhoff_mean)(1.0 + 1e-3) - jax.jit(_birkhoff_mean)(1.0 - 1e-3)) / 2e-3)  # 0.111398
    result = nilsas(van_der_pol, jnp.array([2.0, 0.0]), 1.0, skewed, n_unstable=0, segment_time=1.0, segments=500,
                    members=2, transient=50.0, rtol=1e-9, atol=1e-9)
    print(f"\nvan der Pol: NILSAS {float(result.derivative):.8f}, central differences {exact:.6f}")
    # as for NILSS: a plain average over 500 time units (75 periods) is good to about period / T
    assert abs(float(result.derivative) - exact) < 0.01 * abs(exact)
    assert result.exponents.shape == (2, 0)


def test_forced_oscillator_gives_the_closed_form_for_two_parameters():
    k, amplitude = 2.0, 0.7
    mean, exact = oscillator_exact(k, amplitude)
    result = nilsas(forced_oscillator, jnp.array([0.0, 0.0, 1.0, 0.0]), jnp.array([k, amplitude]),
                    lambda u, s: u[0] ** 2, n_unstable=0, segment_time=1.0, segments=840, discard=40, members=2,
                    transient=60.0, rtol=1e-9, atol=1e-9, spread=1e-7)
    print(f"\nforced oscillator: NILSAS {np.asarray(result.derivative)}, exact {exact}")
    # the adjoint starts at the run's end with its flow component only and reaches the forced
    # response backwards at the damping rate zeta omega_n = 0.42 1/s: the last 40 segments (e^-17)
    # are left out; what remains is the plain average's error of order period / T (4.8 / 800)
    np.testing.assert_allclose(np.asarray(result.derivative), exact, rtol=3e-3)
    assert result.time == 800.0 and "40 left out at the end" in result.summary()
    assert abs(float(result.average) - mean) < 2e-3 * mean


@pytest.mark.extended
def test_the_adjoint_does_not_depend_on_how_many_parameters_there_are():
    """12 parameters: constant forcings ``B s`` added to Lorenz 63 (``B`` 3 x 12, ``s`` = 0). The
    adjoint and every solve are those of the three unit forcings (the same steps), and the
    derivative is ``B^T`` times theirs."""
    B = jnp.asarray(np.random.default_rng(0).normal(size=(3, 12)))

    def forced(weights):
        return lambda u, s: lorenz3(u, S3) + weights @ s

    run = dict(RUN, segments=40, members=2)
    three = nilsas(forced(jnp.eye(3)), U0, jnp.zeros(3), height, **run)
    twelve = nilsas(forced(B), U0, jnp.zeros(12), height, **run)
    np.testing.assert_array_equal(np.asarray(three.steps), np.asarray(twelve.steps))
    np.testing.assert_allclose(np.asarray(twelve.member_derivatives), np.asarray(three.member_derivatives) @ B,
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(np.asarray(three.member_averages), np.asarray(twelve.member_averages))


def test_a_failed_solve_raises_a_solver_error_naming_nilsas():
    with pytest.raises(SolverError, match=r"nilsas: the solve .*max_steps = 2 per segment.*raise max_steps"):
        nilsas(lorenz3, U0, S3, height, n_unstable=1, segment_time=0.25, segments=3, members=2, max_steps=2)
