"""Friction laws beyond Coulomb: each steady force-velocity curve against its closed form
written out here; the bristle laws' steady sliding (LuGre -> its Stribeck curve, Dahl ->
Coulomb) from an independent SciPy integration of the bristle equation; sticking under a
tangential load below the static limit (LuGre, Karnopp) for a block on a plane integrated by
SciPy; the contact work of a clearance joint with bristle friction against its mechanical
energy; vmap and grad through the bristle state; named errors."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import clearance_pendulum, free_journal
from scipy.integrate import solve_ivp

import jaxclear as jc
from jaxclear.contact import friction_laws as fl
from jaxclear.contact.friction import FRICTION_MODELS
from jaxclear.mechanism_files import dumps_mechanism, loads_mechanism

MU_K, MU_S, MU_V, FN = 0.1, 0.15, 0.5, 20.0
V_REF = 1e-3  # Stribeck, Threlfall, Brown-McPhee speeds [m/s]
V = np.concatenate([-np.logspace(-5, 0, 31)[::-1], [0.0], np.logspace(-5, 0, 31)])


def closed_forms():
    """name -> (law, F_T(v) in NumPy), each written from its published form."""
    s = np.sign(V)
    a = np.abs(V)
    x = V / V_REF
    return {
        "viscous": (jc.Friction(MU_K, "viscous", viscous=MU_V), -FN * (MU_K * s + MU_V * V)),
        "stribeck": (jc.Friction(MU_K, "stribeck", static=MU_S, v_stribeck=V_REF, viscous=MU_V),
                     -FN * ((MU_K + (MU_S - MU_K) * np.exp(-(a / V_REF) ** 2)) * s + MU_V * V)),
        "stribeck-1": (jc.Friction(MU_K, "stribeck", static=MU_S, v_stribeck=V_REF, stribeck_exponent=1.0),
                       -FN * (MU_K + (MU_S - MU_K) * np.exp(-a / V_REF)) * s),
        "threlfall": (jc.Friction(MU_K, "threlfall", v_threlfall=V_REF), -MU_K * FN * (1 - np.exp(-3 * a / V_REF)) * s),
        "brown-mcphee": (jc.Friction(MU_K, "brown-mcphee", static=MU_S, v_transition=V_REF, viscous=MU_V),
                         -FN * (MU_K * np.tanh(4 * x) + (MU_S - MU_K) * x / (x**2 / 4 + 0.75) ** 2 + MU_V * V)),
        "karnopp (sliding)": (jc.KarnoppFriction(MU_K, static=MU_S, v_stick=1e-6, viscous=MU_V),
                              np.where(a < 1e-6, 0.0, -FN * (MU_K * s + MU_V * V))),
        "lugre (steady)": (jc.Friction(MU_K, "lugre", static=MU_S, v_stribeck=V_REF, viscous=MU_V),
                           -FN * ((MU_K + (MU_S - MU_K) * np.exp(-(a / V_REF) ** 2)) * s + MU_V * V)),
        "dahl (steady)": (jc.Friction(MU_K, "dahl"), -MU_K * FN * s),
    }


@pytest.mark.parametrize("name", list(closed_forms()))
def test_steady_force_velocity_curve_matches_closed_form(name):
    law, expected = closed_forms()[name]
    got = np.asarray(jax.vmap(lambda v: law(v, FN))(jnp.asarray(V)))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * FN)


def test_karnopp_stick_band_balances_the_load_up_to_the_static_limit():
    law = jc.KarnoppFriction(MU_K, static=MU_S, v_stick=1e-4)
    for load, expected in [(1.0, -1.0), (-2.5, 2.5), (10.0, -MU_S * FN), (-10.0, MU_S * FN)]:
        assert float(law(5e-5, FN, load)) == pytest.approx(expected, abs=1e-12)
    assert float(law(2e-4, FN, 1.0)) == pytest.approx(-MU_K * FN)


def test_brown_mcphee_peak_is_the_static_coefficient_at_the_transition_speed():
    """Published property: the curve peaks at |v| = v_t with mu_k tanh(4) + (mu_s - mu_k)
    (within 1e-3 of mu_s), and the second term's slope vanishes there."""
    law = jc.Friction(MU_K, "brown-mcphee", static=MU_S, v_transition=V_REF)
    v = jnp.linspace(0.2, 3.0, 28001) * V_REF
    f = -np.asarray(jax.vmap(lambda x: law(x, 1.0))(v))
    peak = MU_K * math.tanh(4) + MU_S - MU_K
    assert abs(float(v[np.argmax(f)]) / V_REF - 1) < 0.02
    assert -float(law(V_REF, 1.0)) == pytest.approx(peak, rel=1e-12)
    assert f.max() == pytest.approx(peak, rel=1e-4)  # the tanh term still rises a little past v_t
    assert abs(peak - MU_S) < 1e-3


