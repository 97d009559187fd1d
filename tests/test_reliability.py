"""Reliability: every bad input gets a named answer, also under ``jit``/``vmap``; impossible
states get named statuses; output folders are locked; interruptions end cleanly.

The simulation tests share one compiled function (:func:`_batch`: four members of the Flores
slider-crank, 20 ms, 11 samples) so the whole module compiles the engine once.
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings as hsettings, strategies as st

import jaxclear as jc
from jaxclear import RESULTS, params
from jaxclear._errors import STATUS, invalid_codes
from jaxclear._storage import locked_folder
from jaxclear.cli import main
from jaxclear.fitting.problem import _check_data
from jaxclear.fitting.state import Checkpoint

MECH = jc.preset("flores-slider-crank")
SET = jc.Settings(t_end=jnp.asarray(0.02), n_out=11, throw=False)
CODE = {name: int(getattr(RESULTS, name)._value) for name in RESULTS._name_to_item}


ROD, RB, C = 0.21, 0.01, 5e-4  # the preset's rod mass [kg], bearing radius [m], clearance [m]


def _member(p):
    """One member: p = (restitution, stiffness, friction, gravity magnitude, rod mass [kg],
    bearing radius [m], clearance [m]); the clearance sets the journal radius R_B - c."""
    m = eqx.tree_at(lambda m: m.clearance_joints[0].bearing_radius, MECH, p[5])
    m = params.replace_many(m, {"restitution": p[0], "stiffness": p[1], "friction": p[2], "mass:rod": p[4],
                                "clearance": p[6]})
    m = eqx.tree_at(lambda m: m.gravity, m, jnp.stack([0.0 * p[3], -p[3]]))
    sol = jc.simulate(m, SET)
    finite = jnp.all(jnp.isfinite(sol.q)) & jnp.all(jnp.isfinite(sol.qdot)) & jnp.all(jnp.isfinite(sol.qddot))
    return sol.status, sol.num_steps, jnp.max(sol.penetration), finite, sol.q[-1], sol.peak_penetration[0]


_batch = jax.jit(jax.vmap(_member))
GOOD = (0.9, 1e10, 0.0, 9.81)


def _rows(rows):
    return jnp.asarray([tuple(r) + (ROD, RB, C)[len(r) - 4:] for r in rows], dtype=float)


def _run(rows):
    """(status, steps, max output penetration, finite, q at the end) of up to 4 members."""
    status, steps, pen, finite, q_end, _ = _batch(_rows(rows))
    return np.asarray(status), np.asarray(steps), np.asarray(pen), np.asarray(finite), np.asarray(q_end)


# ---- 1. range checks where objects are built and at run time ----------------------------


@pytest.mark.parametrize(
    "where, value, entry",
    [
        (lambda m: m.clearance_joints[0].law.restitution, 1.5, "invalid_restitution"),
        (lambda m: m.clearance_joints[0].law.restitution, math.nan, "invalid_restitution"),
        (lambda m: m.clearance_joints[0].law.stiffness, -1.0, "invalid_stiffness"),
        (lambda m: m.clearance_joints[0].journal_radius, 0.011, "invalid_clearance"),
        (lambda m: m.clearance_joints[0].friction.coefficient, -0.1, "invalid_friction"),
        (lambda m: m.bodies[1].mass, 0.0, "invalid_mass"),
        (lambda m: m.clearance_joints[0].law.exponent, -1.5, "invalid_parameter"),
    ],
)
def test_check_names_each_invalid_kind(where, value, entry):
    """mech.check() (traceable) returns the entry naming the invalid input; the constructors
    refuse the same values with a ParameterError."""
    assert MECH.check() == RESULTS.successful
    bad = eqx.tree_at(where, MECH, jnp.asarray(value))
    assert bad.check() == getattr(RESULTS, entry)
    assert STATUS[CODE[entry]].startswith("invalid parameter")


def test_invalid_value_reaching_simulate_names_the_joint_the_value_and_the_one_rule():
    """A clearance set after construction (params.replace: no eager check) to -0.1 mm: simulate
    names the joint, the number, its value and the one rule it broke (it listed every rule of
    invalid_clearance, radii and the slider block in its guide alike)."""
    with pytest.raises(jc.ParameterError) as info:
        jc.simulate(params.replace(MECH, "clearance", -1e-4), jc.settings(1e-4, n_out=3))
    assert str(info.value) == ("jaxclear: invalid parameter: clearance joint rod-slider (clearance_joints[0]): "
                               "clearance c = R_B - R_J = -0.0001 m is outside the allowed range (0, inf) m")


@pytest.mark.parametrize("mech, where, value, told", [
    (MECH, lambda m: m.clearance_joints[0].journal_radius, 0.011,
     "clearance joint rod-slider (clearance_joints[0]): clearance c = R_B - R_J = -0.001 m is outside the allowed "
     "range (0, inf) m"),
    (MECH, lambda m: m.bodies[1].mass, 0.0, "body 'rod': mass = 0 kg is outside the allowed range (0, inf) kg"),
    (MECH, lambda m: m.clearance_joints[0].law.restitution, 1.5,
     "clearance joint rod-slider (clearance_joints[0]): restitution = 1.5 is outside the allowed range (0, 1]"),
    (MECH, lambda m: m.clearance_joints[0].friction.coefficient, -0.1,
     "clearance joint rod-slider (clearance_joints[0]): friction coefficient mu = -0.1 is outside the allowed range "
     "[0, inf)"),
    (jc.preset("slider-crank-guide-clearance"), lambda m: m.clearance_joints[0].guide_width, 0.029,
     "translational clearance joint guide (clearance_joints[0]): clearance per side (W - b)/2 (the block must fit "
     "its guide) = -0.0005 m is outside the allowed range (0, inf) m"),
    (jc.preset("flores-slider-crank", viscosity=0.4), lambda m: m.clearance_joints[0].blend_end, 1.2,
     "clearance joint rod-slider (clearance_joints[0]): blend_end = 1.2 is outside the allowed range (0, 1)"),
])
def test_failed_check_names_the_one_rule(mech, where, value, told):
    """Mechanism.failed_check (eager, what simulate's error says) reads the same rules as the
    traced check(): the first failing one, with its value; None for a valid mechanism."""
    assert mech.failed_check() is None
    bad = eqx.tree_at(where, mech, jnp.asarray(value))
    assert bad.check() != RESULTS.successful
    assert bad.failed_check() == told


def test_constructors_refuse_out_of_range_values():
    with pytest.raises(jc.ParameterError, match=r"restitution = 1.5 .*\(0, 1\]"):
        jc.ContactLaw(restitution=1.5)
    with pytest.raises(jc.ParameterError, match="stiffness"):
        jc.ContactLaw(stiffness=-1.0)


def test_check_under_vmap():
    codes = jax.vmap(lambda r: params.replace(MECH, "restitution", r).check()._value)(
        jnp.array([0.9, 1.5, 0.5, jnp.nan]))
    assert codes.tolist() == [0, CODE["invalid_restitution"], 0, CODE["invalid_restitution"]]


@pytest.mark.extended
def test_vmap_invalid_member_gets_its_own_status_and_others_are_untouched():
    """The audit's case: restitution [0.9, 1.5, 0.5] under jit(vmap) gave [0, 0, 0]. Now the
    invalid members are not integrated (0 steps) and the valid ones equal a batch without them
    (bit for bit: the members are independent)."""
    rows = [GOOD, (1.5, 1e10, 0.0, 9.81), (0.5, 1e10, 0.0, 9.81), (0.9, math.nan, 0.0, 9.81)]
    status, steps, _, finite, q_end = _run(rows)
    assert status.tolist() == [0, CODE["invalid_restitution"], 0, CODE["invalid_stiffness"]]
    assert steps[1] == 0 and steps[3] == 0
    assert finite[0] and finite[2]
    ref = _run([GOOD, GOOD, (0.5, 1e10, 0.0, 9.81), GOOD])
    np.testing.assert_array_equal(q_end[[0, 2]], ref[4][[0, 2]])


def test_batched_members_are_independent_of_their_neighbours():
    """Issue 28, point 5: members of jit(vmap(simulate)) differ from their solo runs in their
    last bits and, through the contact dynamics, in their step counts, but no lane is coupled to
    another: a member's outputs are bit for bit the same next to three copies of itself as next
    to members whose candidate steps are non-finite and retried (StopOnNonFinite), sink into a
    soft contact (penetration_too_deep) or are split at other contact onsets (OnsetController,
    another restitution and friction). docs/errors.md, 'Batched runs'."""
    same = [np.asarray(x) for x in _batch(_rows([GOOD] * 4))]
    for x in same:  # identical inputs, identical lanes (a full group of lanes)
        assert all(np.array_equal(x[0], x[k]) for k in range(1, 4))
    rows = [(0.9, 1e10, 0.0, math.inf), GOOD, (0.9, 2e8, 0.0, 9.81), (0.5, 1e10, 0.1, 9.81)]
    mixed = [np.asarray(x) for x in _batch(_rows(rows))]
    assert mixed[0].tolist()[0] == CODE["nonfinite_state"] and mixed[0].tolist()[2] == CODE["penetration_too_deep"]
    assert mixed[1][3] != same[1][1]  # the fourth member's step sequence is another
    for x, y in zip(same, mixed):
        np.testing.assert_array_equal(x[1], y[1])


@pytest.mark.slow  # three compilations of the LuGre benchmark (about 2 minutes on 2 cores)
def test_batched_and_solo_runs_are_equally_accurate():
    """The issue's case: LuGre friction on the benchmark over a quarter revolution, where a
    batch and the solo run take different step sequences (511 and 481 steps in
    benchmarks/bench_batched.py, jax 0.10.2 on CPU). Both are solutions to the tolerance:
    against a reference at rtol 1e-10 / atol 1e-13 their largest normal-force errors (there 37.9
    and 48.5 N of a 28.6 kN peak) are below 0.5 % of the peak and within a factor 4 of each
    other (the errors differ as two nearby tolerances' would)."""
    mech = eqx.tree_at(lambda m: m.clearance_joints[0].friction, MECH, jc.Friction(0.1, model="lugre"))
    t_end = 0.25 * 60 / 5000

    def force(r, s):
        sol = jc.simulate(params.replace(mech, "restitution", r), s)
        return sol.normal_force[:, 0], sol.num_steps

    s = jc.settings(t_end, n_out=101, throw=False)
    ref_s = jc.settings(t_end, n_out=101, throw=False, rtol=1e-10, atol=1e-13, max_steps=2_000_000)
    ref = np.asarray(jax.jit(force)(0.9, ref_s)[0])
    solo, solo_steps = jax.jit(force)(0.9, s)
    batch, batch_steps = jax.jit(jax.vmap(lambda r: force(r, s)))(jnp.full(4, 0.9))
    solo, batch = np.asarray(solo), np.asarray(batch)
    assert all(np.array_equal(batch[0], b) for b in batch)
    e_solo, e_batch = np.abs(solo - ref).max(), np.abs(batch[0] - ref).max()
    print(f"steps solo {int(solo_steps)}, batched {int(batch_steps[0])}; errors {e_solo:.3g} N, {e_batch:.3g} N")
    assert max(e_solo, e_batch) < 5e-3 * ref.max()
    assert 0.25 < e_batch / e_solo < 4.0


# ---- 2. impossible states: non-finite, too deep ---------------------------------------


def test_nonfinite_state_stops_at_once_and_too_soft_contact_is_not_ok():
    """Infinite gravity makes the first step non-finite: status nonfinite_state after a
    handful of steps (not max_steps). A stiffness of 1e-30 (the audit's case) lets the journal
    sink: penetration_too_deep, never ok."""
    status, steps, pen, _, _ = _run([(0.9, 1e10, 0.0, math.inf), (0.9, 1e-30, 0.0, 9.81), GOOD, GOOD])
    assert status[0] == CODE["nonfinite_state"] and steps[0] <= 5
    assert status[1] == CODE["penetration_too_deep"]
    assert pen[1] > 0.1 * float(MECH.clearance_joints[0].journal_radius)
    assert status[2] == 0


def test_penetration_between_output_samples_is_caught():
    """A stiffness of 2e8 N/m^1.5 with 11 output samples over 20 ms (one per 2 ms): at the
    samples the journal is never more than 0.6 mm deep (under the limit 0.95 mm = a tenth of
    R_J), but the running peak over the accepted steps (impacts last ~0.1 ms) passes the limit,
    and the status says so; a stiff 1e10 law stays ok with its peak under the limit."""
    status, _, pen, _, _, peak = (np.asarray(x) for x in _batch(_rows([(0.9, 2e8, 0.0, 9.81), GOOD, GOOD, GOOD])))
    limit = 0.1 * float(MECH.clearance_joints[0].journal_radius)
    assert pen[0] < limit < peak[0]
    assert status[0] == CODE["penetration_too_deep"]
    assert status[1] == 0 and peak[1] < limit


# ---- 8. property test: within and beyond the ranges, through the API and under vmap ------

restitution = st.one_of(st.floats(0.05, 1.0), st.floats(-2.0, 0.0), st.floats(1.0001, 3.0), st.just(math.nan))
stiffness = st.one_of(st.floats(1e8, 1e11), st.floats(-1e10, 0.0), st.just(math.nan), st.just(math.inf))
friction = st.one_of(st.floats(0.0, 0.3), st.floats(-1.0, -1e-6))
mass = st.one_of(st.floats(0.05, 1.0), st.floats(-1.0, 0.0), st.just(math.nan))
bearing = st.one_of(st.floats(0.008, 0.02), st.floats(-0.01, 0.0), st.just(math.nan))
clearance = st.one_of(st.floats(1e-4, 1e-3), st.floats(-1e-3, 0.0), st.floats(0.03, 0.05))


def _valid(p):
    e, k, mu, _, m, rb, c = p
    return 0.0 < e <= 1.0 and 0.0 < k < math.inf and mu >= 0.0 and m > 0.0 and rb > 0.0 and 0.0 < c < rb


def _refused_by_the_api(p) -> bool:
    """Where objects are built with concrete values: params.validate and the constructors raise
    a ParameterError; a bearing radius set by eqx.tree_at (no constructor) is named by
    Mechanism.check()."""
    e, k, mu, _, m, rb, c = p
    m0 = eqx.tree_at(lambda m: m.clearance_joints[0].bearing_radius, MECH, jnp.asarray(rb))
    if m0.check() != RESULTS.successful:
        return True
    try:
        for name, value in {"restitution": e, "stiffness": k, "friction": mu, "mass:rod": m, "clearance": c}.items():
            params.validate(m0, name, value)
        jc.ContactLaw(restitution=e, stiffness=k)
        jc.Friction(mu)
    except jc.ParameterError:
        return True
    return False


@hsettings(max_examples=10, deadline=None, derandomize=True)
@given(st.lists(st.tuples(restitution, stiffness, friction, st.just(9.81), mass, bearing, clearance),
                min_size=4, max_size=4))
def test_property_valid_runs_ok_or_named_invalid_is_named(rows):
    """Restitution, stiffness, friction, a body's mass, the bearing radius and the clearance,
    drawn within and beyond their ranges, four members under jit(vmap): a valid member ends ok
    with finite outputs or with a named status that is not an invalid_* one; an invalid member
    gets an invalid_* status (not integrated) and the API refuses the same values eagerly."""
    status, steps, _, finite, _ = _run(rows)
    for p, code, n, fin in zip(rows, status.tolist(), steps.tolist(), finite.tolist()):
        assert code in STATUS  # always a named status
        if _valid(p):
            assert code not in invalid_codes()
            if code == 0:
                assert fin  # never a NaN with status ok
        else:
            assert code in invalid_codes() and n == 0
            assert _refused_by_the_api(p)


# ---- 3. sizes bounded up front ----------------------------------------------------------


def test_output_size_bounded_before_compiling():
    with pytest.raises(jc.ParameterError, match=r"n_out = 1000000000000 .*--n-out"):
        jc.Settings(t_end=1.0, n_out=10**12)
    with pytest.raises(jc.ParameterError, match="n_out"):
        jc.integrate.revolution_settings(MECH, 1e9)


def test_sweep_sizes_bounded_before_compiling():
    """Runs, samples per run and stored time-series samples are bounded when the configuration
    is built: the error names the option and the limit (and nothing is allocated: a 1e8-run grid
    is refused before its table is built)."""
    from jaxclear.sweep import config_from_dict
    from jaxclear.sweep.config import MAX_RUNS, MAX_TRAJECTORY_SAMPLES
    from jaxclear.integrate._settings import MAX_OUT_SAMPLES

    big = {"grid": {"restitution": {"start": 0.1, "stop": 0.9, "num": 10_000},
                    "stiffness": {"start": 1e9, "stop": 1e10, "num": 10_000}}}
    with pytest.raises(jc.ParameterError, match=rf"100000000 runs .*\[1, {MAX_RUNS}\]"):
        config_from_dict(big)
    long = {"grid": {"restitution": [0.5]}, "run": {"revolutions": 10_000, "samples_per_revolution": 1000}}
    with pytest.raises(jc.ParameterError, match=rf"run.revolutions x run.samples_per_revolution .*{MAX_OUT_SAMPLES}"):
        config_from_dict(long)
    stored = {"grid": {"restitution": {"start": 0.1, "stop": 0.9, "num": 100_000}}, "output": {"trajectories": True}}
    with pytest.raises(jc.ParameterError, match=rf"--trajectories.* 100000 x 601 .*{MAX_TRAJECTORY_SAMPLES}"):
        config_from_dict(stored)
    stored["output"]["trajectories"] = False  # the same sweep without time series is fine
    assert config_from_dict(stored).n_runs == 100_000


# ---- 4. locked output folders -----------------------------------------------------------


def test_output_folder_lock_names_folder_and_holder(tmp_path):
    with locked_folder(tmp_path, "sweep output folder"):
        with pytest.raises(jc.OutputLockedError, match=rf"{tmp_path}.*pid {os.getpid()}"):
            with locked_folder(tmp_path, "sweep output folder"):
                pass
    with locked_folder(tmp_path):  # released after the block
        pass


# ---- 5. fits refuse what they cannot fit; corrupt checkpoints ---------------------------


@pytest.mark.parametrize("data, match", [
    (np.array([1.0, np.nan, 2.0]), "non-finite"),
    (np.array([1.0, 1e300]), "beyond the allowed"),
    (np.zeros(5), "zero everywhere"),
])
def test_fit_refuses_unfittable_data(data, match):
    with pytest.raises(jc.ParameterError, match=match):
        _check_data(data, "record.csv")


def test_fit_refuses_zero_or_nonfinite_start_loss():
    """The loss at the start values: not finite -> FitDataError naming the record and the
    values; exactly zero at the first stage -> FitDataError naming the record (nothing to fit).
    A later stage may start from an exact fit."""
    from types import SimpleNamespace

    from jaxclear.fitting.run import check_start_loss

    stages = [SimpleNamespace(name="velocity 0.25"), SimpleNamespace(name="acceleration 1")]
    problem = SimpleNamespace(meas=SimpleNamespace(path="rig.csv"), stages=stages, free=("restitution",),
                              win=SimpleNamespace(scale=1.0), mech=None)
    for loss in (math.nan, math.inf):
        with pytest.raises(jc.FitDataError, match=r"rig.csv.*not finite.*restitution"):
            check_start_loss(problem, stages[1], loss, np.zeros(1))
    with pytest.raises(jc.FitDataError, match=r"rig.csv.*exactly 0.*velocity 0.25"):
        check_start_loss(problem, stages[0], 0.0, np.zeros(1))
    check_start_loss(problem, stages[1], 0.0, np.zeros(1))
    check_start_loss(problem, stages[0], 1e-3, np.zeros(1))
    assert issubclass(jc.FitDataError, jc.ParameterError)


@pytest.mark.slow  # compiles a sweep chunk (about a minute on a shared machine)
def test_progress_bars_start_after_compilation_and_say_resumed(tmp_path, capsys):
    """A sweep prints a 'compiling' line and starts its bar after the first chunk (so the
    rate leaves the compilation out); a resumed sweep says so in its line and its bar."""
    from jaxclear.sweep import SweepConfig, run_sweep

    def cfg():
        return SweepConfig(grid={"restitution": [0.5, 0.9]}, revolutions=0.01, samples_per_revolution=100,
                           ideal_reference=False, chunk_size=1, out=str(tmp_path), progress=True)

    run_sweep(cfg())
    printed = capsys.readouterr()
    assert "compiling" in printed.out
    # the bar appears when the first chunk (and the compilation, tens of seconds) is done: at
    # 1/2 its clock reads 0 and it has no rate yet
    assert "sweep:  50%" in printed.err and "1/2 [00:00<?" in printed.err and "0/2" not in printed.err
    rows = (tmp_path / "runs.csv").read_text().splitlines()
    (tmp_path / "runs.csv").write_text("\n".join(rows[:2]) + "\n")  # keep run 0 only
    run_sweep(cfg())
    printed = capsys.readouterr()
    assert "resuming" in printed.out and "1 of 2 runs already done" in printed.out
    assert "sweep (resumed)" in printed.err


def test_corrupt_checkpoint_is_a_named_error(tmp_path):
    path = tmp_path / "fit_checkpoint.json"
    path.write_text('{"key": "abc", "state": {"trunc')
    with pytest.raises(jc.CheckpointError, match=r"fit_checkpoint.json.*--restart"):
        Checkpoint(tmp_path, "abc", {}).load()
    path.write_text(json.dumps({"key": "other", "state": {}}))
    assert Checkpoint(tmp_path, "abc", {}).load() is None  # another fit's checkpoint: not this one (resume() refuses it)


# ---- 6./7. interruption, names -----------------------------------------------------------


def test_ctrl_c_prints_one_line_and_exits_130(monkeypatch, capsys, tmp_path):
    def interrupted(args):
        raise KeyboardInterrupt

    parser_run = jc.cli.build_parser
    monkeypatch.setattr(jc.cli, "build_parser", lambda: _with_run(parser_run(), interrupted))
    code = main(["sweep", "sweep.toml", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130
    assert len(err) == 1 and "interrupted" in err[0] and "resume" in err[0] and str(tmp_path) in err[0]


def test_ctrl_c_inside_a_gc_callback_is_not_lost():
    """The fit's defect: a Ctrl-C whose KeyboardInterrupt is raised inside a garbage-collection
    callback (JAX's ``_xla_gc_callback``) is printed and dropped by Python. Under
    :func:`stop_at_safe_points` the signal only sets a flag, read at the next safe point; the
    previous handler is back afterwards, and a second Ctrl-C raises at once."""
    import gc
    import signal

    from jaxclear._interrupt import stop_at_safe_points

    armed = []

    def callback(phase, info):
        if phase == "start" and armed:
            armed.clear()
            os.kill(os.getpid(), signal.SIGINT)
            sum(range(100))  # the Python handler runs at the next bytecode: inside this callback

    # Python's own handler, as in a fresh process (an earlier test in this worker may have left
    # another: stop_at_safe_points then leaves the signal alone, and the flag is never set)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    gc.callbacks.append(callback)
    try:
        with pytest.raises(KeyboardInterrupt):
            with stop_at_safe_points() as interrupt:
                armed.append(True)
                for _ in range(200):  # a collection under way in another thread (a notebook's client
                    gc.collect()      # threads, JAX's) makes gc.collect() return at once, or runs the
                    if interrupt.requested:  # callback there: the flag is then set at the main thread's
                        break                # next bytecode
                    time.sleep(0.01)
                assert interrupt.requested
                interrupt.check()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with pytest.raises(KeyboardInterrupt):
            with stop_at_safe_points() as interrupt:
                os.kill(os.getpid(), signal.SIGINT)
                sum(range(100))
                assert interrupt.requested  # the first: a flag
                os.kill(os.getpid(), signal.SIGINT)  # the second: at once
                sum(range(100))
                pytest.fail("a second Ctrl-C must raise at once")
    finally:
        gc.callbacks.remove(callback)
        signal.signal(signal.SIGINT, before)


def _with_run(parser, run):
    for action in parser._subparsers._group_actions:
        for sub in action.choices.values():
            sub.set_defaults(run=run)
    return parser


def test_unknown_preset_option_is_a_jaxclear_error():
    with pytest.raises(jc.ParameterError, match="bogus"):
        jc.preset("four-bar", bogus=1)


# ---- 4b. two processes, one folder ---------------------------------------------------------

LOCK_TOML = """
[grid]
restitution = [0.5, 0.9]
[run]
revolutions = 0.01
samples_per_revolution = 100
ideal_reference = false
[output]
dir = "{out}"
chunk_size = 1
"""


@pytest.mark.slow  # the first process compiles its sweep (about a minute)
def test_second_process_on_the_same_folder_is_refused(tmp_path):
    """Two OS processes run `jaxclear sweep` into one folder: while the first holds it (it is
    compiling), the second exits at once with code 2 and an error naming the folder and the
    first's pid; the first then finishes, and runs.csv holds every index exactly once."""
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    cfg = tmp_path / "sweep.toml"
    cfg.write_text(LOCK_TOML.format(out=out))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).parents[1]),
                                                       os.environ.get("PYTHONPATH", "")]))
    cmd = [sys.executable, "-m", "jaxclear", "sweep", str(cfg), "--no-plots", "--no-progress"]
    first = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        owner = out / ".jaxclear.lock.owner"
        deadline = time.time() + 120
        while time.time() < deadline and first.poll() is None and not owner.exists():
            time.sleep(0.01)
        assert first.poll() is None and f"pid {first.pid}" in owner.read_text()
        second = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
        assert first.poll() is None, "the first sweep ended before the second tried the folder"
        assert second.returncode == 2
        assert str(out) in second.stderr and f"pid {first.pid}" in second.stderr
        stdout, stderr = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
    assert first.returncode == 0, stderr[-2000:]
    rows = (out / "runs.csv").read_text().splitlines()[1:]
    assert sorted(int(r.split(",")[0]) for r in rows) == [0, 1]
