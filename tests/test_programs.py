"""The store of traced programs (jaxclear/integrate/_programs.py): a run through a stored program
equals the usual jitted run bit for bit, array values are inputs (one program serves every
value), static structure is part of the key, unkeyable arguments and damaged files fall back to
tracing, and a new process loads the program instead of tracing it."""

import dataclasses
import importlib
import json
import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.integrate import _program_keys as keys
from jaxclear.integrate import _programs as programs
from jaxclear.integrate._compile import compiler_options, on_trace
from jaxclear.integrate._runs import revolution_settings

simulate_module = importlib.import_module("jaxclear.integrate._simulate")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture
def store(tmp_path):
    before = programs.folder()  # the session's store (tests/conftest.py), back afterwards
    folder = programs.enable(tmp_path / "programs")
    yield folder
    programs.enable(before)


def _files(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(programs.SUFFIX))


def _plain(mech, s):
    return simulate_module._simulate(mech, dataclasses.replace(s, throw=False), None)


def _assert_same(a, b):
    # the same program on the same inputs: equal to the last bit (XLA is deterministic on CPU)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)


@pytest.mark.extended
def test_stored_program_equals_the_jitted_run_and_serves_every_value(store):
    mech = jc.preset("flores-slider-crank")
    s = revolution_settings(mech, 0.05, n_out=51)
    sol = jc.simulate(mech, s)
    # one program: the run, which also returns the assembly that the eager checks read
    assert len(_files(store)) == 1
    _assert_same(sol, _plain(mech, s))
    # without throw (the checks skipped, the status reported): the same program, nothing traced
    heard = []
    with on_trace(heard.append):
        quiet = jc.simulate(mech, dataclasses.replace(s, throw=False))
    assert heard == [] and len(_files(store)) == 1
    _assert_same(quiet, sol)
    # another clearance (an array value): same programs, no new file, the other value's result
    wider = jc.preset("flores-slider-crank", clearance=0.4e-3)
    sol2 = jc.simulate(wider, s)
    assert len(_files(store)) == 1
    _assert_same(sol2, _plain(wider, s))
    assert not np.array_equal(np.asarray(sol2.penetration), np.asarray(sol.penetration))
    # another output grid (static structure): a new program
    jc.simulate(mech, dataclasses.replace(s, n_out=52))
    assert len(_files(store)) == 2


def test_a_run_at_another_tolerance_is_the_same_program_with_that_tolerances_steps(store):
    """rtol and atol are inputs of the run's program (a convergence check compiles once): a run
    at rtol 1e-9 after one at 1e-6 traces nothing, and equals the plainly jitted run at 1e-9 bit
    for bit, whose steps are not those of 1e-6 (the tolerance reached the step controller)."""
    mech = jc.preset("flores-slider-crank")
    s = revolution_settings(mech, 0.05, n_out=51)
    loose = jc.simulate(mech, s)
    tight_s = dataclasses.replace(s, rtol=1e-9, atol=1e-12)
    heard = []
    with on_trace(heard.append):
        tight = jc.simulate(mech, tight_s)
    assert heard == [] and len(_files(store)) == 1
    _assert_same(tight, _plain(mech, tight_s))
    assert int(tight.num_steps) > 2 * int(loose.num_steps)


def test_unkeyable_arguments_are_traced_as_usual(store):
    class Opaque:  # repr shows an address: not a faithful key
        pass

    assert programs.program_key("p", (Opaque(),)) is None
    assert programs.call("p", lambda x: x, (Opaque(),), lambda: None) is None
    assert programs.program_key("p", (np.zeros(3), "name", 1.5)) is not None


def _user_norm(x):  # a module-level function of a module the key does not cover (this test's)
    return x


def test_a_library_function_is_keyed_by_its_name_and_a_users_is_not():
    """optimistix's ``max_norm`` (a field of its solvers; a wrapper its module makes at import)
    is keyed by its module and name; a lambda, a function made inside another and a function of
    a module outside :data:`TRUSTED_MODULES` stay unkeyable."""
    import optimistix as optx

    norm = optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6).norm
    assert programs.program_key("p", (norm,)) is not None
    assert programs.program_key("p", (norm,)) != programs.program_key("p", (optx.rms_norm,))

    def inner(x):
        return x

    for fun in (lambda x: x, inner, _user_norm):
        assert programs.program_key("p", (fun,)) is None


