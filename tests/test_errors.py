"""Every bad input gives an error that names the cause and the allowed range (issue 2, item 10)."""

import logging

import jax
import jax.numpy as jnp
import pytest
from conftest import free_journal

import jaxclear as jc
from jaxclear import params


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(clearance=0.0), r"clearance.*allowed range \(0"),
        (dict(clearance=-1e-4), r"clearance = -0.0001 m is outside the allowed range \(0"),
        (dict(clearance=0.02), r"clearance = 0.02 m must be smaller than bearing_radius"),
        (dict(restitution=0.0), r"restitution = 0 is outside the allowed range \(0, 1\]"),
        (dict(restitution=1.2), r"restitution = 1.2 is outside the allowed range \(0, 1\]"),
        (dict(restitution=float("nan")), r"restitution must be finite"),
        (dict(friction=-0.1), r"friction \(coefficient mu\) = -0.1 is outside the allowed range \[0, inf\)"),
        (dict(law="nope"), r"unknown contact law 'nope'; valid laws: \[.*lankarani-nikravesh"),
        (dict(stiffness=-1.0), r"stiffness = -1 N/m\^n is outside"),
    ],
)
def test_preset_parameter_errors(kwargs, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.preset("flores-slider-crank", **kwargs)


def test_journal_not_smaller_than_bearing():
    with pytest.raises(jc.ParameterError, match=r"journal_radius = 0.01 m must be smaller than bearing_radius"):
        jc.ClearanceJoint("a", "p", "b", "p", bearing_radius=0.01, journal_radius=0.01)
    with pytest.raises(jc.ParameterError, match=r"journal_radius = -0.001 m is outside the allowed range \(0"):
        jc.ClearanceJoint("a", "p", "b", "p", bearing_radius=0.01, journal_radius=-0.001)


@pytest.mark.parametrize("mass,inertia,match", [
    (0.0, 1.0, r"mass of body 'b' = 0 kg is outside the allowed range \(0, inf\)"),
    (-1.0, 1.0, r"mass of body 'b' = -1 kg"),
    (float("inf"), 1.0, r"mass of body 'b' must be finite"),
    (1.0, float("nan"), r"inertia of body 'b' must be finite"),
    (1.0, 0.0, r"inertia of body 'b' = 0 kg m\^2 is outside"),
])
def test_bad_body(mass, inertia, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.Body("b", mass, inertia)


def test_unknown_preset_lists_valid_ones():
    with pytest.raises(jc.ParameterError, match=r"unknown preset 'nope'; valid presets: \[.*flores-slider-crank"):
        jc.preset("nope")


def test_unknown_body_and_point_names():
    b = jc.Body("crank", 1.0, 1.0, {"A": (0.1, 0.0)})
    with pytest.raises(jc.MechanismError, match=r"unknown body 'rod'; bodies are \['crank'\] and 'ground'"):
        jc.Mechanism([b], joints=[jc.Revolute("crank", "A", "rod", "A")])
    with pytest.raises(jc.MechanismError, match=r"unknown point 'B' on body 'crank'; its points are \['A'\]"):
        jc.Mechanism([b], joints=[jc.Revolute("crank", "B", jc.GROUND, "O")], ground_points={"O": (0, 0)})


def _pendulum(extra_joints=(), drivers=()):
    b = jc.Body("bar", 1.0, 0.01, {"O": (-0.1, 0.0), "E": (0.1, 0.0)}, position=(0.1, 0.0, 0.0))
    return jc.Mechanism(
        [b],
        joints=[jc.Revolute(jc.GROUND, "O", "bar", "O"), *extra_joints],
        drivers=list(drivers),
        ground_points={"O": (0.0, 0.0), "E": (0.2, 0.0)},
    )


def test_redundant_constraints_are_named():
    """Two drivers of the same angle: as many equations as coordinates, but dependent."""
    b1 = jc.Body("crank", 1.0, 0.01, {"O": (-0.1, 0.0), "A": (0.1, 0.0)}, position=(0.1, 0.0, 0.0))
    b2 = jc.Body("link", 1.0, 0.01, {"A": (-0.1, 0.0)}, position=(0.3, 0.0, 0.0))
    mech = jc.Mechanism(
        [b1, b2],
        joints=[jc.Revolute(jc.GROUND, "O", "crank", "O"), jc.Revolute("crank", "A", "link", "A")],
        drivers=[jc.AngleDriver("crank", 1.0), jc.FunctionDriver("crank", "phi", lambda t: 1.0 * t)],
        ground_points={"O": (0, 0)},
    )
    with pytest.raises(jc.MechanismError, match=r"redundant or conflicting constraints: rows FunctionDriver\(crank\)"):
        jc.simulate(mech, jc.settings(0.1))


def test_over_constrained_count():
    mech_args = dict(drivers=[jc.AngleDriver("bar", 1.0)])
    with pytest.raises(jc.MechanismError, match=r"5 constraint equations .* for only 3 coordinates"):
        _pendulum(extra_joints=[jc.Revolute(jc.GROUND, "E", "bar", "E")], **mech_args)


def test_too_few_constraints_for_the_drivers():
    b1 = jc.Body("crank", 1.0, 0.01, {"O": (-0.1, 0.0), "A": (0.1, 0.0)}, position=(0.1, 0.0, 0.0))
    b2 = jc.Body("link", 1.0, 0.01, {"A": (-0.1, 0.0)}, position=(0.3, 0.0, 0.0))
    mech = jc.Mechanism([b1, b2], joints=[jc.Revolute(jc.GROUND, "O", "crank", "O"), jc.Revolute("crank", "A", "link", "A")],
                        drivers=[jc.AngleDriver("crank", 10.0)], ground_points={"O": (0, 0)})
    with pytest.raises(jc.MechanismError, match=r"too few constraints for the drivers: 6 coordinates but only 5"):
        jc.simulate(mech, jc.settings(0.01))
    sol = jc.simulate(mech, jc.settings(0.01, allow_free_dof=True))  # a driven double pendulum is legitimate
    assert bool(jnp.all(jnp.isfinite(sol.q)))


def test_newton_not_converging():
    # the driver asks the centroid of a 0.2 m bar pinned at the origin to sit at x = 0.5 m
    b = jc.Body("bar", 1.0, 0.01, {"O": (-0.1, 0.0), "E": (0.1, 0.0)}, position=(0.1, 0.0, 0.0))
    mech = jc.Mechanism([b], joints=[jc.Revolute(jc.GROUND, "O", "bar", "O")],
                        drivers=[jc.FunctionDriver("bar", "x", lambda t: 0.5 + 0 * t)], ground_points={"O": (0.0, 0.0)})
    with pytest.raises(jc.InitialConditionError, match=r"Newton solve of Phi\(q, 0\) = 0 did not converge"):
        jc.simulate(mech, jc.settings(0.01))


def test_step_limit_is_an_error_naming_max_steps():
    with pytest.raises(jc.SolverError, match=r"max_steps.*raise Settings.max_steps \(now 20, allowed >= 1\)"):
        jc.simulate(jc.preset("flores-slider-crank"), jc.settings(0.01, max_steps=20))


@pytest.mark.extended
def test_failed_run_raises_after_its_program_under_transformations(caplog):
    """A failed run under ``jax.jacfwd`` (called eagerly) and in ``jc.sensitivities`` is the same
    named ``SolverError`` as a plain call, raised in Python after the compiled program returns;
    inside a user's ``jax.jit`` it raises through ``equinox.error_if`` in the user's program.
    Never a silent NaN, and none of jaxclear's own programs holds a host callback, which JAX's
    persistent compilation cache would refuse (issue 41: such programs were compiled anew in
    every process)."""
    mech = free_journal()
    bad = jc.settings(5e-3, max_steps=3)

    def loss(c, s):
        return jc.simulate(params.replace(mech, "restitution", c), s).q[-1, 0]

    with caplog.at_level(logging.DEBUG, logger="jax._src.compiler"):
        with pytest.raises(jc.SolverError, match=r"max_steps before t_end; raise Settings.max_steps \(now 3"):
            jax.jacfwd(loss)(0.9, bad)
        with pytest.raises(jc.SolverError, match=r"max_steps before t_end.*\(the run of jaxclear.sensitivities\)"):
            jc.sensitivities(mech, ["restitution"], bad)
    uncacheable = [r.getMessage() for r in caplog.records if "host callbacks" in r.getMessage()]
    assert not uncacheable, uncacheable
    with pytest.raises(Exception, match="the solver reached max_steps before t_end"):
        jax.block_until_ready(jax.jit(lambda c: loss(c, bad))(0.9))


def test_step_limit_reported_without_throw():
    sol = jc.simulate(jc.preset("flores-slider-crank"), jc.settings(0.01, max_steps=20, throw=False))
    assert int(sol.status) == 1 and jc.STATUS[1].startswith("the solver reached max_steps")


@pytest.mark.parametrize("kwargs,match", [
    (dict(rtol=0.0), r"rtol = 0 is outside the allowed range \(0, 1\)"),
    (dict(atol=-1.0), r"atol = -1 is outside the allowed range \(0, inf\)"),
    (dict(solver="euler9"), r"unknown solver 'euler9'; valid: \["),
    (dict(n_out=1), r"n_out = 1 output samples outside the allowed range \[2, 2000000\]"),
    (dict(stages="fused"), r"stages must be 'unrolled' or 'loop', got 'fused'"),
    (dict(derivative_tolerance=0.0), r"derivative_tolerance = 0 outside the allowed range \(0, 1\]"),
    (dict(derivative_tolerance=2.0), r"derivative_tolerance = 2 outside the allowed range \(0, 1\]"),
])
def test_bad_settings(kwargs, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.settings(0.01, **kwargs)


@pytest.mark.extended
def test_a_traced_tolerance_outside_its_range_is_a_status_naming_it():
    """Tolerances are array leaves, so they can be traced (a ``jax.vmap`` over them), where
    ``Settings``' own check cannot see them: the run checks them too. A lane at rtol 0 or atol
    -1 is status ``invalid_tolerance`` (a zero-length run, no NaN), the others are ok; with
    ``throw`` the same under ``jax.jit`` is an error naming the tolerances and their ranges."""
    import dataclasses

    import jax
    import jax.numpy as jnp

    mech = jc.preset("flores-slider-crank")
    s = jc.settings(2e-4, n_out=11, throw=False)

    def status(rtol, atol):
        return jc.simulate(mech, dataclasses.replace(s, rtol=rtol, atol=atol)).status

    got = jax.vmap(status)(jnp.array([1e-6, 0.0, 1e-6, 1.5]), jnp.array([1e-9, 1e-9, -1.0, 1e-9]))
    bad = int(jc.RESULTS.invalid_tolerance._value)
    assert got.tolist() == [0, bad, bad, bad]
    thrown = dataclasses.replace(s, throw=True)
    with pytest.raises(Exception, match=r"rtol in \(0, 1\) and atol > 0"):
        jax.jit(lambda r: jc.simulate(mech, dataclasses.replace(thrown, rtol=r)).q)(jnp.asarray(0.0)).block_until_ready()


def test_bad_end_time():
    with pytest.raises(jc.ParameterError, match=r"t_end = -1 s must be greater than t_start = 0 s"):
        jc.settings(-1.0)


def test_initial_offset_outside_clearance():
    with pytest.raises(jc.ParameterError, match=r"initial_offset \|e\| = 0.001 m must be smaller than the clearance"):
        free_journal(offset=(1e-3, 0.0))


def test_no_nan_result_without_error():
    """A state that blows up (a torque ramp that spins a free bar to overflow) is an error, never
    a silent NaN."""
    b = jc.Body("bar", 1.0, 1e-30, {"O": (0.0, 0.0)})
    mech = jc.Mechanism([b], loads=[jc.Torque("bar", 0.0, function=lambda t, q, qd: jnp.exp(1e4 * t))], gravity=(0, 0))
    with pytest.raises(jc.SolverError, match="non-finite state|max_steps|solver failed"):
        jc.simulate(mech, jc.settings(1.0, max_steps=2000))
