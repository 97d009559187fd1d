"""Kinematic analysis of driven mechanisms (jaxclear/integrate/_kinematics.py), the command line's
ideal-joint overlay: against the slider-crank's closed form, against the integrated ideal run
(accelerations and reactions), and its derivatives against central differences."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear import params
from jaxclear.integrate._kinematics import is_kinematic, kinematic_solution
from jaxclear.integrate._runs import revolution_settings, simulate_with_ideal
from jaxclear.model import crank_driver

from conftest import slider_crank_exact


def _omega(mech):
    return float(crank_driver(mech)[1].speed)


def test_slider_crank_matches_closed_form():
    """Newton to convergence at every sample: only rounding separates it from the closed form
    (1e-12 relative allows a condition number of D up to ~1e3 over float64's 2e-16)."""
    mech = jc.preset("flores-slider-crank", ideal=True)
    sol = kinematic_solution(mech, revolution_settings(mech, 2.0, n_out=801))
    assert int(sol.status) == 0 and int(sol.num_steps) == 0
    x, v, a = slider_crank_exact(_omega(mech) * np.asarray(sol.ts), _omega(mech))
    for k, exact in enumerate((x, v, a)):
        got = np.asarray(sol.coordinate(mech, "slider", "x", derivative=k))
        assert np.max(np.abs(got - exact)) / np.max(np.abs(exact)) < 1e-12, k
    assert float(sol.drift.max()) < 1e-12


@pytest.mark.extended
def test_a_crank_started_anywhere_assembles_on_the_branch_it_turns_through():
    """A preset built at crank angle 0 and started at another ``angle0`` assembles where turning
    the crank there by hand leads (:func:`jaxclear.integrate.assemble`'s continuation), not on
    the mirror branch: the slider-crank's slider at x = r cos phi + sqrt(l^2 - r^2 sin^2 phi)
    (closed form) for angles round the circle and past a whole turn (it sat at -0.17 m instead
    of 0.07 m at phi = pi before); the four-bar's bodies at angle0 = 3 equal the kinematic
    solution's, which follows the crank from the preset's angle sample by sample. Tolerances: the Newton
    tolerance 1e-10 (m, rad) on the residual, times the Jacobian's conditioning; 1e-9 allowed."""
    from jaxclear.integrate._assembly import assemble

    for ideal in (True, False):
        base = jc.preset("flores-slider-crank", ideal=ideal)
        for phi in (*np.linspace(0.0, 2 * np.pi, 9), 3.3, 7.0, -2.5):
            q = np.asarray(assemble(params.replace(base, "angle0", float(phi))).q)
            x = slider_crank_exact(phi, 1.0)[0]
            assert abs(q[3 * base.body_index("slider")] - x) < 1e-9, (ideal, phi)
            assert abs(q[3 * base.body_index("crank") + 2] - phi) < 1e-9
    four = jc.preset("four-bar", ideal=True)
    omega = _omega(four)
    sol = kinematic_solution(four, jc.settings((3.0 - float(params.get(four, "angle0"))) / omega, n_out=301))
    started = np.asarray(assemble(params.replace(four, "angle0", 3.0)).q)
    assert np.max(np.abs(started - np.asarray(sol.q[-1]))) < 1e-9


@pytest.mark.extended
@pytest.mark.parametrize("name", ["flores-slider-crank", "four-bar"])
def test_agrees_with_the_integrated_ideal_run(name):
    """The integrated run at rtol 1e-10 differs from the exact motion by its own error; 1e-6 of
    each signal's amplitude bounds it with a margin (measured: 7e-7 for the slider-crank's
    reactions, less elsewhere)."""
    mech = jc.preset(name, ideal=True)
    assert is_kinematic(mech)
    s = revolution_settings(mech, 0.5, n_out=201, rtol=1e-10, atol=1e-12)
    kin, ref = kinematic_solution(mech, s), jc.simulate(mech, s)
    np.testing.assert_array_equal(np.asarray(kin.ts), np.asarray(ref.ts))
    for field in ("q", "qdot", "qddot", "reactions"):
        got, want = np.asarray(getattr(kin, field)), np.asarray(getattr(ref, field))
        assert np.max(np.abs(got - want)) <= 1e-6 * np.max(np.abs(want)), field
    assert jax.tree_util.tree_structure(kin) == jax.tree_util.tree_structure(ref)


def test_invalid_parameter_is_a_named_error():
    """A parameter outside its range (a negative mass, which enters only the reactions) is
    reported as for simulate, not returned as a successful run."""
    mech = params.replace(jc.preset("flores-slider-crank", ideal=True), "mass:rod", jnp.asarray(-1.0))
    s = revolution_settings(mech, 0.1, n_out=11)
    with pytest.raises(jc.ParameterError, match="mass"):
        kinematic_solution(mech, s)
    assert int(kinematic_solution(mech, dataclasses.replace(s, throw=False)).status) != 0


def test_clearance_mechanism_is_refused():
    mech = jc.preset("flores-slider-crank")
    assert not is_kinematic(mech)
    with pytest.raises(ValueError, match="not kinematically driven"):
        kinematic_solution(mech, revolution_settings(mech, 0.1))


@pytest.mark.extended
def test_gradient_and_vmap():
    """d(slider acceleration at one sample)/d(crank speed) against a central difference (step
    1e-4 of the speed: truncation ~1e-8 relative, far below the 1e-6 asked), and vmap over two
    speeds equal to the two single runs."""
    mech = jc.preset("flores-slider-crank", ideal=True)
    s = dataclasses.replace(revolution_settings(mech, 0.25, n_out=41), throw=False)

    def acc(speed):
        m = params.replace(mech, "speed", speed)
        return kinematic_solution(m, s).coordinate(m, "slider", "x", derivative=2)[17]

    w = _omega(mech)
    g = jax.grad(acc)(jnp.asarray(w))
    h = 1e-4 * w
    fd = (acc(jnp.asarray(w + h)) - acc(jnp.asarray(w - h))) / (2 * h)
    assert abs(float(g) - float(fd)) <= 1e-6 * abs(float(fd))
    both = jax.vmap(acc)(jnp.asarray([w, 1.1 * w]))
    np.testing.assert_allclose(np.asarray(both), [float(acc(jnp.asarray(w))), float(acc(jnp.asarray(1.1 * w)))],
                               rtol=1e-13)


def test_command_line_overlay_uses_it():
    mech = jc.preset("flores-slider-crank")
    r = simulate_with_ideal(mech, revolution_settings(mech, 0.1, n_out=41))
    assert r.ideal_sol is not None and int(r.ideal_sol.num_steps) == 0  # not integrated
