"""The one checkpoint/journal protocol (jaxclear._checkpoint), the same tests for every
resumable driver: the sweep, the fit, the posterior's sampler, the design, wear (the tolerance
study resumes through its sweeps).

* ``test_rules``: no compilation. Each driver's own state code writes its state; then a changed
  configuration is refused (a ParameterError naming the folder and the changed entry), an
  unknown format is a CheckpointError, a truncated state is a CheckpointError naming the file
  and offering --restart, and a restart ignores the state.
* ``test_kill_and_resume``: each driver with tiny settings, interrupted (KeyboardInterrupt, as
  a Ctrl-C at a safe point or a kill between two writes leaves it) after its first piece of
  work; the same call resumes, computes no saved piece again (counted) and ends on the
  uninterrupted run's numbers; the same call on a locked folder is an OutputLockedError.
"""

from __future__ import annotations

import importlib
import json
import math
import os

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear import _checkpoint, sweep, wearing
from jaxclear._storage import locked_folder

DRIVERS = ("sweep", "fit", "posterior", "design", "wear")


# ---- the protocol itself --------------------------------------------------------------------


def test_changes_name_what_differs():
    old = {"a": 1, "b": {"c": 2.0, "d": "x"}, "e": [1, 2]}
    new = {"a": 1, "b": {"c": 3.0, "d": "x"}, "f": True}
    assert _checkpoint.changes(old, new) == ["b.c: 2.0 -> 3.0", "e: [1, 2] -> (none)", "f: (none) -> true"]
    assert _checkpoint.changes(old, old) == []


def test_journal_cuts_a_partial_last_line_and_refuses_a_damaged_one(tmp_path):
    work = _checkpoint.Work(tmp_path, "demo", "k", {"n": 1})
    assert work.open_journal("j.jsonl") == []
    work.append("j.jsonl", ['{"i": 0}', '{"i": 1}'])
    with open(tmp_path / "j.jsonl", "a") as f:
        f.write('{"i": 2')  # a kill while the line was written
    assert work.open_journal("j.jsonl") == [{"i": 0}, {"i": 1}]
    assert (tmp_path / "j.jsonl").read_text().endswith('{"i": 1}\n')
    text = (tmp_path / "j.jsonl").read_text().replace('{"i": 0}', '{"i": 0')
    (tmp_path / "j.jsonl").write_text(text)
    with pytest.raises(jc.CheckpointError, match=r"j\.jsonl is damaged \(line 2: .*--restart"):
        work.open_journal("j.jsonl")


# ---- per driver: its own state code ---------------------------------------------------------


def _sweep_cfg(out, restitution=(0.9, 0.7)):
    return sweep.SweepConfig(list={"clearance": [0.5e-3, 0.5e-3], "restitution": list(restitution)},
                             revolutions=0.5, transient_revolutions=0.0, chunk_size=1, out=str(out),
                             samples_per_revolution=40, progress=False)


