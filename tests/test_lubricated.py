"""The lubricated joint (short-bearing film, profiles by Gauss points): the film force against
closed forms and independent quadrature, gradients against central differences, bad input.
Full simulations with a profiled joint: tests/test_lubricated_profiles.py."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

import jaxclear as jc
from jaxclear.elements.lubricated import film_force, film_limits, film_ratio, gauss_film_force

MU, R, L, C = 0.4, 0.0095, 0.010, 5e-4  # Pa s, m, m, m


# ---- lubricated joint: the film force -------------------------------------------------


@pytest.mark.parametrize("eps", [0.2, 0.6, 0.9])
def test_steady_short_bearing_load_and_attitude_angle(eps):
    """Steady rotation of the journal (omega = 300 rad/s), bearing at rest, no squeeze, half
    film: radial and tangential loads and the attitude angle against the classical short-bearing
    closed forms (Hamrock et al. 2004, ch. 10). Tolerance 1e-6 (the forms are exact; our result
    is a closed form too, so only rounding is left)."""
    omega = 300.0
    f_n, f_t = film_force(eps, 0.0, 0.5 * omega * eps, R, C, L, MU, "half")
    u = omega * R
    w_r = MU * u * L**3 * eps**2 / (C**2 * (1 - eps**2) ** 2)
    w_t = math.pi * MU * u * L**3 * eps / (4 * C**2 * (1 - eps**2) ** 1.5)
    np.testing.assert_allclose(-float(f_n), w_r, rtol=1e-6)
    np.testing.assert_allclose(float(f_t), w_t, rtol=1e-6)
    np.testing.assert_allclose(math.atan2(float(f_t), -float(f_n)),
                               math.atan(math.pi * math.sqrt(1 - eps**2) / (4 * eps)), rtol=1e-6)


@pytest.mark.parametrize("eps", [0.0, 0.5, 0.95])
def test_pure_squeeze_against_closed_form(eps):
    """No rotation, full film: the force opposes the squeeze rate along the line of centres with
    magnitude mu R L^3 eps_dot pi (1 + 2 eps^2) / (c^2 (1 - eps^2)^(5/2)) (1e-6)."""
    eps_dot = 50.0
    f_n, f_t = film_force(eps, eps_dot, 0.0, R, C, L, MU, "full")
    ref = MU * R * L**3 * eps_dot * math.pi * (1 + 2 * eps**2) / (C**2 * (1 - eps**2) ** 2.5)
    np.testing.assert_allclose(-float(f_n), ref, rtol=1e-6)
    assert abs(float(f_t)) < 1e-9 * ref


@pytest.mark.parametrize("eps,eps_dot,wedge", [(0.3, 50.0, 20.0), (0.6, -80.0, 40.0), (0.9, 30.0, -60.0)])
def test_half_film_with_moving_edges_against_quadrature(eps, eps_dot, wedge):
    """The default half film (film edges where the pressure changes sign, moving with the squeeze
    rate) against SciPy quadrature of the positive pressure (1e-8); the fixed-edge variant differs
    when eps_dot != 0."""
    p = lambda s: (eps_dot * math.cos(s) - wedge * math.sin(s)) / (1 - eps * math.cos(s)) ** 3  # noqa: E731
    psi0 = math.atan2(-wedge, eps_dot)
    a, b = psi0 - math.pi / 2, psi0 + math.pi / 2
    scale = R * MU * L**3 / C**2
    ref_n = -scale * quad(lambda s: p(s) * math.cos(s), a, b, epsabs=0, epsrel=1e-12, limit=200)[0]
    ref_t = -scale * quad(lambda s: p(s) * math.sin(s), a, b, epsabs=0, epsrel=1e-12, limit=200)[0]
    f_n, f_t = film_force(eps, eps_dot, wedge, R, C, L, MU, "half")
    np.testing.assert_allclose([float(f_n), float(f_t)], [ref_n, ref_t], rtol=1e-8)
    g_n, _ = film_force(eps, eps_dot, wedge, R, C, L, MU, "half-fixed")
    assert abs(float(g_n) / float(f_n) - 1) > 0.05


def pi_film_closed_form(eps, eps_dot, omega_bar, length=L):
    """The classical fixed-boundary pi film (Pinkus and Sternlicht, ch. 3, as Flores et al.,
    Nonlinear Dyn. 56 (2009) 277-295 write it for a stationary bearing, omega - 2 gamma_dot = 2
    omega_bar): radial force F_r (along n, from the bearing centre to the journal) and tangential
    force F_t on the journal, written out here independently of film_integrals."""
    k = R * MU * length**3 / C**2
    f_r = -k * (2 * eps**2 * omega_bar / (1 - eps**2) ** 2 + math.pi * (1 + 2 * eps**2) * eps_dot / (2 * (1 - eps**2) ** 2.5))
    f_t = k * (math.pi * eps * omega_bar / (2 * (1 - eps**2) ** 1.5) + 2 * eps * eps_dot / (1 - eps**2) ** 2)
    return f_r, f_t


@pytest.mark.parametrize("eps,eps_dot,omega_bar", [(0.3, 50.0, 200.0), (0.6, -80.0, 40.0), (0.9, 30.0, -60.0),
                                                   (0.6, 50.0, 0.0), (0.0, 20.0, 100.0)])
def test_pi_film_against_the_classical_closed_form(eps, eps_dot, omega_bar):
    """film="pi" is the literature's fixed pi film for every sign of the squeeze rate and of
    omega_bar (1e-10: both are closed forms); "pi-clockwise" is its mirror image (omega_bar and
    F_t change sign)."""
    wedge = omega_bar * eps
    f_n, f_t = film_force(eps, eps_dot, wedge, R, C, L, MU, "pi")
    ref = pi_film_closed_form(eps, eps_dot, omega_bar)
    np.testing.assert_allclose([float(f_n), float(f_t)], ref, rtol=1e-10, atol=1e-12 * max(map(abs, ref)))
    g_n, g_t = film_force(eps, eps_dot, -wedge, R, C, L, MU, "pi-clockwise")
    np.testing.assert_allclose([float(g_n), -float(g_t)], [float(f_n), float(f_t)], rtol=1e-12, atol=1e-12)


def test_pi_film_is_continuous_where_omega_bar_changes_sign():
    """At eps 0.6 and a squeeze rate of 50/s (L 40 mm, mu 0.4 Pa s, R 9.5 mm, c 0.5 mm), the
    "half-fixed" film's tangential force jumps from +142.5 to -142.5 N as omega_bar crosses 0 (its
    film changes side); the pi film's force is linear in omega_bar: at +-1e-9 rad/s it differs by
    less than 1e-8 N (its slope, at most 1.8 N s/rad here, times 2e-9 rad/s), and its value at 0 is the closed form's squeeze term 2 eps eps_dot k/(1 - eps^2)^2."""
    eps, eps_dot, big = 0.6, 50.0, 0.04
    jump = [float(film_force(eps, eps_dot, w * eps, R, C, big, MU, "half-fixed")[1]) for w in (1e-9, -1e-9)]
    np.testing.assert_allclose(jump, [142.5, -142.5], atol=0.05)
    plus, minus = (np.asarray(film_force(eps, eps_dot, w * eps, R, C, big, MU, "pi")) for w in (1e-9, -1e-9))
    assert np.abs(plus - minus).max() < 1e-8
    np.testing.assert_allclose(float(plus[1]), pi_film_closed_form(eps, eps_dot, 0.0, big)[1], rtol=1e-8)
    assert float(plus[1]) == pytest.approx(142.5, abs=0.05)


