r"""The compiled batch function: one pure function ``values (B, P) -> outputs``, jitted once
per sweep structure.

A run has three phases, mapped over each device's rows inside ``jax.shard_map`` over a 1-D
mesh of the devices (batch axis ``"batch"``); the clearance runs side by side (``jax.vmap``) or
one after another (``jax.lax.map``, on CPU: :func:`one_by_one`), the other phases vmapped:

1. :func:`_clearance_run`: the mechanism with the row's parameters, integrated to
   :math:`t_{end} = N_{rev}\, 2\pi / |\omega|` with ``n_out`` output samples;
2. :func:`_ideal_run` (``ideal_reference``): the ideal-joint mechanism at the same speed on the
   same time grid, for the slider-acceleration deviation;
3. :func:`_finish`: the per-run metrics (:func:`jaxclear.analysis.metrics.run_metrics`), the
   statistics of the named channels (:func:`jaxclear.analysis.metrics.channel_metrics`), the
   Poincare section and, optionally, the time series.

The phases run in whatever order XLA schedules them: nothing in the compiled chunk calls LAPACK
(``tests/test_sweep.py::test_compiled_chunk_has_no_lapack_call`` checks the compiled HLO), so
the ordering and per-device caps once needed against jaxlib 0.10's batched-LAPACK thread-pool
deadlock are gone (measurements in ``jaxclear/sweep/__init__.py``).

:data:`TRACES` counts the traces of the per-run function (a Python side effect: traces, not
calls); read it as ``jaxclear.sweep.TRACES.value``.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from .. import params
from ..elements import journal_state
from ..model import Mechanism, crank_period
from ..analysis.channels import channel
from ..analysis.metrics import channel_metrics, run_metrics
from ..analysis.sections import at_samples
from ..integrate import Settings, jit, simulate
from .labels import channel_column, channel_key
from .lanes import lanes_one_by_one, on_devices, over_lanes  # noqa: F401 - the lane runner's names of before
from .plan import Plan, dynamic_settings

#: Metrics that stay defined for a failed run (counts and status); the others become NaN.
_COUNT_KEYS = ("status", "num_steps", "num_accepted_steps", "num_rejected_steps")
_DEVIATION_KEYS = ("peak_acc_deviation_m_s2", "rms_acc_deviation_m_s2")


class TraceCounter:
    """A counter read as ``.value`` (an object, so that the submodule that increments it and the
    users who read it through ``jaxclear.sweep`` share one number)."""

    def __init__(self):
        self.value = 0

    def increment(self):
        self.value += 1

    def __repr__(self):
        return f"TraceCounter(value={self.value})"


#: Number of times the per-run function has been traced (compiled) in this process: ``TRACES.value``.
TRACES = TraceCounter()


def _with_row(plan: Plan, mech: Mechanism, row) -> Mechanism:
    """``mech`` with the row's swept parameters (``row``: (P,) in ``plan.names`` order)."""
    return params.replace_many(mech, {n: row[i] for i, n in enumerate(plan.names)})


def run_settings(plan: Plan, m: Mechanism) -> Settings:
    """Integration settings of one run: the sweep's settings (``plan.settings``, whole: solver,
    tolerances, step limit, derivatives, onsets...) with what the sweep owns replaced:
    ``t_end = revolutions * 2 pi / |omega|`` [s] of the crank driver's (traced) speed ``omega``
    [rad/s] (:func:`~jaxclear.model.crank_period`), ``n_out``, ``t_start`` 0 and ``throw=False``
    (a failure is a status, not an error)."""
    t_end = crank_period(m, plan.revolutions)
    # a solver named keeps diffrax's stage loop: under vmap one copy of the vector field serves
    # every Runge-Kutta stage
    return dataclasses.replace(dynamic_settings(plan.settings), t_end=t_end, n_out=plan.n_out, throw=False)


_settings = run_settings  # the name of before (tests, benchmarks)


def _clearance_run(plan: Plan, mech: Mechanism, row):
    """Phase 1 of a run: the mechanism with this row's parameters, integrated."""
    TRACES.increment()  # a Python side effect: counts traces, not calls
    m = _with_row(plan, mech, row)
    return simulate(m, run_settings(plan, m))


def _ideal_run(plan: Plan, mech: Mechanism, ideal: Mechanism, row):
    """Phase 2: the ideal-joint mechanism with the row's parameters that apply to it (speed,
    masses...), same time grid. Returns (slider acceleration (T,) [m/s^2], status)."""
    m = _with_row(plan, mech, row)
    im = params.replace_many(ideal, {n: row[plan.names.index(n)] for n in plan.ideal_names})
    isol = simulate(im, run_settings(plan, m))
    return isol.coordinate(im, im.role("slider"), "x", derivative=2), isol.status


def _poincare(plan: Plan, m: Mechanism, sol):
    """Journal state ``[e_x, e_y, v_x, v_y]`` [m, m, m/s, m/s] of every clearance joint at the
    section samples: (n_section, n_joints, 4)."""
    k = len(m.clearance_joints)
    if not (k and len(plan.section)):
        return jnp.zeros((len(plan.section), k, 4), sol.ts.dtype)
    sub = at_samples(sol, jnp.asarray(plan.section, dtype=jnp.int32))
    return jax.vmap(lambda q, qd: journal_state(m, q, qd).reshape(k, 4))(sub.q, sub.qdot)


