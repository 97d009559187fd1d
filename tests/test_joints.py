"""Lubricated, translational and pin-in-slot clearance joints: physics against closed forms,
independent quadrature, central differences and the ideal joints."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

import jaxclear as jc
from jaxclear.elements.lubricated import film_force, film_ratio

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
    ({"length": -1e-3}, "width"),
    ({"blend_start": 1.2}, "blend_start"),
    ({"blend_end": 0.0}, "blend_end"),
    ({"blend_start": 0.98, "blend_end": 0.95}, "blend_start"),
    ({"film": "quarter"}, "film"),
])
def test_lubricated_bad_input_is_named(kw, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.LubricatedJoint(jc.GROUND, "hole", "pin", "c", 0.010, 0.0095, **kw)


def test_viscosity_and_width_are_named_parameters():
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    assert float(jc.params.get(mech, "viscosity")) == 0.4
    m2 = jc.params.replace_many(mech, {"viscosity": 1.5, "width": 0.02})
    assert float(m2.clearance_joints[0].viscosity) == 1.5 and float(m2.clearance_joints[0].length) == 0.02
    with pytest.raises(jc.ParameterError, match="LubricatedJoint"):
        jc.params.get(jc.preset("flores-slider-crank"), "viscosity")


@pytest.mark.slow
def test_lubricated_slider_crank_stays_inside_and_approaches_the_ideal():
    """Benchmark slider-crank (5000 rpm), rod-slider joint lubricated: over three revolutions the
    journal never reaches the bearing wall (eps < 1, no impact), the slider's peak acceleration
    after the first revolution is within 15 % of the ideal joint's while the dry joint's is several
    times larger, and the RMS deviation from the ideal acceleration falls as the viscosity grows
    (0.4, 4, 20 Pa s)."""
    ideal = jc.preset("flores-slider-crank", ideal=True)
    s = jc.settings(3 * jc.crank_period(ideal), n_out=3001)
    a_ideal = jc.simulate(ideal, s).coordinate(ideal, "slider", "x", 2)
    steady = slice(1000, None)
    peak_ideal = float(jnp.abs(a_ideal[steady]).max())
    dry = jc.preset("flores-slider-crank")
    peak_dry = float(jnp.abs(jc.simulate(dry, s).coordinate(dry, "slider", "x", 2)[steady]).max())
    assert peak_dry > 5 * peak_ideal
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
