"""The drivers' compiled programs through the store of traced programs (issue 41, item 3): a
second process running the same design or Lyapunov estimate loads them instead of tracing them
and ends on the same numbers bit for bit. `jc.design`: the objective and constraints
(`designing.problem.values_at`), with their Jacobian and the derivative horizon's state tangents
(one program: `jacobian_at`, `tangents_at`), on docs/getting-started.md's design, one iteration;
`jc.lyapunov`: Benettin's run (`chaos.lyapunov._compiled`), two revolutions of the benchmark.
(The fit's: tests/test_fit_programs.py; `jc.simulate`'s: tests/test_programs.py.)"""

import json
import os
import subprocess
import sys
import textwrap

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: The getting-started design (four-bar, three variables, peak force, total mass fixed), one
#: iteration, half a revolution; prints its result, the store's counts and the programs heard tracing.
CHILD = textwrap.dedent("""
    import json, sys, warnings
    import jaxclear as jc
    from jaxclear.integrate import on_trace
    from jaxclear.integrate import _programs as programs

    variables = {"mass:coupler": (0.25, 0.75), "mass:rocker": (0.2, 0.6), "centroid_x:rocker": (-0.05, 0.05)}
    traced = []
    with on_trace(traced.append), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one iteration's verdict: not under test
        res = jc.design(jc.preset("four-bar"), variables, "peak-force", constraints=["total-mass"], revolutions=0.5,
                        out=sys.argv[1], max_iter=1, progress=False)
    print(json.dumps(dict(result=res.to_json(), counts=programs.counts(), traced=traced), default=str))
""")

#: The design's programs, as the on_trace listeners name them.
DESIGN_PROGRAMS = {"evaluate", "_with_tangents"}

#: Two revolutions of the benchmark slider-crank, the largest exponent over quarter revolutions
#: (bench_first_result.py's "chaos" entry).
LYAPUNOV = textwrap.dedent("""
    import json
    import jaxclear as jc
    from jaxclear.integrate import on_trace
    from jaxclear.integrate import _programs as programs

    mech = jc.preset("flores-slider-crank")
    period = float(jc.model.crank_period(mech))
    traced = []
    with on_trace(traced.append):
        r = jc.lyapunov(mech, jc.settings(2 * period, throw=False), interval=period / 4, count=1, samples=4,
                        keep=False)
    print(json.dumps(dict(result=[float(r.exponents[0]), r.running.tolist(), int(r.num_steps)],
                          counts=programs.counts(), traced=traced)))
""")


def _run(cache, out, child=CHILD) -> dict:
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""),
               JAXCLEAR_CACHE_DIR=str(cache))
    env.pop("JAX_COMPILATION_CACHE_DIR", None)  # both stores in JAXCLEAR_CACHE_DIR, as for a user
    proc = subprocess.run([sys.executable, "-c", child, str(out)], env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _numbers(result: dict) -> dict:
    """The result without what differs between two runs by design (wall times, the folder)."""
    drop = {"out", "folder", "created", "gradient_cost"}  # gradient_cost: a ratio of wall times

    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if k not in drop and not k.endswith("_s")}
        if isinstance(x, list):
            return [clean(v) for v in x]
        return x

    return clean(result)


@pytest.mark.extended
def test_a_second_process_loads_the_designs_programs(tmp_path):
    """The first process traces the design's programs, each stored (none unkeyable,
    unserializable or with another output structure); the second traces none of them, loads every
    program the first stored, and ends on the same numbers to the last bit."""
    cache = tmp_path / "cache"
    cold, warm = _run(cache, tmp_path / "a"), _run(cache, tmp_path / "b")
    assert DESIGN_PROGRAMS <= set(cold["traced"]), cold["traced"]
    for run in (cold, warm):
        assert run["counts"]["unkeyable"] == run["counts"]["unserializable"] == run["counts"]["mismatched"] == 0, run
    # the values', the Jacobian's (with the horizon's tangents) and the report's runs
    assert cold["counts"]["loaded"] == 0 and cold["counts"]["traced"] >= 4, cold["counts"]
    # nothing of the design is traced again; only the figure's clearance circle (a plain jit of a
    # few operations, milliseconds, jaxclear/plot/figures.py) is
    assert set(warm["traced"]) <= {"clearance_region"} and warm["counts"]["traced"] == 0, (warm["traced"],
                                                                                          warm["counts"])
    assert warm["counts"]["loaded"] == cold["counts"]["traced"], warm["counts"]
    assert _numbers(warm["result"]) == _numbers(cold["result"])


@pytest.mark.extended
def test_a_second_process_loads_the_lyapunov_program(tmp_path):
    """Benettin's run: traced and stored by the first process, loaded by the second, which traces
    nothing and finds the same exponent, running estimate and steps to the last bit."""
    cache = tmp_path / "cache"
    cold, warm = _run(cache, tmp_path, LYAPUNOV), _run(cache, tmp_path, LYAPUNOV)
    assert "_compiled" in cold["traced"] and cold["counts"]["traced"] >= 1, cold
    assert warm["traced"] == [] and warm["counts"]["traced"] == 0, warm
    assert warm["counts"]["loaded"] == cold["counts"]["traced"] and warm["counts"]["unkeyable"] == 0, warm["counts"]
    assert warm["result"] == cold["result"]