@pytest.mark.parametrize("model", list(FRICTION_MODELS))
def test_friction_never_does_positive_work(model):
    law = jc.Friction(0.3, model=model)
    v = jnp.linspace(-0.01, 0.01, 401)
    assert bool(jnp.all(jax.vmap(lambda x: law(x, 50.0))(v) * v <= 0.0))


# ---------------------------------------------------------------- bristle laws


def _bristle_steady(law, v):
    """Force after integrating dz/dt (the law's rate) at constant slip v with SciPy from z = 0
    over many bristle time constants."""
    rate = jax.jit(lambda z: law.force_and_rate(z, v, FN))
    tau = 1.0 / (float(law.bristle_stiffness) * abs(v) / MU_K)
    sol = solve_ivp(lambda t, z: np.asarray(rate(jnp.asarray(z))[1]), (0, 60 * tau), [0.0], method="LSODA",
                    rtol=1e-12, atol=1e-18)
    return float(rate(jnp.asarray(sol.y[:, -1]))[0])


@pytest.mark.parametrize("v", [-0.1, -1e-3, 3e-4, 1e-3, 2e-3, 0.05])
def test_lugre_steady_sliding_equals_its_stribeck_curve(v):
    law = jc.Friction(MU_K, "lugre", static=MU_S, v_stribeck=V_REF, bristle_stiffness=1e5, bristle_damping=3.0,
                      viscous=MU_V)
    stribeck = -FN * ((MU_K + (MU_S - MU_K) * math.exp(-((v / V_REF) ** 2))) * math.copysign(1, v) + MU_V * v)
    assert _bristle_steady(law, v) == pytest.approx(stribeck, rel=1e-8)


@pytest.mark.parametrize("v", [-0.02, 1e-4, 0.3])
def test_dahl_steady_sliding_is_coulomb(v):
    law = jc.Friction(MU_K, "dahl", bristle_stiffness=2e5)
    assert _bristle_steady(law, v) == pytest.approx(-MU_K * FN * math.copysign(1, v), rel=1e-8)


def _block(law, load, v0=0.0, t_end=1.0, mass=1.0):
    """A block of ``mass`` on a plane (F_N = m g) pushed by a constant tangential ``load`` [N],
    with friction ``law``: SciPy integration of [x, v, W, bristle...], W' = F_T v."""
    fn = mass * 9.81
    if law.state_size:
        def friction(v, z):
            return law.force_and_rate(z, v, fn)
    elif isinstance(law, jc.KarnoppFriction):
        def friction(v, z):
            return law(v, fn, load), jnp.zeros(0)
    else:
        def friction(v, z):
            return law(v, fn), jnp.zeros(0)
    friction = jax.jit(friction)

    def rhs(t, y):
        f, zdot = friction(y[1], jnp.asarray(y[3:]))
        f = float(f)
        return [y[1], (load + f) / mass, f * y[1], *np.asarray(zdot)]

    def stops(t, y):  # a launched block comes to rest: end there (a static law would chatter)
        return y[1] if v0 > 0 else 1.0

    stops.terminal, stops.direction = True, -1
    y0 = [0.0, v0, 0.0] + [0.0] * law.state_size
    return solve_ivp(rhs, (0, t_end), y0, method="LSODA", rtol=1e-10, atol=1e-14, events=stops)


