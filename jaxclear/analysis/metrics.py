"""Scalar metrics of a simulation (the one place these formulas live).

:func:`run_metrics` is the one implementation: JAX-traceable, so sweeps ``jax.vmap`` and
``jax.jit`` it over a batch of solutions (one row per run). :func:`joint_metrics` gives the
same contact quantities per clearance joint; :func:`run_metrics` pools them over the joints.

:func:`summary` is derived from them: it converts their values of the whole run to plain
Python numbers (JSON-serializable) and adds only labels, sizes, the status message and the
wall time; the command line writes it to ``summary.json`` and prints it. Quantities that do
not apply to a mechanism (contact quantities without a clearance joint, slider quantities
without a slider) are ``None``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._errors import STATUS
from .._numbers import as_typed
from ..integrate import Solution
from ..integrate import jit
from ..model import Mechanism, crank_driver
from .channels import channel

#: Keys of :func:`summary`, in output order, with their units (``-`` for dimensionless).
SUMMARY_KEYS: dict[str, str] = {
    "mechanism": "-",
    "t_end_s": "s",
    "n_samples": "-",
    "clearance_joints": "-",
    "peak_contact_force_n": "N",
    "peak_contact_force_per_joint_n": "N",
    "peak_friction_force_n": "N",
    "max_penetration_m": "m",
    "max_penetration_per_joint_m": "m",
    "impacts": "-",
    "impacts_per_joint": "-",
    "peak_slider_acc_m_s2": "m/s^2",
    "max_constraint_drift": "m or rad",
    "fraction_free_flight": "-",
    "fraction_impact": "-",
    "fraction_continuous_contact": "-",
    "energy_dissipated_j": "J",
    "num_steps": "-",
    "num_accepted_steps": "-",
    "num_rejected_steps": "-",
    "status": "-",
    "status_message": "-",
    "wall_time_s": "s",
}

#: Keys of :func:`run_metrics`, in output order, with their units. Contact keys appear only for
#: a mechanism with clearance joints, slider keys only with a ``slider`` role, the
#: acceleration-deviation keys only when the ideal-joint acceleration is given, the per-revolution
#: energy only with a crank (:func:`jaxclear.model.crank_driver`).
RUN_METRIC_KEYS: dict[str, str] = {
    "peak_contact_force_n": "N",
    "rms_contact_force_n": "N",
    "max_penetration_m": "m",
    "impacts": "-",
    "fraction_free_flight": "-",
    "fraction_impact": "-",
    "fraction_continuous_contact": "-",
    "energy_dissipated_j": "J",
    "energy_dissipated_per_rev_j": "J",
    "peak_slider_acc_m_s2": "m/s^2",
    "peak_acc_deviation_m_s2": "m/s^2",
    "rms_acc_deviation_m_s2": "m/s^2",
    "max_constraint_drift": "m or rad",
    "num_steps": "-",
    "num_accepted_steps": "-",
    "num_rejected_steps": "-",
    "status": "-",
}

#: Keys of :func:`joint_metrics` (arrays of shape ``(n_clearance_joints,)``), with their units.
JOINT_METRIC_KEYS: dict[str, str] = {
    "peak_contact_force_n": "N",
    "peak_friction_force_n": "N",
    "max_penetration_m": "m",
    "impacts": "-",
    "energy_dissipated_j": "J",
}

_MODES = (("fraction_free_flight", 0), ("fraction_impact", 1), ("fraction_continuous_contact", 2))


# --------------------------------------------------------------------------------------
# JAX-traceable metrics (sweeps: vmapped over runs, one row per run)
# --------------------------------------------------------------------------------------


def _window_peak(samples, running, start: int):
    """Largest value per joint (k,) over the window ``[start:]`` of a quantity known at the
    samples (T', k) and as a running maximum over accepted solver steps (T, k): if the running
    maximum grew inside the window, its final value was reached inside the window (to within the
    solver step that contains sample ``start``); otherwise only the samples are known."""
    grew = running[-1] > running[start]
    step_peak = jnp.where(grew, running[-1], -jnp.inf)
    return jnp.maximum(jnp.max(samples, axis=0), step_peak)


def joint_metrics(mech: Mechanism, sol: Solution, start: int = 0) -> dict:
    """Contact metrics per clearance joint over the window ``sol.ts[start:]`` (``start``
    static), as JAX arrays of shape ``(k,)`` (traceable); ``{}`` without clearance joints.
    Keys and units: :data:`JOINT_METRIC_KEYS`.

    * ``peak_contact_force_n``, ``max_penetration_m``: largest normal force / penetration in the
      window over the samples and the running peaks of every accepted solver step
      (``memory.peak_force``, ``memory.peak_penetration``; see :func:`_window_peak`); penetration
      floored at 0 (never touched: 0).
    * ``peak_friction_force_n``: largest ``|F_T|`` over the window's samples.
    * ``impacts``: contact onsets inside the window (``memory.impacts`` at the end minus at
      sample ``start``; counted at every solver step, so exact even for impacts shorter than the
      output spacing).
    * ``energy_dissipated_j``: minus the contact work over the window (``memory.work`` at the
      end minus at sample ``start``) [J]; if the window ends during a contact, this includes the
      elastic energy then stored in it.
    """
    if not mech.clearance_joints:
        return {}
    mem = sol.memory
    return {
        "peak_contact_force_n": _window_peak(sol.normal_force[start:], mem.peak_force, start),
        "peak_friction_force_n": jnp.max(jnp.abs(sol.friction_force[start:]), axis=0),
        "max_penetration_m": jnp.maximum(_window_peak(sol.penetration[start:], mem.peak_penetration, start), 0.0),
        "impacts": mem.impacts[-1] - mem.impacts[start],
        "energy_dissipated_j": -(mem.work[-1] - mem.work[start]),
    }


#: Statistics of a named output channel over the metrics window, in column order: smallest,
#: largest, mean and root mean square of the window's samples (:func:`channel_metrics`).
_CHANNEL_STATS = {"min": jnp.min, "max": jnp.max, "mean": jnp.mean,
                  "rms": lambda x: jnp.sqrt(jnp.mean(jnp.square(x.astype(float))))}
CHANNEL_STATS = tuple(_CHANNEL_STATS)


def channel_metrics(mech: Mechanism, sol: Solution, names, start: int = 0) -> dict:
    """:data:`CHANNEL_STATS` of each named output channel (:mod:`jaxclear.analysis.channels`,
    e.g. ``joint:0:min_film_thickness``, ``joint:0:rear_lower_normal_force``) over the window's
    samples ``sol.ts[start:]`` (``start`` static): ``{(name, stat): scalar}``, traceable (sweeps
    vmap it over runs), in the channel's unit. Statistics of the samples only: a peak between two
    samples is not seen (unlike ``peak_contact_force_n``, which reads the solver steps' running
    peak); the mean and RMS weight the samples equally (a uniform output grid: time averages)."""
    out = {}
    for name in names:
        x = channel(mech, sol, name)[start:]
        out.update({(name, stat): f(x) for stat, f in _CHANNEL_STATS.items()})
    return out


def _mode_fractions(sol: Solution, start: int = 0) -> dict:
    """Shares of the window's samples (x joints) in each contact mode (``Solution.mode``): the
    integer count divided by the number of entries (correctly rounded)."""
    mode = sol.mode[start:]
    return {key: jnp.count_nonzero(mode == m).astype(sol.ts.dtype) / mode.size for key, m in _MODES}


def _slider_acc(mech: Mechanism, sol: Solution, start: int = 0):
    """Slider ``x''`` [m/s^2] over the window, or None without a ``slider`` role."""
    slider = mech.role("slider")
    if slider is None:
        return None
    return sol.coordinate(mech, slider, "x", derivative=2)[start:]


def run_metrics(mech: Mechanism, sol: Solution, ideal_acc=None, start: int = 0) -> dict:
    """Scalar metrics of one run as JAX arrays (traceable: ``jax.vmap`` it over a batch of
    solutions). Keys and units: :data:`RUN_METRIC_KEYS`.

    The *window* is the output samples ``sol.ts[start:]`` (``start`` static, e.g. the first
    sample after a transient); ``start = 0`` is the whole run. Several clearance joints are
    pooled (maxima over joints, sums of impacts and energies, fractions over joints x samples).

    * ``peak_contact_force_n``, ``max_penetration_m``, ``impacts``, ``energy_dissipated_j``:
      :func:`joint_metrics` pooled over the joints.
    * ``rms_contact_force_n``: root mean square of the normal force over the window's samples
      (free flight counts as 0).
    * ``fraction_*``: share of the window's samples (x joints) in free flight, impact (contact
      shorter than ``Settings.continuous_contact_after``) and continuous contact
      (``Solution.mode`` 0, 1, 2).
    * ``energy_dissipated_per_rev_j``: the dissipated energy divided by the crank revolutions in
      the window, ``(ts[-1] - ts[start]) |omega| / 2 pi`` of the crank driver.
    * ``peak_slider_acc_m_s2``: largest ``|x''|`` of the slider in the window;
      ``peak_acc_deviation_m_s2``, ``rms_acc_deviation_m_s2``: peak and RMS over the window of
      ``x'' - x''_ideal``, with ``ideal_acc`` (T,) the slider acceleration of the ideal-joint
      mechanism sampled on the same grid ``sol.ts`` (e.g. ``ideal.coordinate(ideal_mech,
      "slider", "x", 2)``).
    * ``max_constraint_drift``: largest ``|Phi|`` over all samples (mixed units: m for position
      constraints, rad for angles); solver step counts; ``status`` (0 ok, see
      :data:`jaxclear.STATUS`).
    """
    out: dict = {}
    ts = sol.ts
    per_joint = joint_metrics(mech, sol, start)
    if per_joint:
        out["peak_contact_force_n"] = jnp.max(per_joint["peak_contact_force_n"])
        out["rms_contact_force_n"] = jnp.sqrt(jnp.mean(sol.normal_force[start:] ** 2))
        out["max_penetration_m"] = jnp.max(per_joint["max_penetration_m"])
        out["impacts"] = jnp.sum(per_joint["impacts"])
        out.update(_mode_fractions(sol, start))
        out["energy_dissipated_j"] = dissipated = jnp.sum(per_joint["energy_dissipated_j"])
        crank = crank_driver(mech)
        if crank is not None:
            revs = (ts[-1] - ts[start]) * jnp.abs(crank[1].speed) / (2.0 * jnp.pi)
            out["energy_dissipated_per_rev_j"] = dissipated / revs
    acc = _slider_acc(mech, sol, start)
    if acc is not None:
        out["peak_slider_acc_m_s2"] = jnp.max(jnp.abs(acc))
        if ideal_acc is not None:
            dev = acc - ideal_acc[start:]
            out["peak_acc_deviation_m_s2"] = jnp.max(jnp.abs(dev))
            out["rms_acc_deviation_m_s2"] = jnp.sqrt(jnp.mean(dev**2))
    out["max_constraint_drift"] = jnp.max(sol.drift) if sol.drift.size else jnp.zeros((), ts.dtype)
    out["num_steps"] = sol.num_steps
    out["num_accepted_steps"] = sol.num_accepted_steps
    out["num_rejected_steps"] = sol.num_rejected_steps
    out["status"] = sol.status
    return {key: out[key] for key in RUN_METRIC_KEYS if key in out}


# --------------------------------------------------------------------------------------
# Plain-Python views of the metrics (command line, summary.json)
# --------------------------------------------------------------------------------------


def _float(x) -> float:
    return float(np.asarray(x))


def _count(x) -> int:
    """A counter (float array of whole numbers) as an int."""
    return int(round(_float(x)))


def peak_slider_acceleration(mech: Mechanism, sol: Solution) -> float | None:
    """Largest ``|x''|`` of the slider body [m/s^2] over the samples, or None without a slider
    (``peak_slider_acc_m_s2`` of :func:`run_metrics`)."""
    acc = _slider_acc(mech, sol)
    return None if acc is None else _float(np.max(np.abs(np.asarray(acc))))


def mode_fractions(sol: Solution) -> tuple[float, float, float] | None:
    """Fractions of samples (over all joints and times) in free flight, impact and continuous
    contact (``Solution.mode`` 0, 1, 2; the ``fraction_*`` of :func:`run_metrics`); None without
    clearance joints."""
    if np.asarray(sol.mode).size == 0:
        return None
    fractions = _mode_fractions(sol)
    return tuple(_float(fractions[key]) for key, _ in _MODES)  # type: ignore[return-value]


@jit
def _metrics_program(mech: Mechanism, sol: Solution) -> tuple[dict, dict]:
    """:func:`run_metrics` and :func:`joint_metrics` over the whole run as one compiled program
    (op by op they were some forty small programs, each compiled in a new process)."""
    return run_metrics(mech, sol), joint_metrics(mech, sol)


def summary(mech: Mechanism, sol: Solution, wall_time_s: float | None = None) -> dict:
    """Scalar results of one simulation as plain Python values (see :data:`SUMMARY_KEYS`):
    :func:`run_metrics` and :func:`joint_metrics` over the whole run (``start = 0``; see them
    for the definitions) converted to floats and ints, plus

    * ``mechanism``, ``clearance_joints`` (names), ``t_end_s`` (last sample time [s]),
      ``n_samples``;
    * ``*_per_joint*``: the per-joint values of :func:`joint_metrics` (lists, ``[]`` without
      clearance joints) and ``peak_friction_force_n``, the largest ``|F_T|`` over them [N];
    * ``status_message``: the text of ``status`` in :data:`jaxclear.STATUS`;
    * ``wall_time_s``: as given (the command line includes JIT compilation).
    """
    m, per_joint = _metrics_program(mech, sol)
    per_joint = {key: np.asarray(v, dtype=float) for key, v in per_joint.items()}
    contact = bool(per_joint)
    status = int(np.asarray(m["status"]))
    ts = np.asarray(sol.ts, dtype=float)
    out: dict = {
        "mechanism": mech.name,
        "t_end_s": as_typed(float(ts[-1])),  # the end the user asked for (3 revolutions: 0.036, not ...04)
        "n_samples": int(ts.shape[0]),
        "clearance_joints": [c.name for c in mech.clearance_joints],
        "peak_contact_force_per_joint_n": [float(v) for v in per_joint.get("peak_contact_force_n", [])],
        "peak_friction_force_n": float(np.max(per_joint["peak_friction_force_n"])) if contact else None,
        "max_penetration_per_joint_m": [float(v) for v in per_joint.get("max_penetration_m", [])],
        "impacts_per_joint": [_count(v) for v in per_joint.get("impacts", [])],
        "status_message": STATUS.get(status, f"unknown status {status}"),
        "wall_time_s": None if wall_time_s is None else float(wall_time_s),
    }
    for key in ("peak_contact_force_n", "max_penetration_m", "energy_dissipated_j", "peak_slider_acc_m_s2",
                "max_constraint_drift", "fraction_free_flight", "fraction_impact", "fraction_continuous_contact"):
        out[key] = _float(m[key]) if key in m else None
    for key in ("impacts", "num_steps", "num_accepted_steps", "num_rejected_steps"):
        out[key] = _count(m[key]) if key in m else None
    out["status"] = status
    return {key: out[key] for key in SUMMARY_KEYS}


__all__ = [
    "summary", "SUMMARY_KEYS", "peak_slider_acceleration", "mode_fractions", "run_metrics", "RUN_METRIC_KEYS",
    "joint_metrics", "JOINT_METRIC_KEYS",
]