def test_a_remembered_key_is_the_key_built_anew(store):
    """:func:`program_key` remembers the key of a structure met before (building it took a tenth of
    a warm call): what it returns equals the key built from the arguments, for the run's own
    arguments and after a change of a static value (another contact law, another sample count),
    which gets its own key."""
    import jax.numpy as jnp

    mech = jc.preset("flores-slider-crank")
    s = revolution_settings(mech, 0.05, n_out=51)
    other = jc.preset("flores-slider-crank", law="flores")
    calls = [(mech, s), (mech, dataclasses.replace(s, n_out=52)), (other, s), (mech, s),
             (jax.tree_util.tree_map(lambda x: x + 1.0 if eqx_is_float(x) else x, mech), s)]
    found = []
    for args in calls:
        options = ";".join(f"{o}={getattr(jax.config, o, None)}" for o in programs.KEYED_OPTIONS)
        built = keys._key("p", args, options)
        for _ in range(2):  # built, then remembered
            key, leaves = programs.program_key("p", args)
            assert key == built
            assert len(leaves) == len([x for x in jax.tree_util.tree_leaves(args) if isinstance(x, (jax.Array, np.ndarray))])
        found.append(key)
    assert len(set(found[:3])) == 3 and found[3] == found[0] == found[4]
    # a Python number among the leaves is keyed by its type and value
    assert programs.program_key("p", (jnp.ones(2), 1))[0] != programs.program_key("p", (jnp.ones(2), 1.0))[0]


def eqx_is_float(x):
    return isinstance(x, jax.Array) and jax.numpy.issubdtype(x.dtype, jax.numpy.floating)


def test_a_mechanism_passed_again_is_not_transferred_again(monkeypatch):
    """The committed copy of an uncommitted array is kept while the array lives: the second call
    transfers nothing, and the copy goes with the array."""
    import gc

    import jax.numpy as jnp

    moved = []
    real = jax.device_put

    def counting(x, *a, **k):
        moved.append(len(x) if isinstance(x, list) else 1)
        return real(x, *a, **k)

    monkeypatch.setattr(jax, "device_put", counting)
    x, y = jnp.arange(3.0), jnp.ones(2)
    first = programs._placed([x, y])
    assert moved == [2] and all(a.committed for a in first)
    second = programs._placed([x, y])
    assert moved == [2] and all(a is b for a, b in zip(first, second))
    ident = id(x)
    assert ident in programs._COPIES
    del x, first, second
    gc.collect()
    assert ident not in programs._COPIES
    # a read-only NumPy array that owns its data is kept too; a writable one is converted anew
    constant, loose = np.array(2.0), np.array(3.0)
    constant.flags.writeable = False
    moved.clear()
    programs._placed([constant, loose])
    programs._placed([constant, loose])
    assert moved == [2, 1]
    loose += 1.0  # a writable array may change between calls: the new value goes in
    assert float(programs._placed([constant, loose])[1]) == 4.0


def test_the_lanes_rule_of_the_process_is_in_the_key(monkeypatch):
    """Whether XLA's single-kernel loops are on decides, while tracing, ``jax.lax.map`` or
    ``jax.vmap`` (the run's post-processing, the lanes of a batch): a program traced under one
    answer is never served under the other."""
    args = (np.zeros(3), "name")
    monkeypatch.setattr(keys, "loop_kernels_active", lambda: True)
    on = programs.program_key("p", args)
    monkeypatch.setattr(keys, "loop_kernels_active", lambda: False)
    assert programs.program_key("p", args)[0] != on[0]


def test_an_output_structure_other_than_the_callers_is_not_stored(store):
    """The caller's ``out_structure`` is checked against the traced program's output: a wrong one
    stores nothing and the call runs as usual (``None``: the caller's plain jit)."""
    before = programs.counts()["mismatched"]
    out = programs.call("pair", lambda x: (x, 2 * x), (np.ones(3),), lambda: jax.tree_util.tree_structure(0))
    assert out is None and programs.counts()["mismatched"] == before + 1 and _files(store) == []
    out = programs.call("pair", lambda x: (x, 2 * x), (np.ones(3),), lambda: jax.tree_util.tree_structure((0, 0)))
    np.testing.assert_array_equal(out[1], 2 * np.ones(3))
    assert len(_files(store)) == 1


def test_a_stored_program_compiles_once_for_its_own_outputs(store):
    """A stored program's outputs come back committed to their device; called on them (a solver
    step on the step before's unknowns) it is not compiled again: every argument is committed
    alike (before, the fit's solver step compiled twice, 41 s each on 2 cores)."""
    from jax import monitoring

    compiled = []

    def listener(event, duration, **kw):
        if event == "/jax/core/compile/backend_compile_duration" and kw.get("fun_name") == "jit(stored_program)":
            compiled.append(duration)

    monitoring.register_event_duration_secs_listener(listener)
    try:
        def step(x, y):
            return x + y, x * y

        x = jax.numpy.asarray(np.arange(3.0))
        for _ in range(3):
            x, y = programs.call("step", step, (x, np.ones(3)), lambda: jax.tree_util.tree_structure((0, 0)))
    finally:
        monitoring.unregister_event_duration_listener(listener)
    assert len(compiled) == 1, compiled
    np.testing.assert_array_equal(x, np.arange(3.0) + 3)


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