def test_lugre_sticks_under_a_load_below_the_static_limit():
    """Load 0.8 mu_s F_N (above the kinetic limit mu_k F_N, so Coulomb sliding would not stop):
    the block creeps a few pre-sliding lengths mu_s/sigma_0 (1.5 um; the suddenly applied load
    overshoots the static one, load/(sigma_0 F_N)) and then stays put: no drift between 0.25 s and
    0.5 s. At 1.2 mu_s F_N it slides away."""
    sigma0, mass = 1e5, 1.0
    fn = 9.81 * mass
    law = jc.Friction(MU_K, "lugre", static=MU_S, v_stribeck=V_REF, bristle_stiffness=sigma0,
                      bristle_damping=2 * math.sqrt(sigma0 * mass / fn))
    load = 0.8 * MU_S * fn
    sol = _block(law, load, t_end=0.5)
    x, v, z = sol.y[0, -1], sol.y[1, -1], sol.y[3, -1]
    assert abs(v) < 1e-9
    assert z == pytest.approx(load / (sigma0 * fn), rel=1e-6)  # the bristles carry the load
    assert 0 < x < 3 * MU_S / sigma0
    assert abs(_block(law, load, t_end=0.25).y[0, -1] - x) < 1e-12  # stuck: no drift
    assert _block(law, 1.2 * MU_S * fn, t_end=0.5).y[0, -1] > 0.01


def test_karnopp_sticks_under_a_load_below_the_static_limit():
    mass = 1.0
    fn = 9.81 * mass
    law = jc.KarnoppFriction(MU_K, static=MU_S, v_stick=1e-4)
    stuck = _block(law, 0.8 * MU_S * fn, t_end=0.5)
    assert np.max(np.abs(stuck.y[0])) == 0.0 and np.max(np.abs(stuck.y[1])) == 0.0
    slides = _block(law, 1.2 * MU_S * fn, t_end=0.5)
    # after leaving the band it accelerates at (load - mu_k F_N)/m
    assert slides.y[1, -1] == pytest.approx((1.2 * MU_S - MU_K) * fn / mass * 0.5, rel=1e-3)


@pytest.mark.parametrize("model", ["viscous", "stribeck", "threlfall", "brown-mcphee", "lugre", "dahl"])
def test_block_energy_lost_equals_friction_work(model):
    """A block launched at 0.2 m/s slides until it stops: its kinetic energy change equals the
    integral of F_T v (1e-7 of the initial energy), and that work is negative."""
    law = jc.Friction(MU_K, model, static=MU_S, viscous=MU_V, bristle_damping=1.0)
    sol = _block(law, 0.0, v0=0.2, t_end=0.3)
    dke = 0.5 * sol.y[1, -1] ** 2 - 0.5 * 0.2**2
    assert sol.y[2, -1] < 0
    assert abs(dke - sol.y[2, -1]) < 1e-7 * 0.5 * 0.2**2


# ---------------------------------------------------------------- inside a clearance joint


def _energy(mech, q, qdot):
    body = mech.bodies[0]
    g = np.asarray(mech.gravity)
    return (0.5 * float(body.mass) * (qdot[0] ** 2 + qdot[1] ** 2) + 0.5 * float(body.inertia) * qdot[2] ** 2
            - float(body.mass) * (g[0] * q[0] + g[1] * q[1]))


def test_clearance_joint_carries_bristle_state_and_its_work_balances_energy():
    """The clearance pendulum with LuGre friction: the joint's slice holds the memory and one
    bristle state; the mechanical energy lost equals the contact work the joint integrated
    (normal and friction power) to 1e-3 of it, the rest being the elastic energy stored at
    the end (contact and bristles, bounded here)."""
    law = jc.Friction(0.2, "lugre", static=0.3, bristle_stiffness=1e5, bristle_damping=1e-2)
    mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction, clearance_pendulum(restitution=0.5), law)
    assert mech.clearance_joints[0].state_size == 7
    sol = jc.simulate(mech, jc.settings(0.2, n_out=5, rtol=1e-8, atol=1e-12))
    assert int(sol.status) == 0
    z = np.asarray(sol.element_states[0].friction)
    assert z.shape == (5, 1) and np.all(np.abs(z) <= 0.3 / 1e5 * 1.01)  # |z| <= mu_s/sigma_0
    q, qd = np.asarray(sol.q), np.asarray(sol.qdot)
    lost = _energy(mech, q[-1], qd[-1]) - _energy(mech, q[0], qd[0])
    work = float(sol.memory.work[-1, 0])
    assert work < 0 and abs(lost - work) < 1e-3 * abs(work), (lost, work)