@pytest.mark.slow
def test_pi_film_slider_crank_finishes_with_the_steps_of_the_half_film():
    """Lubricated benchmark slider-crank (mu 0.4 Pa s, L 40 mm), one revolution at rtol 1e-6: the
    pi film's run finishes (status ok) with at most 1.3x the accepted steps of the half film
    (measured 1132 against 955; the half-fixed film needs ~15x over two revolutions at the default
    tolerances and stalls at rtol 1e-8), and stays inside the bearing."""
    steps = {}
    for film in ("half", "pi"):
        mech = jc.preset("flores-slider-crank", viscosity=0.4, length=0.04, film=film)
        sol = jc.simulate(mech, jc.settings(jc.crank_period(mech), n_out=20, rtol=1e-6))
        assert int(sol.status) == 0 and float(sol.ts[-1]) == pytest.approx(float(jc.crank_period(mech)))
        assert float(jnp.linalg.norm(sol.ecc[:, 0], axis=-1).max()) < C
        steps[film] = int(sol.num_accepted_steps)
    assert steps["pi"] < 1.3 * steps["half"], steps


def test_film_force_and_its_derivative_are_continuous_across_the_blend_bounds():
    """The film force evaluated at g(eps) (C1 saturation between blend_start and blend_end): the
    jumps of force and d force / d eps across each bound vanish with the step: at +-1e-9 they are
    below 1e-6 (force) and 1e-5 (derivative, which changes at the rate F''(eps) * 2e-9) relative to
    the force and the slope just below the bound."""
    e0, e1 = 0.95, 0.99

    def force(eps):
        return film_force(film_ratio(eps, e0, e1), 40.0, 30.0, R, C, L, MU, "half")[0]

    dforce = jax.grad(force)
    for bound in (e0, e1):
        lo, hi = bound - 1e-9, bound + 1e-9
        scale = abs(float(force(bound)))
        assert abs(float(force(hi) - force(lo))) < 1e-6 * scale
        d_lo, d_hi = float(dforce(lo)), float(dforce(hi))
        dscale = max(abs(float(dforce(bound - 1e-3))), 1.0)
        assert abs(d_hi - d_lo) < 1e-5 * dscale, (bound, d_lo, d_hi)
    assert abs(float(dforce(e1 + 1e-3))) == 0.0  # saturated above blend_end


