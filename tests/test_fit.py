"""Identification (jaxclear.fitting, jaxclear.fit, jaxclear fit): the sensor model, the optimiser, bad input, a small
end-to-end fit with an interruption and a resume, and (slow) the acceptance runs of the issue.

Acceptance criteria (issue 4): records made by jaxclear with known parameters, the sensor model
and white noise at SNR 20 dB; the fit starts 3x off in stiffness and 0.3 off in restitution;
it must recover stiffness within 5 % and restitution within 0.02, for the benchmark slider-crank
and the Flores 2011 rig, and the reported std must cover the true error. "Cover" is checked as
|error| <= 3 std (a 99.7 % interval for a correct Gaussian std; one realisation per seed).
"""

import jaxclear  # noqa: F401  (float64 first)

import json
import math
import os
import re
import signal
import warnings

import jax
import numpy as np
import optax
import pytest
import scipy.signal

import jaxclear as jc
from jaxclear import fitting
from jaxclear import params
from jaxclear.cli import main
from conftest import assert_strict_json
from jaxclear.analysis.sensor import Accelerometer, record_times

PNG = b"\x89PNG\r\n\x1a\n"


# --------------------------------------------------------------------------------------
# sensor model
# --------------------------------------------------------------------------------------


def test_accelerometer_filter_is_the_analogue_butterworth():
    """The first-order-hold discretisation is exact for piecewise-linear input: against SciPy's
    lsim of the analogue 2nd-order Butterworth (also first-order hold) to 1e-9 of the input
    amplitude; unit DC gain; |H(f_c)| = 1/sqrt(2); gain and bias applied after the filter."""
    fc, dt = 2000.0, 1e-5
    t = np.arange(4000) * dt
    u = np.sin(2 * np.pi * 700 * t) + (t > 0.01) * 3.0 + 50 * t
    sensor = Accelerometer(fc, gain=1.5, bias=-2.0)
    y = np.asarray(sensor.filter(dt, np.asarray(u)))
    wc = 2 * np.pi * fc
    # SciPy's state is in controllable canonical form; start it at rest on u[0] as the sensor does
    a, b, c, d = scipy.signal.tf2ss([wc**2], [1.0, math.sqrt(2) * wc, wc**2])
    x0 = np.linalg.solve(a, -b[:, 0] * u[0])
    _, y_ref, _ = scipy.signal.lsim((a, b, c, d), u, t, X0=x0, interp=True)
    assert np.max(np.abs(y - y_ref)) < 1e-9 * np.max(np.abs(u))
    out = np.asarray(sensor(dt, np.asarray(u)))
    np.testing.assert_allclose(out, 1.5 * y - 2.0, rtol=1e-12, atol=1e-12)
    # steady sine at the cut-off: amplitude 1/sqrt(2)
    s = np.sin(2 * np.pi * fc * t)
    ys = np.asarray(Accelerometer(fc).filter(dt, np.asarray(s)))
    assert abs(np.max(np.abs(ys[2000:])) - 1 / math.sqrt(2)) < 2e-3
    np.testing.assert_allclose(np.asarray(Accelerometer(None).filter(dt, np.asarray(u))), u)


