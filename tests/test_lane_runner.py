"""The one lane runner (jaxclear.sweep.lanes, issue 40 item 3) and the one way to start a run
from a state (Mechanism.started).

* the lanes one after another (``jax.lax.map``) and side by side (``jax.vmap``) give the same
  numbers, and so do chunked and unchunked runs (the last chunk padded);
* ``lyapunov_map(out=...)``, killed after its first chunk (KeyboardInterrupt, as a kill between
  two writes leaves it), resumes: the same call computes only the chunks not on disk (counted)
  and ends on the uninterrupted map's numbers, bit for bit; a locked folder and a folder of
  another map are refused;
* ``Mechanism.started`` under jit, vmap and grad, equal to the two paths it replaces (the fit
  window's and the design ensemble's, written out here as they were).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.model import crank_driver
from jaxclear.sweep import lanes
from jaxclear.sweep.devices import make_mesh
from jaxclear._storage import locked_folder


# ---- map or vmap, chunks ----------------------------------------------------------------------


def _steps(x, y):
    """A lane whose loop runs its own number of steps (Newton's square root of x, from y)."""
    def body(c):
        z, k = c
        return 0.5 * (z + x / z), k + 1

    z, k = jax.lax.while_loop(lambda c: jnp.abs(c[0] * c[0] - x) > 1e-12 * x, body, (y, 0))
    return {"root": z, "steps": k}


X = np.array([2.0, 9.0, 1e4, 0.3, 7.0])
Y = np.array([1.0, 1.0, 1.0, 3.0, 0.5])


def test_map_and_vmap_give_the_same_lanes():
    by_map = jax.jit(lambda x, y: lanes.over_lanes(_steps, x, y, one_by_one=True))(X, Y)
    side = jax.jit(lambda x, y: lanes.over_lanes(_steps, x, y, one_by_one=False))(X, Y)
    batched = jax.jit(lambda x, y: lanes.over_lanes(_steps, x, y, batch_size=2))(X, Y)
    rule = jax.jit(lambda x, y: lanes.over_lanes(_steps, x, y))(X, Y)
    for other in (side, batched, rule):
        for k in by_map:
            assert np.array_equal(np.asarray(by_map[k]), np.asarray(other[k]))
    assert len(set(np.asarray(by_map["steps"]).tolist())) > 1  # the lanes took different numbers of steps
    np.testing.assert_allclose(np.asarray(by_map["root"]), np.sqrt(X), rtol=1e-12)


def test_rule_is_one_by_one_on_cpu_with_single_kernel_loops():
    from jaxclear._xla_flags import loop_kernels_active

    assert lanes.lanes_one_by_one("cpu") == loop_kernels_active()
    assert not lanes.lanes_one_by_one("gpu")
    from jaxclear.sweep import batch

    assert batch.over_lanes is lanes.over_lanes and batch.lanes_one_by_one is lanes.lanes_one_by_one


def _simulated(rows, mech, one_by_one=None):
    """A chunk of runs of ``mech`` at the clearances ``rows`` (B, 1): the lane runner's rule inside
    its devices (or ``one_by_one`` as given)."""
    def one(row):
        m = jc.params.replace(mech, "clearance", row[0])
        sol = jc.simulate(m, jc.settings(2e-3, n_out=5, rtol=1e-6, atol=1e-9, throw=False))
        return {"ecc": sol.ecc, "q": sol.q, "status": sol.status}

    return lanes.over_lanes(one, rows, one_by_one=one_by_one)


@pytest.fixture(scope="module")
def slider_crank():
    return jc.preset("flores-slider-crank")


@pytest.mark.extended
def test_chunked_equals_unchunked(slider_crank):
    """Five runs at once and in chunks of two (the last one padded by repeating its last run):
    the same bits; map and vmap of the same runs agree to rounding."""
    mesh = make_mesh()
    values = np.array([[0.5e-3], [0.4e-3], [0.3e-3], [0.6e-3], [0.45e-3]])
    compiled = eqx.filter_jit(lambda rows, m: lanes.on_devices(_simulated, mesh, rows, m))
    whole = lanes.run_lanes(compiled, values, slider_crank, chunk=None, mesh=mesh)
    chunked = lanes.run_lanes(compiled, values, slider_crank, chunk=2, mesh=mesh)
    assert whole["ecc"].shape[0] == 5 and not np.any(whole["status"])
    for k in whole:
        assert np.array_equal(whole[k], chunked[k])
    assert lanes.chunks_todo(5, 2, {0, 1, 3}) == [1, 2]
    lo, hi, rows = lanes.padded_chunk(values, 2, 2)
    assert (lo, hi) == (4, 5) and np.array_equal(rows, values[[4, 4]])
    # the engine's runs one after another and side by side: the same runs to the integration's
    # error, not bit for bit (XLA:CPU vectorises the side-by-side lanes' arithmetic, which rounds
    # differently, and a step decided near the error threshold then differs, which the impacts
    # amplify: measured up to 8.9e-8 m in the eccentricity (1.8e-4 of the clearance), 1.7e-7 in q)
    side = jax.tree_util.tree_map(np.asarray, eqx.filter_jit(
        lambda rows, m: _simulated(rows, m, one_by_one=False))(values, slider_crank))
    clearance = float(slider_crank.clearance_joints[0].clearance)
    assert np.array_equal(side["status"], whole["status"])
    np.testing.assert_allclose(side["ecc"], whole["ecc"], rtol=0, atol=1e-3 * clearance)
    np.testing.assert_allclose(side["q"], whole["q"], rtol=0, atol=1e-5)


# ---- lyapunov_map: chunks, a folder written as it goes, resume --------------------------------


MAP = dict(revolutions=4, count=1, samples=2, channels=["joint:0:ecc_x"])
SPEEDS = [[2000.0], [2500.0], [3000.0]]


def _map(mech, **kw):
    return jc.lyapunov_map(mech, jc.settings(1.0, rtol=1e-4, atol=1e-7), ["speed_rpm"], SPEEDS, **MAP, **kw)


def _fields(mp):
    return {k: np.asarray(getattr(mp, k)) for k in ("values", "exponents", "spread", "stderr", "status",
                                                    "run_status", "sections", "running")}


def _counting(monkeypatch, stop_at=None):
    """Count the chunks the lane runner computes; the call ``stop_at[0]`` raises
    KeyboardInterrupt before it starts (the chunks before it are on disk)."""
    calls, inner = [], lanes.compute_chunk

    def counted(*args, **kwargs):
        calls.append(1)
        if len(calls) == stop_at[0]:
            raise KeyboardInterrupt
        return inner(*args, **kwargs)

    monkeypatch.setattr(lanes, "compute_chunk", counted)
    return calls


@pytest.mark.extended
def test_lyapunov_map_resumes_after_a_kill(slider_crank, tmp_path, monkeypatch):
    # uninterrupted, nothing written, in the chunks of the resumed map: one compiled program for
    # the three maps (that the chunks do not change the rows: test_chunked_equals_unchunked)
    whole = _fields(_map(slider_crank, chunk=1))
    assert not np.any(whole["status"]) and np.all(np.isfinite(whole["exponents"]))
    out = tmp_path / "map"
    stop_at = [2]
    calls = _counting(monkeypatch, stop_at)
    with pytest.raises(KeyboardInterrupt):
        _map(slider_crank, chunk=1, out=out)
    stop_at[0] = None
    assert sorted(p.name for p in (out / "chunks").iterdir()) == ["chunk_000000.npz"]
    assert not (out / "lyapunov_map.npz").exists()
    calls.clear()
    resumed = _fields(_map(slider_crank, chunk=1, out=out))
    assert len(calls) == 2  # the chunk on disk is not computed again
    for k in whole:
        assert np.array_equal(whole[k], resumed[k]), k
    calls.clear()
    again = _fields(_map(slider_crank, chunk=1, out=out))  # finished: read back, nothing computed
    assert len(calls) == 0
    for k in whole:
        assert np.array_equal(whole[k], again[k]), k
    monkeypatch.undo()

    # a locked folder is refused at once; so is a folder holding another map, unless restart
    with locked_folder(out):
        with pytest.raises(jc.OutputLockedError, match=str(out)):
            _map(slider_crank, chunk=1, out=out)
    with pytest.raises(jc.ParameterError, match=r"lyapunov_map output folder .*changed: .*chunk: 1 -> 2"):
        _map(slider_crank, chunk=2, out=out)
    with pytest.raises(jc.ParameterError, match=r"chunk = 0 is outside the allowed range"):
        _map(slider_crank, chunk=0)


# ---- one way to start a run from a state ------------------------------------------------------


def _window_start_of_before(mech, driver, t_start, guess_q, guess_qd, elements):
    """fitting/window.py's WindowModel.mechanism before Mechanism.started."""
    if driver is not None:
        crank = mech.drivers[driver]
        mech = eqx.tree_at(lambda m: m.drivers[driver].angle0, mech, crank.angle0 + crank.speed * t_start)
    n_b = len(mech.bodies)
    mech = eqx.tree_at(lambda m: [b.position for b in m.bodies], mech, [guess_q[3 * i: 3 * i + 3] for i in range(n_b)])
    mech = eqx.tree_at(lambda m: [b.velocity for b in m.bodies], mech, [guess_qd[3 * i: 3 * i + 3] for i in range(n_b)])
    if elements:
        mech = eqx.tree_at(lambda m: list(m.clearance_joints), mech, elements)
    return mech


def _design_start_of_before(m, shift, offset, guess_q, guess_qd):
    """designing/problem.py's _start before Mechanism.started."""
    i, crank = crank_driver(m)
    m = eqx.tree_at(lambda mm: mm.drivers[i].angle0, m, crank.angle0 + shift)
    for b in range(len(m.bodies)):
        m = eqx.tree_at(lambda mm: (mm.bodies[b].position, mm.bodies[b].velocity), m,
                        (guess_q[3 * b: 3 * b + 3], guess_qd[3 * b: 3 * b + 3]))
    for j, joint in enumerate(m.clearance_joints):
        m = eqx.tree_at(lambda mm: mm.clearance_joints[j], m, joint.started_within(offset))
    return m


def _same(a, b):
    la, ta = jax.tree_util.tree_flatten(eqx.filter(a, eqx.is_array))
    lb, tb = jax.tree_util.tree_flatten(eqx.filter(b, eqx.is_array))
    return ta == tb and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(la, lb))