def _lubricated_pendulum(**kw):
    pin = jc.Body("pin", 1.0, 1e-3, {"c": (0.0, 0.0)}, position=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 200.0))
    joint = jc.LubricatedJoint(jc.GROUND, "hole", "pin", "c", 0.010, 0.0095, **kw)
    return jc.Mechanism([pin], clearance_joints=[joint], gravity=(0.0, -9.81), ground_points={"hole": (0.0, 0.0)})


def test_lubricated_element_gradients_match_central_differences():
    """Generalized force of the element (film plus dry contact: the journal 2 um into the wall)
    differentiated by JAX with respect to the coordinates, the velocities and the viscosity, against
    central differences (step 1e-7 relative; tolerance 1e-5 relative to the largest entry)."""
    mech = _lubricated_pendulum(viscosity=0.4)
    joint = mech.clearance_joints[0]
    q = jnp.array([3e-4, -4.02e-4, 0.1])
    qd = jnp.array([0.05, -0.02, 200.0])

    def gen(q, qd, mu):
        j = eqx.tree_at(lambda j: j.viscosity, joint, mu)
        return j.contact(mech, q, qd, jnp.asarray(0.1))[0]

    gen = jax.jit(gen)
    for arg, x in ((0, q), (1, qd)):
        jac = jax.jacfwd(gen, argnums=arg)(q, qd, jnp.asarray(0.4))
        for i in range(3):
            h = 1e-7 * max(abs(float(x[i])), 1e-3)
            xp, xm = x.at[i].add(h), x.at[i].add(-h)
            args_p = (xp, qd) if arg == 0 else (q, xp)
            args_m = (xm, qd) if arg == 0 else (q, xm)
            fd = (gen(*args_p, jnp.asarray(0.4)) - gen(*args_m, jnp.asarray(0.4))) / (2 * h)
            np.testing.assert_allclose(jac[:, i], fd, atol=1e-5 * float(jnp.abs(jac).max()))
    g = jax.jacfwd(gen, argnums=2)(q, qd, jnp.asarray(0.4))
    fd = (gen(q, qd, jnp.asarray(0.4 + 1e-6)) - gen(q, qd, jnp.asarray(0.4 - 1e-6))) / 2e-6
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-9 * float(jnp.abs(g).max()))


