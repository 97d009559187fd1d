"""Sweeps (jaxclear.sweep, `jaxclear sweep`): input checks before any compute, compile-once,
failure isolation, the per-run metrics, the CSV/NPZ files, kill-and-resume, sharding over
several devices, the plots and the notebook.

Runs are kept short (half or one crank revolution of the Flores benchmark at 5000 rpm, 40
output samples per revolution, Bogacki-Shampine 3(2) which compiles faster than Tsit5) so that
the fast tests stay within their budget; compilation dominates their time.

Equality tolerances: sweeps are deterministic on one machine. A run's numbers depend only on
its parameters and on the shape of the batch it is computed in (the same compiled program),
never on the other members' values or on which process or device computes it, so results that
come from the same batch layout are compared for exact (bitwise) equality, not with a
tolerance. The clearance dynamics are chaotic, so runs batched differently or unbatched are
not compared trace for trace.
"""

import jaxclear  # noqa: F401  (float64 first)

import csv
import json
import math
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear._xla_flags import loop_kernels_active
from jaxclear import sweep
from jaxclear.analysis import metrics
from jaxclear.integrate._state import element_states
from jaxclear.cli import main
from jaxclear import ParameterError

ROOT = Path(__file__).resolve().parents[1]
FAST_RUN = dict(samples_per_revolution=40, solver="bosh3", progress=False)


def _env(**extra):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("XLA_FLAGS", None)
    env.update(extra)
    return env


# --------------------------------------------------------------------------------------
# Bad input: clear errors before any compute
# --------------------------------------------------------------------------------------

GOOD = {"grid": {"clearance": [0.25e-3, 0.5e-3], "restitution": [0.5, 0.9]}, "run": {"revolutions": 1}}


def _doc(**changes):
    doc = json.loads(json.dumps(GOOD))
    for key, value in changes.items():
        table, _, name = key.partition("__")
        if name:
            doc.setdefault(table, {})[name] = value
        elif value is None:
            doc.pop(table, None)
        else:
            doc[table] = value
    return doc


@pytest.mark.parametrize("changes,match", [
    (dict(grid={}), r"the grid has no parameters"),
    (dict(grid__clearance=[]), r"parameter 'clearance': empty list of values"),
    (dict(grid__clearence=[1e-3]), r"unknown parameter 'clearence'; did you mean 'clearance'\?"),
    (dict(grid__clearance=[0.25e-3, -1e-3]), r"clearance = -0.001 m is outside the allowed range \(0, inf\) m"),
    (dict(grid__clearance=[0.02]), r"clearance = 0.02 m must be smaller than the bearing radius 0.01 m"),
    (dict(grid__restitution=[0.5, 1.5]), r"restitution = 1.5 is outside the allowed range \(0, 1\]"),
    (dict(grid__restitution=[0.5, "high"]), r"parameter 'restitution', value #2: expected a number, got 'high'"),
    (dict(grid__friction=[float("nan")]), r"parameter 'friction', value #1: values must be finite"),
    (dict(grid__speed_rpm=[0.0, 1000.0]), r"speed_rpm = 0: crank revolutions are undefined"),
    (dict(grid__speed=[100.0], grid__speed_rpm=[1000.0]), r"parameters 'speed' and 'speed_rpm' set the same"),
    (dict(grid__mass=[1.0]), r"parameter 'mass' needs a body: mass:BODY"),
    (dict(**{"grid__mass:piston": [1.0]}), r"unknown body|piston"),
    (dict(**{"grid__clearance@1": [1e-3]}), r"joint index 1 outside \[0, 0\]"),
    (dict(grid__restitution={"start": 0.5, "stop": 0.9}), r"a range needs start, stop and num \(missing \['num'\]\)"),
    (dict(grid__restitution={"start": 0.5, "stop": 0.9, "num": 3, "step": 1}), r"unknown key\(s\) \['step'\]"),
    (dict(grid=None, list={"clearance": [1e-4, 2e-4], "restitution": [0.5, 0.7, 0.9]}),
     r"different lengths \{'clearance': 2, 'restitution': 3\}"),
    (dict(list={"clearance": [1e-4]}), r"give exactly one of 'grid'"),
    (dict(grid=None), r"give exactly one of 'grid'"),
    (dict(gird={"clearance": [1e-4]}), r"unknown table\(s\) or key\(s\) \['gird'\]"),
    (dict(run__revolution=2), r"unknown key\(s\) \['revolution'\] in \[run\]; allowed: \['revolutions'"),
    (dict(output__folder="x"), r"unknown key\(s\) \['folder'\] in \[output\]"),
    (dict(mechanism={"preset": "flores-slider-crank", "clearence": 1e-3}),
     r"unknown key\(s\) \['clearence'\] for preset 'flores-slider-crank' in \[mechanism\]"),
    (dict(mechanism={"preset": "no-such"}), r"unknown preset 'no-such'"),
    (dict(mechanism={"preset": "flores-slider-crank", "restitution": 2.0}), r"\[mechanism\]: restitution"),
    (dict(run__revolutions=0), r"run.revolutions = 0 is outside the allowed range \(0, inf\)"),
    (dict(run__transient_revolutions=1), r"transient_revolutions = 1 is outside the allowed range \[0, revolutions"),
    (dict(run__samples_per_revolution=2.5), r"samples_per_revolution = 2.5: expected an integer >= 2"),
    (dict(run__revolutions=0.3, run__samples_per_revolution=5), r"revolutions x samples_per_revolution = 1.5 must"),
    (dict(run__solver="rk99"), r"unknown solver 'rk99'"),
    (dict(run__rtol=2.0), r"rtol = 2 is outside the allowed range \(0, 1\)"),
    (dict(run__max_steps=0), r"max_steps = 0 outside the allowed range \[1, inf\)"),
    (dict(output__chunk_size=0), r"chunk_size = 0: expected 'auto' or an integer >= 1"),
    (dict(output__devices=99), r"output.devices = 99: expected an integer in \[1, "),
    (dict(output__trajectories="yes"), r"trajectories = 'yes': expected true or false"),
    (dict(output__channels="joint:0:mode"), r"output.channels = 'joint:0:mode': expected a list of channel names"),
    (dict(output__channels=["joint:0:film_force"]), r"output.channels: .*joint:0:film_force"),
    (dict(output__channels=["joint:3:penetration"]), r"output.channels: .*joint:3"),
    (dict(output__channels=["joint:0:mode", "joint:0:mode"]), r"share the column name 'joint_0_mode'"),
])
def test_bad_config_is_a_clear_error_before_any_compute(changes, match, tmp_path):
    before = sweep.TRACES.value
    out = tmp_path / "never"
    doc = _doc(**changes)
    doc.setdefault("output", {})["dir"] = str(out)
    with pytest.raises(ParameterError, match=match):
        sweep.config_from_dict(doc, source="cfg.toml")
    assert sweep.TRACES.value == before and not out.exists()