class _State:
    """A driver's state written by its own code (``write``), read back with its rules
    (``read(config, restart)``), the file to damage and the changed entry a mismatch names."""

    def __init__(self, kind, tmp_path):
        self.kind, self.out = kind, tmp_path / kind

    def write(self):
        getattr(self, f"_write_{self.kind}")()

    def read(self, changed=False, restart=False):
        return getattr(self, f"_read_{self.kind}")(changed, restart)

    # sweep: the manifest is the header, runs.csv the journal
    def _write_sweep(self):
        cfg = _sweep_cfg(self.out)
        _, _, self.layout = sweep.driver._layout(cfg)
        sweep.store.prepare_output(cfg, str(self.out), False, self.layout)
        self.file, self.named = sweep.MANIFEST_NAME, "restitution"

    def _read_sweep(self, changed, restart):
        cfg = _sweep_cfg(self.out, (0.9, 0.5) if changed else (0.9, 0.7))
        return sweep.store.prepare_output(cfg, str(self.out), restart, self.layout)

    # fit: fit_checkpoint.json
    def _config(self, changed):
        return {"max_iter": 20 if changed else 10, "free": ["stiffness"]}

    def _write_fit(self):
        from jaxclear.fitting.state import Checkpoint, FitState

        Checkpoint(self.out, "k-fit", self._config(False)).save(FitState(iteration=3, theta=(1.0,)))
        self.file, self.named = "fit_checkpoint.json", "max_iter: 10 -> 20"

    def _read_fit(self, changed, restart):
        from jaxclear.fitting.state import Checkpoint

        ckpt = Checkpoint(self.out, "k-fit-2" if changed else "k-fit", self._config(changed))
        return None if restart else ckpt.resume()

    # posterior: posterior_checkpoint.npz
    def _write_posterior(self):
        from jaxclear.fitting.posterior import POSTERIOR_CHECKPOINT, _DRAW_FIELDS, FORMAT
        from jaxclear.fitting.sampler import StepSize

        work = _checkpoint.Work(self.out, "posterior", "k-post", {"seed": 0}, version=FORMAT)
        arrays = {f: np.zeros((2, 3)) for f in ("position", "grad", *_DRAW_FIELDS)}
        arrays.update(lp=np.zeros((2, 3)), logdensity=np.zeros(2), x=np.zeros((2, 3, 1)),
                      **{f: np.zeros(2) for f in StepSize._fields})
        work.write_npz(POSTERIOR_CHECKPOINT, arrays)
        self.file, self.named = POSTERIOR_CHECKPOINT, "seed: 0 -> 1"

    def _read_posterior(self, changed, restart):
        from jaxclear.fitting.posterior import FORMAT, _load

        work = _checkpoint.Work(self.out, "posterior", "k-post-2" if changed else "k-post",
                                {"seed": int(changed)}, version=FORMAT)
        return _load(work, not restart)

    # design: design_evaluations.jsonl
    def _write_design(self):
        from jaxclear.designing.journal import JOURNAL_NAME, Journal

        Journal(self.out, "k-design", config={"method": "L-BFGS-B"}).add([0.5], [1.0], [0], 0.1)
        self.file, self.named = JOURNAL_NAME, "method: \"L-BFGS-B\" -> \"SLSQP\""

    def _read_design(self, changed, restart):
        from jaxclear.designing.journal import Journal

        j = Journal(self.out, "k-design-2" if changed else "k-design", not restart,
                    config={"method": "SLSQP" if changed else "L-BFGS-B"})
        return j.loaded or None

    # wear: wear.json
    def _write_wear(self):
        from jaxclear.wearing.service import _write_state

        os.makedirs(self.out)
        record = {k: 1.0 for k in wearing.service.RECORD_KEYS} | {"depth_m": [0.0] * 8}
        _write_state(str(self.out), "k-wear", {"coefficient": 1e-14}, [record])
        self.file, self.named = "wear.json", "coefficient: 1e-14 -> 2e-14"

    def _read_wear(self, changed, restart):
        from jaxclear.wearing.service import _load_state, _work

        work = _work(str(self.out), "k-wear-2" if changed else "k-wear", {"coefficient": 2e-14 if changed else 1e-14})
        return _load_state(work, restart, 8) or None