@pytest.mark.parametrize("kw,match", [
    ({"viscosity": 0.0}, "viscosity"),
    ({"length": -1e-3}, "length"),
    ({"blend_start": 1.2}, "blend_start"),
    ({"blend_end": 0.0}, "blend_end"),
    ({"blend_start": 0.98, "blend_end": 0.95}, "blend_start"),
    ({"film": "quarter"}, "film"),
])
def test_lubricated_bad_input_is_named(kw, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.LubricatedJoint(jc.GROUND, "hole", "pin", "c", 0.010, 0.0095, **kw)


def test_viscosity_and_length_are_named_parameters_and_width_is_deprecated():
    """One name for the film width: ``length`` (the joint's axial length) in the constructor,
    presets, parameter names and mechanism files; ``width``, the old name of the parameter,
    attribute and file key, still works with a DeprecationWarning."""
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    assert float(jc.params.get(mech, "viscosity")) == 0.4
    m2 = jc.params.replace_many(mech, {"viscosity": 1.5, "length": 0.02})
    assert float(m2.clearance_joints[0].viscosity) == 1.5 and float(m2.clearance_joints[0].length) == 0.02
    with pytest.raises(jc.ParameterError, match="LubricatedJoint"):
        jc.params.get(jc.preset("flores-slider-crank"), "viscosity")
    assert "width" not in jc.params.parameter_names()
    with pytest.warns(DeprecationWarning, match="'width' is deprecated; use 'length'"):
        m3 = jc.params.replace(mech, "width", 0.03)
    assert float(m3.clearance_joints[0].length) == 0.03
    with pytest.warns(DeprecationWarning, match="width is deprecated; use length"):
        assert float(m3.clearance_joints[0].width) == 0.03


def test_preset_lubricated_joint_takes_film_options():
    """The preset's lubricated joint takes the film width (``length``), ``film`` and the blend;
    the film options without ``viscosity`` (a dry joint) are refused, naming them."""
    mech = jc.preset("flores-slider-crank", viscosity=0.4, length=0.04, film="pi", blend_start=0.9, blend_end=0.97)
    j = mech.clearance_joints[0]
    assert isinstance(j, jc.LubricatedJoint) and j.film == "pi"
    assert (float(j.length), float(j.blend_start), float(j.blend_end)) == (0.04, 0.9, 0.97)
    default = jc.preset("flores-slider-crank", viscosity=0.4).clearance_joints[0]
    assert default.film == "half" and float(default.length) == 0.010
    with pytest.raises(jc.ParameterError, match=r"\['blend_end', 'film'\].*viscosity"):
        jc.preset("flores-slider-crank", film="pi", blend_end=0.97)
    with pytest.raises(jc.ParameterError, match="film"):
        jc.preset("flores-slider-crank", viscosity=0.4, film="quarter")


@pytest.mark.slow
def test_lubricated_slider_crank_stays_inside_and_approaches_the_ideal():
    """Benchmark slider-crank (5000 rpm), rod-slider joint lubricated: over three revolutions the
    journal never reaches the bearing wall (eps < 1, no impact), the slider's peak acceleration
    after the first revolution is within 15 % of the ideal joint's while the dry joint's is more than
    three times larger (on the output grid), and the RMS deviation from the ideal acceleration falls as the viscosity grows
    (0.4, 4, 20 Pa s)."""
    ideal = jc.preset("flores-slider-crank", ideal=True)
    s = jc.settings(3 * jc.crank_period(ideal), n_out=3001)
    a_ideal = jc.simulate(ideal, s).coordinate(ideal, "slider", "x", 2)
    steady = slice(1000, None)
    peak_ideal = float(jnp.abs(a_ideal[steady]).max())
    dry = jc.preset("flores-slider-crank")
    peak_dry = float(jnp.abs(jc.simulate(dry, s).coordinate(dry, "slider", "x", 2)[steady]).max())
    assert peak_dry > 3 * peak_ideal
    rms = []
    for mu in (0.4, 4.0, 20.0):
        mech = jc.preset("flores-slider-crank", viscosity=mu)
        sol = jc.simulate(mech, s)
        eps = jnp.linalg.norm(sol.ecc[:, 0], axis=-1) / 5e-4
        assert float(eps.max()) < 1.0 and float(sol.impacts[0]) == 0.0
        a = sol.coordinate(mech, "slider", "x", 2)
        assert float(jnp.abs(a[steady]).max()) < 1.15 * peak_ideal
        rms.append(float(jnp.sqrt(jnp.mean((a - a_ideal)[steady] ** 2))))
    assert rms[0] > rms[1] > rms[2]


# ---- lubricated joint: the film force on profiles by Gauss points ----------------------

N_E, N_G = 180, 4  # the default rule: element width D = 2 pi / 180
D = 2 * math.pi / N_E


def _circle_case(eps, angle=0.7, v_n=0.01, v_t=-0.02, w_j=500.0, w_b=20.0):
    """Eccentricity, relative velocity, and the closed form's (eps_dot, wedge) of one state."""
    n = np.array([math.cos(angle), math.sin(angle)])
    t = np.array([-n[1], n[0]])
    e, v = eps * C * n, v_n * n + v_t * t
    return jnp.asarray(e), jnp.asarray(v), v_n / C, (0.5 * (w_j + w_b) * eps * C - v_t) / C, n, t, w_j, w_b


def _closed(eps, eps_dot, wedge, n, t, film):
    f_n, f_t = film_force(eps, eps_dot, wedge, R, C, L, MU, film)
    return np.asarray(f_n * n + f_t * t)


def _gauss(e, v, w_j, w_b, film, jp=None, bp=None, phi_j=0.3, phi_b=-0.2, blend=None):
    return np.asarray(gauss_film_force(e, v, w_j, w_b, phi_j, phi_b, R, C, L, MU, jp, bp, N_E, N_G, film, blend))


@pytest.mark.parametrize("eps", [0.2, 0.6, 0.9])
def test_gauss_points_reproduce_the_full_film_closed_form(eps):
    """Circles, full (Sommerfeld) film: the integrand is smooth and periodic. The 4-point rule's
    error on an element of width D is (4!)^4 D^9 / (9 (8!)^3) |f^(8)| = 4e-23 |f^(8)|, and
    (1 - eps cos)^-3 has its nearest complex pole at distance arccosh(1/eps) >= 0.47 rad, so
    |f^(8)| < 45 8! / 0.47^8 f_max = 8e8 f_max: below 1e-11 f_max over the 180 elements, against a
    force of order f_max times the 0.3 rad width of the pressure peak. Tolerance 1e-10."""
    e, v, eps_dot, wedge, n, t, w_j, w_b = _circle_case(eps)
    ref = _closed(eps, eps_dot, wedge, n, t, "full")
    np.testing.assert_allclose(_gauss(e, v, w_j, w_b, "full"), ref, rtol=0, atol=1e-10 * np.linalg.norm(ref))


@pytest.mark.parametrize("eps", [0.2, 0.6, 0.9])
@pytest.mark.parametrize("v_n", [0.01, -0.05])
def test_gauss_points_reproduce_the_half_film_closed_form_within_the_kink_bound(eps, v_n):
    """Circles, half-Sommerfeld film (p >= 0): max(p, 0) has a kink at each of the two film edges
    psi_k (the closed form's film_limits), inside some element, where the rule loses its order.
    There max(p, 0) - p is zero on one side and at most |p'(psi_k)| D in size on the other, so the
    element's error is at most 2 D |p'(psi_k)| D; the smooth remainder is exact to 1e-10 as above.
    Bound on |F_gauss - F_closed|: R (2 D^2 sum_k |p'(psi_k)|) + 1e-10 |F|, with
    p'(psi) = (mu L^3 / c^2)(-eps_dot sin psi - wedge cos psi) / (1 - eps cos psi)^3 at the edges,
    where its numerator's other part vanishes. The error is also checked to be below 1e-4 |F|."""
    e, v, eps_dot, wedge, n, t, w_j, w_b = _circle_case(eps, v_n=v_n)
    ref = _closed(eps, eps_dot, wedge, n, t, "half")
    got = _gauss(e, v, w_j, w_b, "half")
    edges = np.asarray(film_limits(eps_dot, wedge, "half"))
    slope = MU * L**3 / C**2 * np.abs(-eps_dot * np.sin(edges) - wedge * np.cos(edges)) / (1 - eps * np.cos(edges)) ** 3
    bound = R * 2 * D**2 * slope.sum() + 1e-10 * np.linalg.norm(ref)
    err = np.linalg.norm(got - ref)
    assert err <= bound, (err, bound)
    assert err < 1e-4 * np.linalg.norm(ref)


@pytest.mark.parametrize("film", ["full", "half"])
def test_first_harmonic_profiles_are_shifted_circles(film):
    """A journal profile a cos(theta - phi_J) is, for the film thickness, a circular journal whose
    centre sits a u(phi_J) further out, moving with it at omega_J a perp(u(phi_J)); a bearing
    profile b cos(theta - phi_B) moves the bearing centre by b u(phi_B) (so e -> e - b u(phi_B)).
    The Gauss-point force on the profiles equals the closed form at the shifted eccentricity and
    velocity: 1e-10 for the full film (smooth integrand), the kink bound for the half film."""
    a, b, phi_j, phi_b = 1e-4, 5e-5, 0.3, -0.2
    e, v, _, _, _, _, w_j, w_b = _circle_case(0.5)
    u = lambda phi: np.array([math.cos(phi), math.sin(phi)])  # noqa: E731
    perp = lambda x: np.array([-x[1], x[0]])  # noqa: E731
    e_s = np.asarray(e) + a * u(phi_j) - b * u(phi_b)
    v_s = np.asarray(v) + w_j * a * perp(u(phi_j)) - w_b * b * perp(u(phi_b))
    got = _gauss(e, v, w_j, w_b, film, jc.FourierProfile([a]), jc.FourierProfile([b]), phi_j=phi_j, phi_b=phi_b)
    eps = np.linalg.norm(e_s) / C
    n = e_s / np.linalg.norm(e_s)
    t = perp(n)
    eps_dot, wedge = v_s @ n / C, (0.5 * (w_j + w_b) * np.linalg.norm(e_s) - v_s @ t) / C
    ref = _closed(eps, eps_dot, wedge, n, t, film)
    tol = 1e-10 if film == "full" else 1e-4
    np.testing.assert_allclose(got, ref, rtol=0, atol=tol * np.linalg.norm(ref))


@pytest.mark.parametrize("eps_s", [0.97, 1.05])
def test_blend_of_a_first_harmonic_is_the_blend_of_the_shifted_circle(eps_s):
    """The film's saturation acts on the closure k = c - h of the profiled film, so a bearing
    profile b cos(theta - phi_B) (a circle shifted by b u(phi_B)) saturates as the shifted circle:
    the Gauss-point force with the blend (0.95, 0.99) equals the closed form at the ratio
    g(|e_s|/c), full film, inside the blend (0.97) and past the wall (1.05). The thinnest film is
    taken at the Gauss points, which miss the true minimum by at most half the largest node gap,
    0.68 pi/180 / 2 = 6e-3 rad, so eps_h = eps (1 - d) with 0 <= d <= 1 - cos 6e-3 = 1.8e-5, and the
    film is that of the ratio g(eps_h) eps / eps_h: the bound is the closed form's change from
    g(eps) to g(eps (1 - d)) / (1 - d) at d = 1.8e-5, plus 1e-10 (smooth integrand). Inside the blend the
    ratio of the nominal eccentricity (e/c = 1.11) would be far off: checked."""
    b, phi_b, blend = 1e-4, -0.2, (0.95, 0.99)
    e_s, v, _, _, n, t, w_j, w_b = _circle_case(eps_s)
    u_b = np.array([math.cos(phi_b), math.sin(phi_b)])
    e = np.asarray(e_s) + b * u_b  # nominal eccentricity and velocity (the shifted centre turns with the bearing)
    v_nominal = np.asarray(v) + w_b * b * np.array([-u_b[1], u_b[0]])
    got = _gauss(jnp.asarray(e), jnp.asarray(v_nominal), w_j, w_b, "full", bp=jc.FourierProfile([b]), phi_b=phi_b,
                 blend=blend)
    eps_dot, wedge = float(np.asarray(v) @ n) / C, (0.5 * (w_j + w_b) * eps_s * C - float(np.asarray(v) @ t)) / C

    def closed(ratio):
        return _closed(ratio, eps_dot, wedge, n, t, "full")

    d = 1.8e-5
    ref = closed(film_ratio(eps_s, *blend))
    bound = np.linalg.norm(closed(film_ratio(eps_s * (1 - d), *blend) / (1 - d)) - ref) + 1e-10 * np.linalg.norm(ref)
    assert np.linalg.norm(got - ref) <= bound, (np.linalg.norm(got - ref), bound)
    if eps_s < blend[1]:  # (past blend_end both ratios saturate)
        nominal = closed(film_ratio(np.linalg.norm(e) / C, *blend))
        assert np.linalg.norm(nominal - ref) > 100 * bound


def test_oval_film_force_gradient_matches_central_differences():
    """d F / d (oval amplitude) through the Gauss points (forward mode) against a central
    difference (step 1e-9 m on 2e-5 m; truncation O(h^2), relative 1e-6)."""
    e, v, _, _, _, _, w_j, w_b = _circle_case(0.6)

    def force(amp):
        return gauss_film_force(e, v, w_j, w_b, 0.3, 0.0, R, C, L, MU, jc.oval(amp, 0.4), None, N_E, N_G, "full")

    g = np.asarray(jax.jacfwd(force)(jnp.asarray(2e-5)))
    fd = (np.asarray(force(jnp.asarray(2e-5 + 1e-9))) - np.asarray(force(jnp.asarray(2e-5 - 1e-9)))) / 2e-9
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6 * np.abs(g).max())


