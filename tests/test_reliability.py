"""Reliability: every bad input gets a named answer, also under ``jit``/``vmap``; impossible
states get named statuses; output folders are locked; interruptions end cleanly.

The simulation tests share one compiled function (:func:`_batch`: four members of the Flores
slider-crank, 20 ms, 11 samples) so the whole module compiles the engine once.
"""

from __future__ import annotations

import json
import math
import os

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


def _member(p):
    """One member: p = (restitution, stiffness, friction, gravity magnitude)."""
    m = params.replace_many(MECH, {"restitution": p[0], "stiffness": p[1], "friction": p[2]})
    m = eqx.tree_at(lambda m: m.gravity, m, jnp.stack([0.0 * p[3], -p[3]]))
    sol = jc.simulate(m, SET)
    return sol.status, sol.num_steps, jnp.max(sol.penetration), jnp.all(jnp.isfinite(sol.q)) & jnp.all(
        jnp.isfinite(sol.qdot)), sol.q[-1]


_batch = jax.jit(jax.vmap(_member))
GOOD = (0.9, 1e10, 0.0, 9.81)


def _run(rows):
    status, steps, pen, finite, q_end = _batch(jnp.asarray(rows, dtype=float))
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


def test_constructors_refuse_out_of_range_values():
    with pytest.raises(jc.ParameterError, match=r"restitution = 1.5 .*\(0, 1\]"):
        jc.ContactLaw(restitution=1.5)
    with pytest.raises(jc.ParameterError, match="stiffness"):
        jc.ContactLaw(stiffness=-1.0)


def test_check_under_vmap():
    codes = jax.vmap(lambda r: params.replace(MECH, "restitution", r).check()._value)(
        jnp.array([0.9, 1.5, 0.5, jnp.nan]))
    assert codes.tolist() == [0, CODE["invalid_restitution"], 0, CODE["invalid_restitution"]]


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


# ---- 8. property test: within and beyond the ranges, through the API and under vmap ------

restitution = st.one_of(st.floats(0.05, 1.0), st.floats(-2.0, 0.0), st.floats(1.0001, 3.0), st.just(math.nan))
stiffness = st.one_of(st.floats(1e8, 1e11), st.floats(-1e10, 0.0), st.just(math.nan), st.just(math.inf))
friction = st.one_of(st.floats(0.0, 0.3), st.floats(-1.0, -1e-6))


def _valid(p):
    return 0.0 < p[0] <= 1.0 and 0.0 < p[1] < math.inf and p[2] >= 0.0


@hsettings(max_examples=8, deadline=None, derandomize=True)
@given(st.lists(st.tuples(restitution, stiffness, friction), min_size=4, max_size=4))
def test_property_valid_runs_ok_or_named_invalid_is_named(rows):
    rows = [(*r, 9.81) for r in rows]
    status, _, _, finite, _ = _run(rows)
    for p, code, fin in zip(rows, status.tolist(), finite.tolist()):
        assert code in STATUS  # always a named status
        if _valid(p):
            assert code not in invalid_codes()
            if code == 0:
                assert fin  # never a NaN with status ok
        else:
            assert code in invalid_codes()
        # the API refuses the same values where objects are built
        if not _valid(p):
            with pytest.raises(jc.ParameterError):
                params.replace_many(MECH, {"restitution": p[0], "stiffness": p[1], "friction": p[2]})
                jc.ContactLaw(restitution=p[0], stiffness=p[1])
                jc.Friction(p[2])


# ---- 3. sizes bounded up front ----------------------------------------------------------


def test_output_size_bounded_before_compiling():
    with pytest.raises(jc.ParameterError, match=r"n_out = 1000000000000 .*--n-out"):
        jc.Settings(t_end=1.0, n_out=10**12)
    with pytest.raises(jc.ParameterError, match="n_out"):
        jc.integrate.runs.revolution_settings(MECH, 1e9)


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


def test_corrupt_checkpoint_is_a_named_error(tmp_path):
    path = tmp_path / "fit_checkpoint.json"
    path.write_text('{"key": "abc", "state": {"trunc')
    with pytest.raises(jc.CheckpointError, match=r"fit_checkpoint.json.*--restart"):
        Checkpoint(tmp_path, "abc", {}).load()
    path.write_text(json.dumps({"key": "other", "state": {}}))
    assert Checkpoint(tmp_path, "abc", {}).load() is None  # another fit's checkpoint: replaced


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


def _with_run(parser, run):
    for action in parser._subparsers._group_actions:
        for sub in action.choices.values():
            sub.set_defaults(run=run)
    return parser


def test_unknown_preset_option_is_a_jaxclear_error():
    with pytest.raises(jc.ParameterError, match="bogus"):
        jc.preset("four-bar", bogus=1)
