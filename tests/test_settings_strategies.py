"""Settings made of strategy objects (issue 40, item 1): the solver an instance, the derivatives
``Sensitivity``/``ThroughLoop``, the output sampling ``SampleLoop``/``SampleBlock``, the onsets
``ExactOnsets``/``StepOnsets``. The old keywords (``adjoint``, ``derivative_tolerance``,
``checkpoints``, ``stages``, ``exact_onsets``, ``sampling``) and names give equal settings (equal
pytree structure, hash and key of the store of traced programs); bad names are ParameterErrors
naming the parameter and the allowed values; the old attributes read back with a warning."""

import dataclasses
import warnings

import diffrax
import equinox as eqx
import jax
import pytest

import jaxclear as jc
from jaxclear.integrate import _programs as programs, _strategies as strategies
from jaxclear.integrate._solvers import OnsetController, StopOnNonFinite

# (old spelling, new spelling) of the same settings
SAME = [
    (dict(), dict(solver=diffrax.Tsit5(), derivatives=jc.Sensitivity(), output=jc.SampleLoop(),
                  onsets=jc.ExactOnsets())),
    (dict(adjoint="sensitivity", derivative_tolerance=0.5), dict(derivatives=jc.Sensitivity(tolerance=0.5))),
    (dict(derivative_tolerance=1), dict(derivatives=jc.Sensitivity(1.0))),
    (dict(adjoint="recursive", checkpoints=16), dict(derivatives=jc.ThroughLoop("recursive", checkpoints=16))),
    (dict(adjoint="recursive"), dict(derivatives=jc.ThroughLoop())),
    (dict(adjoint="forward"), dict(derivatives=jc.ThroughLoop(adjoint="forward"))),
    (dict(adjoint="forward", checkpoints=16), dict(derivatives="forward")),  # checkpoints were ignored
    (dict(adjoint="direct", derivative_tolerance=0.3), dict(derivatives=jc.ThroughLoop("direct"))),
    (dict(solver="dopri5"), dict(solver=diffrax.Dopri5())),
    (dict(stages="unrolled"), dict(solver=jc.UnrolledExplicitRK(diffrax.Tsit5()))),
    (dict(stages="loop", solver="bosh3"), dict(solver=diffrax.Bosh3())),
    (dict(stages="unrolled", solver="kvaerno5"), dict(solver=diffrax.Kvaerno5())),  # implicit: its own loop
    (dict(sampling="block"), dict(output=jc.SampleBlock())),
    (dict(sampling="block"), dict(output="block")),
    (dict(sampling="loop"), dict(output=jc.SampleLoop())),
    (dict(exact_onsets=False), dict(onsets=jc.StepOnsets())),
    (dict(exact_onsets=True), dict(onsets=jc.ExactOnsets())),
]


@pytest.mark.parametrize("old,new", SAME)
def test_old_spellings_and_new_objects_give_equal_settings(old, new):
    a, b = jc.settings(0.01, **old), jc.settings(0.01, **new)
    assert bool(eqx.tree_equal(a, b))
    sa, sb = jax.tree_util.tree_structure(a), jax.tree_util.tree_structure(b)
    assert sa == sb and hash(sa) == hash(sb)  # the same compiled program (jit's cache key)
    ka, kb = programs.program_key("simulate", (a,)), programs.program_key("simulate", (b,))
    assert ka is not None and ka[0] == kb[0]  # keyable, the same stored program


def test_different_strategies_give_different_keys():
    keys = {programs.program_key("simulate", (jc.settings(0.01, **kw),))[0]
            for kw in (dict(), dict(derivatives=jc.Sensitivity(0.5)), dict(derivatives=jc.ThroughLoop()),
                       dict(derivatives=jc.ThroughLoop(checkpoints=8)), dict(output=jc.SampleBlock()),
                       dict(output=jc.SampleBlock(size=32)), dict(onsets=jc.StepOnsets()),
                       dict(solver=jc.UnrolledExplicitRK(diffrax.Tsit5())))}
    assert len(keys) == 8


