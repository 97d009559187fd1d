"""Translational and pin-in-slot clearance joints, and mechanisms mixing several kinds of element
(the lubricated joint: tests/test_lubricated.py): physics against closed forms, independent
quadrature, central differences and the ideal joints."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc


# ---- translational clearance joint ----------------------------------------------------


def BLOCK_SETTINGS(t_end):  # noqa: N802  (one compiled simulation serves both block tests)
    return jc.settings(t_end, n_out=3, rtol=1e-9, atol=1e-13)


def _block(c=1e-4, restitution=0.3, offset=(0.0, 0.0), velocity=(0.0, 0.0), gravity=(0.0, -9.81), inertia=2.8e-4,
           friction=0.0):
    """A 1 kg block (50 mm x 30 mm) in a ground guide with clearance c per side."""
    slider = jc.Body("slider", 1.0, inertia, {"S": (0.0, 0.0)}, position=(0.0, 0.0, 0.0))
    joint = jc.TranslationalClearanceJoint(
        jc.GROUND, "g", "slider", "S", 0.05, 0.03, 0.03 + 2 * c, initial_offset=offset, initial_velocity=velocity,
        law=jc.make_law("lankarani-nikravesh", restitution=restitution, stiffness=4.8e9), friction=jc.Friction(friction))
    return jc.Mechanism([slider], clearance_joints=[joint], gravity=gravity, ground_points={"g": (0.0, 0.0)})


def test_block_resting_in_its_guide_carries_half_its_weight_on_each_lower_corner():
    """Dropped from 1 um above the lower surface, the block settles (c_r = 0.3): the two lower
    corners then carry m g / 2 each and the upper ones nothing (1e-5 relative: what is left of
    the contact oscillation after 0.3 s)."""
    mech = _block(offset=(-1e-4 + 1e-6, 0.0))
    sol = jc.simulate(mech, BLOCK_SETTINGS(0.3))
    joint = mech.clearance_joints[0]
    f_n = joint.corner_forces(mech, sol.q[-1], sol.qdot[-1], sol.element_states[0].corners.impact_velocity[-1])[0]
    np.testing.assert_allclose(np.asarray(f_n), [9.81 / 2, 9.81 / 2, 0.0, 0.0], rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(float(sol.normal_force[-1, 0]), 9.81, rtol=1e-5)


def test_single_corner_impact_reproduces_the_laws_effective_restitution():
    """A tilted block (theta = 4 mrad) moving towards the lower surface at 0.01 m/s, no gravity:
    only its rear-lower corner touches; the ratio of that corner's normal speed after and before
    the impact equals the Lankarani-Nikravesh effective restitution for c_r = 0.5 (0.725, the
    rounded table value; tolerance 2e-3), although the block also starts to spin (the ratio
    holds at the contact point for any effective mass; the slow approach keeps the centripetal
    acceleration of the spinning corner, which grows like v^2, below 1e-3 of the result)."""
    c, theta, v = 5e-4, 4e-3, 0.01
    y0 = -c + 0.025 * math.sin(theta) - 0.015 * (1 - math.cos(theta)) + 2e-6  # rear-lower corner 2 um above
    mech = _block(c=c, restitution=0.5, offset=(y0, theta), velocity=(-v, 0.0), gravity=(0.0, 0.0))
    joint = mech.clearance_joints[0]
    sol = jc.simulate(mech, BLOCK_SETTINGS(2e-6 / v + 1.2e-3))
    impacts = np.asarray(sol.element_states[0].corners.impacts[-1])
    np.testing.assert_array_equal(impacts, [1.0, 0.0, 0.0, 0.0])
    kin0 = joint.corner_kinematics(mech, sol.q[0], sol.qdot[0])
    kin1 = joint.corner_kinematics(mech, sol.q[-1], sol.qdot[-1])
    assert float(kin1.delta[0]) < 0  # separated
    ratio = -float(kin1.deltadot[0]) / float(kin0.deltadot[0])
    assert abs(ratio - 0.725) < 2e-3, ratio


def test_spinning_block_jams_on_diagonal_corners():
    """A centred block spinning at 1 rad/s, no gravity: at theta = 2c/l (4 ms) the rear-lower and
    front-upper corners reach opposite surfaces together (jamming): both carry force at once,
    equal by symmetry (1e-6), the others none, everything finite."""
    mech = _block(velocity=(0.0, 1.0), gravity=(0.0, 0.0))
    joint = mech.clearance_joints[0]
    sol = jc.simulate(mech, BLOCK_SETTINGS(4.03e-3))
    corners = sol.element_states[0].corners
    f_n = np.asarray(joint.corner_forces(mech, sol.q[-1], sol.qdot[-1], corners.impact_velocity[-1])[0])
    assert np.all(np.isfinite(np.asarray(sol.q))) and np.all(np.isfinite(f_n))
    np.testing.assert_array_equal(np.asarray(corners.impacts[-1]), [1.0, 0.0, 0.0, 1.0])
    assert f_n[0] > 0 and f_n[3] > 0 and f_n[1] == 0 and f_n[2] == 0
    np.testing.assert_allclose(f_n[0], f_n[3], rtol=1e-6)


@pytest.mark.slow
def test_guide_clearance_converges_to_the_ideal_translational_joint():
    """Slider-crank with a guide clearance (1000 rpm, one revolution): shrinking the clearance
    (1e-4, 1e-5, 1e-6 m) while stiffening the corners (K x 10 per step) drives the slider's
    position and velocity to the ideal joint's; the lateral offset stays within about the
    clearance plus the contact deformation."""
    ideal = jc.preset("slider-crank-guide-clearance", ideal=True)
    s = jc.settings(jc.crank_period(ideal), n_out=501, rtol=1e-8, atol=1e-12)
    ref = jc.simulate(ideal, s)
    x0, v0 = ref.coordinate(ideal, "slider", "x"), ref.coordinate(ideal, "slider", "x", 1)
    devs = []
    for c, k in [(1e-4, 4.8e9), (1e-5, 4.8e10), (1e-6, 4.8e11)]:
        mech = jc.preset("slider-crank-guide-clearance", clearance=c, stiffness=k)
        sol = jc.simulate(mech, s)
        dx = float(jnp.max(jnp.abs(sol.coordinate(mech, "slider", "x") - x0)))
        dv = float(jnp.sqrt(jnp.mean((sol.coordinate(mech, "slider", "x", 1) - v0) ** 2)))
        assert float(jnp.abs(sol.coordinate(mech, "slider", "y")).max()) < 1.5 * c
        devs.append((dx, dv))
    assert devs[0][0] > devs[1][0] > devs[2][0]
    assert devs[0][1] > devs[1][1] > devs[2][1]
    assert isinstance(jc.preset("slider-crank-guide-clearance").ideal().joints[-1], jc.Translational)


@pytest.mark.parametrize("kw,match", [
    ({"slider_height": 0.03, "guide_width": 0.029}, "does not fit"),
    ({"slider_length": 0.0}, "slider_length"),
    ({"initial_offset": (2e-4, 0.0)}, "initial_offset"),
    ({"law": jc.make_law("lankarani-nikravesh")}, "explicit stiffness"),
])
def test_translational_bad_input_is_named(kw, match):
    args = {"slider_length": 0.05, "slider_height": 0.03, "guide_width": 0.0302} | kw
    with pytest.raises(jc.ParameterError, match=match):
        jc.TranslationalClearanceJoint(jc.GROUND, "g", "slider", "S", **args)


@pytest.mark.parametrize("kw,match", [
    ({"guide_width": -0.03}, "guide_width"),
    ({"slider_height": 0.0}, "slider_height"),
    ({"corner_radius": 0.0}, "corner_radius"),
    ({"impact_velocity_floor": -1.0}, "impact_velocity_floor"),
    ({"axis": (0.0, 0.0)}, "axis"),
])
def test_translational_more_bad_input_is_named(kw, match):
    args = {"slider_length": 0.05, "slider_height": 0.03, "guide_width": 0.0302} | kw
    with pytest.raises(jc.ParameterError, match=match):
        jc.TranslationalClearanceJoint(jc.GROUND, "g", "slider", "S", **args)


CODE = {name: int(getattr(jc.RESULTS, name)._value) for name in jc.RESULTS._name_to_item}


def _codes(mech, where, values):
    """Status codes of ``mech.check()`` with the leaf at ``where`` set to each of ``values``,
    evaluated once eagerly (first value) and under jit(vmap) (all)."""
    def code(v):
        return eqx.tree_at(where, mech, v).check()._value

    eager = eqx.tree_at(where, mech, jnp.asarray(values[0])).check()
    traced = jax.jit(jax.vmap(code))(jnp.asarray(values, dtype=float))
    assert int(eager._value) == int(traced[0])
    return [int(c) for c in traced]


@pytest.mark.parametrize("where, bad, entry", [
    (lambda m: m.clearance_joints[0].guide_width, 0.029, "invalid_clearance"),  # the slider does not fit
    (lambda m: m.clearance_joints[0].slider_height, 0.031, "invalid_clearance"),
    (lambda m: m.clearance_joints[0].slider_length, 0.0, "invalid_clearance"),
    (lambda m: m.clearance_joints[0].corner_radius, -1e-3, "invalid_parameter"),
    (lambda m: m.clearance_joints[0].impact_velocity_floor, 0.0, "invalid_parameter"),
    (lambda m: m.clearance_joints[0].angle, math.nan, "invalid_parameter"),
    (lambda m: m.clearance_joints[0].law.stiffness, -1.0, "invalid_stiffness"),
    (lambda m: m.clearance_joints[0].law.restitution, 1.5, "invalid_restitution"),
    (lambda m: m.clearance_joints[0].friction.coefficient, -0.1, "invalid_friction"),
])
def test_translational_check_names_bad_numbers_inside_jit_and_vmap(where, bad, entry):
    """The constructor refuses these values (tests above); a value that reaches the joint as a
    traced leaf (a sweep, a fit) gets the named status instead, eagerly and under jit(vmap),
    the valid members of the batch untouched."""
    mech = jc.preset("slider-crank-guide-clearance")
    good = float(where(mech))
    assert _codes(mech, where, [bad, good]) == [CODE[entry], 0]


@pytest.mark.parametrize("field, bad", [
    ("viscosity", 0.0), ("viscosity", -0.4), ("length", 0.0),  # the film width
    ("blend_start", 0.0), ("blend_start", 1.0), ("blend_end", 1.2),
    ("blend_start", 0.995),  # above blend_end = 0.99: wrong order
])
def test_lubricated_check_names_bad_numbers_inside_jit_and_vmap(field, bad):
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    where = lambda m: getattr(m.clearance_joints[0], field)  # noqa: E731
    assert _codes(mech, where, [bad, float(where(mech))]) == [CODE["invalid_parameter"], 0]


def test_pin_slot_check_names_a_negative_slot_length_inside_jit_and_vmap():
    mech = jc.preset("slider-crank-pin-slot")
    where = lambda m: m.clearance_joints[0].slot_length  # noqa: E731
    assert _codes(mech, where, [-1e-3, 0.0, 1e-3]) == [CODE["invalid_parameter"], 0, 0]


def test_translational_penetration_limit_reports_a_block_sinking_through_its_guide():
    """The limit is a tenth of the corner radius (0.1 mm for the 1 mm corner). With K = 1 N/m^1.5
    (a law far too soft) the resting block sinks under gravity: after 10 ms of free fall it is
    g t^2 / 2 = 0.49 mm deep, beyond the limit, so the run ends penetration_too_deep; with the
    physical K it stays ok."""
    mech = _block(offset=(-1e-4 + 1e-6, 0.0))
    joint = mech.clearance_joints[0]
    assert float(joint.penetration_limit()) == pytest.approx(1e-4, rel=1e-12)
    soft = eqx.tree_at(lambda m: m.clearance_joints[0].law.stiffness, mech, jnp.asarray(1.0))
    s = jc.settings(0.01, n_out=3, throw=False)
    assert int(jc.simulate(soft, s).status) == CODE["penetration_too_deep"]
    assert int(jc.simulate(mech, s).status) == 0


def test_named_parameters_address_the_translational_joint():
    mech = jc.preset("slider-crank-guide-clearance")
    np.testing.assert_allclose(float(jc.params.get(mech, "clearance")), 1e-4)
    m2 = jc.params.replace_many(mech, {"clearance": 2e-4, "stiffness": 1e10, "restitution": 0.5})
    joint = m2.clearance_joints[0]
    np.testing.assert_allclose(float(joint.guide_width), 0.03 + 4e-4)
    assert float(jc.params.get(m2, "stiffness")) == 1e10 and float(joint.law.restitution) == 0.5


# ---- pin-in-slot joint ----------------------------------------------------------------


def _as_slot(joint, slot_length=0.0):
    return jc.PinSlotJoint(joint.bearing_body, joint.bearing_point, joint.journal_body, joint.journal_point,
                           joint.bearing_radius, joint.journal_radius, slot_length=slot_length, length=joint.length,
                           law=joint.law, friction=joint.friction, name=joint.name)


def _slot_benchmark():
    dry = jc.preset("flores-slider-crank", friction=0.1)
    slot = _as_slot(dry.clearance_joints[0])
    mech = jc.Mechanism(dry.bodies, dry.joints, dry.drivers, [slot], gravity=dry.gravity,
                        ground_points=dry.ground_points, roles=dict(dry.roles))
    return dry, mech


def test_zero_length_slot_is_the_revolute_clearance_joint():
    """With l = 0 the stadium is the bearing's circle: the element's generalized force equals the
    revolute clearance joint's at random states (journal up to 0.6 mm from the centre, so
    in and out of contact, friction 0.1) to rounding (1e-15 relative)."""
    dry, mech = _slot_benchmark()
    joint, slot = dry.clearance_joints[0], mech.clearance_joints[0]
    both = jax.jit(lambda q, qd: (joint.contact(dry, q, qd, jnp.asarray(0.3))[0],
                                  slot.contact(mech, q, qd, jnp.asarray(0.3))[0]))
    q0, _ = dry.guess()
    key = jax.random.PRNGKey(0)
    for _ in range(5):
        k1, k2, key = jax.random.split(key, 3)
        g1, g2 = both(q0 + 6e-4 * jax.random.normal(k1, q0.shape), jax.random.normal(k2, q0.shape))
        np.testing.assert_allclose(g2, g1, rtol=1e-15, atol=1e-15 * float(jnp.abs(g1).max()))


@pytest.mark.slow
def test_zero_length_slot_simulates_like_the_revolute_clearance_joint():
    """Two crank revolutions of the benchmark slider-crank with the l = 0 slot and with the revolute
    clearance joint agree to rounding (the same operations: 1e-12 allowed)."""
    dry, mech = _slot_benchmark()
    s = jc.settings(2 * jc.crank_period(dry), n_out=11)
    a, b = jc.simulate(dry, s), jc.simulate(mech, s)
    np.testing.assert_allclose(b.q, a.q, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b.normal_force, a.normal_force, rtol=1e-12, atol=1e-9)


def test_pin_moves_freely_along_the_slot_and_stops_at_its_end():
    """A free pin in a ground slot (l = 2 mm, c = 0.5 mm), no gravity, moving along the slot at
    0.1 m/s: no contact until it has travelled l/2 + c = 1.5 mm (the semicircular end), then one
    impact (the stadium geometry)."""
    pin = jc.Body("pin", 1.0, 1e-3, {"c": (0.0, 0.0)}, position=(0.0, 0.0, 0.0))
    slot = jc.PinSlotJoint(jc.GROUND, "slot", "pin", "c", 0.010, 0.0095, slot_length=2e-3,
                           initial_velocity=(0.1, 0.0))
    mech = jc.Mechanism([pin], clearance_joints=[slot], gravity=(0.0, 0.0), ground_points={"slot": (0.0, 0.0)})
    sol = jc.simulate(mech, jc.settings(1.4e-3 / 0.1, n_out=3))
    assert float(sol.impacts[0]) == 0.0
    sol = jc.simulate(mech, jc.settings(1.6e-3 / 0.1, n_out=3))
    assert float(sol.impacts[0]) == 1.0


def test_pin_slot_bad_input_is_named():
    with pytest.raises(jc.ParameterError, match="slot_length"):
        jc.PinSlotJoint(jc.GROUND, "slot", "pin", "c", 0.010, 0.0095, slot_length=-1e-3)
    with pytest.raises(jc.ParameterError, match="initial_offset"):
        jc.PinSlotJoint(jc.GROUND, "slot", "pin", "c", 0.010, 0.0095, slot_length=1e-3, initial_offset=(0.0, 6e-4))
    jc.PinSlotJoint(jc.GROUND, "slot", "pin", "c", 0.010, 0.0095, slot_length=1e-3, initial_offset=(9e-4, 0.0))
    assert isinstance(jc.preset("slider-crank-pin-slot").ideal().joints[-1], jc.Revolute)
    line = jc.PinSlotJoint(jc.GROUND, "slot", "pin", "c", 0.010, 0.0095, slot_length=1e-3, ideal="line")
    assert isinstance(line.ideal_joint(), jc.PointOnLine)
    with pytest.raises(jc.ParameterError, match="ideal"):
        jc.PinSlotJoint(jc.GROUND, "slot", "pin", "c", 0.010, 0.0095, ideal="weld")


# ---- several kinds of element in one mechanism ------------------------------------------


def _mixed(speed_rpm=1000.0):
    """Benchmark slider-crank with a lubricated crank-rod joint, the dry rod-slider clearance
    joint and a clearance in the slider's guide (friction 0.05 in the guide)."""
    guide = jc.preset("slider-crank-guide-clearance", speed_rpm=speed_rpm, friction=0.05)
    dry = jc.preset("flores-slider-crank", speed_rpm=speed_rpm).clearance_joints[0]
    crank_rod = jc.LubricatedJoint("rod", "A", "crank", "A", 0.010, 0.0095, viscosity=0.4, name="crank-rod")
    keep = [j for j in guide.joints if not (isinstance(j, jc.Revolute) and {j.body_i, j.body_j} != {jc.GROUND, "crank"})]
    return jc.Mechanism(guide.bodies, keep, guide.drivers, [crank_rod, dry, *guide.clearance_joints],
                        gravity=guide.gravity, ground_points=guide.ground_points, roles=dict(guide.roles), name="mixed")