def _trajectories(plan: Plan, m: Mechanism, sol, ideal_acc) -> dict:
    """The stored time series of one run (``trajectories = true``), keys ``traj_*`` (a named
    channel's: ``traj_KEY``, :func:`~jaxclear.sweep.labels.channel_key`)."""
    out = {"traj_ts": sol.ts, "traj_ecc": sol.ecc, "traj_normal_force": sol.normal_force,
           "traj_penetration": sol.penetration, "traj_mode": sol.mode}
    slider = m.role("slider")
    if slider is not None:
        out["traj_slider_acc"] = sol.coordinate(m, slider, "x", derivative=2)
        if ideal_acc is not None:
            out["traj_ideal_slider_acc"] = ideal_acc
    out.update({f"traj_{channel_key(name)}": channel(m, sol, name) for name in plan.channels})
    return out


def _finish(plan: Plan, mech: Mechanism, row, sol, ideal_acc, ideal_status):
    """Phase 3: metrics (NaN for a failed run; deviation metrics NaN when the ideal run failed),
    Poincare points and optional time series of one run."""
    m = _with_row(plan, mech, row)
    met = run_metrics(m, sol, ideal_acc, plan.start)
    failed = sol.status != 0
    out = {}
    for key, value in met.items():
        if key not in _COUNT_KEYS:
            value = jnp.where(failed, jnp.nan, value)
            if ideal_status is not None and key in _DEVIATION_KEYS:
                value = jnp.where(ideal_status != 0, jnp.nan, value)
        out[key] = value
    for (name, stat), value in channel_metrics(m, sol, plan.channels, plan.start).items():
        out[channel_column(name, stat)] = jnp.where(failed, jnp.nan, value.astype(sol.ts.dtype))
    if ideal_status is not None:
        out["ideal_status"] = ideal_status
    out["t_end_s"] = sol.ts[-1]
    out["poincare"] = _poincare(plan, m, sol)
    if plan.trajectories:
        out.update(_trajectories(plan, m, sol, ideal_acc))
    return out


def run_outputs(plan: Plan, mech: Mechanism, ideal: Mechanism | None, row):
    """One run, unbatched: the three phases in order (what :func:`_runs` batches). Its outputs
    (metrics, Poincare points, time series) are a pure function of the parameter row ``(P,)``, so
    ``jax.jacfwd`` of it gives the metrics' derivatives through the engine's error-controlled
    sensitivities (the tolerance study's linearised estimate from derivatives)."""
    sol = _clearance_run(plan, mech, row)
    ideal_acc = ideal_status = None
    if ideal is not None:
        ideal_acc, ideal_status = _ideal_run(plan, mech, ideal, row)
    return _finish(plan, mech, row, sol, ideal_acc, ideal_status)


def one_by_one(plan: Plan) -> bool:
    """Whether a device integrates its runs one after another (``jax.lax.map``) rather than side
    by side (``jax.vmap``): ``not plan.side_by_side`` where that is set, else on CPU with
    single-kernel loops (``jaxclear/_xla_flags.py``). There the lanes of a ``vmap`` batch run
    one after another inside the loop's kernel anyway, and the batch runs until its slowest
    member is done. Measured 2026-11-26 (Intel Xeon, 2 cores, ``benchmarks/bench_sweep.py``, 32
    runs of one revolution): chunks of 16 runs 217 sims/s one after another against 130 side by
    side on one device, 423 against 217 on two. On accelerators ``vmap`` is what fills the
    device."""
    if plan.side_by_side is not None:
        return not plan.side_by_side
    return lanes_one_by_one(None if plan.mesh is None else plan.mesh.devices.flat[0].platform)


def _runs(plan: Plan, mech: Mechanism, ideal: Mechanism | None, rows):
    """A batch of runs (B, P) -> dict of (B, ...). The clearance runs go one after another or
    side by side (:func:`one_by_one`); the ideal runs and the metrics are vmapped over the batch
    (an ideal mechanism that no swept parameter changes is integrated once, unbatched: vmap
    leaves it unbatched)."""
    sol = over_lanes(lambda r: _clearance_run(plan, mech, r), rows, one_by_one=one_by_one(plan))
    ideal_acc = ideal_status = None
    if ideal is not None:
        ideal_acc, ideal_status = jax.vmap(lambda r: _ideal_run(plan, mech, ideal, r))(rows)
    return jax.vmap(lambda r, s, a, st: _finish(plan, mech, r, s, a, st))(rows, sol, ideal_acc, ideal_status)


@jit
def run_chunk(values, mech: Mechanism, ideal: Mechanism | None, plan: Plan):
    """``values`` (B, P) sharded over ``plan.mesh`` -> dict of (B, ...) outputs (the lane runner's
    :func:`~jaxclear.sweep.lanes.on_devices`)."""
    return on_devices(lambda rows, m, i: _runs(plan, m, i, rows), plan.mesh, values, mech, ideal)


def compiled_hlo(values, mech: Mechanism, ideal: Mechanism | None, plan: Plan) -> str:
    """Optimized HLO text of the chunk function compiled for these arguments (what XLA runs;
    e.g. to check which custom calls, such as LAPACK kernels, it contains)."""
    return run_chunk.lower(values, mech, ideal, plan).compile().compiled.as_text()