def test_bad_toml_and_missing_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[grid]\nclearance = [1e-3,\n")
    with pytest.raises(ParameterError, match=r"bad.toml: not valid TOML"):
        sweep.load_config(bad)
    with pytest.raises(ParameterError, match=r"cannot read sweep configuration .*nope.toml"):
        sweep.load_config(tmp_path / "nope.toml")


def test_cli_bad_config_exit_code_and_message(tmp_path, capsys):
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[grid]\nclearance = [1e-3]\nrestitution = [0.5, 1.2]\n[output]\ndir = 'o'\n")
    assert main(["sweep", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "restitution = 1.2 is outside the allowed range (0, 1]" in err
    cfg.write_text("[grid]\nclearance = [1e-3]\n")
    assert main(["sweep", str(cfg), "--out", str(tmp_path / "o"), "--channel", "joint:0:film_force"]) == 2
    err = capsys.readouterr().err  # the dry joint has no film: the error names the channel and the allowed names
    assert err.startswith("error: ") and "output.channels" in err and "joint:0:film_force" in err
    assert "Traceback" not in err and not (tmp_path / "o").exists()


def test_cli_writes_the_dataset_once(tmp_path, monkeypatch, capsys):
    """`jaxclear sweep` writes ``results.nc`` once (``run_sweep(..., write_dataset=False)``, then
    the command's :meth:`SweepResult.write` with the figures), not once in the sweep and again at
    the end. The folder holds a finished sweep made without computing anything (manifest, both
    rows), so nothing is compiled and runs.csv is left as it was."""
    import importlib

    out = tmp_path / "out"
    cfg_path = tmp_path / "s.toml"
    cfg_path.write_text(f'[grid]\nclearance = [2e-4, 5e-4]\n[run]\nrevolutions = 1\n[output]\ndir = "{out}"\n')
    cfg = sweep.load_config(cfg_path)
    _, _, layout = sweep.driver._layout(cfg)
    sweep.store.prepare_output(cfg, str(out), False, layout)
    columns = sweep.csv_columns(cfg)
    with open(out / "runs.csv", "a") as f:
        for i, c in enumerate(cfg.values[:, 0]):
            f.write(",".join([str(i), repr(float(c))] + ["0"] * (len(columns) - 3) + ["ok"]) + "\n")
    rows = (out / "runs.csv").read_text()
    dataset = importlib.import_module("jaxclear.sweep.dataset")
    written = []

    def counted(ds, path):
        written.append(str(path))
        return dataset.atomic_write_netcdf(path, ds)

    monkeypatch.setattr(dataset, "write_netcdf", counted)
    before = sweep.TRACES.value
    assert main(["sweep", str(cfg_path), "--no-plots", "--no-progress"]) == 0
    assert written == [str(out / sweep.NETCDF_NAME)]
    assert sweep.TRACES.value == before and (out / "runs.csv").read_text() == rows
    assert "(0 computed now)" in capsys.readouterr().out
    np.testing.assert_array_equal(sweep.open_dataset(out)["clearance"].values, [2e-4, 5e-4])


def test_grid_and_list_layout():
    cfg = sweep.config_from_dict({"grid": {"clearance": [1e-4, 2e-4, 3e-4],
                                           "restitution": {"start": 0.5, "stop": 0.9, "num": 2}}})
    assert cfg.names == ("clearance", "restitution") and cfg.n_runs == 6
    # first name slowest (C order), as the docstring says
    np.testing.assert_array_equal(cfg.values[:, 0], [1e-4, 1e-4, 2e-4, 2e-4, 3e-4, 3e-4])
    np.testing.assert_array_equal(cfg.values[:, 1], [0.5, 0.9] * 3)
    lst = sweep.config_from_dict({"list": {"speed_rpm": [1000.0, 2000.0], "friction": [0.0, 0.1]}})
    np.testing.assert_array_equal(lst.values, [[1000.0, 0.0], [2000.0, 0.1]])
    logs = sweep.config_from_dict({"grid": {"stiffness": {"start": 1e9, "stop": 1e11, "num": 3, "spacing": "log"}}})
    np.testing.assert_allclose(logs.values[:, 0], [1e9, 1e10, 1e11], rtol=1e-12)
    # the same sweep has the same hash; another value changes it
    again = sweep.config_from_dict({"grid": {"clearance": [1e-4, 2e-4, 3e-4], "restitution": [0.5, 0.9]}})
    assert again.sweep_hash() == cfg.sweep_hash()
    other = sweep.config_from_dict({"grid": {"clearance": [1e-4, 2e-4, 3.0000001e-4], "restitution": [0.5, 0.9]}})
    assert other.sweep_hash() != cfg.sweep_hash()
    # the example config is valid
    ex = sweep.load_config(ROOT / "examples" / "sweep.toml")
    assert ex.n_runs == 12 and ex.section == (400, 600, 800, 1000, 1200)
    # it teaches: several chunks (progress, resume) and several Poincare points per run
    assert ex.n_runs // ex.chunk_size >= 4 and len(ex.section) > 1


def test_auto_chunk_size():
    # memory-bound: 1 MB budget / 4 / (4096 B x 1001 samples) < 1 -> 1 run per device
    assert sweep.auto_chunk_size(1001, 2, 100, memory_bytes=1 << 20) == 2
    assert sweep.auto_chunk_size(101, 1, 1000, memory_bytes=1 << 34) == sweep.DEFAULT_RUNS_PER_DEVICE
    assert sweep.auto_chunk_size(101, 4, 5, memory_bytes=1 << 34) == 8  # runs rounded up to the devices
    assert sweep.auto_chunk_size(101, 1, 3, memory_bytes=1 << 34) == 3


def test_trace_count_is_read_as_value_and_ideal_defaults_to_mechanism_ideal():
    assert isinstance(sweep.TRACES.value, int)
    with pytest.warns(DeprecationWarning, match=r"TRACES.value"):
        assert sweep.TRACE_COUNT == sweep.TRACES.value  # the old spelling still reads the number
    mech = jc.preset("flores-slider-crank")
    cfg = sweep.SweepConfig(mechanism=mech, grid={"clearance": [0.25e-3]}, revolutions=1)
    assert cfg.ideal is not None and cfg.ideal.name == mech.name + "-ideal" and not cfg.ideal.clearance_joints
    assert cfg.ideal_names == ()  # clearance does not apply to the ideal-joint mechanism
    assert sweep.SweepConfig(mechanism=mech, grid={"clearance": [0.25e-3]}, ideal_reference=False).ideal is None


def test_compiled_chunk_has_no_lapack_call():
    """The compiled chunk (clearance runs, ideal-joint runs, metrics; 2 runs on one device)
    contains no LAPACK custom call. jaxlib 0.10's batched CPU LAPACK kernels split a large batch
    over the intra-op thread pool and block the calling thread, so two concurrent ones (two
    host devices, or the clearance and ideal phases) could deadlock; the sweep no longer orders
    its phases or caps its runs per device against that, so this must stay true."""
    cfg = sweep.SweepConfig(grid={"clearance": [0.25e-3, 0.5e-3]}, revolutions=0.5, ideal_reference=True,
                            **FAST_RUN)
    assert cfg.ideal is not None
    plan = sweep.make_plan(cfg, sweep.make_mesh(1))
    text = sweep.compiled_hlo(sweep.put_chunk(cfg.values, plan.mesh), cfg.base_mechanism, cfg.ideal, plan)

    def lapack_targets(hlo: str) -> list[str]:
        return sorted(t for t in set(re.findall(r'custom_call_target="([^"]+)"', hlo)) if "lapack" in t.lower())

    # control: the check sees a LAPACK call where there is one (a batched LU solve on CPU)
    control = jax.jit(jax.vmap(jnp.linalg.solve)).lower(jnp.ones((4, 3, 3)), jnp.ones((4, 3))).compile().as_text()
    if jax.default_backend() == "cpu":
        assert lapack_targets(control), "the check cannot see LAPACK calls: the HLO format changed"
    assert lapack_targets(text) == []


@pytest.mark.extended
def test_runs_one_after_another_or_side_by_side():
    """On CPU with single-kernel loops a device integrates its runs one after another
    (``jax.lax.map``), elsewhere or with ``Plan(side_by_side=True)`` side by side (``jax.vmap``).
    Both give each run's own result: the same status and step count as the unbatched per-run
    function, and metrics within 1e-5 relative. The three are differently compiled programs
    whose rounding the impacts amplify (the dynamics are chaotic): over a quarter revolution
    (6 and 15 impacts) the measured differences are at most 5e-7; over half a revolution the
    step counts already part (1978, 1980, 1983)."""
    import dataclasses

    cfg = sweep.SweepConfig(grid={"clearance": [0.25e-3, 1.0e-3]}, revolutions=0.25, ideal_reference=False,
                            transient_revolutions=0.0, **FAST_RUN)
    plan = sweep.make_plan(cfg, sweep.make_mesh(1))
    assert sweep.batch.one_by_one(plan) == (jax.default_backend() == "cpu" and loop_kernels_active())
    side = dataclasses.replace(plan, side_by_side=True)
    assert not sweep.batch.one_by_one(side)
    assert sweep.batch.one_by_one(dataclasses.replace(plan, side_by_side=False))
    values = sweep.put_chunk(cfg.values, plan.mesh)
    outs = [sweep.fetch_chunk(sweep.run_chunk(values, cfg.base_mechanism, None, p)) for p in (plan, side)]
    single = [jax.jit(lambda r: sweep.run_outputs(plan, cfg.base_mechanism, None, r))(row) for row in cfg.values]
    for k, row in enumerate(cfg.values):
        ref = {key: np.asarray(v) for key, v in single[k].items()}
        assert int(ref["status"]) == 0
        for out in outs:
            assert int(out["status"][k]) == 0
            assert int(out["num_steps"][k]) == int(ref["num_steps"])
            for key in ("peak_contact_force_n", "rms_contact_force_n", "peak_slider_acc_m_s2", "impacts"):
                np.testing.assert_allclose(out[key][k], ref[key], rtol=1e-5, err_msg=key)


# --------------------------------------------------------------------------------------
# Metrics on a hand-made solution (exact)
# --------------------------------------------------------------------------------------


def _fake_solution(mech, t_end):
    """A Solution with known samples (T = 6) for one clearance joint."""
    T = 6
    ts = jnp.linspace(0.0, t_end, T)
    z = jnp.zeros((T, 9))
    acc = jnp.array([0.0, 1.0, -3.0, 2.0, 5.0, -1.0])
    qddot = z.at[:, 6].set(acc)  # slider x'' (body 2: coordinates 6, 7, 8)
    fn = jnp.array([[0.0], [100.0], [0.0], [7.0], [40.0], [0.0]])
    pen = jnp.array([[-1e-4], [2e-6], [-1e-5], [1e-7], [3e-6], [-2e-5]])
    mode = jnp.array([[0], [1], [0], [2], [2], [0]], dtype=jnp.int32)
    mem = jc.ContactMemory(
        impact_velocity=jnp.zeros((T, 1)), contact_start=jnp.zeros((T, 1)),
        impacts=jnp.array([[0.0], [1.0], [1.0], [2.0], [2.0], [3.0]]),
        work=jnp.array([[0.0], [-0.5], [-0.5], [-0.7], [-1.1], [-1.1]]),
        peak_force=jnp.array([[0.0], [150.0], [150.0], [150.0], [150.0], [150.0]]),
        peak_penetration=jnp.array([[-1.0], [2.5e-6], [2.5e-6], [2.5e-6], [4e-6], [4e-6]]),
    )
    return jc.Solution(ts=ts, q=z, qdot=z, qddot=qddot, reactions=jnp.zeros((T, 7)),
                       drift=jnp.array([0.0, 1e-9, 3e-9, 2e-9, 0.0, 0.0]), ecc=jnp.zeros((T, 1, 2)),
                       penetration=pen, normal_force=fn, friction_force=jnp.zeros((T, 1)), mode=mode, element_states=element_states(mech, mem),
                       num_steps=jnp.asarray(10), num_accepted_steps=jnp.asarray(8),
                       num_rejected_steps=jnp.asarray(2), status=jnp.asarray(0))


def test_run_metrics_exact_on_known_samples():
    """Every metric by hand on a 6-sample solution; window = samples 2..5. Exact up to float
    rounding (rtol 1e-12)."""
    mech = jc.preset("flores-slider-crank")  # 5000 rpm
    period = 60.0 / 5000.0
    sol = _fake_solution(mech, t_end=period)  # one revolution, samples every period/5
    ideal_acc = jnp.array([0.0, 1.0, -1.0, 1.0, 1.0, 1.0])
    m = {k: float(v) for k, v in metrics.run_metrics(mech, sol, ideal_acc, start=2).items()}
    # running peak force did not grow after sample 2 -> only the window's samples count
    assert m["peak_contact_force_n"] == 40.0
    # running peak penetration grew inside the window (2.5e-6 -> 4e-6) -> the step value
    assert m["max_penetration_m"] == 4e-6
    assert math.isclose(m["rms_contact_force_n"], math.sqrt((0 + 49 + 1600 + 0) / 4), rel_tol=1e-12)
    assert m["impacts"] == 2.0  # 3 at the end - 1 at sample 2
    assert (m["fraction_free_flight"], m["fraction_impact"], m["fraction_continuous_contact"]) == (0.5, 0.0, 0.5)
    assert math.isclose(m["energy_dissipated_j"], 0.6, rel_tol=1e-12)
    assert math.isclose(m["energy_dissipated_per_rev_j"], 0.6 / 0.6, rel_tol=1e-12)  # window = 3/5 revolution
    assert m["peak_slider_acc_m_s2"] == 5.0
    dev = np.array([-2.0, 1.0, 4.0, -2.0])
    assert m["peak_acc_deviation_m_s2"] == 4.0
    assert math.isclose(m["rms_acc_deviation_m_s2"], math.sqrt(np.mean(dev**2)), rel_tol=1e-12)
    assert m["max_constraint_drift"] == 3e-9
    assert (m["num_steps"], m["num_accepted_steps"], m["num_rejected_steps"], m["status"]) == (10, 8, 2, 0)
    # whole run: the running peaks (over solver steps) exceed the samples
    w = {k: float(v) for k, v in metrics.run_metrics(mech, sol, None, start=0).items()}
    assert w["peak_contact_force_n"] == 150.0 and w["max_penetration_m"] == 4e-6 and w["impacts"] == 3.0
    assert "peak_acc_deviation_m_s2" not in w
    assert list(w) == [k for k in metrics.RUN_METRIC_KEYS if k in w]


def test_channel_statistics_exact_on_known_samples():
    """min, max, mean and RMS of named channels over the window (samples 2..5), by hand on the
    6-sample solution; exact up to float rounding (rtol 1e-12)."""
    mech = jc.preset("flores-slider-crank")
    sol = _fake_solution(mech, t_end=0.012)
    m = metrics.channel_metrics(mech, sol, ["joint:0:normal_force", "joint:0:mode", "body:slider:x:acc"], start=2)
    assert [float(m[("joint:0:normal_force", s)]) for s in ("min", "max")] == [0.0, 40.0]
    assert math.isclose(m[("joint:0:normal_force", "mean")], 47.0 / 4, rel_tol=1e-12)
    assert math.isclose(m[("joint:0:normal_force", "rms")], math.sqrt((49 + 1600) / 4), rel_tol=1e-12)
    assert math.isclose(m[("joint:0:mode", "mean")], 1.0, rel_tol=1e-12)  # modes 0, 2, 2, 0
    assert math.isclose(m[("body:slider:x:acc", "rms")], math.sqrt((9 + 4 + 25 + 1) / 4), rel_tol=1e-12)
    assert list(dict.fromkeys(s for _, s in m)) == list(metrics.CHANNEL_STATS)


@pytest.mark.extended
def test_sweep_carries_element_channels(tmp_path):
    """A lubricated slider-crank swept over clearance with the film's own outputs as channels:
    the chunks their time series, equal to the element's outputs of the same run simulated alone
    with the sweep's settings (:meth:`Solution.element_outputs`) within 1e-8 of their largest
    value; ``runs.csv`` their min/max/mean/RMS (rtol 1e-12: the same samples); the dataset their
    units and names. rtol 1e-10: at 1e-6 the two differently compiled programs take other steps
    and the film force, stiff near eps = 0.93, differs by 1.8 % (its discretization error); at
    1e-10 they agree to 2e-10. The heat-map label reads the channel's unit."""
    names = ["joint:0:min_film_thickness", "joint:0:film_force", "joint:0:eccentricity_ratio"]
    cfg = sweep.SweepConfig(list={"clearance": [0.25e-3, 0.5e-3]}, preset_options={"viscosity": 0.4},
                            revolutions=0.25, ideal_reference=False, trajectories=True, channels=names,
                            rtol=1e-10, atol=1e-13, out=str(tmp_path / "o"), **FAST_RUN)
    res = sweep.run_sweep(cfg)
    traj = res.trajectories()
    ds = res.to_xarray()
    for r, c in enumerate([0.25e-3, 0.5e-3]):
        mech = jc.preset("flores-slider-crank", viscosity=0.4, clearance=c)
        plan = sweep.make_plan(cfg, None)
        sol = jc.simulate(mech, sweep.batch._settings(plan, mech))  # the sweep's integration settings
        own = sol.element_outputs(mech, 0)
        for name in names:
            x = np.asarray(own[name.split(":")[2]])
            key = sweep.labels.channel_key(name)
            y = traj["traj_" + key][r]
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-8 * np.max(np.abs(x)), err_msg=name)
            for stat, want in (("min", y.min()), ("max", y.max()), ("mean", y.mean()), ("rms", np.sqrt(np.mean(y**2)))):
                np.testing.assert_allclose(res.table[f"{stat}__{key}"][r], want, rtol=1e-12, err_msg=f"{stat} {name}")
    assert 0 < res.table["min__joint_0_min_film_thickness"][0] < 0.25e-3  # a film, thinner than the clearance
    assert ds["min__joint_0_min_film_thickness"].attrs == {"units": "m", "long_name": "min of joint:0:min_film_thickness"}
    assert ds["rms__joint_0_film_force"].attrs["units"] == "N"
    assert ds["max__joint_0_eccentricity_ratio"].attrs["units"] == "1"
    assert res.to_dataframe().attrs["units"]["mean__joint_0_film_force"] == "N"
    from jaxclear.sweep.figures import metric_label
    assert metric_label("max__joint_0_film_force", res.manifest["channel_columns"]) == "max of joint:0:film_force [N]"


def test_run_metrics_agrees_with_summary():
    """On a real (unbatched) run the traceable metrics over the whole run equal the NumPy
    summary's (same definitions: samples and running step peaks); rtol 1e-12 (rounding)."""
    mech = jc.preset("flores-slider-crank")
    sol = jc.simulate(mech, jc.settings(0.25 * jc.crank_period(mech), n_out=51, solver="bosh3"))
    s = metrics.summary(mech, sol)
    m = {k: float(v) for k, v in metrics.run_metrics(mech, sol).items()}
    for key in ("peak_contact_force_n", "max_penetration_m", "impacts", "fraction_free_flight", "fraction_impact",
                "fraction_continuous_contact", "energy_dissipated_j", "peak_slider_acc_m_s2", "max_constraint_drift",
                "num_steps", "status"):
        assert math.isclose(m[key], float(s[key]), rel_tol=1e-12, abs_tol=0.0), key
    assert s["impacts"] >= 1  # the quarter revolution contains contact


# --------------------------------------------------------------------------------------
# One in-process sweep: compile once, padding, failure isolation, files
# --------------------------------------------------------------------------------------

# run 3 has a 1 mg slider: its contact is so stiff that it exhausts max_steps (status 1); run 4
# repeats run 2, which shares its chunk with run 3 (chunks of 2: [0 1] [2 3] [4 pad])
E2E = {
    "clearance": [0.25e-3, 0.5e-3, 1.0e-3, 0.5e-3, 1.0e-3],
    "restitution": [0.9, 0.7, 0.5, 0.9, 0.5],
    "speed_rpm": [5000.0, 4000.0, 5000.0, 5000.0, 5000.0],
    "mass:slider": [0.14, 0.14, 0.14, 1e-6, 0.14],
}


def _e2e(out):
    cfg = sweep.SweepConfig(list=E2E, revolutions=1.0, transient_revolutions=0.5, chunk_size=2, out=str(out),
                            trajectories=True, max_steps=10_000, **FAST_RUN)
    before = sweep.TRACES.value
    res = sweep.run_sweep(cfg)
    traces = sweep.TRACES.value - before
    again = sweep.run_sweep(cfg)  # everything is on disk: nothing to do, nothing compiled
    return cfg, res, traces, again, sweep.TRACES.value - before


def _check_compiled_once_for_the_whole_sweep(e2e):
    cfg, res, traces, again, traces_after = e2e
    assert traces == 1  # 3 chunks (the last padded), one trace
    assert traces_after == 1 and again.computed == 0
    assert res.computed == 5


def _check_rows_and_columns(e2e, tmp_path):
    cfg, res, *_ = e2e
    t = res.table
    np.testing.assert_array_equal(t["run"], np.arange(5))  # padded row dropped
    assert list(t) == sweep.csv_columns(cfg)
    for name in E2E:
        np.testing.assert_array_equal(t[name], E2E[name])
    # t_end follows the swept speed (one revolution)
    np.testing.assert_allclose(t["t_end_s"], 60.0 / np.array(E2E["speed_rpm"]), rtol=1e-14)
    with open(Path(cfg.out) / "runs.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert len(rows) == 6 and all(len(r) == len(rows[0]) for r in rows)


def _check_failed_run_is_flagged_and_does_not_poison_the_others(e2e):
    _, res, *_ = e2e
    t = res.table
    np.testing.assert_array_equal(t["status"], [0, 0, 0, 1, 0])
    assert t["status_message"][3] == jc.STATUS[1] and t["status_message"][0] == "ok"
    assert t["num_steps"][3] == 10_000 and math.isnan(t["peak_contact_force_n"][3])
    assert np.all(np.isfinite(t["peak_contact_force_n"][[0, 1, 2, 4]]))
    # run 2 (chunk partner: the failing run 3) and run 4 (partner: a copy of itself) are the
    # same simulation in the same lane of the same program: bitwise equal
    for col, values in t.items():
        if col not in ("run",):
            assert values[2] == values[4] or (values[2] != values[2] and values[4] != values[4]), col


def _check_metric_values_are_physical(e2e):
    _, res, *_ = e2e
    t = {k: v[[0, 1, 2, 4]] for k, v in res.table.items()}
    assert np.all(t["peak_contact_force_n"] > 1e3) and np.all(t["rms_contact_force_n"] > 0)
    assert np.all(t["rms_contact_force_n"] < t["peak_contact_force_n"])
    assert np.all((t["max_penetration_m"] > 0) & (t["max_penetration_m"] < 1e-3))
    np.testing.assert_allclose(t["fraction_free_flight"] + t["fraction_impact"] + t["fraction_continuous_contact"], 1.0,
                               rtol=1e-12)
    assert np.all(t["energy_dissipated_j"] > 0)  # c_r < 1 or friction: contacts dissipate
    # window = the second half revolution
    np.testing.assert_allclose(t["energy_dissipated_per_rev_j"], t["energy_dissipated_j"] / 0.5, rtol=1e-12)
    assert np.all(t["rms_acc_deviation_m_s2"] <= t["peak_acc_deviation_m_s2"])
    assert np.all(t["max_constraint_drift"] < 1e-5)
    np.testing.assert_array_equal(t["ideal_status"], 0)
    assert np.all(t["num_steps"] == t["num_accepted_steps"] + t["num_rejected_steps"])


def _check_poincare_and_trajectories(e2e):
    cfg, res, *_ = e2e
    assert cfg.section == (40,)  # one whole revolution after the half-revolution transient
    assert res.poincare.shape == (5, 1, 1, 4)
    traj = res.trajectories()
    np.testing.assert_array_equal(traj["run"], np.arange(5))
    assert traj["traj_ecc"].shape == (5, 41, 1, 2) and traj["traj_slider_acc"].shape == (5, 41)
    # the section point is the journal state at sample 40 (the end of the revolution)
    np.testing.assert_array_equal(res.poincare[:, 0, 0, :2], traj["traj_ecc"][:, 40, 0, :])
    ok = res.table["status"] == 0
    dev = traj["traj_slider_acc"][ok, 20:] - traj["traj_ideal_slider_acc"][ok, 20:]
    # recomputed in NumPy from the stored series: equal to rounding (XLA fuses the subtraction)
    np.testing.assert_allclose(np.max(np.abs(dev), axis=1), res.table["peak_acc_deviation_m_s2"][ok], rtol=1e-12)


def _check_resume_guards(e2e, tmp_path):
    cfg, *_ = e2e
    # another sweep into the same folder is refused before any compute
    other = sweep.SweepConfig(list={**E2E, "restitution": [0.9, 0.7, 0.5, 0.9, 0.6]}, revolutions=1.0,
                              transient_revolutions=0.5, chunk_size=2, out=cfg.out, trajectories=True,
                              max_steps=10_000, **FAST_RUN)
    with pytest.raises(ParameterError, match=r"holds a different sweep"):
        sweep.run_sweep(other)
    # a partial last line (a kill during a write) is cut off, complete rows are kept
    path = tmp_path / "runs.csv"
    path.write_text("run,a\n0,1.0\n1,2.0\n2,3")
    assert sweep.repair_csv(str(path), ["run", "a"]) == {0, 1}
    assert path.read_text() == "run,a\n0,1.0\n1,2.0\n"
    path.write_text("run,a\n0,1.0\n0,1.0\n")
    with pytest.raises(jc.CheckpointError, match=r"line 3: run 0 appears twice.*--restart"):
        sweep.repair_csv(str(path), ["run", "a"])
    path.write_text("run,b\n")
    with pytest.raises(ParameterError, match=r"is not this sweep's"):
        sweep.repair_csv(str(path), ["run", "a"])


def _check_labelled_results(e2e):
    """``results.nc`` is written beside ``runs.csv`` and holds the table (a list sweep: one
    ``run`` dimension, the parameters as coordinates); the DataFrame has the table's rows."""
    cfg, res, *_ = e2e
    ds = sweep.open_dataset(Path(cfg.out) / sweep.NETCDF_NAME)
    assert ds["peak_contact_force_n"].dims == ("run",)
    for name in E2E:
        np.testing.assert_array_equal(ds[name].values, E2E[name])
    for col in ("peak_contact_force_n", "energy_dissipated_j", "t_end_s", "status", "num_steps"):
        np.testing.assert_array_equal(ds[col].values, res.table[col])
    np.testing.assert_array_equal(ds["poincare"].values, res.poincare)
    assert ds["peak_contact_force_n"].attrs["units"] == "N" and ds["clearance"].attrs["units"] == "m"
    df = res.to_dataframe()
    assert list(df.index) == list(range(5)) and df.loc[3, "status"] == 1


@pytest.mark.extended
def test_in_process_sweep(tmp_path):
    """One sweep of 5 runs in chunks of 2 (the last padded) with a failing run, then every check
    on it (one test, so that parallel test workers do not each compile it)."""
    e2e = _e2e(tmp_path / "e2e")
    _check_compiled_once_for_the_whole_sweep(e2e)
    _check_rows_and_columns(e2e, tmp_path)
    _check_failed_run_is_flagged_and_does_not_poison_the_others(e2e)
    _check_metric_values_are_physical(e2e)
    _check_poincare_and_trajectories(e2e)
    _check_labelled_results(e2e)
    _check_resume_guards(e2e, tmp_path)


# --------------------------------------------------------------------------------------
# Kill with SIGKILL and resume (separate processes, the command line)
# --------------------------------------------------------------------------------------

KILL_TOML = """\
[mechanism]
preset = "flores-slider-crank"
[grid]
clearance = [0.25e-3, 0.5e-3, 0.75e-3, 1.0e-3]
restitution = [0.5, 0.7, 0.9]
[run]
revolutions = 0.5
samples_per_revolution = 40
solver = "bosh3"
ideal_reference = false
[output]
dir = "{out}"
chunk_size = 2
progress = false
"""


def _data_rows(path: Path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return {int(r[0]): r for r in rows[1:]}


RESUME_SCRIPT = textwrap.dedent("""
    import sys
    from jaxclear.cli import main
    # the resumed command line, then an uninterrupted reference in the same process (compiled once)
    sys.exit(main(["sweep", sys.argv[1], "--no-plots"]) or main(["sweep", sys.argv[2], "--no-plots"]))
""")


@pytest.mark.extended
def test_kill_and_resume(tmp_path):
    """`python -m jaxclear sweep` killed with SIGKILL after its first chunk reached the CSV (plus
    a partial line appended, as a kill in the middle of a write leaves), then the same command
    again: every index exactly once, and every row identical (exact) to an uninterrupted
    reference sweep run afterwards in that second process."""
    # the second process reuses the compile; two host devices named (the command line would
    # otherwise take one per core, and on many cores one chunk would hold every run)
    env = _env(JAX_COMPILATION_CACHE_DIR=str(tmp_path / "xla-cache"),
               XLA_FLAGS="--xla_force_host_platform_device_count=2")
    ref_cfg, cfg = tmp_path / "ref.toml", tmp_path / "cfg.toml"
    ref_cfg.write_text(KILL_TOML.format(out=tmp_path / "ref"))
    cfg.write_text(KILL_TOML.format(out=tmp_path / "out"))
    csv_path = tmp_path / "out" / "runs.csv"
    proc = subprocess.Popen([sys.executable, "-m", "jaxclear", "sweep", str(cfg), "--no-plots"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 300
        while time.time() < deadline and proc.poll() is None:
            if csv_path.exists() and len(csv_path.read_text().splitlines()) >= 3:  # header + one chunk
                break
            time.sleep(0.005)
        assert proc.poll() is None, "the sweep ended (or failed) before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    partial = _data_rows(csv_path)
    assert 2 <= len(partial) < 12
    with open(csv_path, "a") as f:
        f.write("11,0.001,0.9,0.006,123")  # a row cut short by the kill
    script = tmp_path / "resume.py"
    script.write_text(RESUME_SCRIPT)
    resumed = subprocess.run([sys.executable, str(script), str(cfg), str(ref_cfg)], env=env, capture_output=True,
                             text=True, timeout=400)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert f"({12 - len(partial)} computed now)" in resumed.stdout
    assert "on 2 CPU devices" in resumed.stdout
    with open(csv_path, newline="") as f:
        indices = [int(r[0]) for r in list(csv.reader(f))[1:]]
    assert sorted(indices) == list(range(12))  # each exactly once
    reference = _data_rows(tmp_path / "ref" / "runs.csv")
    assert sorted(reference) == list(range(12))
    assert _data_rows(csv_path) == reference
    a, b = sweep.read_results(tmp_path / "ref"), sweep.read_results(tmp_path / "out")
    np.testing.assert_array_equal(a.poincare, b.poincare)


# --------------------------------------------------------------------------------------
# Several devices
# --------------------------------------------------------------------------------------

MULTI_DEVICE_SCRIPT = textwrap.dedent("""
    import json, sys
    import jax
    import numpy as np
    import jaxclear
    from jaxclear import sweep
    assert jax.device_count() == 2, jax.devices()
    out = sys.argv[1]
    kw = dict(grid={"clearance": [0.25e-3, 0.5e-3, 1e-3], "restitution": [0.5, 0.9]}, revolutions=0.5,
              samples_per_revolution=40, solver="bosh3", ideal_reference=False, progress=False)
    # sharded: chunks of 4 split over the 2 devices (2 runs each); single device: chunks of 2
    two = sweep.run_sweep(sweep.SweepConfig(devices=2, chunk_size=4, out=out + "/two", **kw))
    one = sweep.run_sweep(sweep.SweepConfig(devices=1, chunk_size=2, out=out + "/one", **kw))
    cfg = sweep.SweepConfig(devices=2, chunk_size=4, out=out + "/x", **kw)
    plan_mesh = sweep.make_mesh(2)
    arr = sweep.put_chunk(cfg.values[:4], plan_mesh)
    manifest = json.load(open(out + "/two/manifest.json"))
    same = all(np.array_equal(two.table[k], one.table[k]) for k in two.table)
    print(json.dumps({"same": bool(same), "input_devices": len(arr.sharding.device_set),
                      "shard_shape": list(arr.addressable_shards[0].data.shape),
                      "layout": manifest["layout"], "traces": sweep.TRACES.value,
                      "poincare_same": bool(np.array_equal(two.poincare, one.poincare))}))
""")


@pytest.mark.extended
def test_sharded_over_two_cpu_devices(tmp_path):
    """Two host CPU devices forced with XLA_FLAGS (before jax is imported, hence a subprocess):
    the batch is sharded over a Mesh of both with NamedSharding, and the results equal the
    single-device sweep whose chunks are the per-device batches (same batch layout: exact).
    Exact because sweeps integrate with diffrax's stage loop (Settings(stages="loop")); with
    unrolled stages the partitioned program is fused differently and rounds differently in the
    last bits, which the chaotic runs amplify."""
    script = tmp_path / "multi.py"
    script.write_text(MULTI_DEVICE_SCRIPT)
    env = _env(XLA_FLAGS="--xla_force_host_platform_device_count=2")
    done = subprocess.run([sys.executable, str(script), str(tmp_path)], env=env, capture_output=True, text=True,
                          timeout=400)
    assert done.returncode == 0, done.stderr[-3000:]
    info = json.loads(done.stdout.strip().splitlines()[-1])
    assert info["input_devices"] == 2 and info["shard_shape"] == [2, 2]
    assert info["layout"]["devices"] == 2 and info["layout"]["chunk_size"] == 4
    assert info["traces"] == 2  # one compile per mesh (two devices, then one)
    assert info["same"] and info["poincare_same"]


DISTRIBUTED_SCRIPT = textwrap.dedent("""
    import sys
    import jax
    port, pid, n, out, chunk = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], int(sys.argv[5])
    if n > 1:
        jax.distributed.initialize(coordinator_address=f"localhost:{port}", num_processes=n, process_id=pid)
    import jaxclear as jc
    cfg = jc.SweepConfig(grid={"clearance": [0.25e-3, 0.5e-3, 1e-3], "restitution": [0.5, 0.9]}, revolutions=0.5,
                         samples_per_revolution=40, solver="bosh3", ideal_reference=False, progress=False,
                         chunk_size=chunk, out=out)
    jc.run_sweep(cfg)
    print("devices", jax.device_count(), "processes", jax.process_count())
""")


@pytest.mark.slow
def test_two_processes_with_jax_distributed(tmp_path):
    """The multi-host recipe of docs/theory/sweep.md on one machine: two processes joined by
    jax.distributed (one CPU device each, gloo collectives), chunks of 4 split over both; the
    CSV equals a one-process sweep whose chunks are the per-device batches (exact)."""
    import socket

    script = tmp_path / "dist.py"
    script.write_text(DISTRIBUTED_SCRIPT)
    with socket.socket() as sock:
        sock.bind(("localhost", 0))
        port = str(sock.getsockname()[1])
    env = _env()
    procs = [subprocess.Popen([sys.executable, str(script), port, str(i), "2", str(tmp_path / "two"), "4"], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(2)]
    outs = [p.communicate(timeout=500) for p in procs]
    for p, (o, e) in zip(procs, outs):
        assert p.returncode == 0, e[-3000:]
    assert "devices 2 processes 2" in outs[0][0]
    one = subprocess.run([sys.executable, str(script), port, "0", "1", str(tmp_path / "one"), "2"], env=env,
                         capture_output=True, text=True, timeout=500)
    assert one.returncode == 0, one.stderr[-3000:]
    assert _data_rows(tmp_path / "two" / "runs.csv") == _data_rows(tmp_path / "one" / "runs.csv")
    manifest = json.loads((tmp_path / "two" / "manifest.json").read_text())
    assert manifest["layout"]["processes"] == 2 and manifest["layout"]["devices"] == 2


# --------------------------------------------------------------------------------------
# Plots (synthetic data, no simulation)
# --------------------------------------------------------------------------------------


def _synthetic_result(tmp_path):
    xs, ys = np.array([0.1e-3, 0.25e-3, 0.5e-3]), np.array([0.5, 0.7, 0.9])
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    n = X.size
    table = {"run": np.arange(n), "clearance": X.ravel(), "restitution": Y.ravel(),
             "peak_contact_force_n": 1e4 * (1 + X.ravel() * 1e3) * Y.ravel(), "status": np.zeros(n, int)}
    table["peak_contact_force_n"][4] = np.nan  # a failed run
    rng = np.random.default_rng(0)
    poincare = rng.normal(scale=1e-4, size=(n, 5, 1, 4))
    return sweep.SweepResult(str(tmp_path), table, ("clearance", "restitution"), poincare,
                             {"clearance": xs, "restitution": ys}, "grid")


def test_plots_write_png(tmp_path):
    res = _synthetic_result(tmp_path)
    z = res.grid("peak_contact_force_n", "clearance", "restitution")
    assert z.shape == (3, 3) and np.isnan(z[1, 1])
    assert z[2, 0] == res.table["peak_contact_force_n"][2]  # clearance index 0, restitution index 2
    paths = [tmp_path / n for n in ("heat.png", "bif.png", "poincare.png")]
    sweep.heatmap(res, "peak_contact_force_n", x="clearance", y="restitution", path=paths[0])
    sweep.bifurcation(res, "clearance", coordinate="e", path=paths[1])
    sweep.poincare_plot(res, path=paths[2])
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ParameterError, match="unknown metric"):
        res.grid("nope", "clearance", "restitution")
    with pytest.raises(ParameterError, match="unknown Poincare coordinate"):
        sweep.poincare_coordinate(res.poincare, "w_z")


# --------------------------------------------------------------------------------------
# The notebook
# --------------------------------------------------------------------------------------


SWEEP_FIGURES = ["sweeps_bifurcation_0.png", "sweeps_bifurcation_1.png", "sweeps_heatmap_energy_dissipated_per_rev_j.png",
                 "sweeps_heatmap_peak_contact_force_n.png", "sweeps_heatmap_rms_acc_deviation_m_s2.png",
                 "sweeps_poincare_0.png", "sweeps_poincare_1.png"]


@pytest.mark.extended
def test_notebook_runs(tmp_path, monkeypatch):
    """Execute a copy of notebooks/sweeps.ipynb with JAXCLEAR_QUICK=1 (a 2 x 2 map and 3
    speeds; the committed notebook holds the outputs of the full version, about 2 minutes on 2
    cores), figures to a scratch folder."""
    import shutil

    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    shutil.copy(ROOT / "notebooks" / "sweeps.ipynb", tmp_path / "sweeps.ipynb")
    nb = nbformat.read(tmp_path / "sweeps.ipynb", as_version=4)
    monkeypatch.setenv("JAXCLEAR_QUICK", "1")
    monkeypatch.setenv("JAXCLEAR_FIGURES", str(tmp_path / "figures"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the notebook's scratch sweep folders
    monkeypatch.setenv("PYTHONPATH", str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    assert sorted(p.name for p in (tmp_path / "figures").glob("*.png")) == SWEEP_FIGURES
    text = "".join(o.get("text", "") for o in outputs)
    assert "4 runs in" in text and "compiled 1 time(s); failed runs: 0" in text
    assert "compiled 0 time(s)" in text  # the second speed sweep reuses the first one's compilation


def test_committed_notebook_has_outputs_and_figures():
    nbformat = pytest.importorskip("nbformat")
    nb = nbformat.read(ROOT / "notebooks" / "sweeps.ipynb", as_version=4)
    assert all(c.outputs for c in nb.cells if c.cell_type == "code")
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {})]
    assert len(images) == 7
    assert "quick: False" in "".join(o.get("text", "") for o in nb.cells[1].outputs)
    for name in SWEEP_FIGURES:
        assert (ROOT / "notebooks" / "figures" / name).stat().st_size > 10_000, name
