"""Design on steady operation (``jc.design(..., steady=SteadyOperation(...))``, issue 44 item 4): the
objective a long-time average, its gradient by least-squares shadowing.

Truths that do not come from the shadowing code:

* the forced, damped pendulum of tests/test_steady_shadowing.py, whose steady running is a
  stable periodic motion: the derivative of the mean squared spin of its bar with respect to the
  hinge's damping is -75.1717 (m^2... rad^2/s^2 per N m s/rad) by central differences of plain
  averages at rtol 1e-10 (steps 1e-2 and 1e-3 agree to 1.5e-4; test_steady_shadowing.py computes
  them again in every run);
* the benchmark slider-crank's ideal slider acceleration in closed form
  (``bench_steady_averages.slider_crank_exact``), against the per-sample deviation the steady
  rms-deviation averages (the ideal joint's motion there by Newton's method).
"""

import json
import math
import warnings

import jax
import numpy as np
import pytest

import jaxclear as jc
from jaxclear import designing
from jaxclear.designing.steady import SteadyRms
from test_steady_shadowing import REVOLUTIONS, TRANSIENT, forced_pendulum, spin_squared

#: d<spin^2>/d(torsion_damping:hinge) of the forced pendulum (module docstring).
DAMPING_SLOPE = -75.1717
LOW, HIGH = 0.05, 0.15


@pytest.mark.extended
def test_a_steady_design_has_the_shadowing_gradient_of_the_average_and_walks_to_the_bound(tmp_path):
    mech = forced_pendulum()
    steady = designing.SteadyOperation(revolutions=REVOLUTIONS, transient_revolutions=TRANSIENT, samples_per_segment=16)
    s = jc.settings(1.0, rtol=1e-8, atol=1e-10, allow_free_dof=True)
    objective = spin_squared(mech)
    kw = dict(settings=s, steady=steady, max_iter=4, progress=False, plots=False, report_sensitivity=False,
              out=tmp_path / "design")
    with warnings.catch_warnings():
        warnings.simplefilter("error", jc.chaos.ShadowingWarning)  # resolved: no warning
        res = jc.design(mech, {"torsion_damping:hinge": (LOW, HIGH)}, objective, **kw)
    report = res.chaos["steady"]
    assert report["gradients"] >= 1 and report["unresolved"] == 0 and report["failed"] == 0
    first = report["reports"][0]
    assert first["u"][0] == pytest.approx(0.5, abs=1e-15)  # the start, 0.1 N m s/rad
    # the journal's gradient over the unit cube is the average's derivative times the range: the
    # shadowing on the design's own grid against central differences of plain averages (1e-3,
    # as in test_steady_shadowing.py; measured there 1.4e-5)
    assert first["gradient"][0] / (HIGH - LOW) == pytest.approx(DAMPING_SLOPE, rel=1e-3)
    assert first["error"][0] < 1e-2 * abs(first["gradient"][0])
    assert max(first["exponents"]) < -1.0  # stable: the shadowing's premise holds
    # more damping, less spin: the optimum is the range's upper end, and the objective fell
    assert res.design["torsion_damping:hinge"] == pytest.approx(HIGH, abs=1e-9)
    assert res.objective["optimum"] < res.objective["start"]
    assert res.settings["steady"]["revolutions"] == REVOLUTIONS
    assert "averaged over 20 revolutions of steady operation after 42" in res.objective["description"]
    # resumed from its journal: the same design, every evaluation replayed, the gradients' errors too
    again = jc.design(mech, {"torsion_damping:hinge": (LOW, HIGH)}, objective, **kw)
    assert again.design == res.design and again.evaluations["replayed"] == sum(res.evaluations.values())
    assert again.chaos["steady"]["reports"] == report["reports"]
    lines = (tmp_path / "design" / designing.JOURNAL_NAME).read_text().splitlines()
    assert any("extra" in json.loads(line) for line in lines[1:])


def test_the_steady_rms_deviation_reads_the_ideal_joints_motion_at_each_sample():
    from bench_steady_averages import slider_crank_exact

    mech = jc.preset("flores-slider-crank")
    sol = jc.simulate(mech, jc.settings(0.006, n_out=120))
    i = 3 * mech.body_index("slider")
    omega, angle0 = float(jc.params.get(mech, "speed")), float(jc.params.get(mech, "angle0"))
    got = jax.vmap(lambda t, q, qd, qdd: SteadyRms("body:slider:x:acc")(t, q, qd, qdd, mech))(
        sol.ts, sol.q, sol.qdot, sol.qddot)
    ideal = slider_crank_exact(angle0 + omega * np.asarray(sol.ts), omega)[2]
    want = (np.asarray(sol.qddot[:, i]) - ideal) ** 2
    # Newton's method to 1e-10 of the constraints (4 iterations from within a clearance): the
    # ideal acceleration to ~1e-9 of its size (8e4 m/s^2), so the squares to ~1e-3 (m/s^2)^2
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-9, atol=1e-3 * (1 + want.max() * 1e-6))


