"""The store of traced programs (jaxclear/integrate/programs.py): a run through a stored program
equals the usual jitted run bit for bit, array values are inputs (one program serves every
value), static structure is part of the key, unkeyable arguments and damaged files fall back to
tracing, and a new process loads the program instead of tracing it."""

import dataclasses
import importlib
import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.integrate import programs
from jaxclear.integrate.compile import compiler_options
from jaxclear.integrate.runs import revolution_settings

simulate_module = importlib.import_module("jaxclear.integrate.simulate")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture
def store(tmp_path):
    folder = programs.enable(tmp_path / "programs")
    yield folder
    programs.enable(None)


def _files(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(programs.SUFFIX))


def _plain(mech, s):
    return simulate_module._simulate(mech, dataclasses.replace(s, throw=False), None)


def _assert_same(a, b):
    # the same program on the same inputs: equal to the last bit (XLA is deterministic on CPU)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)


def test_stored_program_equals_the_jitted_run_and_serves_every_value(store):
    mech = jc.preset("flores-slider-crank")
    s = revolution_settings(mech, 0.05, n_out=51)
    sol = jc.simulate(mech, s)
    # one program: the run, which also returns the assembly that the eager checks read
    assert len(_files(store)) == 1
    _assert_same(sol, _plain(mech, s))
    # another clearance (an array value): same programs, no new file, the other value's result
    wider = jc.preset("flores-slider-crank", clearance=0.4e-3)
    sol2 = jc.simulate(wider, s)
    assert len(_files(store)) == 1
    _assert_same(sol2, _plain(wider, s))
    assert not np.array_equal(np.asarray(sol2.penetration), np.asarray(sol.penetration))
    # another output grid (static structure): a new program
    jc.simulate(mech, dataclasses.replace(s, n_out=52))
    assert len(_files(store)) == 2


def test_unkeyable_arguments_are_traced_as_usual(store):
    class Opaque:  # repr shows an address: not a faithful key
        pass

    assert programs.program_key("p", (Opaque(),)) is None
    assert programs.call("p", lambda x: x, (Opaque(),), lambda: None) is None
    assert programs.program_key("p", (np.zeros(3), "name", 1.5)) is not None


def test_damaged_file_is_traced_again_and_replaced(store):
    mech = jc.preset("flores-slider-crank")
    s = dataclasses.replace(revolution_settings(mech, 0.05, n_out=51), throw=False)
    args = (mech, s, None)
    fun = simulate_module._simulate.__wrapped__
    key, _ = programs.program_key(f"simulate:{fun.__module__}.{fun.__qualname__}", args)
    path = store / f"{key}{programs.SUFFIX}"
    path.write_bytes(b"not a program")
    sol = programs.call("simulate", fun, args,
                        lambda: simulate_module.solution_structure(mech), compiler_options=compiler_options())
    assert path.stat().st_size > 1000
    _assert_same(sol, _plain(mech, s))


def test_a_new_process_loads_instead_of_tracing(store):
    mech = jc.preset("flores-slider-crank")
    jc.simulate(mech, revolution_settings(mech, 0.05, n_out=51))
    script = textwrap.dedent(f"""
        import jaxclear as jc
        from jaxclear.integrate import programs
        from jaxclear.integrate.runs import revolution_settings
        programs.enable({str(store)!r})
        def no_trace(*a, **k):
            raise AssertionError("traced although the program is stored")
        programs._export = no_trace
        mech = jc.preset("flores-slider-crank")
        sol = jc.simulate(mech, revolution_settings(mech, 0.05, n_out=51))
        print("steps", int(sol.num_steps))
    """)
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "steps" in proc.stdout


def test_prepare_traces_once_and_the_overlay_runs_through_the_store(store, monkeypatch):
    """simulate_with_ideal traces the clearance run first (prepare_simulate), then runs both;
    the call after prepare does not trace again, and the results equal the plain runs."""
    from jaxclear.integrate.runs import simulate_with_ideal

    mech = jc.preset("flores-slider-crank")
    s = revolution_settings(mech, 0.05, n_out=51)
    simulate_module.prepare_simulate(mech, s)
    assert len(_files(store)) == 1

    def no_trace(*a, **k):
        raise AssertionError("traced again after prepare")

    monkeypatch.setattr(programs, "_export", no_trace)
    sol = jc.simulate(mech, s)
    _assert_same(sol, _plain(mech, s))
    monkeypatch.undo()
    r = simulate_with_ideal(mech, s)
    _assert_same(r.sol, sol)
    assert int(r.ideal_sol.status) == 0 and len(_files(store)) == 2  # the kinematic overlay's program


def test_on_trace_reports_cache_misses_only():
    """``on_trace`` listeners hear of a top-level trace (a program JAX compiles next) and of
    nothing else: not a call that hits the cache, not a call inside a user's jit, not after the
    block (the fit says "compiling ..." through it, only when it compiles)."""
    from jaxclear.integrate.compile import jit, on_trace

    @jit
    def double(x):
        return 2.0 * x

    heard = []
    with on_trace(heard.append):
        double(np.ones(3))
        double(np.zeros(3))  # the same shapes: cached
        assert heard == ["double"]
        double(np.ones(4))  # a new shape: traced
        jax.jit(lambda x: double(x) + 1)(np.ones(5))  # inside a user's jit: inlined, not a program of its own
    double(np.ones(6))
    assert heard == ["double", "double"]