@pytest.mark.slow
def test_mixed_elements_energy_balance_closes():
    """Lubricated, dry revolute and translational clearance elements together (1000 rpm, one
    revolution): the change of kinetic plus potential energy equals the driver's work (its
    torque times the crank speed, integrated from the output by Simpson's rule on 8001 samples)
    plus the work of every element's forces (integrated in the elements' states: film, contact
    elasticity, damping and friction). Tolerance 1e-3 of the driver's largest cumulative work
    (the quadrature of the impulsive driver torque dominates)."""
    from scipy.integrate import cumulative_simpson

    mech = _mixed()
    assert [type(e).__name__ for e in mech.clearance_joints] == ["LubricatedJoint", "ClearanceJoint",
                                                                 "TranslationalClearanceJoint"]
    sol = jc.simulate(mech, jc.settings(jc.crank_period(mech), n_out=8001, rtol=1e-9, atol=1e-12))
    assert np.all(np.asarray(sol.impacts) >= 0) and sol.normal_force.shape == (8001, 3)
    energy = jax.vmap(lambda q, qd: jc.energy(mech, q, qd))(sol.q, sol.qdot)
    omega = sol.coordinate(mech, "crank", "phi", 1)
    power = -np.asarray(sol.reactions[:, -1]) * np.asarray(omega)
    w_driver = cumulative_simpson(power, x=np.asarray(sol.ts), initial=0.0)
    w_elements = np.asarray(sol.memory.work).sum(axis=-1)
    residual = np.asarray(energy - energy[0]) - w_driver - w_elements
    scale = np.abs(w_driver).max()
    assert np.abs(residual).max() < 1e-3 * scale, (np.abs(residual).max(), scale)