def test_replace_with_old_keywords_changes_only_their_part():
    s = jc.settings(0.01, derivatives=jc.ThroughLoop("recursive", checkpoints=16), output=jc.SampleBlock())
    assert dataclasses.replace(s, checkpoints=64).derivatives == jc.ThroughLoop("recursive", 64)
    assert dataclasses.replace(s, adjoint="forward").derivatives == jc.ThroughLoop("forward")
    back = dataclasses.replace(s, adjoint="sensitivity", derivative_tolerance=0.2)
    assert back.derivatives == jc.Sensitivity(0.2) and back.output == jc.SampleBlock()
    assert dataclasses.replace(back, derivative_tolerance=1.0).derivatives == jc.Sensitivity(1.0)
    u = dataclasses.replace(jc.settings(0.01, solver="dopri5"), stages="unrolled")
    assert u.solver == jc.UnrolledExplicitRK(diffrax.Dopri5())
    assert dataclasses.replace(u, stages="loop").solver == diffrax.Dopri5()
    assert dataclasses.replace(s, sampling="loop").output == jc.SampleLoop()
    assert dataclasses.replace(s, exact_onsets=False).onsets == jc.StepOnsets()
    assert dataclasses.replace(s, rtol=1e-8).derivatives == s.derivatives  # the objects carried over


def test_old_attributes_read_back_with_a_deprecation_warning():
    s = jc.settings(0.01, adjoint="recursive", checkpoints=16, stages="unrolled", exact_onsets=False,
                    sampling="block")
    expected = dict(adjoint="recursive", checkpoints=16, stages="unrolled", exact_onsets=False, sampling="block",
                    derivative_tolerance=0.1)
    field = dict(adjoint="derivatives", checkpoints="derivatives", stages="solver", exact_onsets="onsets",
                 sampling="output", derivative_tolerance="derivatives")
    for name, value in expected.items():
        with pytest.warns(DeprecationWarning, match=rf"Settings\.{name} is deprecated.*; use Settings\.{field[name]}"):
            assert getattr(s, name) == value
    d = jc.settings(0.01, derivative_tolerance=0.25)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert (d.adjoint, d.derivative_tolerance, d.checkpoints, d.stages, d.exact_onsets, d.sampling) == (
            "sensitivity", 0.25, None, "loop", True, "loop")
    # on the class: the old defaults, no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert (jc.Settings.adjoint, jc.Settings.derivative_tolerance, jc.Settings.checkpoints, jc.Settings.stages,
                jc.Settings.exact_onsets, jc.Settings.sampling) == ("sensitivity", 0.1, None, "loop", True, "loop")


@pytest.mark.parametrize("kwargs,match", [
    (dict(adjoint="backsolve"), r"adjoint must be one of \['sensitivity', 'recursive', 'forward', 'direct'\], "
                                r"got 'backsolve'"),
    (dict(derivatives="backsolve"), r"adjoint must be one of \['sensitivity', 'recursive', 'forward', 'direct'\]"),
    (dict(derivatives=3), r"derivatives = 3: expected Sensitivity\(...\), ThroughLoop\(...\) or one of the names"),
    (dict(sampling="dense"), r"sampling must be 'loop' or 'block', got 'dense'"),
    (dict(output="dense"), r"sampling must be 'loop' or 'block', got 'dense'"),
    (dict(output=jc.ExactOnsets()), r"output = ExactOnsets\(\): expected SampleLoop\(\), SampleBlock\(...\) or one"),
    (dict(stages="fused"), r"stages must be 'unrolled' or 'loop', got 'fused'"),
    (dict(solver="euler9"), r"unknown solver 'euler9'; valid: \['bosh3', 'dopri5', 'dopri8', 'kvaerno5', 'tsit5'\]"),
    (dict(solver=diffrax.Euler()), r"solver = Euler\(\): expected one of \['bosh3', .*Runge-Kutta solver instance"),
    (dict(onsets="maybe"), r"onsets = 'maybe': expected ExactOnsets\(\) or StepOnsets\(\)"),
    (dict(exact_onsets="yes"), r"exact_onsets must be True or False, got 'yes'"),
    (dict(derivative_tolerance=0.0), r"derivative_tolerance = 0 outside the allowed range \(0, 1\]"),
])
def test_bad_names_raise_parameter_errors_naming_the_field_and_the_allowed_values(kwargs, match):
    with pytest.raises(jc.ParameterError, match=match):
        jc.settings(0.01, **kwargs)