def test_started_equals_the_window_and_design_paths(slider_crank):
    mech = slider_crank
    i, crank = crank_driver(mech)
    q, qd = mech.guess()
    q, qd = q + 0.01 * jnp.arange(q.shape[0]), qd - 0.5
    joint = mech.clearance_joints[0]
    elements = [joint.with_start(jnp.asarray([1e-4, -2e-4]), jnp.asarray([0.01, 0.02]))]
    t_start = 0.0123
    old = _window_start_of_before(mech, i, t_start, q, qd, elements)
    new = mech.started(angle0=crank.angle0 + crank.speed * t_start, q=q, qdot=qd).started(elements=elements)
    assert _same(old, new)
    assert _same(_window_start_of_before(mech, None, t_start, q, qd, []), mech.started(q=q, qdot=qd, elements=[]))
    offset = jnp.asarray([0.3, -0.4])
    old = _design_start_of_before(mech, 0.7, offset, q, qd)
    new = mech.started(angle0=crank.angle0 + 0.7, q=q, qdot=qd, within=offset)
    assert _same(old, new)
    assert float(new.drivers[i].angle0) == pytest.approx(float(crank.angle0) + 0.7)
    with pytest.raises(jc.MechanismError, match="force element"):
        mech.started(elements=elements * 2)