def test_record_times_by_time_and_by_crank_angle():
    t = np.array([0.5, 0.6, 0.7])
    meas = jc.Measurements(time_s=t, slider_acc_m_s2=np.zeros(3), crank_angle_rad=np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(record_times(meas), [0.0, 0.1, 0.2], atol=1e-15)
    np.testing.assert_allclose(record_times(meas, time_offset=1.0), [1.0, 1.1, 1.2])
    np.testing.assert_allclose(record_times(meas, "crank", speed=10.0, angle0=1.0), [0.0, 0.1, 0.2])
    with pytest.raises(jc.ParameterError, match="crank_angle_rad"):
        record_times(jc.Measurements(time_s=t, slider_acc_m_s2=np.zeros(3)), "crank", speed=10.0)
    bad = jc.Measurements(time_s=t, slider_acc_m_s2=np.zeros(3), crank_angle_rad=np.array([1.0, 3.0, 2.0]))
    with pytest.raises(jc.ParameterError, match="data row 3"):
        record_times(bad, "crank", speed=10.0)
    # resampling onto another grid (as the fit's jnp.interp does): linear, end values held outside
    np.testing.assert_allclose(np.interp([0.5, 1.5, 3.0], [0.0, 1.0, 2.0], [0.0, 10.0, 30.0]), [5.0, 20.0, 30.0])


@pytest.mark.extended
@pytest.mark.parametrize("extend,cap", [(0, math.inf), (3, 0.5)])
def test_fit_levenberg_marquardt_on_rosenbrock(extend, cap):
    """The fit's optimistix Levenberg-Marquardt (Nielsen damping, optional step extension and
    step cap) on Rosenbrock's residuals (10 (y1 - y0^2), 1 - y0): the minimum is (1, 1) exactly;
    from (-1.2, 1) no step exceeds the cap in any coordinate."""
    import jax.numpy as jnp
    import optimistix as optx
    from jaxclear.fitting import lm

    def fn(y, _):
        return jnp.stack([10 * (y[1] - y[0] ** 2), 1 - y[0]])

    solver = lm.with_scale(lm.levenberg_marquardt(1e-10, 1e-10, extend=extend, max_step=cap), jnp.ones(2))
    sol = optx.least_squares(fn, solver, jnp.array([-1.2, 1.0]), max_steps=200)
    np.testing.assert_allclose(np.asarray(sol.value), [1.0, 1.0], atol=1e-8)
    y = jnp.array([-1.2, 1.0])

    def fa(y, args):
        return fn(y, args), None

    f_struct = jax.eval_shape(lambda: fn(y, None))
    state = solver.init(fa, y, None, {}, f_struct, None, frozenset())
    for _ in range(60):
        y_new, state, _ = solver.step(fa, y, None, {}, state, frozenset())
        assert float(jnp.max(jnp.abs(state.y_eval - y_new))) <= cap * (1 + 1e-12)
        y = y_new


def test_the_solver_step_is_traced_once_from_a_fresh_state():
    """The solver state's array leaves keep their types from ``_init`` through ``_step`` (the
    damping's scalars were weakly typed at the start, strongly after a step), so that with the
    store of traced programs off (or arguments it cannot key) the fit's step is traced and
    compiled once, not twice, per stage structure."""
    import equinox as eqx
    import jax.numpy as jnp
    from jaxclear.fitting import solver as fit_solver
    from jaxclear.integrate import on_trace

    class Rosenbrock(eqx.Module):
        def __call__(self, u, args):
            r = jnp.stack([10 * (u[1] - u[0] ** 2), 1 - u[0]])
            return r, r

    opt = fit_solver.make_optimizer()
    fn, y = Rosenbrock(), jnp.array([-1.2, 1.0])
    arrays = fit_solver._init(opt.solver, fn, y, None)
    traced = []
    with on_trace(traced.append):
        for _ in range(4):
            out = fit_solver._step(opt.solver, fn, y, None, arrays)
            assert [x.weak_type for x in jax.tree_util.tree_leaves(out[1])] == \
                [x.weak_type for x in jax.tree_util.tree_leaves(arrays)]
            y, arrays = out[0], out[1]
    assert traced == ["_step"], traced


def _primitives(jaxpr) -> set:
    """Names of the primitives of ``jaxpr`` and of every jaxpr inside it."""
    names = set()
    for eqn in jaxpr.eqns:
        names.add(eqn.primitive.name)
        for value in eqn.params.values():
            for sub in value if isinstance(value, (list, tuple)) else (value,):
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    names |= _primitives(inner)
    return names


def test_the_solver_step_holds_no_model_and_follows_the_evaluation_it_is_given():
    """The fit's compiled step receives the model's residual and Jacobian at its trial point
    (``StageArgs``, evaluated outside it) and holds no copy of the model: its program has no
    loop (an integration is a ``while``). Given the evaluation of Rosenbrock's residual at each
    step's ``y_eval`` (the protocol of :class:`~jaxclear.fitting.solver.StageRun`), the steps
    reach its minimum (1, 1) to 1e-8 from the classical start (-1.2, 1)."""
    import jax.numpy as jnp
    from jaxclear.fitting import solver as fit_solver

    opt = fit_solver.make_optimizer()
    fn = fit_solver.StageResidual()

    def evaluation(u):
        u = jnp.asarray(u)
        r = jnp.stack([10.0 * (u[1] - u[0] ** 2), 1.0 - u[0]])
        jac = jnp.array([[-20.0 * u[0], 10.0], [-1.0, 0.0]])
        return fit_solver.StageArgs(r, jac, u, jnp.zeros((1, 1, 2)))

    y = jnp.array([-1.2, 1.0])
    arrays = fit_solver._init(opt.solver, fn, y, evaluation(y))
    jaxpr = jax.make_jaxpr(lambda y, args, arrays: fit_solver._step(opt.solver, fn, y, args, arrays))(
        y, evaluation(y), arrays)
    assert "while" not in _primitives(jaxpr.jaxpr), sorted(_primitives(jaxpr.jaxpr))
    for _ in range(60):
        y, arrays, _, done, _ = fit_solver._step(opt.solver, fn, y, evaluation(arrays.y_eval), arrays)
    exact = np.array([1.0, 1.0])
    assert np.max(np.abs(np.asarray(y) - exact)) < 1e-8, (np.asarray(y), exact)


def test_column_scale_of_a_stage_without_influence():
    """A stage whose unknowns do not change its samples (a horizon before the first contact) has a
    zero Jacobian: its scale is 1, not a subnormal floor that XLA on CPU flushes to zero (which
    made ``x = u / D`` a 0 / 0 and the start loss NaN); a zero column beside a non-zero one gets
    the 1e-12 relative floor, a normal number. ``influences`` tells the two stages apart."""
    from jaxclear.fitting.solver import column_scale, influences
    zero = np.zeros((50, 2))
    np.testing.assert_array_equal(column_scale(zero), [1.0, 1.0])
    assert not influences(zero)
    d = column_scale(np.array([[3.0, 0.0], [4.0, 0.0]]))  # column norms 5 and 0
    np.testing.assert_allclose(d, math.sqrt(1e-3) * np.array([5.0, 5e-12]), rtol=1e-15)
    u = 25.0 * d  # the solver's unknowns; x = u / D inside compiled code must come back exactly
    np.testing.assert_allclose(np.asarray(jax.jit(lambda a, b: a / b)(u, d)), [25.0, 25.0], rtol=1e-15)
    assert influences(np.array([[3.0, 0.0], [4.0, 0.0]]))


def test_levenberg_marquardt_is_an_optax_transformation():
    """On an exponential fit y = a exp(-b t): converges from far in a few iterations through the
    optax interface (update with the extra arguments jacobian, residual, value_fn). The spelling
    is deprecated (the fit runs optimistix's Levenberg-Marquardt) and warns so."""
    t = np.linspace(0, 3, 40)
    y = 2.0 * np.exp(-1.3 * t)

    def residual(z):
        return np.exp(z[0]) * np.exp(-np.exp(z[1]) * t) - y

    def jac(z):
        e = np.exp(-np.exp(z[1]) * t)
        return np.stack([np.exp(z[0]) * e, -np.exp(z[0]) * t * np.exp(z[1]) * e], axis=1)

    with pytest.warns(DeprecationWarning, match="optimistix"):
        opt = jc.levenberg_marquardt()
    assert isinstance(opt, optax.GradientTransformationExtraArgs)
    z = np.array([np.log(0.2), np.log(5.0)])
    state = opt.init(z)
    for _ in range(30):
        r, J = residual(z), jac(z)
        step, state = opt.update(J.T @ r, state, z, jacobian=J, residual=r,
                                 value_fn=lambda x: 0.5 * float(np.sum(residual(np.asarray(x)) ** 2)))
        z = np.asarray(optax.apply_updates(z, step))
    np.testing.assert_allclose(np.exp(z), [2.0, 1.3], rtol=1e-8)


# --------------------------------------------------------------------------------------
# bad input (issue 7): clear errors naming the line, column or parameter, before any compilation
# --------------------------------------------------------------------------------------


def _csv(tmp_path, text, name="data.csv"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


GOOD_ROWS = "".join(f"{i * 1e-5:.6g},{100.0 * math.sin(i / 10):.6g}\n" for i in range(200))


@pytest.mark.parametrize(
    "text,match",
    [
        ("time_s,acc\n0,1\n1e-5,2\n", r"line 1: missing required column\(s\) \['slider_acc_m_s2'\]"),
        ("time,slider_acc_m_s2\n0,1\n1e-5,2\n", r"line 1: missing required column\(s\) \['time_s'\]"),
        ("# rig: test\ntime_s,slider_acc_m_s2\n0,1\n2e-5,2\n1e-5,3\n", r"line 5, column 'time_s'.*strictly increasing"),
        ("time_s,slider_acc_m_s2\n0,1\nnan,2\n", r"line 3, column 'time_s': non-finite value 'nan'"),
        ("time_s,slider_acc_m_s2\n0,1\n1e-5,inf\n", r"line 3, column 'slider_acc_m_s2': non-finite"),
        ("time_s,slider_acc_m_s2\n0,1\n1e-5,abc\n", r"line 3, column 'slider_acc_m_s2': non-numeric value 'abc'"),
        ("time_s,slider_acc_m_s2\n0,1\n1e-5,2\n2e-5,3\n", r"holding 3 sample\(s\) each; at least 4 are needed"),
    ],
    ids=["missing-column", "misnamed-column", "time-not-increasing", "time-nan", "acc-inf", "acc-text", "too-short"],
)
def test_cli_fit_bad_records(tmp_path, capsys, text, match):
    code = main(["fit", _csv(tmp_path, text), "--out", str(tmp_path / "out"), "--no-progress"])
    out, err = capsys.readouterr()
    assert code == 2
    assert err.startswith("error: ")
    assert re.search(match, err), err
    assert "compiling" not in out  # the data are checked before anything is compiled


@pytest.mark.parametrize(
    "args,match",
    [
        (["--free", "stiffness,stifness"], r"free parameter 'stifness' does not exist.*did you mean 'stiffness'\?"),
        (["--free", "mass:piston"], r"free parameter 'mass:piston' does not exist.*piston"),
        (["--start", "restitution=1.5"], r"start value of 'restitution' is outside its bounds: restitution = 1.5 is "
                                         r"outside the allowed range \(0, 1\]"),
        (["--start", "restitution=1"], r"restitution = 1 is outside \(0, 1\), the open interval"),
        (["--start", "stiffness=-2e10"], r"start value of 'stiffness' is outside its bounds: stiffness = -2e\+10"),
        (["--free", "friction"], r"friction = 0 is on the bound 0 of \(0, inf\)"),
        (["--start", "clearance=0.5e-3"], r"start value given for 'clearance', which is not a free parameter"),
        (["--start", "clearance"], r"expected NAME=VALUE"),
        (["--windows", "0"], r"argument --windows: 0 is outside the allowed range \[1, inf\)"),
    ],
)
def test_cli_fit_bad_parameters(tmp_path, capsys, args, match):
    path = _csv(tmp_path, "time_s,slider_acc_m_s2\n" + GOOD_ROWS)
    code = main(["fit", path, "--window", "1e-3", "--out", str(tmp_path / "out"), "--no-progress", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert re.search(match, err), err


def test_fit_api_bad_input():
    mech = jc.preset("flores-slider-crank")
    meas = jc.Measurements(time_s=np.arange(100) * 1e-5, slider_acc_m_s2=np.ones(100))
    with pytest.raises(jc.ParameterError, match="free parameter 'youngs' does not exist"):
        jc.fit(meas, mech, free=["youngs"], window=5e-4)
    with pytest.raises(jc.ParameterError, match="record shorter than the fit windows"):
        jc.fit(meas, mech, window=5e-4, windows=3)
    bad = jc.Measurements(time_s=np.array([0.0, 1e-5, np.nan]), slider_acc_m_s2=np.ones(3))
    with pytest.raises(jc.ParameterError, match="column 'time_s' has a non-finite value at sample 2"):
        jc.fit(bad, mech)
    with pytest.raises(jc.ParameterError, match="no 'slider' role"):
        jc.fit(meas, jc.preset("four-bar"), window=5e-4)
    with pytest.raises(jc.ParameterError, match="horizons"):
        jc.fit(meas, mech, window=5e-4, horizons=(0.5,))
    with pytest.raises(jc.ParameterError, match="unknown optimizer 'sgd'"):
        jc.fit(meas, mech, window=5e-4, optimizer="sgd")
    with pytest.raises(jc.ParameterError, match="profile = 'friction' is not a free parameter of this fit; valid: "
                       "stiffness, restitution"):
        jc.fit(meas, mech, window=5e-4, profile="friction")


# --------------------------------------------------------------------------------------
# a small fit end to end (fast): benchmark, first 1 ms (3 impacts), interrupted and resumed
# --------------------------------------------------------------------------------------

SENSOR = Accelerometer(20e3)


@pytest.fixture(scope="module")
def small_record(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fit-small")
    mech = jc.preset("flores-slider-crank")
    path = folder / "record.csv"
    jc.synthetic_record(mech, 1.2e-3, 200e3, SENSOR, snr_db=20, seed=7, path=path)
    return mech, str(path), folder


class _Stop(Exception):
    pass


def check_small_fit_resumes_after_an_interruption(small_record):
    """2x off in stiffness, 0.15 off in restitution, a 1 ms window: stopped after 3 iterations,
    then run again with the same inputs: it resumes from the checkpoint (the iteration count
    continues) and recovers the parameters (5 %, 0.02) with an error within 3 std; the resumed
    fit ends bit for bit where an uninterrupted one does."""
    mech, path, folder = small_record
    k0 = float(params.get(mech, "stiffness"))
    out = folder / "api"
    start = {"stiffness": 2 * k0, "restitution": 0.75}
    seen = []

    def stop(record):
        seen.append(record["iteration"])
        if len(seen) == 3:
            raise _Stop

    with pytest.raises(_Stop):
        jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, out=out, progress=False, callback=stop)
    saved = json.loads((out / fitting.CHECKPOINT_NAME).read_text())
    assert saved["state"]["total"] == 3
    resumed = []
    res = jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, out=out, progress=False,
                 callback=lambda r: resumed.append(r["iteration"]))
    assert res.settings["resumed"] and resumed[0] == 4
    assert res.iterations >= 3 + len(resumed)  # (a last update that finds no decrease is counted too)
    err_k = res.estimates["stiffness"] / k0 - 1
    err_e = res.estimates["restitution"] - 0.9
    assert abs(err_k) < 0.05 and abs(err_e) < 0.02, res.estimates
    assert abs(err_k * k0) <= 3 * res.std["stiffness"] and abs(err_e) <= 3 * res.std["restitution"]
    assert res.loss < 0.02 and abs(res.residual_autocorrelation) < 0.3
    d = res.to_dict()
    for key in ("estimates", "std", "loss", "iterations", "wall_time_s"):
        assert key in d
    # the resume is exact: the same fit without interruption ends on the same numbers, bit for bit
    whole = jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, progress=False)
    assert whole.estimates == res.estimates and whole.iterations == res.iterations
    assert [h["values"] for h in whole.history] == [h["values"] for h in res.history]


def check_cli_fit_writes_json_and_plot(small_record, capsys):
    """The command line on the same record (same compiled model): fit.json with the issue's keys,
    fit.png; a second call resumes from the finished checkpoint without iterating."""
    mech, path, folder = small_record
    out = folder / "cli"
    args = ["fit", path, "--window", "1e-3", "--sensor-cutoff-hz", "20000", "--start", "stiffness=1.3e11",
            "--start", "restitution=0.75", "--out", str(out), "--no-progress"]
    capsys.readouterr()
    assert main(args) == 0
    assert "compiling" not in capsys.readouterr().out  # compiled by the API fit before: nothing to say
    d = json.loads((out / "fit.json").read_text())
    assert set(d["estimates"]) == {"stiffness", "restitution"} == set(d["std"])
    assert isinstance(d["loss"], float) and d["iterations"] >= 1 and d["wall_time_s"] > 0
    assert abs(d["estimates"]["restitution"] - 0.9) < 0.02
    # values from the user as typed, not through their arithmetic (R_B - R_J = 0.0005000000000000004,
    # a logit and back); the record's metadata too
    assert d["start"] == {"stiffness": 1.3e11, "restitution": 0.75} and d["fixed"]["clearance"] == 0.0005
    assert "# true_clearance: 0.0005\n" in open(path, encoding="utf-8").read()
    assert (out / "fit.png").read_bytes()[:8] == PNG
    capsys.readouterr()
    assert main(args) == 0
    d2 = json.loads((out / "fit.json").read_text())
    assert d2["iterations"] == d["iterations"] and d2["settings"]["resumed"]
    assert "fit.json" in assert_strict_json(out)  # and fit_checkpoint.json where it is kept
    assert "(resumed from the checkpoint)" in capsys.readouterr().out  # the summary says it resumed


def check_profile_likelihood_of_a_finished_fit(small_record, capsys):
    """``--profile all`` added to the finished CLI fit (same --out): the fit resumes without
    iterating and only the profile runs. Each point holds its parameter exactly at its value
    (the held column of the Levenberg-Marquardt step is zero), the deviance is 0 at the estimate
    and rises on both sides to past the 90 % threshold; the interval holds the estimate and the
    reported std is its longer half over 1.645. On this 1 ms engine-made record the loss is
    nearly quadratic over the interval, so the profile's half-width lies within 25 % of the
    Gauss-Newton 1.645 std (where they differ is the point of a profile: the coverage on records
    of an independent simulator is measured in benchmarks/bench_profile.py). Run again, nothing
    is refitted."""
    mech, path, folder = small_record
    out = folder / "cli"
    args = ["fit", path, "--window", "1e-3", "--sensor-cutoff-hz", "20000", "--start", "stiffness=1.3e11",
            "--start", "restitution=0.75", "--out", str(out), "--no-progress", "--profile", "all"]
    before = json.loads((out / "fit.json").read_text())
    capsys.readouterr()
    assert main(args) == 0
    printed = capsys.readouterr().out
    d = json.loads((out / "fit.json").read_text())
    assert d["iterations"] == before["iterations"] and d["estimates"] == before["estimates"]
    assert "profile likelihood of stiffness: 90 % interval [" in printed
    saved = json.loads((out / fitting.CHECKPOINT_NAME).read_text())["state"]
    for i, name in enumerate(("stiffness", "restitution")):
        p = d["profiles"][name]
        est, lo, hi = d["estimates"][name], *p["interval"]
        assert lo < est < hi and p["better"] is None and not p["open"], p
        assert d["std"][name] == pytest.approx(max(est - lo, hi - est) / 1.6448536269514722, rel=1e-12)
        assert p["std_gauss_newton"] == pytest.approx(before["std"][name], rel=1e-9)
        assert 0.75 < (hi - lo) / 2 / (1.645 * p["std_gauss_newton"]) < 1.25, (name, p)
        values, dev = np.array(p["values"]), np.array(p["deviance"])
        j = int(np.argmin(np.abs(values - est)))
        assert dev[j] == 0.0 and np.all(np.diff(dev[: j + 1]) < 0) and np.all(np.diff(dev[j:]) > 0), p
        assert dev[0] > 2.706 and dev[-1] > 2.706
        points = [q for q in saved["profile"] if q["name"] == name]
        z_hat = saved["theta"][i]
        assert points and all(q["theta"][i] == z_hat + q["side"] * q["dz"] for q in points)
    n_points = len(saved["profile"])
    assert main(args) == 0
    again = json.loads((out / "fit.json").read_text())
    assert len(json.loads((out / fitting.CHECKPOINT_NAME).read_text())["state"]["profile"]) == n_points
    assert again["profiles"] == d["profiles"]


def check_ctrl_c_stops_the_fit_after_a_checkpointed_iteration(small_record):
    """A real SIGINT during iteration 2 (sent by the callback): the fit finishes that iteration,
    checkpoints it and raises KeyboardInterrupt; the Ctrl-C handler is restored; the same call
    resumes at iteration 3."""
    mech, path, folder = small_record
    out = folder / "ctrl-c"
    start = {"stiffness": 1.3e11, "restitution": 0.75}
    seen = []

    def interrupt_at_2(record):
        seen.append(record["iteration"])
        if record["iteration"] == 2:
            os.kill(os.getpid(), signal.SIGINT)

    # Python's own Ctrl-C handler, as in a fresh process: in a pytest-xdist worker an earlier test
    # (or the worker) may have left another handler, under which the fit, rightly, installs none
    # (once, in CI, this check then saw no KeyboardInterrupt)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        try:
            jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, out=out, progress=False,
                   callback=interrupt_at_2)
        except KeyboardInterrupt:
            pass
        else:
            pytest.fail(f"no KeyboardInterrupt; iterations seen {seen}; handler before the check {before!r}")
        assert seen == [1, 2] and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)
    assert json.loads((out / fitting.CHECKPOINT_NAME).read_text())["state"]["total"] == 2
    resumed = []
    jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, out=out, progress=False,
           callback=lambda r: resumed.append(r["iteration"]))
    assert resumed[:1] == [3]


