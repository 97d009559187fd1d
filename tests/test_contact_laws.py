"""Contact laws against truths that are not jaxclear's: the impact relation of the dissipative
Hertz family and its table (docs/theory/impact-memory.md), the closed form of the foundation
integral (docs/theory/hybrid.md), an independent NumPy
integration for non-circular profiles, the clipped linear oscillator in closed form, and
hand-evaluated friction laws."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import free_journal
from scipy.optimize import brentq
from test_engine import C_R, RESTITUTION_TABLE, effective_restitution_exact, simulated_restitution

import jaxclear as jc
from jaxclear.elements import kinematics
from jaxclear.contact import friction as fr
from jaxclear.contact.hybrid import foundation_modulus, small_gap_force
from jaxclear.contact import HYSTERESIS_FACTORS

RB, RJ, L = 0.010, 0.0095, 0.010
C = RB - RJ
KF = 2.787e11  # Winkler modulus of steel, E(1-nu)/((1+nu)(1-2nu)) with E = 207 GPa, nu = 0.3


# ---------------------------------------------------------------- effective restitution


@pytest.mark.extended
@pytest.mark.parametrize("law", sorted(RESTITUTION_TABLE))
def test_single_impact_every_law_matches_table(law):
    """All columns and rows of the restitution table, within 2e-3 (the table is rounded to 1e-3)."""
    for c_r, expected in zip(C_R, RESTITUTION_TABLE[law]):
        got = simulated_restitution(law, c_r)
        assert abs(got - expected) < 2e-3, (law, c_r, got, expected)


@pytest.mark.parametrize("law,c_r", [("lankarani-nikravesh", 0.42), ("flores", 0.23), ("hunt-crossley", 0.81),
                                     ("gonthier", 0.65), ("qin-lu", 0.15), ("hertz", 0.5),
                                     ("herbert-mcwhannell", 0.37), ("lee-wang", 0.58)])
def test_single_impact_obeys_implicit_relation(law, c_r):
    """Off the table: the simulated e solves -chi e - ln(1 - chi e) = chi - ln(1 + chi) to 2e-5
    (the onset update is exact to the step's third order; rtol 1e-9)."""
    chi = float(HYSTERESIS_FACTORS[law](c_r))
    assert abs(simulated_restitution(law, c_r, speed=0.7) - effective_restitution_exact(chi)) < 2e-5


@pytest.mark.parametrize("law,chi_name", [("hybrid", "qin-lu"), ("liu", "lankarani-nikravesh"), ("bai-zhao", "qin-lu")])
@pytest.mark.parametrize("c_r", [0.3, 0.75])
def test_cylindrical_laws_obey_the_relation_of_their_damping(law, chi_name, c_r):
    """The relation holds for any elastic force f(delta) (the elastic work cancels over the
    loop), so the hybrid model (Qin-Lu damping), Liu (LN damping) and Bai-Zhao (Qin-Lu) must
    reproduce it too; the hybrid's Qin-Lu column of the table follows."""
    chi = float(HYSTERESIS_FACTORS[chi_name](c_r))
    assert abs(simulated_restitution(law, c_r) - effective_restitution_exact(chi)) < 2e-5


def kelvin_voigt_exact(c_r):
    """Clipped linear oscillator: contact ends when k delta + d deltadot = 0 (brentq on the
    closed-form damped motion); e = exit over entry speed."""
    zeta = -math.log(c_r) / math.sqrt(math.pi**2 + math.log(c_r) ** 2)
    w = 1.0
    wd = w * math.sqrt(1 - zeta**2)
    delta = lambda t: math.exp(-zeta * w * t) * math.sin(wd * t) / wd  # noqa: E731
    rate = lambda t: math.exp(-zeta * w * t) * (math.cos(wd * t) - zeta * w / wd * math.sin(wd * t))  # noqa: E731
    ts = brentq(lambda t: w**2 * delta(t) + 2 * zeta * w * rate(t), 1e-9, math.pi / wd)
    return -rate(ts)


@pytest.mark.parametrize("c_r", [0.3, 0.6, 0.9])
def test_kelvin_voigt_single_impact_closed_form(c_r):
    e = simulated_restitution_kv(c_r)
    assert abs(e - kelvin_voigt_exact(c_r)) < 2e-5, (e, kelvin_voigt_exact(c_r))


def simulated_restitution_kv(c_r):
    mech = free_journal(restitution=c_r, law="kelvin-voigt", stiffness=1e8, effective_mass=1.0)
    # 3001 samples: the program of the energy check below (kelvin-voigt), compiled once for both
    sol = jc.simulate(mech, jc.settings(1.6e-3, n_out=3001, rtol=1e-9, atol=1e-13))
    return -float(sol.qdot[-1, 0])


ALL_LAWS = sorted(set(jc.law_names()))


@pytest.mark.extended
@pytest.mark.parametrize("law", ALL_LAWS)
def test_hysteresis_never_pulls_and_energy_loss_matches_restitution(law):
    """During one impact F_N >= 0 at every sample (no adhesive pull at separation), and the work of
    the contact force over the closed impact equals -(1 - e^2) times the entry kinetic energy
    (energy bookkeeping in the state against the momentum-based e), to 1e-6 of the entry energy."""
    extra = {"effective_mass": 1.0, "stiffness": 1e8} if law == "kelvin-voigt" else {}
    mech = free_journal(restitution=0.4, law=law, **extra)
    sol = jc.simulate(mech, jc.settings(1.6e-3, n_out=3001, rtol=1e-9, atol=1e-13))
    assert float(sol.impacts[-1]) == 1.0
    f = np.asarray(sol.normal_force[:, 0])
    assert f.min() >= 0.0 and f.max() > 0.0
    e = -float(sol.qdot[-1, 0])
    entry = 0.5 * 1.0 * 1.0**2  # entry kinetic energy [J]
    assert abs(float(sol.memory.work[-1, 0]) + (1 - e**2) * entry) < 1e-6 * entry


# ---------------------------------------------------------------- the hybrid model


def kin_at(delta, law, angle=0.3, phi_j=0.0):
    body = jc.Body("pin", 1.0, 1e-3, {"c": (0.0, 0.0)})
    joint = jc.ClearanceJoint(jc.GROUND, "hole", "pin", "c", RB, RJ, length=L, law=law)
    mech = jc.Mechanism([body], clearance_joints=[joint], ground_points={"hole": (0, 0)})
    e = C + delta
    q = jnp.array([e * np.cos(angle), e * np.sin(angle), phi_j])
    return kinematics(mech, joint, q, jnp.zeros(3))


def test_foundation_modulus_of_steel():
    assert abs(float(foundation_modulus(jc.STEEL)) / KF - 1) < 1e-3


@pytest.mark.parametrize("delta,ref", [(1e-7, 141.2), (1e-6, 4459.0), (1e-5, 1.394e5)])
def test_closed_form_reference_values(delta, ref):
    """The closed form's reference values (docs/theory/hybrid.md; L = 10 mm, h = c) to their printed 4 digits."""
    f = float(small_gap_force(C + delta, C, foundation_modulus(jc.STEEL), C, RJ, L))
    assert abs(f / ref - 1) < 5e-4


@pytest.mark.parametrize("delta", [1e-7, 1e-6, 1e-5])
def test_hybrid_arc_matches_closed_form(delta):
    """Arc placement on the small-gap profile: the integrand is smooth on the arc, so 2 x 4
    Gauss points are exact to 1e-6 relative (the issue's bound)."""
    law = jc.HybridLaw(restitution=1.0, geometry="small-gap", placement="arc", n_elements=2, n_gauss=4)
    kin = kin_at(delta, law)
    exact = float(small_gap_force(kin.e, C, foundation_modulus(jc.STEEL), C, RJ, L))
    assert abs(float(law.normal_force(kin, 1.0)) / exact - 1) < 1e-6


def test_hybrid_fixed_converges_to_closed_form():
    """Fixed (body-fixed, whole circumference) placement: the contact arc is a few degrees, so the
    error falls as the elements shrink; shown for N_e = 45 .. 1440 (2 points each) at
    delta = 1e-6 m, ending below 5e-4 relative."""
    kin = kin_at(1e-6, jc.HybridLaw())
    exact = float(small_gap_force(kin.e, C, foundation_modulus(jc.STEEL), C, RJ, L))
    errors = []
    for n_e in (45, 90, 180, 360, 720, 1440):
        law = jc.HybridLaw(restitution=1.0, geometry="small-gap", placement="fixed", n_elements=n_e, n_gauss=2)
        errors.append(abs(float(law.normal_force(kin, 1.0)) / exact - 1))
    assert errors[-1] < 5e-4
    assert errors[-1] < errors[0] / 50
    assert max(errors[3:]) < min(errors[:2])


@pytest.mark.parametrize("delta", [1e-7, 1e-6, 1e-5])
def test_exact_circle_geometry_gives_about_2_5_percent_more(delta):
    exact_geometry = jc.HybridLaw(restitution=1.0, geometry="exact", placement="arc")
    small = jc.HybridLaw(restitution=1.0, geometry="small-gap", placement="arc")
    kin = kin_at(delta, exact_geometry)
    ratio = float(exact_geometry.normal_force(kin, 1.0)) / float(small.normal_force(kin, 1.0))
    assert 1.02 < ratio < 1.03, ratio


def test_fixed_and_arc_agree_on_exact_geometry():
    kin = kin_at(3e-6, jc.HybridLaw(), phi_j=0.7)
    arc = float(jc.HybridLaw(restitution=1.0, placement="arc").normal_force(kin, 1.0))
    fixed = float(jc.HybridLaw(restitution=1.0, placement="fixed", n_elements=720, n_gauss=2).normal_force(kin, 1.0))
    assert abs(fixed / arc - 1) < 2e-3


def winkler_force_numpy(e_vec, phi_j, amp, theta0, n=400_000):
    """Independent dense trapezoid integration (NumPy) of the Winkler pressure of an oval journal
    R_J + amp cos 2(theta - theta0) (body-fixed theta) in a circular bearing: force vector [N]."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    g = th + phi_j
    u = np.stack([np.cos(g), np.sin(g)], axis=1)
    r = RJ + amp * np.cos(2 * (th - theta0))
    p = e_vec[None, :] + r[:, None] * u
    delta = np.linalg.norm(p, axis=1) - RB
    pressure = float(foundation_modulus(jc.STEEL)) * np.maximum(delta, 0) / C
    return -(2 * np.pi / n) * np.sum((pressure * RJ * L)[:, None] * u, axis=0)


@pytest.mark.parametrize("theta0,sign", [(0.3, +1), (0.3 + np.pi / 2, -1)])
def test_oval_journal_force_follows_geometry(theta0, sign):
    """An oval journal (+-1 um, penetration 2 um) whose long axis points at the contact pushes harder than the
    circle, one whose short axis does pushes less; both equal the independent NumPy integral
    (0.5 % with 1440 points). Only the point model can do this."""
    amp, delta, angle, phi_j = 1e-6, 2e-6, 0.3, 0.0
    law = jc.HybridLaw(restitution=1.0, placement="fixed", n_elements=720, n_gauss=2, journal_profile=jc.oval(amp, theta0))
    circle = jc.HybridLaw(restitution=1.0, placement="arc")
    kin = kin_at(delta, law, angle=angle, phi_j=phi_j)
    f_oval, direction = law.contact_force(kin, 1.0)
    ref = winkler_force_numpy(np.asarray(kin.ecc), phi_j, amp, theta0)
    assert abs(float(f_oval) / np.linalg.norm(ref) - 1) < 5e-3
    np.testing.assert_allclose(np.asarray(direction), -ref / np.linalg.norm(ref), atol=1e-3)
    f_circle = float(circle.normal_force(kin, 1.0))
    assert sign * (float(f_oval) - f_circle) > 0.2 * f_circle
    # the profile moves contact onset: penetration is the deepest point overlap
    assert sign * (float(law.penetration(kin)) - delta) > 0.9 * amp


def _swap_into_benchmark(names):
    for name in names:
        mech = jc.preset("flores-slider-crank", law=name)
        sol = jc.simulate(mech, jc.settings(4e-4, n_out=11))
        assert int(sol.status) == 0 and float(sol.impacts[0]) >= 1, name  # the first impact is at 0.23 ms


def test_laws_swap_into_the_benchmark_with_one_argument():
    """One argument swaps the law of the benchmark's clearance joint (the single-impact tests above
    run every law inside a clearance joint; here two that differ most from the default)."""
    _swap_into_benchmark(["hybrid", "kelvin-voigt"])


@pytest.mark.slow
def test_every_law_swaps_into_the_benchmark_with_one_argument():
    _swap_into_benchmark(ALL_LAWS)


# ---------------------------------------------------------------- friction


def test_ambrosio_by_hand():
    mu, fn = 0.2, 100.0
    for v, expected in [(5e-5, 0.0), (-5e-5, 0.0), (5.5e-4, -0.5 * mu * fn), (-5.5e-4, 0.5 * mu * fn),
                        (2e-3, -mu * fn), (-1.0, mu * fn)]:
        assert float(fr.ambrosio(v, fn, mu, 1e-4, 1e-3)) == pytest.approx(expected, abs=1e-12)


def test_coulomb_and_smooth_by_hand():
    assert float(fr.coulomb(0.3, 10.0, 0.1)) == pytest.approx(-1.0)
    assert float(fr.smooth_coulomb(1e-3, 10.0, 0.1, 1e-3)) == pytest.approx(-math.tanh(1.0))
    g = jax.grad(lambda v: fr.smooth_coulomb(v, 10.0, 0.1, 1e-3))(0.0)
    assert float(g) == pytest.approx(-1000.0)


@pytest.mark.parametrize("model", ["ambrosio", "coulomb", "smooth", "none"])
def test_friction_never_does_positive_work(model):
    law = jc.Friction(0.3, model=model)
    v = jnp.linspace(-0.01, 0.01, 401)
    assert bool(jnp.all(jax.vmap(lambda x: law(x, 50.0))(v) * v <= 0.0))


def test_friction_selectable_per_joint():
    """The friction law of a joint is swapped by replacing one field (here on the clearance
    pendulum, which slides along the bearing wall after landing)."""
    import equinox as eqx
    from conftest import clearance_pendulum

    mech = clearance_pendulum(restitution=0.5, friction=0.1)
    m = eqx.tree_at(lambda m: m.clearance_joints[0].friction, mech, jc.Friction(0.1, model="smooth"))
    sol = jc.simulate(m, jc.settings(0.1, n_out=51))
    assert int(sol.status) == 0 and float(jnp.abs(sol.friction_force).max()) > 0


# ---------------------------------------------------------------- bad input


def test_unknown_law_lists_valid_ones():
    with pytest.raises(jc.ParameterError, match=r"unknown contact law 'hertzz'; valid laws: \[.*'hybrid'"):
        jc.make_law("hertzz")


@pytest.mark.parametrize("kwargs,match", [
    (dict(n_elements=0), r"n_elements = 0 is outside the allowed range: an integer in \[1, 100000\]"),
    (dict(n_gauss=0), r"n_gauss = 0 is outside the allowed range: an integer in \[1, 64\]"),
    (dict(thickness=0.0), r"thickness \(h\) = 0 m is outside the allowed range \(0, inf\)"),
    (dict(thickness=-1e-3), r"thickness \(h\) = -0.001 m is outside"),
    (dict(placement="spiral"), r"placement must be 'fixed' or 'arc'"),
    (dict(restitution=0.0), r"restitution = 0 is outside the allowed range \(0, 1\]"),
])
def test_hybrid_bad_parameters(kwargs, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.HybridLaw(**kwargs)


def test_profile_making_journal_larger_than_bearing():
    law = jc.HybridLaw(placement="fixed", journal_profile=jc.oval(0.6e-3))
    with pytest.raises(jc.ParameterError, match=r"the profiles make the journal larger than the bearing"):
        jc.ClearanceJoint(jc.GROUND, "hole", "pin", "c", RB, RJ, law=law)


def test_fixed_placement_in_a_simulation():
    """The fixed-placement hybrid law inside a jitted simulation: its body-fixed unit vectors
    (from the angle-addition formulas) equal cos/sin of the node angles to 1e-13, and the run
    has finite, positive contact forces whenever the journal penetrates."""
    from jaxclear.elements import kinematics

    mech = jc.preset("flores-slider-crank", law="hybrid",
                     law_options={"placement": "fixed", "n_elements": 90, "n_gauss": 2})
    sol = jc.simulate(mech, jc.settings(1.0e-3, n_out=401))
    joint = mech.clearance_joints[0]
    inside = np.flatnonzero(np.asarray(sol.penetration[:, 0]) > 0)
    assert inside.size >= 3
    assert np.all(np.isfinite(np.asarray(sol.normal_force)))
    assert np.all(np.asarray(sol.normal_force[inside, 0]) > 0)
    kin = kinematics(mech, joint, sol.q[inside[0]], sol.qdot[inside[0]])
    angles, weights = joint.law.points(kin)
    cu, su, _, w = joint.law._directions(kin)
    np.testing.assert_allclose(np.asarray(cu), np.cos(np.asarray(angles)), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(su), np.sin(np.asarray(angles)), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(w), np.asarray(weights), rtol=1e-15)
