"""The ANCF beam (issue 43, items 3 and 5): statics and natural frequencies against truths not
from our code (Euler-Bernoulli closed forms, the elastica's elliptic integrals and Mattiasson's
table), material damping, derivatives, input checks.

The beam is steel, 1 m, 10 mm x 10 mm: EI = 175 N m^2, EA = 2.1e7 N, slender (L/b = 100), so
shear and the extensibility the elastica leaves out are far below the tolerances."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

import jaxclear  # noqa: F401  (float64)
from jaxclear._errors import MechanismError, ParameterError
from jaxclear.flexible import ancf
from jaxclear.flexible.beam import AncfBeam
from jaxclear.flexible.statics import natural_frequencies, static_equilibrium
from jaxclear.flexible.supports import BeamLoad, ClampSupport, PinSupport

E, RHO, B, L = 2.1e11, 7800.0, 0.01, 1.0
A, I = B * B, B**4 / 12
EI = E * I


def steel(n, **kw):
    return AncfBeam("rod", L, E, RHO, A, I, n_elements=n, **kw)


def tip_under(n, alpha, steps):
    """Tip position of a cantilever (clamped at x = 0 along x) under a vertical dead load
    P = alpha EI / L^2 at its end."""
    beam = steel(n)
    load = BeamLoad("end", (0.0, -alpha * EI / L**2))
    res = static_equilibrium(beam, [ClampSupport("start")], [load], steps=steps, iterations=10)
    assert float(res.residual) < 1e-6  # N: the Newton iterations converged (loads of 1e-4 to 1e4 N)
    return np.asarray(beam.position(res.e, L))


# ---- (a) statics -------------------------------------------------------------------------


def test_small_tip_deflection_matches_euler_bernoulli():
    """P L^3 / (3 EI) for a small load (v/L = 6e-4). The cubic interpolation holds the linear
    solution exactly; what is left is the coupling of the axial strain |r'| - 1 to the slope,
    which one element cannot relax (membrane locking of the cable element: an error growing
    like the load squared, 5.4e-8 at P = 0.01 N, 5.4e-4 at 1 N with one element) and which
    vanishes fast as elements are added: measured relative errors 5.3e-5 (1 element),
    2.0e-6 (2), 4.1e-7 (4)."""
    alpha = 1.8e-3  # P = 0.315 N
    exact = alpha / 3 * L
    errors = [abs(-tip_under(n, alpha, steps=1)[1] - exact) / exact for n in (1, 2, 4)]
    assert errors[0] < 1e-4 and errors[1] < 5e-6 and errors[2] < 1e-6
    assert errors[0] > errors[1] > errors[2]


def elastica(alpha):
    """Tip of the inextensible elastica of a cantilever under a transverse end load,
    alpha = P L^2/EI: (u/L, v/L, tip rotation) from the elliptic-integral solution (Bisshopp and
    Drucker 1945), integrated here by quadrature: sqrt(2 alpha) = int_0^t dth / sqrt(sin t -
    sin th), x/L = sqrt(2 sin t / alpha), y/L = int_0^t sin th dth / sqrt(...) / sqrt(2 alpha),
    with sin th = sin t (1 - v^2) to remove the end singularity (tip rotations t up to 1.5 rad:
    alpha up to about 25)."""
    def integral(t, f):
        st = math.sin(t)

        def g(v):
            s = st * (1 - v * v)
            return 2 * math.sqrt(st) * f(s) / math.sqrt(1 - s * s)
        return quad(g, 0, 1, epsabs=1e-13, epsrel=1e-13)[0]

    t = brentq(lambda t: integral(t, lambda s: 1.0) - math.sqrt(2 * alpha), 1e-6, 1.5, xtol=1e-14)
    return 1 - math.sqrt(2 * math.sin(t) / alpha), integral(t, lambda s: s) / math.sqrt(2 * alpha), t


#: Mattiasson (1981), Table 1: alpha = P L^2/EI -> (u/L, v/L) of the tip of a cantilever under a
#: transverse end load (five digits)
MATTIASSON = {1.0: (0.05643, 0.30172), 2.0: (0.16064, 0.49346), 5.0: (0.38763, 0.71379), 10.0: (0.55500, 0.81061)}


def test_elastica_table_is_the_elliptic_solution():
    """The tabulated values and our quadrature of the elliptic integrals agree to the table's
    five digits (so either is the truth for the next test)."""
    for alpha, (u, v) in MATTIASSON.items():
        uu, vv, _ = elastica(alpha)
        assert abs(uu - u) < 6e-6 and abs(vv - v) < 6e-6


def test_large_tip_deflection_converges_to_the_elastica():
    """Large deflection (alpha = 1, 5, 10: tip rotation up to 82 degrees), 20 load steps. The
    error in v/L at alpha = 10 is 9.7e-3 with 4 elements, 1.2e-3 with 8 and 1.7e-5 with 16
    (the table's five digits and the beam's axial stretch, P/EA = 8e-5, are the floor); with 16
    elements every displacement is within 1e-4 L of the table (largest 5.1e-5, u/L at
    alpha = 10)."""
    errors = {}
    for n in (4, 8, 16):
        for alpha in (1.0, 5.0, 10.0):
            x, y = tip_under(n, alpha, steps=20)
            u, v = MATTIASSON[alpha]
            errors[n, alpha] = max(abs((L - x) / L - u), abs(-y / L - v))
    for alpha in (1.0, 5.0, 10.0):
        assert errors[16, alpha] < 1e-4
        assert errors[4, alpha] > 4 * errors[8, alpha] and errors[8, alpha] > 4 * errors[16, alpha]


# ---- (b) natural frequencies ---------------------------------------------------------------


def test_cantilever_and_pinned_frequencies_converge_at_fourth_order():
    """First frequencies against the Euler-Bernoulli closed forms omega = (beta L)^2
    sqrt(EI / (rho A L^4)): cantilever beta_n L = 1.87510, 4.69409 (Blevins), pinned-pinned
    n pi. Cubic Hermite elements converge at order 2(p + 1 - m) = 4 in the eigenvalue
    (Strang and Fix); measured, cantilever first frequency: relative errors 4.8e-3, 4.8e-4,
    3.3e-5, 2.1e-6 with 1, 2, 4, 8 elements (observed orders 3.3, 3.9, 4.0)."""
    scale = math.sqrt(EI / (RHO * A * L**4))
    cantilever = np.array([1.875104069, 4.694091133]) ** 2 * scale
    pinned = (np.arange(1, 4) * math.pi) ** 2 * scale
    errs_c, errs_p = [], []
    for n in (1, 2, 4, 8):
        beam = steel(n)
        w = np.asarray(natural_frequencies(beam, [ClampSupport("start")], count=2))
        errs_c.append(abs(w[0] - cantilever[0]) / cantilever[0])
        if n >= 4:
            assert np.allclose(w, cantilever, rtol=2e-3)
        if n >= 2:
            wp = np.asarray(natural_frequencies(beam, [PinSupport("start"), PinSupport("end")], count=3))
            errs_p.append(abs(wp[0] - pinned[0]) / pinned[0])
            if n == 8:
                assert np.allclose(wp, pinned, rtol=2e-3) and abs(wp[0] / pinned[0] - 1) < 1e-4
    orders_c = np.log2(np.array(errs_c[:-1]) / np.array(errs_c[1:]))
    orders_p = np.log2(np.array(errs_p[:-1]) / np.array(errs_p[1:]))
    assert errs_c[-1] < 5e-6 and np.all(orders_c[1:] > 3.7) and np.all(orders_p > 3.7), (orders_c, orders_p)


def test_free_beam_has_three_rigid_modes_and_frequency_derivative():
    """An unsupported beam has three zero frequencies (two translations and a rotation: the strain
    measures vanish exactly under rigid motion), and d omega / d E = omega / (2 E) through the
    eigenproblem (the derivative of a closed form's square root)."""
    beam = steel(4)
    w = np.asarray(natural_frequencies(beam))
    assert np.all(w[:3] < 1e-3 * w[3])
    def first(modulus):
        return natural_frequencies(AncfBeam("rod", L, modulus, RHO, A, I, n_elements=4), [ClampSupport("start")],
                                   count=1)[0]
    w1, dw = jax.value_and_grad(first)(jnp.asarray(E))
    assert abs(float(dw) - float(w1) / (2 * E)) < 1e-9 * float(w1) / E


def test_kelvin_voigt_damping_is_stiffness_proportional():
    """About the straight beam the Kelvin-Voigt force's velocity Jacobian is -eta K (C = eta K:
    modal damping ratio eta omega / 2), the dissipation function is >= 0 and zero under a
    rigid motion (a translation and a rotation rate)."""
    eta = 1e-3
    beam = steel(3, retardation=eta)
    e0 = beam.reference()
    c = jax.jacfwd(lambda v: beam.damping_force(e0, v))(jnp.zeros(beam.n_coordinates))
    k = jax.hessian(beam.strain_energy)(e0)
    assert np.allclose(np.asarray(c), -eta * np.asarray(k), atol=1e-9 * float(jnp.abs(k).max()))
    rigid = jnp.tile(jnp.array([0.3, -0.2, 0.0, 0.0]), beam.n_elements + 1)
    spin = jax.jvp(lambda a: AncfBeam("rod", L, E, RHO, A, I, n_elements=3, angle=a).reference(),
                   (jnp.zeros(()),), (jnp.ones(()),))[1]
    for v in (rigid, spin):
        assert abs(float(beam.dissipation(e0, v))) < 1e-12
    v = jax.random.normal(jax.random.PRNGKey(0), (beam.n_coordinates,))
    assert float(beam.dissipation(e0, v)) > 0


def test_mass_matrix_is_exact():
    """Total mass rho A L (translation), and the element matrix is the textbook consistent mass
    of the cubic Hermite element (its [0, 0] entry 13/35 rho A h)."""
    beam = steel(5)
    m = beam.mass_matrix()
    ones = jnp.tile(jnp.array([1.0, 0.0, 0.0, 0.0]), beam.n_elements + 1)
    assert abs(float(ones @ m @ ones) - RHO * A * L) < 1e-12 * RHO * A * L
    me = ancf.mass_matrix(2.0, 0.5)
    assert abs(float(me[0, 0]) - 13 / 35 * 2.0 * 0.5) < 1e-14
    assert np.all(np.linalg.eigvalsh(np.asarray(m)) > 0)


def test_bad_input_is_named():
    with pytest.raises(ParameterError, match="modulus"):
        AncfBeam("rod", L, -1.0, RHO, A, I)
    with pytest.raises(ParameterError, match=r"n_elements = 0 must be an integer in \[1, 200\]"):
        AncfBeam("rod", L, E, RHO, A, I, n_elements=0)
    with pytest.raises(ParameterError, match="retardation"):
        AncfBeam("rod", L, E, RHO, A, I, retardation=-1.0)
    with pytest.raises(ParameterError, match="arc length of point 'mid'"):
        AncfBeam("rod", L, E, RHO, A, I, points={"mid": 1.5})
    with pytest.raises(MechanismError, match="unknown point 'middle'"):
        natural_frequencies(steel(2), [PinSupport("middle")])


# ---- (c) dynamics --------------------------------------------------------------------------

#: the flexible pendulum of Berzeri and Shabana (2000): L = 1.2 m, A = 0.0018 m^2,
#: I = 1.215e-8 m^4, rho = 5540 kg/m^3, E = 0.7 MPa (a very soft beam: it swings like a heavy
#: rope), pinned at one end, released horizontal at rest under gravity
PENDULUM = dict(length=1.2, modulus=0.7e6, density=5540.0, area=0.0018, second_moment=1.215e-8)


def test_free_flexible_pendulum_conserves_energy():
    """Kinetic + strain + gravity energy of the undamped pendulum over its first swing (1 s, the
    tip from (1.2, 0) through the bottom to (-1.20, -0.29) m), 4 elements, Tsit5 at rtol 1e-8:
    the largest drift measured is 1.9e-8 J of the 70 J the fall releases (3e-10; the pin's
    Baumgarte terms do work only on the constraint residual, ~1e-12 m). With Kelvin-Voigt damping
    (eta = 0.01 s) the energy falls, and the energy lost equals the dissipated work integrated
    along (2 D), to 1e-7 of the energy released."""
    from jaxclear.flexible.motion import BeamSystem, energies, simulate_beam

    ts = jnp.linspace(0.0, 1.0, 51)
    released = PENDULUM["density"] * PENDULUM["area"] * 1.2 * 9.81 * 0.6  # m g L/2 = 70.4 J
    for eta in (0.0, 0.01):
        beam = AncfBeam("pendulum", n_elements=4, retardation=eta, **PENDULUM)
        system = BeamSystem(beam, [PinSupport("start")])
        run = simulate_beam(system, ts, solver="tsit5", rtol=1e-8, atol=1e-10)
        assert int(run.result._value) == 0
        energy = np.asarray(energies(system, run))
        balance = energy + np.asarray(run.dissipated) - energy[0]
        assert np.abs(balance).max() < 1e-7 * released, np.abs(balance).max()
        if eta == 0.0:
            tip = np.asarray(beam.position(run.e[-1], 1.2))
            assert tip[0] < -1.0  # swung to the other side
        else:
            assert np.all(np.diff(energy) < 1e-9) and float(run.dissipated[-1]) > 1e-3 * released


def modal_spinup(length, ei, rho_a, omega, duration, t_end, stiffening):
    """The tip deflection [m] in the rotating frame, as a function of time, of the linear
    floating-frame model of a spun-up cantilever with its first clamped-free mode
    phi(x) = cosh bx - cos bx - sigma (sinh bx - sin bx), b L = 1.8751 (Kane, Ryan and
    Banerjee 1987, their "conventional" model): m q'' + (k - w^2 m [+ w^2 k_g]) q = -w' p, with
    m = int rho A phi^2, k = omega_1^2 m, p = int rho A x phi and, only with ``stiffening``, the
    centrifugal tension's k_g = int rho A (L^2 - x^2)/2 phi'^2. Integrated by SciPy."""
    from scipy.integrate import solve_ivp

    bl = 1.875104069
    b = bl / length
    sigma = (math.cosh(bl) + math.cos(bl)) / (math.sinh(bl) + math.sin(bl))

    def phi(x):
        return math.cosh(b * x) - math.cos(b * x) - sigma * (math.sinh(b * x) - math.sin(b * x))

    def dphi(x):
        return b * (math.sinh(b * x) + math.sin(b * x) - sigma * (math.cosh(b * x) - math.cos(b * x)))

    m = rho_a * quad(lambda x: phi(x) ** 2, 0, length)[0]
    k = b**4 * ei / rho_a * m
    p = rho_a * quad(lambda x: x * phi(x), 0, length)[0]
    kg = rho_a * quad(lambda x: 0.5 * (length**2 - x * x) * dphi(x) ** 2, 0, length)[0]

    def f(t, y):
        c = 2 * math.pi / duration
        w = omega / duration * (t - math.sin(c * t) / c) if t < duration else omega
        a = omega / duration * (1 - math.cos(c * t)) if t < duration else 0.0
        stiff = k - w * w * m + (w * w * kg if stiffening else 0.0)
        return [y[1], (-stiff * y[0] - a * p) / m]

    sol = solve_ivp(f, (0, t_end), [0.0, 0.0], rtol=1e-10, atol=1e-12, dense_output=True, max_step=0.01)
    return lambda t: sol.sol(t)[0] * phi(length)


@pytest.mark.slow
def test_spin_up_stays_bounded_where_the_linear_model_diverges():
    """The spin-up of Kane, Ryan and Banerjee (1987): a cantilever (L = 8 m, E = 68.95 GPa,
    rho = 2766.67 kg/m^3, A = 7.2968e-5 m^2, I = 8.2189e-9 m^4; first frequency 2.91 rad/s)
    clamped to a hub turned by theta(t) with the angular velocity rising smoothly to
    Omega_s = 6 rad/s over T_s = 15 s. Above the first frequency, the linear floating-frame model
    without the centrifugal stiffening diverges (its tip deflection passes 1e3 m by 10 s and
    1e20 m by 20 s); the ANCF beam (4 elements, Tsit5) stays bounded: largest tip deflection in the
    rotating frame 0.744 m (near the largest angular acceleration), within 1 cm after the
    spin-up. The same one-mode model with the stiffening term (the truth not from our code)
    gives 0.758 m and -0.628, -0.427 m at 5 and 10 s against the beam's -0.620, -0.434 m:
    within 3 % of the largest deflection. About 100 s of integration: 745,000 steps, held by
    the axial frequency (docs/theory/flexible-links.md)."""
    from jaxclear.flexible.motion import BeamSystem, simulate_beam
    from jaxclear.flexible.supports import SpinUp

    length, modulus, rho, area, second = 8.0, 6.895e10, 2766.67, 7.2968e-5, 8.2189e-9
    spin = SpinUp(6.0, 15.0)
    beam = AncfBeam("blade", length, modulus, rho, area, second, n_elements=4)
    system = BeamSystem(beam, [ClampSupport("start", angle=spin)], gravity=(0.0, 0.0))
    ts = jnp.linspace(0.0, 20.0, 201)
    run = simulate_beam(system, ts, solver="tsit5", rtol=1e-6, atol=1e-8, max_steps=2_000_000)
    assert int(run.result._value) == 0
    theta = jax.vmap(spin)(ts)
    tip = jax.vmap(lambda e: beam.position(e, length))(run.e)
    v = np.asarray(-jnp.sin(theta) * tip[:, 0] + jnp.cos(theta) * tip[:, 1])
    t = np.asarray(ts)
    linear = modal_spinup(length, modulus * second, rho * area, 6.0, 15.0, 20.0, stiffening=False)(t)
    stiffened = modal_spinup(length, modulus * second, rho * area, 6.0, 15.0, 20.0, stiffening=True)(t)
    assert abs(linear[100]) > 1e3 and abs(linear[-1]) > 1e20
    assert np.abs(v).max() < 1.0 and np.abs(v[t >= 16.0]).max() < 1e-2
    assert np.abs(v - stiffened).max() < 0.03 * np.abs(stiffened).max()