class _Bar:
    """A stand-in for tqdm that records (n, total) after every update and what is written."""

    log: list = []
    written: list = []

    def __init__(self, total=None, initial=0, **kwargs):
        self.total, self.n = total, initial

    def update(self, k):
        self.n += k
        _Bar.log.append((self.n, self.total))

    def set_description(self, *a):
        pass

    set_postfix = refresh = close = set_description

    @staticmethod
    def write(text):
        _Bar.written.append(text)


def check_progress_bar_totals(small_record, monkeypatch):
    """The bar's total is the plan's most iterations left plus those done, from the first
    iteration on: never below the count, never growing, equal to it at the end; resumed, it
    starts at the iterations done before. "compiling" is not said: the model is compiled."""
    from jaxclear.fitting import driver

    mech, path, folder = small_record
    monkeypatch.setattr(driver, "tqdm", _Bar)
    out = folder / "bar"
    start = {"stiffness": 1.3e11, "restitution": 0.8}

    def stop(record):
        if record["iteration"] == 2:
            raise _Stop

    with pytest.raises(_Stop):
        jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, starts=1, out=out, callback=stop)
    assert _Bar.log[0] == (1, 75) and _Bar.log[1][1] <= 75  # 15 + 15 + 15 + 30: the plan's limits
    _Bar.log.clear()
    res = jc.fit(path, mech, start=start, sensor=SENSOR, window=1e-3, starts=1, out=out)
    ns, totals = zip(*_Bar.log)
    assert ns == tuple(range(3, res.iterations + 1)) and all(t >= n for n, t in _Bar.log)
    assert list(totals) == sorted(totals, reverse=True) and totals[0] <= 75  # stages done count what they took
    assert not any("compiling" in w for w in _Bar.written) and any("resuming" in w for w in _Bar.written)