@pytest.mark.slow  # about 5 min on a shared 2-core machine (compiles the reverse-mode gradient)
def test_bristle_state_under_vmap_and_grad():
    """One oblique impact with LuGre friction: a vmapped batch over the bristle stiffness equals
    the single runs, and d(loss)/d(sigma_0) through the bristle state matches central
    differences (1e-3, the tolerance of tests/test_gradients.py)."""
    base = free_journal(restitution=0.8, offset=(-0.2e-3, 0.25e-3),
                        friction=jc.Friction(0.2, "lugre", static=0.25, bristle_stiffness=1e4, bristle_damping=1e-3))
    s = jc.settings(1.0e-3, n_out=3, rtol=1e-10, atol=1e-14)

    def loss(sigma0):
        mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction.bristle_stiffness, base, sigma0)
        sol = jc.simulate(mech, s)
        return sol.qdot[-1, 1] + 1e3 * sol.q[-1, 1]

    f = jax.jit(loss)
    batch = jax.vmap(f)(jnp.array([1e4, 3e4]))
    np.testing.assert_allclose(np.asarray(batch), [float(f(1e4)), float(f(3e4))], rtol=1e-9)
    assert abs(float(batch[0]) - float(batch[1])) > 1e-6  # the bristles matter
    g = float(jax.jit(jax.grad(loss))(1e4))
    h = 1e-4 * 1e4
    fd = (float(f(1e4 + h)) - float(f(1e4 - h))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-3)


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize("model,kwargs,word", [
    ("stribeck", {"static": 0.05}, "static"),
    ("lugre", {"static": 0.05}, "static"),
    ("brown-mcphee", {"static": 0.05}, "static"),
    ("lugre", {"bristle_stiffness": -1e5}, "bristle_stiffness"),
    ("dahl", {"bristle_stiffness": 0.0}, "bristle_stiffness"),
    ("lugre", {"bristle_damping": -1.0}, "bristle_damping"),
    ("viscous", {"viscous": -0.1}, "viscous"),
    ("stribeck", {"v_stribeck": 0.0}, "v_stribeck"),
    ("threlfall", {"v_threlfall": -1.0}, "v_threlfall"),
    ("brown-mcphee", {"v_transition": 0.0}, "v_transition"),
])
def test_out_of_range_friction_parameters_raise_named_errors(model, kwargs, word):
    with pytest.raises(jc.ParameterError, match=word):
        jc.Friction(0.1, model, **kwargs)


def test_karnopp_static_below_kinetic_is_refused():
    with pytest.raises(jc.ParameterError, match="static"):
        jc.KarnoppFriction(0.2, static=0.1)


@pytest.mark.parametrize("field,value", [("static", 0.05), ("bristle_stiffness", -1.0), ("bristle_damping", -1.0)])
def test_run_time_check_of_traced_friction_parameters(field, value):
    """Inside jit (no eager check) the law's check() reports invalid_friction."""
    law = jc.Friction(0.1, "lugre", static=0.2)
    code = jax.jit(lambda x: eqx.tree_at(lambda f: getattr(f, field), law, x).check())(jnp.asarray(value))
    assert code == jc.RESULTS.invalid_friction
    assert law.check() == jc.RESULTS.successful


def test_new_friction_laws_round_trip_through_mechanism_files():
    for law in [jc.Friction(0.1, "lugre", static=0.2, bristle_damping=2.0, viscous=0.1),
                jc.Friction(0.1, "brown-mcphee", static=0.12), jc.Friction(0.05, "threlfall")]:
        mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction, jc.preset("flores-slider-crank"), law)
        assert eqx.tree_equal(loads_mechanism(dumps_mechanism(mech)), mech)


def test_static_helper_defaults_to_kinetic():
    assert float(fl.check_static(0.3, None)) == 0.3