def test_started_is_traceable(slider_crank):
    mech = slider_crank
    q, qd = mech.guess()
    i = crank_driver(mech)[0]

    def moved(angle, offset):
        m = mech.started(angle0=angle, q=q, qdot=qd, within=offset)
        return m.drivers[i].angle0 + jnp.sum(m.clearance_joints[0].initial_offset)

    eager = moved(0.5, jnp.asarray([0.2, 0.1]))
    assert float(jax.jit(moved)(0.5, jnp.asarray([0.2, 0.1]))) == float(eager)
    angles = jnp.asarray([0.0, 0.5, 1.0])
    batch = jax.vmap(moved, in_axes=(0, None))(angles, jnp.asarray([0.2, 0.1]))
    assert np.allclose(np.asarray(batch) - np.asarray(angles), float(eager) - 0.5)
    g_angle, g_offset = jax.grad(moved, argnums=(0, 1))(0.5, jnp.asarray([0.2, 0.1]))
    assert float(g_angle) == 1.0
    clearance = float(mech.clearance_joints[0].clearance)
    np.testing.assert_allclose(np.asarray(g_offset), clearance, rtol=1e-15)


def test_host_rows_splits_over_threads_and_keeps_the_order(monkeypatch):
    """:func:`~jaxclear.sweep.lanes.host_rows`: the rows split into one part per thread (one
    shape: the last part padded), each through the function on its own thread, the outputs in
    the rows' order and the padding dropped; the same numbers as one call, for a compiled lanes
    function too (its lanes are independent); ``JAXCLEAR_HOST_THREADS`` sets the threads."""
    import threading

    import jax.numpy as jnp

    from jaxclear.sweep.lanes import host_map, host_rows, host_threads

    monkeypatch.setenv("JAXCLEAR_HOST_THREADS", "3")
    assert host_threads() == 3
    seen = []

    def f(rows):
        seen.append((rows.shape, threading.get_ident()))
        return rows[:, 0] * 2.0

    rows = np.arange(50.0).reshape(25, 2)
    np.testing.assert_array_equal(host_rows(f, rows), rows[:, 0] * 2.0)
    assert sorted(s for s, _ in seen) == [(9, 2)] * 3  # 25 rows: parts of 9, the last padded
    seen.clear()
    np.testing.assert_array_equal(host_rows(f, rows[:10]), rows[:10, 0] * 2.0)
    assert [s for s, _ in seen] == [(10, 2)]  # under 8 rows a part: one call
    square = jax.jit(lambda r: jnp.sin(r) ** 2)
    rows = np.linspace(0.0, 3.0, 64)
    # an elementwise kernel may take a vector path for one length and a scalar one for another:
    # within rounding, not bit for bit (the way in's lanes, jax.lax.map, run one scalar path)
    np.testing.assert_allclose(host_rows(square, rows), np.asarray(square(rows)), rtol=0, atol=1e-15)
    assert host_map(lambda x: x * x, range(7)) == [x * x for x in range(7)]
    monkeypatch.setenv("JAXCLEAR_HOST_THREADS", "1")
    assert host_threads() == 1 and host_map(str, [1, 2]) == ["1", "2"]
    monkeypatch.setenv("JAXCLEAR_HOST_THREADS", "0")
    with pytest.raises(ValueError, match="JAXCLEAR_HOST_THREADS = '0' must be an integer >= 1"):
        host_threads()


def test_ahead_runs_on_a_thread_of_its_own_and_keeps_an_error(monkeypatch):
    """:func:`~jaxclear.sweep.lanes.ahead`: the call runs on another thread (a daemon, so an
    interrupted caller does not wait for it), its result or its exception kept in the future it
    returns; with one host thread nothing runs ahead (None)."""
    import threading

    from jaxclear.sweep.lanes import ahead

    monkeypatch.setenv("JAXCLEAR_HOST_THREADS", "2")
    where = []
    done = ahead(lambda x: where.append(threading.current_thread()) or x + 1, 41)
    assert done.result(timeout=60) == 42
    assert where[0] is not threading.main_thread() and where[0].daemon
    failed = ahead(lambda: 1 / 0)
    assert isinstance(failed.exception(timeout=60), ZeroDivisionError)
    monkeypatch.setenv("JAXCLEAR_HOST_THREADS", "1")
    assert ahead(lambda: where.append("ran")) is None and where[-1] != "ran"