@pytest.mark.parametrize("make,match", [
    (lambda: jc.ThroughLoop("backsolve"), r"ThroughLoop adjoint must be one of \['recursive', 'forward', 'direct'\]"),
    (lambda: jc.ThroughLoop("forward", checkpoints=4), r"checkpoints = 4 is a setting of adjoint='recursive' only"),
    (lambda: jc.ThroughLoop(checkpoints=0), r"checkpoints = 0 outside the allowed range: an integer >= 1 or None"),
    (lambda: jc.Sensitivity(tolerance=0.0), r"Sensitivity tolerance = 0 outside the allowed range \(0, 1\]"),
    (lambda: jc.Sensitivity(tolerance=1.5), r"Sensitivity tolerance = 1.5 outside the allowed range \(0, 1\]"),
    (lambda: jc.SampleBlock(size=0), r"SampleBlock size = 0 outside the allowed range: an integer >= 1"),
])
def test_bad_strategy_objects_raise_parameter_errors(make, match):
    with pytest.raises(jc.ParameterError, match=match):
        make()


def test_strategies_are_public():
    for name in ("Sensitivity", "ThroughLoop", "SampleLoop", "SampleBlock", "ExactOnsets", "StepOnsets"):
        assert name in jc.__all__ and getattr(jc, name) is getattr(strategies, name)
        assert getattr(jc.integrate, name) is getattr(strategies, name)
    assert jc.SOLVERS is strategies.SOLVERS


def test_each_strategy_owns_its_behaviour():
    """What the integration used to branch on names for, each object answers."""
    tsit5 = diffrax.Tsit5()
    assert jc.Sensitivity().solver(tsit5) is tsit5
    assert jc.ThroughLoop("recursive").solver(tsit5) is tsit5
    for kind in ("forward", "direct"):  # diffrax's differentiable stage loop
        assert jc.ThroughLoop(kind).solver(tsit5) == diffrax.Tsit5(scan_kind="bounded")
    unrolled = jc.UnrolledExplicitRK(tsit5)
    assert jc.ThroughLoop("forward").solver(unrolled) is unrolled  # no stage loop to swap
    # the adjoint handed to diffeqsolve: the kind, the checkpoints, the sampling's buffers
    loop, block = jc.SampleLoop(), jc.SampleBlock()
    assert type(jc.Sensitivity().loop_adjoint(loop)) is diffrax.RecursiveCheckpointAdjoint
    assert jc.ThroughLoop(checkpoints=8).loop_adjoint(loop).checkpoints == 8
    assert type(jc.ThroughLoop("forward").loop_adjoint(loop)) is diffrax.ForwardMode
    assert type(jc.ThroughLoop("direct").loop_adjoint(block)) is jc.integrate.sampling.DirectAdjoint
    assert type(jc.Sensitivity().loop_adjoint(block)) is jc.integrate.sampling.RecursiveCheckpointAdjoint
    # the mode a parameter gradient is taken in
    assert jc.Sensitivity(0.5).for_mode("forward") == jc.Sensitivity(0.5)
    assert jc.ThroughLoop(checkpoints=8).for_mode("forward") == jc.ThroughLoop("forward")
    assert jc.ThroughLoop("forward").for_mode("reverse") == jc.ThroughLoop("recursive")
    assert jc.ThroughLoop("direct").for_mode("reverse") == jc.ThroughLoop("direct")
    assert jc.Sensitivity(0.5).tolerances(1e-6, 1e-9) == (1e-6 * 0.5, 1e-9 * 0.5)
    # the output sampling: diffrax's saving, or the controller writing blocks
    inner = StopOnNonFinite(diffrax.PIDController(rtol=1e-6, atol=1e-9))
    ts = jax.numpy.linspace(0.0, 1.0, 5)
    controller, saveat = loop.saving(inner, ts, diffrax.LocalLinearInterpolation)
    assert controller is inner and not loop.dense_to_controller and saveat.subs.ts is ts
    controller, saveat = jc.SampleBlock(size=2).saving(inner, ts, diffrax.LocalLinearInterpolation)
    assert isinstance(controller, jc.integrate.sampling.SampleWriter) and controller.block == 2
    assert block.dense_to_controller and saveat.controller_state
    # the onsets: the controller wrapped for a mechanism with clearance joints only
    mech, ideal = jc.preset("flores-slider-crank"), jc.preset("flores-slider-crank", ideal=True)
    assert isinstance(jc.ExactOnsets().controller(inner, mech), OnsetController)
    assert jc.ExactOnsets().controller(inner, ideal) is inner
    assert jc.StepOnsets().controller(inner, mech) is inner