def test_karnopp_in_a_joint_is_refused_by_name():
    """Karnopp's stick band needs the tangential load on the sliding body, which no force element
    knows: every joint refuses it at construction, and a law swapped in afterwards (tree_at) is
    refused when the mechanism is checked."""
    law = jc.KarnoppFriction(MU_K, static=MU_S)
    with pytest.raises(jc.ParameterError, match="KarnoppFriction cannot be used in a ClearanceJoint"):
        jc.ClearanceJoint(jc.GROUND, "a", "b", "c", friction=law)
    with pytest.raises(jc.ParameterError, match="TranslationalClearanceJoint"):
        jc.TranslationalClearanceJoint(jc.GROUND, "a", "b", "c", friction=law)
    mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction, free_journal(), law)
    with pytest.raises(jc.ParameterError, match="tangential load"):
        mech.clearance_joints[0].check()


def test_translational_joint_corners_carry_bristle_states_and_stick():
    """A 1 kg block (50 mm x 30 mm, clearance 0.1 mm per side) dropped from 1 um onto the lower
    guide surface, pushed along the guide by P = 0.5 N < mu_k m g, with LuGre friction at its
    corners (sigma_1 = 2 sqrt(sigma_0/g): the bristles critically damped with the block's mass).
    The joint carries one bristle state per corner (slice 24 + 4). Truths: after 0.3 s the block
    is at rest (|v| < 1e-6 m/s, it moved < 1e-9 m over the last 0.15 s: no creep, which the
    memoryless steady curve, zero at zero slip, cannot give) and the corners' friction balances
    the load (statics, sum F_T = -P, to 1e-4: what is left of the contact oscillation); each
    loaded corner's bristle deflection is within the stick bound mu_s/sigma_0; the upper
    corners never touch and their bristles stay relaxed. The block lands flat (one impact per
    lower corner, together), so both lower bristles have moved with it since the same onset and
    carry the same deflection, which the statics fix by hand: z = P/(sigma_0 m g) (to 1e-5;
    measured 2e-8)."""
    sigma0, p = 1e5, 0.5
    law = jc.Friction(MU_K, "lugre", static=MU_S, bristle_stiffness=sigma0,
                      bristle_damping=2 * math.sqrt(sigma0 / 9.81))
    slider = jc.Body("slider", 1.0, 2.8e-4, {"S": (0.0, 0.0)}, position=(0.0, 0.0, 0.0))
    joint = jc.TranslationalClearanceJoint(
        jc.GROUND, "g", "slider", "S", 0.05, 0.03, 0.03 + 2e-4, initial_offset=(-1e-4 + 1e-6, 0.0),
        law=jc.make_law("lankarani-nikravesh", restitution=0.3, stiffness=4.8e9), friction=law)
    mech = jc.Mechanism([slider], clearance_joints=[joint], loads=[jc.PointForce("slider", "S", (p, 0.0))],
                        ground_points={"g": (0.0, 0.0)})
    assert joint.state_size == 28
    sol = jc.simulate(mech, jc.settings(0.3, n_out=3, rtol=1e-9, atol=1e-13))
    assert int(sol.status) == 0
    state = sol.element_states[0]
    z = np.asarray(state.friction[-1])  # (4 corners, 1)
    f_n, f_t, _ = joint.corner_forces(mech, sol.q[-1], sol.qdot[-1], state.corners.impact_velocity[-1],
                                      state.friction[-1])
    assert abs(float(sol.qdot[-1, 0])) < 1e-6
    assert abs(float(sol.q[-1, 0]) - float(sol.q[1, 0])) < 1e-9
    np.testing.assert_allclose(float(jnp.sum(f_t)), -p, rtol=1e-4)
    assert np.all(z[:2, 0] > 0) and np.all(z[:2, 0] <= MU_S / sigma0) and np.all(z[2:] == 0.0)
    np.testing.assert_array_equal(np.asarray(state.corners.impacts[-1]), [1.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(z[:2, 0], p / (sigma0 * 1.0 * 9.81), rtol=1e-5)
    assert float(f_n[2]) == 0.0 and float(f_n[3]) == 0.0