def check_one_start_that_stops_on_max_iter_is_fitted_again_from_several(small_record):
    """By default (starts=None) a start that stops on max_iter (here 1 iteration in the last stage, from
    3x the stiffness) is followed by the whole fit from AUTO_STARTS starts, which is the result
    and says why; a fit interrupted in that refit resumes the refit, not the single start; an
    explicit starts=1 is left alone, and its warning names --starts and --start."""
    from jaxclear.fitting.driver import AUTO_STARTS

    mech, path, folder = small_record
    start = {"stiffness": 3 * float(params.get(mech, "stiffness")), "restitution": 0.6}
    kwargs = dict(start=start, sensor=SENSOR, window=1e-3, max_iter=1, progress=False)
    with pytest.warns(UserWarning, match=r"--starts N.*this fit had 1\).*--start NAME=VALUE"):
        one = jc.fit(path, mech, starts=1, **kwargs)
    assert one.stop_reason == "max_iter" and one.settings["starts"] == 1 and "auto_starts" not in one.settings
    out = folder / "auto"
    stages = []

    def stop_in_the_refit(record):
        stages.append(record["stage"])
        if record["stage"].startswith(f"start 2/{AUTO_STARTS}"):
            raise _Stop

    with pytest.raises(_Stop):
        jc.fit(path, mech, out=out, callback=stop_in_the_refit, **kwargs)
    assert stages[0].startswith("start 1/1") and sum(s.startswith("start 1/1") for s in stages) < len(stages)
    resumed = []
    res = jc.fit(path, mech, out=out, callback=lambda r: resumed.append(r["stage"]), **kwargs)
    assert not any(s.startswith("start 1/1") for s in resumed) and resumed[0].startswith(f"start 2/{AUTO_STARTS}")
    assert res.settings["starts"] == AUTO_STARTS and res.settings["resumed"]
    whole = jc.fit(path, mech, **kwargs)  # uninterrupted: the same refit, bit for bit
    assert whole.settings["auto_starts"] == f"{AUTO_STARTS} starts: one start stopped on max_iter = 1"
    assert res.settings["auto_starts"] == whole.settings["auto_starts"]
    assert whole.estimates == res.estimates and whole.iterations == res.iterations