CHILD = textwrap.dedent("""
    import json
    from jax import monitoring
    traces, events = [], []
    monitoring.register_event_duration_secs_listener(
        lambda e, d, **kw: e.endswith("jaxpr_trace_duration") and traces.append(str(kw.get("fun_name"))))
    monitoring.register_event_listener(lambda e, **kw: events.append(e))
    import jaxclear as jc  # nothing configured: the caches jaxclear keeps by default
    from jaxclear.integrate import _programs as programs
    mech = jc.preset("flores-slider-crank")
    sol = jc.simulate(mech, jc.settings(2e-3))  # what benchmarks/bench_first_result.py runs
    print(json.dumps(dict(status=int(sol.status), folder=str(jc.cache_folder()), traces=traces,
                          counts=programs.counts(), hits=events.count("/jax/compilation_cache/cache_hits"),
                          writes=events.count("/jax/compilation_cache/cache_misses"))))
""")


@pytest.mark.extended
def test_a_second_process_neither_traces_nor_compiles_the_run(tmp_path):
    """Issue 41, item 3: the Python API keeps its programs across processes by default. Two fresh
    processes run the benchmark's ``jc.simulate`` with the same ``JAXCLEAR_CACHE_DIR`` and nothing
    configured: the first traces the run and writes it to both stores; the second loads the traced
    program (no trace of the run) and JAX's compiled one (persistent-cache hits, nothing compiled
    and written), with the same result."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""),
               JAXCLEAR_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    runs = []
    for _ in range(2):
        proc = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    cold, warm = runs
    assert cold["status"] == warm["status"] == 0 and cold["folder"] == warm["folder"] == str(tmp_path / "cache")
    run_traces = ("flat", "_simulate_and_assemble")  # the run's trace (for the store, and as a plain jit)
    assert cold["counts"]["traced"] >= 1 and any(t in run_traces for t in cold["traces"]) and cold["writes"] >= 1
    assert warm["counts"]["traced"] == 0 and warm["counts"]["loaded"] >= 1, warm["counts"]
    assert not [t for t in warm["traces"] if t in run_traces], warm["traces"]
    assert warm["hits"] >= 1 and warm["writes"] == 0, warm  # read from JAX's cache, nothing compiled anew
    assert any((tmp_path / "cache" / "programs").glob(f"*{programs.SUFFIX}"))
    assert any((tmp_path / "cache").glob("*-cache"))


def test_prepare_traces_once_and_the_overlay_runs_through_the_store(store, monkeypatch):
    """simulate_with_ideal traces the clearance run first (prepare_simulate), then runs both;
    the call after prepare does not trace again, and the results equal the plain runs."""
    from jaxclear.integrate._runs import simulate_with_ideal

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
    from jaxclear.integrate._compile import jit, on_trace

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


def test_on_trace_hears_a_miss_of_the_store_and_not_a_load(store):
    """A program traced for the store (a miss) is told to the ``on_trace`` listeners as a plain
    jit's trace is (the fit's "compiling ..."); a call served by the store is not."""
    from jaxclear.integrate._compile import jit, on_trace

    @jit
    def triple(x):
        return 3.0 * x

    heard = []
    with on_trace(heard.append):
        out = triple.stored("triple", lambda: jax.tree_util.tree_structure(0), np.ones(3))
        triple.stored("triple", lambda: jax.tree_util.tree_structure(0), np.zeros(3))  # the same program
    assert heard == ["triple"] and len(_files(store)) == 1
    np.testing.assert_array_equal(out, 3.0 * np.ones(3))


_SLOW_TRACES: list = []


def _slow_square(x):
    """A program whose trace takes 0.5 s (and is counted): two threads ask for it together."""
    import time

    _SLOW_TRACES.append(1)
    time.sleep(0.5)
    return x * x + 1.0


def test_two_threads_asking_for_one_program_trace_and_compile_it_once(store):
    """The store's one-thread rule (jaxclear/integrate/_programs.py, ``_runner``, ``_Runner``):
    two threads that ask for the same program at once (the fit's way in splits its candidates
    over the host's threads) trace it once and compile it once; the second waits for the first
    and both get the program's result."""
    import threading

    from jax import monitoring

    compiled = []
    monitoring.register_event_duration_secs_listener(
        lambda event, d, **kw: compiled.append(kw.get("fun_name")) if event.endswith("backend_compile_duration") else None)
    before = programs.counts()["traced"]
    start, out = threading.Barrier(2), [None, None]

    def ask(i):
        start.wait()
        out[i] = programs.call("two-threads", _slow_square, (np.arange(3.0) + 0.25,),
                               lambda: jax.tree_util.tree_structure(0))

    threads = [threading.Thread(target=ask, args=(i,)) for i in range(2)]
    [t.start() for t in threads]
    [t.join(timeout=120) for t in threads]
    expected = (np.arange(3.0) + 0.25) ** 2 + 1.0
    for o in out:
        np.testing.assert_array_equal(np.asarray(o), expected)
    assert len(_SLOW_TRACES) == 1 and programs.counts()["traced"] == before + 1
    assert compiled.count("jit(stored_program)") == 1, compiled