@pytest.mark.parametrize("kwargs, message", [
    (dict(steady="long"), r"steady must be a jaxclear.designing.SteadyOperation"),
    (dict(steady=designing.SteadyOperation(revolutions=0)), r"steady.revolutions = 0 is outside the allowed range \[1, inf\)"),
    (dict(steady=designing.SteadyOperation(blocks=1)), r"steady.blocks = 1 is outside the allowed range \[2, inf\)"),
    (dict(steady=designing.SteadyOperation(), ensemble=designing.Ensemble(starts=2)), r"ensembles do not apply"),
    (dict(steady=designing.SteadyOperation(), objective="peak-force"), r"objective 'peak-force' has no steady form"),
    (dict(steady=designing.SteadyOperation(), objective="rms-deviation:skip=0.5"), r"without skip"),
    (dict(steady=designing.SteadyOperation(), constraints=["peak-force<=5000"]), r"constraints on runs do not apply"),
])
def test_a_steady_design_refuses_what_does_not_apply_naming_it(kwargs, message):
    mech = jc.preset("flores-slider-crank")
    kwargs = dict(kwargs)
    objective = kwargs.pop("objective", "rms-deviation")
    with pytest.raises(jc.ParameterError, match=message):
        jc.design(mech, {"mass:rod": (0.105, 0.315)}, objective, progress=False, plots=False, **kwargs)


def test_the_steady_value_is_the_plain_average_after_the_transient():
    """The value a steady design minimises, against the mean of the objective over a plain run's
    samples after the transient (the same grid), computed here with NumPy."""
    from jaxclear.designing.problem import build_problem
    from jaxclear.designing.steady import SteadyEvaluation

    mech = forced_pendulum()
    steady = designing.SteadyOperation(revolutions=4, transient_revolutions=2, discard_revolutions=1,
                              segments_per_revolution=4, samples_per_segment=4, blocks=2)
    s = jc.settings(1.0, rtol=1e-8, atol=1e-10, allow_free_dof=True)
    variables = designing.check_variables(mech, {"torsion_damping:hinge": (LOW, HIGH)})
    problem = build_problem(mech, variables, designing.objective(spin_squared(mech)), (),
                            (designing.OperatingPoint(),), designing.Ensemble(), 1.0, 64, s)
    values, status = SteadyEvaluation(problem, steady).value(np.asarray([0.5]))
    period = 2 * math.pi / abs(float(jc.params.get(mech, "speed")))
    sol = jc.simulate(mech, jc.settings(7 * period, n_out=7 * 16 + 1, rtol=1e-8, atol=1e-10, allow_free_dof=True))
    spin = np.asarray(sol.qdot[:, 3 * mech.body_index("bob") + 2])
    assert int(status[0]) == 0
    assert float(values[0]) == pytest.approx(np.mean(spin[3 * 16:-1] ** 2), rel=1e-12)


def test_differential_evolution_needs_no_gradient_finds_the_bound_and_replays(tmp_path):
    """``method="differential-evolution"`` on the steady pendulum design: no gradient (the
    report's are NaN), 5 members a generation, and the best design
    is the most damped one it evaluated (the average falls with the damping: DAMPING_SLOPE < 0,
    the truth of the central differences); resumed from its journal, every evaluation replayed
    and the same design to the last bit (a fixed seed)."""
    mech = forced_pendulum()
    steady = designing.SteadyOperation(revolutions=REVOLUTIONS, transient_revolutions=TRANSIENT, samples_per_segment=16)
    s = jc.settings(1.0, rtol=1e-8, atol=1e-10, allow_free_dof=True)
    kw = dict(settings=s, steady=steady, method="differential-evolution", max_iter=3, progress=False, plots=False,
              report_sensitivity=False, out=tmp_path / "design")
    res = jc.design(mech, {"torsion_damping:hinge": (LOW, HIGH)}, spin_squared(mech), **kw)
    assert res.settings["method"] == "differential-evolution"
    assert res.evaluations["gradients"] == 0  # none at the iterates, none at the optimum
    assert math.isnan(res.gradient["torsion_damping:hinge"]) and math.isnan(res.gradient_norm)
    assert res.chaos["steady"]["gradients"] == 0 and res.chaos["warnings"] == []  # no shadowing: nothing to warn of
    # the start and at most 3 generations of 5 (SciPy's start member is the design's start: replayed)
    assert res.iterations <= 3 and res.evaluations["values"] <= designing.optimize.POPULATION_PER_VARIABLE * 3
    assert all(math.isnan(h["gradient_norm"]) for h in res.history)
    lines = [json.loads(line) for line in (tmp_path / "design" / designing.JOURNAL_NAME).read_text().splitlines()[1:]]
    evaluated = [LOW + (HIGH - LOW) * e["u"][0] for e in lines if e.get("kind", "value") == "value"]
    assert res.design["torsion_damping:hinge"] == pytest.approx(max(evaluated), rel=1e-12)
    assert res.objective["optimum"] < res.objective["start"]
    again = jc.design(mech, {"torsion_damping:hinge": (LOW, HIGH)}, spin_squared(mech), **kw)
    assert again.design == res.design and again.evaluations["replayed"] == sum(res.evaluations.values())