def check_every_phase_of_the_automatic_refit_resumes(small_record, monkeypatch):
    """A noise-free record (its residual is not white, lag-1 autocorrelation 0.93: the single start
    is followed by AUTO_STARTS starts) fitted with starts=None and stopped, as a kill would stop it
    (every iteration is checkpointed before the callback sees it), in the single start, at the
    switch to the refit and in the refit: the same call resumes there, says so ("resuming" in
    the progress output, settings["resumed"]), fits no checkpointed iteration again and ends on
    the uninterrupted fit's numbers and notes (issue 42, item 8: a fit killed in the single start
    ran it on, then the refit, and said resumed false; a resumed refit forgot why it ran)."""
    from jaxclear.fitting import driver
    from jaxclear.fitting.driver import AUTO_STARTS

    mech, _, folder = small_record
    path = folder / "noise-free.csv"
    jc.synthetic_record(mech, 1.2e-3, 200e3, SENSOR, snr_db=None, path=path)
    kwargs = dict(start={"stiffness": 1.3e11, "restitution": 0.75}, sensor=SENSOR, window=1e-3)
    monkeypatch.setattr(driver, "tqdm", _Bar)
    seen = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # not white, by construction
        whole = jc.fit(path, mech, progress=False, callback=seen.append, **kwargs)
    n_one = [r["iteration"] for r in seen].index(1, 1)  # the refit counts its iterations from 1 again
    assert whole.settings["auto_starts"].startswith(f"{AUTO_STARTS} starts: one start left a residual that is not")
    assert n_one > 3 and len(seen) == n_one + whole.iterations and not whole.settings["resumed"]

    def stopped_then_resumed(name: str, stop_at=None, first_only=False):
        """Stop after call ``stop_at`` of the callback (or run the single start alone), then resume."""
        out = folder / f"auto-{name.replace(' ', '-')}"
        calls = []

        def stop(record):
            calls.append(record)
            if len(calls) == stop_at:
                raise _Stop

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            if first_only:  # the single start's checkpoint, finished: a kill at the switch before the refit's
                jc.fit(path, mech, starts=1, out=out, progress=False, **kwargs)
            else:
                with pytest.raises(_Stop):
                    jc.fit(path, mech, out=out, progress=False, callback=stop, **kwargs)
            _Bar.written.clear()
            again = []
            res = jc.fit(path, mech, out=out, callback=again.append, **kwargs)
        assert res.settings["resumed"] and any("resuming" in w for w in _Bar.written), (name, _Bar.written)
        assert res.estimates == whole.estimates and res.iterations == whole.iterations, name
        assert res.settings["auto_starts"] == whole.settings["auto_starts"], name
        assert [h["values"] for h in res.history] == [h["values"] for h in whole.history], name
        return len(again)

    assert stopped_then_resumed("single start", stop_at=3) == len(seen) - 3
    assert stopped_then_resumed("switch", first_only=True) == whole.iterations
    assert stopped_then_resumed("refit", stop_at=n_one + 3) == whole.iterations - 3
    # killed at the switch, the refit's state checkpointed and none of its iterations: the refit resumes
    plan = driver.run_plan

    def killed_in_the_refit(problem, *args):
        if problem.settings["starts"] == AUTO_STARTS:
            raise _Stop
        return plan(problem, *args)

    monkeypatch.setattr(driver, "run_plan", killed_in_the_refit)
    out = folder / "auto-switched"
    with pytest.raises(_Stop), warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        jc.fit(path, mech, out=out, progress=False, **kwargs)
    monkeypatch.setattr(driver, "run_plan", plan)
    saved = json.loads((out / fitting.CHECKPOINT_NAME).read_text())
    assert saved["config"]["starts"] == AUTO_STARTS and saved["state"]["total"] == 0
    assert whole.settings["auto_starts"].endswith(saved["state"]["refit"])
    again = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = jc.fit(path, mech, out=out, progress=False, callback=again.append, **kwargs)
    assert len(again) == whole.iterations and res.settings["resumed"] and res.estimates == whole.estimates
    assert res.settings["auto_starts"] == whole.settings["auto_starts"]