def test_lubricated_joint_with_profiles():
    """A zero profile gives the closed-form element force (full film: 1e-10, as above); the
    profiles are the dry law's (one geometry for film and wall); profiles are refused with a law
    that assumes circles, with the hybrid law's arc placement, when given twice, with the
    fixed-edge film, for too few points, and when they close the film."""
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    d = mech.clearance_joints[0]
    args = (d.bearing_body, d.bearing_point, d.journal_body, d.journal_point, d.bearing_radius, d.journal_radius)
    q = jnp.asarray([0.025, 0, 0, 0.11, 0, 0, 0.17 + 3e-4, 1e-4, 0.0])
    qd = jnp.asarray([0, 2.0, 500, 0, 1, -100, 0.5, 0.3, 0.0])

    fixed = jc.HybridLaw(placement="fixed")

    def film(**kw):
        joint = jc.LubricatedJoint(*args, viscosity=0.4, film="full", **kw)
        return np.asarray(joint.film_force(eqx.tree_at(lambda m: m.clearance_joints, mech, (joint,)), q, qd))

    ref = film()
    np.testing.assert_allclose(film(journal_profile=jc.FourierProfile([0.0]), law=fixed), ref,
                               atol=1e-10 * np.abs(ref).max())
    assert np.linalg.norm(film(journal_profile=jc.oval(5e-5), law=fixed) - ref) > 1e-3 * np.linalg.norm(ref)
    # the profiles live on the law: given to the joint or to its law, the same joint
    oval = jc.oval(5e-5)
    by_joint = jc.LubricatedJoint(*args, law=fixed, journal_profile=oval)
    by_law = jc.LubricatedJoint(*args, law=jc.HybridLaw(placement="fixed", journal_profile=oval))
    assert bool(eqx.tree_equal(by_joint.law.journal_profile, by_joint.journal_profile, oval))
    assert by_joint.law.bearing_profile is None and by_joint.bearing_profile is None
    assert bool(eqx.tree_equal(by_joint, by_law))
    for kw, match in [({"journal_profile": jc.oval(1e-5)}, "assumes a circular journal"),
                      ({"journal_profile": jc.oval(1e-5), "law": jc.HybridLaw()}, "placement='fixed'"),
                      ({"journal_profile": oval, "law": by_law.law}, "given twice"),
                      ({"film": "half-fixed", "journal_profile": jc.oval(1e-5), "law": fixed}, "half-fixed"),
                      ({"film": "half-fixed", "law": by_law.law}, "half-fixed"),
                      ({"journal_profile": jc.oval(1e-5), "law": fixed, "n_gauss": 0}, "n_gauss"),
                      ({"journal_profile": jc.oval(3e-4), "bearing_profile": jc.oval(-3e-4), "law": fixed},
                       "larger than the bearing")]:
        with pytest.raises(jc.ParameterError, match=match):
            jc.LubricatedJoint(*args, **kw)