@pytest.mark.slow
def test_mixed_elements_batch_under_vmap():
    """The mixed mechanism batched over the crank-rod film viscosity with jax.vmap: each member
    matches its own unbatched run: slider position to 1e-6 m (1 % of the guide clearance; batched
    and single runs round differently and the impacts amplify rounding), impacts per element
    exactly, and the members differ from each other."""
    mech = _mixed()
    s = jc.settings(0.25 * jc.crank_period(mech), n_out=5, stages="loop")
    mus = jnp.array([0.1, 1.0])
    batched = jax.vmap(lambda mu: jc.simulate(jc.params.replace(mech, "viscosity@0", mu), s))(mus)
    for i, mu in enumerate(mus):
        one = jc.simulate(jc.params.replace(mech, "viscosity@0", mu), s)
        x_b, x_1 = batched.coordinate(mech, "slider", "x")[i], one.coordinate(mech, "slider", "x")
        np.testing.assert_allclose(x_b, x_1, atol=1e-6)
        np.testing.assert_array_equal(batched.impacts[i], one.impacts)
    assert float(jnp.abs(batched.ecc[0, -1, 0] - batched.ecc[1, -1, 0]).max()) > 1e-6


@pytest.mark.slow
def test_simulation_gradient_wrt_viscosity_and_length_matches_central_differences():
    """d(slider velocity at 2 ms)/d(viscosity, length = film width) of the lubricated benchmark (forward mode
    through diffrax) against central differences of the simulation (relative steps 1e-5,
    tolerance 1e-4: rtol 1e-10 integration)."""
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    s = jc.settings(2e-3, n_out=3, rtol=1e-10, atol=1e-13)

    def loss(sol, m):
        return sol.coordinate(m, "slider", "x", 1)[-1]

    value, grads = jc.parameter_grad(loss, mech, ["viscosity", "length"], s, mode="forward")
    for name, x0 in (("viscosity", 0.4), ("length", 0.010)):
        h = 1e-5 * x0
        up = loss(jc.simulate(jc.params.replace(mech, name, x0 + h), s), mech)
        down = loss(jc.simulate(jc.params.replace(mech, name, x0 - h), s), mech)
        fd = float(up - down) / (2 * h)
        np.testing.assert_allclose(float(grads[name]), fd, rtol=1e-4, atol=1e-9)
