"""The fit's compiled programs through the store of traced programs (issue 41, item 3, for the
fit): the window's evaluation (jaxclear/fitting/window.py), the way in's scoring
(jaxclear/fitting/way_in.py) and the Levenberg-Marquardt solver's init and step
(jaxclear/fitting/solver.py). A second process fitting a record of the same structure loads them
instead of tracing them, and ends on the same numbers bit for bit; with the store off the fit
runs as before, on the same numbers."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: A small fit (benchmark slider-crank, a 0.7 ms record, one 0.5 ms window, one horizon, one
#: start, 2 iterations) and the way in on that record's window with 12 of its candidate starts
#: (every 130th of the grid's 1560; the same scoring program as the whole grid's, at 12 lanes).
#: Prints the results, the store's counts and the programs heard tracing (``on_trace``: a miss of
#: the store, or a plain jit's trace).
CHILD = textwrap.dedent("""
    import json, warnings
    import jaxclear as jc
    from jaxclear.fitting import way_in
    from jaxclear.fitting.problem import build_problem
    from jaxclear.integrate import on_trace
    from jaxclear.integrate import _programs as programs

    mech = jc.preset("flores-slider-crank")
    sensor = jc.Accelerometer(20e3)
    record = jc.synthetic_record(mech, 0.7e-3, 200e3, sensor, snr_db=20, seed=7)
    traced = []
    with on_trace(traced.append), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the fit's verdict on 2 iterations: not under test
        res = jc.fit(record, mech, start={"stiffness": 1.5e11, "restitution": 0.8}, sensor=sensor, window=0.5e-3,
                     horizons=(1.0,), starts=1, max_iter=2, progress=False)
        settings = dict(max_iter=1, ftol=1e-6, xtol=1e-5, rtol=1e-8, atol=1e-11, max_steps=None, align="time",
                        time_offset=0.0, optimizer="lm")
        problem = build_problem(record, mech, ("stiffness", "restitution"), None, sensor, 0.5e-3, 1, (1.0,), None, 1,
                                settings, start_state="free")
        grid = way_in.candidates
        way_in.candidates = lambda m: grid(m)[::130]
        ranked, report = way_in.find_start(problem.model, problem.mech, problem.z0,
                                           problem.window_input(0, 0.25, False, problem.window_guesses), 0.25)
    print(json.dumps(dict(estimates=res.estimates, std=res.std, loss=res.loss, iterations=res.iterations,
                          history=[h["values"] for h in res.history], way_in=ranked.tolist(),
                          passes=report["passes"], counts=programs.counts(), traced=traced,
                          folder=str(jc.cache_folder()))))
""")

#: The fit's programs, as the on_trace listeners name them.
FIT_PROGRAMS = {"evaluate_window", "_init", "_step", "_scores"}


def _run(env) -> dict:
    proc = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _env(cache) -> dict:
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""),
               JAXCLEAR_CACHE_DIR=str(cache))
    env.pop("JAX_COMPILATION_CACHE_DIR", None)  # both stores in JAXCLEAR_CACHE_DIR, as for a user
    return env


def _results(run: dict) -> dict:
    return {k: run[k] for k in ("estimates", "std", "loss", "iterations", "history", "way_in", "passes")}


@pytest.fixture(scope="module")
def two_processes(tmp_path_factory):
    """The child run twice with one fresh ``JAXCLEAR_CACHE_DIR``: cold (it traces and stores the
    programs) and warm."""
    cache = tmp_path_factory.mktemp("fit-programs") / "cache"
    return _run(_env(cache)), _run(_env(cache))


@pytest.mark.extended
def test_a_second_process_loads_the_fits_programs(two_processes):
    """The first process traces the fit's programs, each stored (none unkeyable, unserializable
    or with an output structure other than its caller's); the second traces none of them (nor
    anything else: the run of the record too is loaded), loads them, and ends on the same numbers
    to the last bit: the same programs, loaded (json keeps every float's bits)."""
    cold, warm = two_processes
    assert FIT_PROGRAMS <= set(cold["traced"]), cold["traced"]
    for run in (cold, warm):
        assert run["counts"]["unkeyable"] == run["counts"]["unserializable"] == run["counts"]["mismatched"] == 0, run
    # the run of the record, the window's evaluation, the solver's init and step, the way in's scoring
    assert cold["counts"]["traced"] >= 5 and cold["counts"]["loaded"] == 0, cold["counts"]
    assert warm["traced"] == [] and warm["counts"]["traced"] == 0, (warm["traced"], warm["counts"])
    assert warm["counts"]["loaded"] == cold["counts"]["traced"], warm["counts"]
    assert _results(warm) == _results(cold)


@pytest.mark.slow
def test_the_fit_runs_as_before_with_the_store_off(two_processes):
    """``JAXCLEAR_CACHE_DIR=off``: nothing goes through the store and the fit and the way in end
    on the numbers of the stored programs, bit for bit (a stored program is the plain program,
    exported). Slow: with the store off nothing of the other processes' compilations is reused
    (about 60 s of CPU for the compilations alone)."""
    cold, _ = two_processes
    off = _run(_env("off"))
    assert off["folder"] == "None"
    assert all(v == 0 for v in off["counts"].values()), off["counts"]
    assert FIT_PROGRAMS <= set(off["traced"]), off["traced"]
    assert _results(off) == _results(cold)


def test_the_way_ins_longer_scorings_run_the_whole_window_and_its_first_rounds_a_part():
    """A run's sample count is part of its compiled program, so the way in's longer scorings
    (its last round over the first half, the approach speed chosen again over a stage's horizon,
    a window revisited over its whole length) all run the whole window: one program, where each
    horizon was one. Its first rounds, hundreds of candidates, run the first part only."""
    from test_lab_fit import small_free_start_problem

    from jaxclear.fitting import way_in

    whole = small_free_start_problem()[1].model
    for horizon in (way_in.WAY_IN_HORIZON, 0.75, 1.0):
        assert way_in.scoring_model(whole, horizon) is whole
    first = way_in.scoring_model(whole, 0.25)
    n = whole.settings.n_out - 1
    assert first.settings.n_out - 1 == pytest.approx((0.25 + way_in.SCORED_BEYOND) * n, abs=1)
    assert float(first.settings.t_end) == pytest.approx((first.settings.n_out - 1) * float(whole.h), rel=1e-12)
