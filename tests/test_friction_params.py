"""The friction laws' parameters by name (jaxclear.params): every name reads and sets its leaf of
the joint's friction law, ranges are checked, a law without the parameter is refused by name,
a vmapped batch over a name (what a sweep runs) equals single runs, and the gradient with
respect to a friction parameter through the simulation matches central differences.

Truths: the values set by hand (get/replace), the single runs (batch), central differences of
the simulation itself (gradient)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import free_journal

import jaxclear as jc

#: name -> (friction law having it, the law's field, a valid value, an invalid value)
CASES = {
    "friction_static": (jc.Friction(0.1, "lugre", static=0.2), "static", 0.3, -0.1),
    "friction_viscous": (jc.Friction(0.1, "viscous", viscous=0.2), "viscous", 0.5, -1.0),
    "v_stribeck": (jc.Friction(0.1, "stribeck", static=0.2), "v_stribeck", 2e-3, 0.0),
    "stribeck_exponent": (jc.Friction(0.1, "stribeck", static=0.2), "stribeck_exponent", 1.0, 0.0),
    "v_threlfall": (jc.Friction(0.1, "threlfall"), "v_threlfall", 3e-3, 0.0),
    "v_transition": (jc.Friction(0.1, "brown-mcphee", static=0.2), "v_transition", 3e-3, -1.0),
    "bristle_stiffness": (jc.Friction(0.1, "lugre", static=0.2), "bristle_stiffness", 3e5, 0.0),
    "bristle_damping": (jc.Friction(0.1, "lugre", static=0.2), "bristle_damping", 2e-3, -1.0),
}


def _with_friction(mech, law):
    return eqx.tree_at(lambda m: m.clearance_joints[0].friction, mech, law)


@pytest.mark.parametrize("name", sorted(CASES))
def test_friction_parameter_names_reach_their_leaves(name):
    law, field, value, bad = CASES[name]
    mech = _with_friction(free_journal(), law)
    assert name in jc.params.parameter_names()
    assert float(jc.params.get(mech, name)) == float(getattr(law, field))
    new = jc.params.replace(mech, name, value)
    assert float(getattr(new.clearance_joints[0].friction, field)) == value
    assert float(jc.params.get(new, f"{name}@0")) == value
    with pytest.raises(jc.ParameterError, match=name):
        jc.params.validate(mech, name, [bad])
    # a law without it (the default Ambrosio law) is refused, naming the laws that have it
    with pytest.raises(jc.ParameterError, match=f"no '{field}'"):
        jc.params.get(free_journal(), name)


def test_translational_joint_friction_parameters_by_name():
    """The names address a translational clearance joint's friction law too."""
    mech = _with_friction(jc.preset("slider-crank-guide-clearance"), jc.Friction(0.1, "lugre", static=0.2))
    assert isinstance(mech.clearance_joints[0], jc.TranslationalClearanceJoint)
    assert float(jc.params.get(jc.params.replace(mech, "bristle_stiffness", 2e5), "bristle_stiffness")) == 2e5


@pytest.mark.slow  # about 2 min on a shared 2-core machine (a vmapped and a forward-mode compile)
def test_friction_viscous_batch_and_gradient_through_the_simulation():
    """One oblique impact with viscous friction (mu = 0, mu_v = 0.2 s/m: smooth in the slip, so the
    explicit solver meets no sign switch; Coulomb's sign(v) chatters to max_steps): a vmapped
    batch over ``friction_viscous`` (as a sweep runs it) equals single runs (1e-9 relative);
    d(tangential velocity after the impact)/d mu_v (forward mode through diffrax) against central
    differences of the simulation (relative step 1e-4, tolerance 1e-4: rtol 1e-10 integration,
    the friction law smooth in mu_v). The value of the sensitivity solve against the plain run:
    two error-controlled solutions at rtol 1e-10 (the solve's steps sized for its tangent too, at
    a tenth of the tolerance), so within 1e-9 relative (measured 1.2e-10 with one tangent; with
    the 63 of every scalar of the mechanism, before jc.sensitivities integrated one per name,
    below 1e-12 by the many more steps)."""
    mech = free_journal(restitution=0.8, offset=(-0.2e-3, 0.25e-3), friction=jc.Friction(0.0, "viscous", viscous=0.2))
    s = jc.settings(1.0e-3, n_out=3, rtol=1e-10, atol=1e-14)

    def loss(sol, m):
        return sol.qdot[-1, 1]

    run = jax.jit(lambda x: loss(jc.simulate(jc.params.replace(mech, "friction_viscous", x), s), mech))
    batch = jax.vmap(run)(jnp.array([0.2, 1.0]))
    np.testing.assert_allclose(np.asarray(batch), [float(run(0.2)), float(run(1.0))], rtol=1e-9)
    assert abs(float(batch[0]) - float(batch[1])) > 1e-6  # the viscous term matters

    value, grads = jc.parameter_grad(loss, mech, ["friction_viscous"], s, mode="forward")
    h = 1e-4 * 0.2
    fd = (float(run(0.2 + h)) - float(run(0.2 - h))) / (2 * h)
    assert float(value) == pytest.approx(float(run(0.2)), rel=1e-9)
    assert float(grads["friction_viscous"]) == pytest.approx(fd, rel=1e-4)