@pytest.mark.extended
def test_small_fit_api_and_cli(small_record, capsys, monkeypatch):
    """The checks above in one test, so that a parallel run (pytest -n) compiles the model once."""
    check_small_fit_resumes_after_an_interruption(small_record)
    check_cli_fit_writes_json_and_plot(small_record, capsys)
    check_profile_likelihood_of_a_finished_fit(small_record, capsys)
    check_ctrl_c_stops_the_fit_after_a_checkpointed_iteration(small_record)
    check_progress_bar_totals(small_record, monkeypatch)
    check_one_start_that_stops_on_max_iter_is_fitted_again_from_several(small_record)
    check_every_phase_of_the_automatic_refit_resumes(small_record, monkeypatch)


@pytest.mark.slow  # a fresh process compiles the fit's model (about a minute on 2 shared cores)
def test_ctrl_c_stops_jaxclear_fit_with_exit_130(small_record, tmp_path):
    """``jaxclear fit`` in a subprocess gets SIGINT once its first iteration is checkpointed:
    it stops after the iteration under way, keeps the checkpoint, prints one line and exits with
    130 (before the flag, 1 of 4 tries ran to the end with exit code 0)."""
    import subprocess
    import sys
    import time

    _, path, _ = small_record
    out = tmp_path / "fit"
    ckpt = out / fitting.CHECKPOINT_NAME
    proc = subprocess.Popen([sys.executable, "-m", "jaxclear", "--no-cache", "fit", path, "--window", "1e-3",
                             "--sensor-cutoff-hz", "20000", "--start", "stiffness=1.3e11", "--max-iter", "200",
                             "--out", str(out), "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.time() + 600
        while not (ckpt.exists() and json.loads(ckpt.read_text())["state"]["total"] >= 1):
            assert proc.poll() is None and time.time() < deadline, proc.communicate()
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    lines = stderr.strip().splitlines()
    assert proc.returncode == 130, (stdout, stderr)
    assert len(lines) == 1 and "interrupted" in lines[0] and "checkpointed" in lines[0], stderr
    assert "Traceback" not in stderr and not (out / "fit.json").exists()
    state = json.loads(ckpt.read_text())["state"]
    assert 1 <= state["total"] and state["stop_reason"] == ""


@pytest.mark.slow  # two fresh processes compile the fit's model (about a minute each on 2 shared cores)
def test_jaxclear_fit_killed_in_either_fit_of_the_automatic_refit_resumes(small_record, tmp_path, capsys):
    """``jaxclear fit`` on a noise-free record (the single start is followed by AUTO_STARTS starts)
    killed with SIGKILL after 3 checkpointed iterations of the single start, and of the refit:
    the same command resumes ("resuming" in its output, "(resumed from the checkpoint)" in the
    summary, fit.json's settings.resumed) and ends on the uninterrupted fit's estimates (issue
    42, item 8: killed in the single start, it said resumed false)."""
    import subprocess
    import sys
    import time

    mech, _, _ = small_record
    path = str(tmp_path / "noise-free.csv")
    jc.synthetic_record(mech, 1.2e-3, 200e3, SENSOR, snr_db=None, path=path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        whole = jc.fit(path, mech, start={"stiffness": 1.3e11, "restitution": 0.75}, sensor=SENSOR, window=1e-3,
                       progress=False)
    for starts in (1, 4):
        out = tmp_path / f"fit-{starts}"
        ckpt = out / fitting.CHECKPOINT_NAME
        args = ["fit", path, "--window", "1e-3", "--sensor-cutoff-hz", "20000", "--start", "stiffness=1.3e11",
                "--start", "restitution=0.75", "--out", str(out), "--no-plots"]
        proc = subprocess.Popen([sys.executable, "-m", "jaxclear", *args], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        try:
            deadline = time.time() + 600
            while True:
                assert proc.poll() is None and time.time() < deadline, starts
                try:
                    saved = json.loads(ckpt.read_text())
                except (OSError, ValueError):
                    saved = None
                if saved and saved["config"]["starts"] == starts and saved["state"]["total"] >= 3:
                    break
                time.sleep(0.05)
            proc.send_signal(signal.SIGKILL)
        finally:
            proc.kill()
            proc.wait()
        capsys.readouterr()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            assert main(args) == 0
        text = "".join(capsys.readouterr())
        assert "jaxclear fit: resuming" in text and "(resumed from the checkpoint)" in text, text
        d = json.loads((out / "fit.json").read_text())
        assert d["settings"]["resumed"] and d["estimates"] == whole.estimates, (starts, d["estimates"])
        assert d["settings"]["auto_starts"] == whole.settings["auto_starts"]


# --------------------------------------------------------------------------------------
# acceptance (slow)
# --------------------------------------------------------------------------------------

ACCEPTANCE = {
    # preset: (record length [s], sample rate [Hz], sensor cut-off [Hz])
    "flores-slider-crank": (3.2e-3, 200e3, 20e3),
    "flores-2011-rig": (0.08, 50e3, 5e3),
}


def _acceptance(name, seed, tmp_path, law=None):
    length, rate, cutoff = ACCEPTANCE[name]
    truth = jc.preset(name) if law is None else jc.preset(name, law=law)
    mech = jc.preset(name)
    sensor = Accelerometer(cutoff)
    k0 = float(params.get(mech, "stiffness"))
    e0 = float(params.get(mech, "restitution"))
    record = jc.synthetic_record(truth, length, rate, sensor, snr_db=20, seed=seed, path=tmp_path / "record.csv")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = jc.fit(tmp_path / "record.csv", mech, start={"stiffness": 3 * k0, "restitution": e0 - 0.3},
                     sensor=sensor, out=tmp_path, progress=False)
    res.write(tmp_path)  # fit.json, fit.png
    line = (f"{name} seed {seed}: stiffness {res.estimates['stiffness']:.5g} (true {k0:.5g}, error "
            f"{100 * (res.estimates['stiffness'] / k0 - 1):+.3f} %, std {100 * res.std['stiffness'] / k0:.3f} %), "
            f"restitution {res.estimates['restitution']:.5f} (true {e0}, error {res.estimates['restitution'] - e0:+.2e}, "
            f"std {res.std['restitution']:.2e}), loss {res.loss:.4g}, {res.iterations} iterations, "
            f"{res.wall_time_s:.0f} s, noise sigma {record.metadata['noise_sigma_m_s2']:.4g} vs fitted "
            f"{res.noise_sigma_m_s2:.4g}")
    print(line)
    return res, k0, e0, caught


@pytest.mark.slow
@pytest.mark.parametrize("name,seed", [("flores-slider-crank", 0), ("flores-slider-crank", 1), ("flores-2011-rig", 0)])
def test_acceptance_recovers_stiffness_and_restitution(name, seed, tmp_path):
    res, k0, e0, caught = _acceptance(name, seed, tmp_path)
    err_k = res.estimates["stiffness"] - k0
    err_e = res.estimates["restitution"] - e0
    assert abs(err_k) / k0 < 0.05, res.estimates
    assert abs(err_e) < 0.02, res.estimates
    assert abs(err_k) <= 3 * res.std["stiffness"], (err_k, res.std)
    assert abs(err_e) <= 3 * res.std["restitution"], (err_e, res.std)
    # the residual is white noise at the record's level (20 dB: sigma^2 = mean(signal^2) / 100)
    assert abs(res.residual_autocorrelation) < 0.1
    assert res.converged and not [w for w in caught if "residuals are not white" in str(w.message)]


def own_slider_crank(tmp_path):
    """A slider-crank of one's own, as a user writes it: the benchmark's file with a 40 mm crank,
    a 150 mm rod (0.25 kg), a 0.2 kg slider, 3000 rpm, 0.3 mm clearance, c_r 0.85."""
    text = jc.preset_file("flores-slider-crank").read_text(encoding="utf-8")
    for old, new in [('name = "flores-slider-crank"', 'name = "own-slider-crank"'),
                     ("position = [0.025, 0.0, 0.0]", "position = [0.02, 0.0, 0.0]"),
                     ("O = [-0.025, 0.0]\nA = [0.025, 0.0]", "O = [-0.02, 0.0]\nA = [0.02, 0.0]"),
                     ("mass = 0.21\ninertia = 0.00025\nposition = [0.11, 0.0, 0.0]",
                      "mass = 0.25\ninertia = 0.0005\nposition = [0.115, 0.0, 0.0]"),
                     ("A = [-0.06, 0.0]\nB = [0.06, 0.0]", "A = [-0.075, 0.0]\nB = [0.075, 0.0]"),
                     ("mass = 0.14\ninertia = 0.0001\nposition = [0.16999999999999998, 0.0, 0.0]",
                      "mass = 0.2\ninertia = 0.0001\nposition = [0.19, 0.0, 0.0]"),
                     ("speed = 523.5987755982989", "speed = 314.1592653589793"),
                     ("journal_radius = 0.0095", "journal_radius = 0.0097"), ("restitution = 0.9", "restitution = 0.85")]:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "own.toml"
    path.write_text(text, encoding="utf-8")
    return jc.load_mechanism(path)


@pytest.mark.slow
def test_own_slider_crank_from_a_far_restitution(tmp_path):
    """The outside check's case: one's own slider-crank, c_r from 0.85, truth 0.6, 10 % noise
    (20 dB), 10 ms at 100 kHz, 20 kHz sensor, the defaults otherwise (a single start stopped
    there at max_iter with c_r 0.6945 +- 0.0025, 38 std off; starts=None now refits such a
    start from 4). Measured here (3 noise seeds): c_r 0.6000 +- 0.0005, one start converged."""
    mech = own_slider_crank(tmp_path)
    sensor = Accelerometer(20e3)
    truth = params.replace(mech, "restitution", 0.6)
    jc.synthetic_record(truth, 0.01, 100e3, sensor, snr_db=20, seed=0, path=tmp_path / "record.csv")
    res = jc.fit(tmp_path / "record.csv", mech, sensor=sensor, progress=False)
    print("own slider-crank:", res.estimates, res.std, res.iterations, res.stop_reason, res.settings.get("auto_starts"))
    err_e = res.estimates["restitution"] - 0.6
    assert abs(err_e) < 0.01 and abs(err_e) <= 3 * res.std["restitution"], (res.estimates, res.std)
    k0 = float(params.get(mech, "stiffness"))
    assert abs(res.estimates["stiffness"] / k0 - 1) < 0.05
    assert res.converged and res.residual_autocorrelation < 0.3


@pytest.mark.slow
def test_data_from_another_contact_law(tmp_path):
    """Data from a linear Kelvin-Voigt contact (k = 1e8 N/m), fitted with Lankarani-Nikravesh:
    no crash, an honest report: the residual stays far above the noise (loss >> 0.01), it is
    strongly autocorrelated, and the fit warns that the std then understate the error."""
    res, _, _, caught = _acceptance("flores-slider-crank", 5, tmp_path, law="kelvin-voigt")
    assert math.isfinite(res.loss) and res.loss > 0.1
    assert res.residual_autocorrelation > 0.5
    assert any("residuals are not white" in str(w.message) for w in caught)
    d = json.loads((tmp_path / "fit.json").read_text())
    assert d["warnings"] and d["residual_lag1_autocorrelation"] > 0.5


@pytest.mark.slow
def test_multiple_shooting_windows(tmp_path):
    """Three back-to-back windows of 3 ms on the benchmark (the journal state at the start of
    windows 2 and 3 estimated): the parameters are recovered as well."""
    mech = jc.preset("flores-slider-crank")
    k0 = float(params.get(mech, "stiffness"))
    record = jc.synthetic_record(mech, 9.2e-3, 200e3, SENSOR, snr_db=20, seed=3)
    res = jc.fit(record, mech, start={"stiffness": 3 * k0, "restitution": 0.6}, sensor=SENSOR, window=3e-3,
                 windows=3, progress=False)
    print("multiple shooting:", res.estimates, res.std, res.window_losses)
    assert res.n_unknowns == 2 + 2 * 4
    assert abs(res.estimates["stiffness"] / k0 - 1) < 0.05 and abs(res.estimates["restitution"] - 0.9) < 0.02


@pytest.mark.slow
def test_several_starts_and_adam(tmp_path, small_record):
    """starts=3 runs the first stage from three starts and continues from the best; an optax
    first-order optimiser (adam) runs through the same loop."""
    mech, path, _ = small_record
    k0 = float(params.get(mech, "stiffness"))
    res = jc.fit(path, mech, start={"stiffness": 2 * k0, "restitution": 0.75}, sensor=SENSOR, window=1e-3, starts=3,
                 progress=False)
    assert len([h for h in res.history if h["stage"].startswith("start 3/3")]) >= 1
    assert abs(res.estimates["restitution"] - 0.9) < 0.02
    res2 = jc.fit(path, mech, start={"stiffness": 1.2 * k0, "restitution": 0.85}, sensor=SENSOR, window=1e-3,
                  optimizer="adam:0.05", max_iter=40, progress=False)
    assert res2.loss < 0.05 and abs(res2.estimates["restitution"] - 0.9) < 0.05


# --------------------------------------------------------------------------------------
# the notebook
# --------------------------------------------------------------------------------------


@pytest.mark.extended
def test_identification_notebook_runs(tmp_path):
    """notebooks/identification.ipynb end to end with JAXCLEAR_QUICK=1 (short record, few
    iterations): no error, its figures written."""
    from test_notebooks import execute_notebook

    nb = execute_notebook("identification.ipynb", tmp_path)
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
    figures = sorted(p.name for p in (tmp_path / "figures").glob("*.png"))
    assert "identification_fit.png" in figures and "identification_profiles.png" in figures


def test_committed_identification_notebook_has_outputs_and_figures():
    import nbformat
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "notebooks"
    nb = nbformat.read(root / "identification.ipynb", as_version=4)
    assert all(c.outputs for c in nb.cells if c.cell_type == "code")
    assert (root / "figures" / "identification_fit.png").stat().st_size > 10_000
    assert (root / "figures" / "identification_profiles.png").stat().st_size > 10_000