@pytest.mark.parametrize("kind", DRIVERS)
def test_rules(kind, tmp_path):
    st = _State(kind, tmp_path)
    st.write()
    path = st.out / st.file
    assert st.read() is not None or kind == "sweep"  # the same configuration resumes (a sweep: no row yet)
    # a changed configuration is refused, naming the folder and what changed, and the way out
    with pytest.raises(jc.ParameterError, match="holds a different " + kind) as err:
        st.read(changed=True)
    assert str(st.out) in str(err.value) and st.named in str(err.value) and "--restart" in str(err.value)
    # nothing was discarded by the refusal
    assert st.read() is not None or kind == "sweep"
    # an unknown format: an error naming the file and both formats
    data = path.read_bytes()
    if kind == "posterior":
        with np.load(path) as f:
            arrays = {k: f[k] for k in f.files}
        head = json.loads(str(arrays["header"]))
        np.savez(path, **{**arrays, "header": np.asarray(json.dumps({**head, "format": 99}))})
    elif kind == "design":
        lines = data.decode().split("\n")
        path.write_text("\n".join([json.dumps({**json.loads(lines[0]), "format": 99})] + lines[1:]))
    elif kind == "sweep":
        path.write_text(json.dumps({**json.loads(data), "format_version": 99}))
    else:
        path.write_text(json.dumps({**json.loads(data), "format": 99}))
    with pytest.raises(jc.CheckpointError, match=rf"{st.file}.* format 99.*reads format 1.*--restart"):
        st.read()
    # a truncated state: an error naming the file, offering --restart
    path.write_bytes(data[: len(data) // 2] if kind != "design" else data[:10])
    with pytest.raises(jc.CheckpointError, match=rf"{st.file}.*--restart"):
        st.read()
    # a restart ignores it (and a driver's next save replaces it)
    assert st.read(restart=True) is None or kind == "sweep"


# ---- per driver: killed after the first piece of work, resumed --------------------------------


class _Gaussian(eqx.Module):
    """A density with the interface of the posterior's ``LogPosterior`` that the sampler uses."""

    x0: jax.Array
    chol: jax.Array

    def __call__(self, u):
        return -0.5 * jnp.sum((self.x0 + self.chol @ u) ** 2)


def _counting(monkeypatch, module, name, stop_at=None):
    """Count the calls of ``module.name`` (one piece of work each); the call ``stop_at`` raises
    KeyboardInterrupt before it starts (the pieces before it are saved)."""
    calls = []
    inner = getattr(module, name)

    def counted(*args, **kwargs):
        calls.append(1)
        if len(calls) == stop_at:
            raise KeyboardInterrupt
        return inner(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


def _posterior(out, monkeypatch, stop_at=None):
    post = importlib.import_module("jaxclear.fitting.posterior")  # (jaxclear.fitting.posterior is the function)

    s = dict(chains=2, chunk=10, draws=20, warmup=10, max_tree_depth=4, seed=1)
    key = _checkpoint.key({k: v for k, v in s.items() if k != "draws"})
    lp = _Gaussian(jnp.asarray([0.1, -0.2]), jnp.eye(2))
    calls = _counting(monkeypatch, post, "nuts_chunk", stop_at)
    try:
        run = post._sample(lp, s, key, out, True, False)
    finally:
        monkeypatch.undo()
    return run["x"], len(calls), 3  # 1 warm-up chunk + 2 chunks of draws


def _sweep(out, monkeypatch, stop_at=None):
    calls = _counting(monkeypatch, sweep.driver, "_compute", stop_at)
    try:
        res = sweep.run_sweep(_sweep_cfg(out))
    finally:
        monkeypatch.undo()
    return res.table["peak_contact_force_n"], len(calls), 2


FOUR_BAR = {"centroid_x:crank": (-0.3, 0.1), "centroid_x:rocker": (-0.4, 0.1)}


def _shaking(sol, mech):
    masses = jnp.stack([jnp.asarray(b.mass, dtype=float) for b in mech.bodies])
    acc = sol.qddot.reshape(sol.qddot.shape[0], -1, 3)[:, :, :2]
    return jnp.mean(jnp.sum(jnp.einsum("b,tbk->tk", masses, acc) ** 2, axis=1))


def _design(out, monkeypatch, stop_at=None):
    seen = []

    def stop(record):
        seen.append(record)
        if len(seen) == stop_at:
            raise KeyboardInterrupt

    # the programs of tests/test_design.py's balanced four-bar and of notebooks/design.ipynb's first
    # design (the same objective, variables and samples): one compilation for the three, through
    # the session's compilation cache
    res = jc.design(jc.preset("four-bar").ideal(), FOUR_BAR, _shaking, out=out, callback=stop, max_iter=4,
                    samples_per_revolution=64, check_chaos=False, plots=False, progress=False)
    computed = res.evaluations["values"] + res.evaluations["gradients"] - res.evaluations["replayed"]
    return res.history[-1]["objective"], computed, None


W_M, W_G, W_RB, W_RJ, W_L = 10.0, 9.81, 0.010, 0.0095, 0.010
W_OMEGA = 2 * math.pi * 100.0


def _wear(out, monkeypatch, stop_at=None):
    c = W_RB - W_RJ
    ring = jc.Body("ring", 1.0, 1e-4, {"c": (0.0, 0.0)})
    pin = jc.Body("pin", W_M, 1e-3, {"c": (0.0, 0.0)}, position=(0.0, -0.999 * c, 0.0))
    law = jc.HybridLaw(restitution=0.5, placement="fixed", n_elements=72, thickness=c)
    joint = jc.ClearanceJoint("ring", "c", "pin", "c", W_RB, W_RJ, length=W_L, law=law,
                              initial_offset=(0.0, -0.999 * c), name="ring-pin")
    mech = jc.Mechanism([ring, pin], [jc.Revolute(jc.GROUND, "o", "ring", "c")], [jc.AngleDriver("ring", W_OMEGA, 0.0)],
                        clearance_joints=[joint], gravity=(0.0, -W_G), ground_points={"o": (0.0, 0.0)}, name="rig")
    period = 2 * math.pi / W_OMEGA
    settings = jc.settings(0.6 * period, n_out=201, allow_free_dof=True)
    options = jc.WearOptions(coefficient=1e-14, updates=2, cycles_per_update=10.0, settle=0.1 * period, n_nodes=36,
                             harmonics=8)
    calls = _counting(monkeypatch, wearing.service, "_window", stop_at)
    try:
        h = jc.wear(mech, settings, options, out, progress=False)
    finally:
        monkeypatch.undo()
    return h.depth, len(calls), 2


def _fit(out, monkeypatch, stop_at=None):
    folder = out.parent
    mech = jc.preset("flores-slider-crank")
    path = folder / "record.csv"
    sensor = jc.Accelerometer(20e3)
    if not path.exists():
        jc.synthetic_record(mech, 1.2e-3, 200e3, sensor, snr_db=20, seed=7, path=path)
    seen = []

    def stop(record):
        seen.append(record)
        if len(seen) == stop_at:
            raise KeyboardInterrupt

    res = jc.fit(path, mech, start={"stiffness": 1.3e11, "restitution": 0.75}, sensor=sensor, window=1e-3, starts=1,
                 max_iter=6, out=out, progress=False, callback=stop)
    return np.asarray([res.estimates[k] for k in sorted(res.estimates)]), len(seen), None


def _locked_posterior(out):
    """:func:`jaxclear.posterior` as far as its lock (the density built around the fit replaced
    by the Gaussian: the lock is taken before the sampler starts)."""
    post = importlib.import_module("jaxclear.fitting.posterior")  # (jaxclear.fitting.posterior is the function)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(post, "_log_posterior", lambda *args: (_Gaussian(jnp.zeros(2), jnp.eye(2)),
                                                          {"problem_key": "p", "priors": {}}))
        jc.posterior(None, None, ("stiffness",), fit_result=object(), out=out, progress=False)


#: The pieces of work a run interrupted at the start of its second piece saved: one chunk, one
#: update; the design's journal lines; the fit's iterations (checkpointed before its callback).
SAVED = {"posterior": lambda out: 1, "sweep": lambda out: 1, "wear": lambda out: 1, "fit": lambda out: 2,
         "design": lambda out: len((out / "design_evaluations.jsonl").read_text().splitlines()) - 1}


RUNS = {"posterior": _posterior, "sweep": _sweep, "design": _design, "wear": _wear, "fit": _fit}
LOCKED = {"posterior": _locked_posterior, "sweep": lambda out: sweep.run_sweep(_sweep_cfg(out)),
          "design": lambda out: _design(out, None), "wear": lambda out: _wear(out, pytest.MonkeyPatch()),
          "fit": lambda out: _fit(out, pytest.MonkeyPatch())}


@pytest.mark.extended
@pytest.mark.parametrize("kind", [pytest.param(k, marks=pytest.mark.slow) if k == "fit" else k for k in DRIVERS])
def test_kill_and_resume(kind, tmp_path, monkeypatch):
    """Interrupted after its first piece of work, the same call resumes, does no saved piece again
    and ends on the uninterrupted run's numbers; a locked folder is refused at once. (The fit is
    slow: its model compiles for about a minute on 2 shared cores.)"""
    run = RUNS[kind]
    whole, n_whole, expected = run(tmp_path / "whole", monkeypatch)
    if expected is not None:
        assert n_whole == expected
    with pytest.raises(KeyboardInterrupt):
        run(tmp_path / "killed", monkeypatch, stop_at=2)  # the first piece done and saved
    saved = SAVED[kind](tmp_path / "killed")
    assert saved >= 1
    again, n_again, _ = run(tmp_path / "killed", monkeypatch)
    assert n_again == n_whole - saved, (n_again, n_whole, saved)  # no saved piece is done again
    np.testing.assert_array_equal(np.asarray(again), np.asarray(whole))  # bit for bit
    if kind in LOCKED:
        with locked_folder(tmp_path / "killed"):
            with pytest.raises(jc.OutputLockedError, match=str(tmp_path / "killed")):
                LOCKED[kind](tmp_path / "killed")
