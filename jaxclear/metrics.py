"""Scalar summaries of a simulation (the one place these formulas live).

:func:`summary` turns a :class:`~jaxclear.solve.Solution` into a flat dictionary of plain
Python numbers (JSON-serializable) that the command line writes to ``summary.json`` and
prints, and that sweeps and reports can tabulate. Quantities that do not apply to a
mechanism (contact quantities without a clearance joint, slider quantities without a slider)
are ``None``.
"""

from __future__ import annotations

import numpy as np

from .model import Mechanism
from ._errors import STATUS
from .integrate import Solution

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


def _np(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _float(x) -> float:
    return float(np.asarray(x))


def peak_slider_acceleration(mech: Mechanism, sol: Solution) -> float | None:
    """Largest ``|x''|`` of the slider body [m/s^2] over the samples, or None without a slider."""
    slider = mech.role("slider")
    if slider is None:
        return None
    acc = _np(sol.coordinate(mech, slider, "x", derivative=2))
    return _float(np.max(np.abs(acc)))


def mode_fractions(sol: Solution) -> tuple[float, float, float] | None:
    """Fractions of samples (over all joints and times) in free flight, impact and continuous
    contact (``Solution.mode`` 0, 1, 2); None without clearance joints."""
    mode = np.asarray(sol.mode)
    if mode.size == 0:
        return None
    n = mode.size
    return tuple(float(np.count_nonzero(mode == m)) / n for m in (0, 1, 2))  # type: ignore[return-value]


def summary(mech: Mechanism, sol: Solution, wall_time_s: float | None = None) -> dict:
    """Scalar results of one simulation as plain Python values (see :data:`SUMMARY_KEYS`).

    * ``peak_contact_force_n``: largest normal contact force over the samples and every accepted
      solver step's end (``memory.peak_force``), over the joints [N];
      ``peak_friction_force_n``: largest ``|F_T|`` [N].
    * ``max_penetration_m``: largest penetration ``e - c`` over the samples and solver steps [m], 0 if the
      journal never touched its bearing at a sample.
    * ``impacts``: number of contact onsets over the run (counted at every solver step, so
      exact even for impacts shorter than the output spacing), total and per joint.
    * ``peak_slider_acc_m_s2``: largest ``|x''|`` of the slider [m/s^2].
    * ``max_constraint_drift``: largest ``|Phi(q, t)|`` of the ideal joints and drivers
      (mixed units: m for position constraints, rad for angles).
    * ``fraction_*``: share of samples (joints x times) in free flight, impact (contact shorter
      than ``Settings.continuous_contact_after``) and continuous contact.
    * ``energy_dissipated_j``: minus the work of the contact forces over the run [J] (if the
      run ends during a contact, this includes the elastic energy then stored in it).
    * solver statistics, ``status`` (0 ok) and ``status_message`` (:data:`jaxclear.STATUS`).
    * ``wall_time_s``: as given (the command line includes JIT compilation).
    """
    ts = _np(sol.ts)
    k = len(mech.clearance_joints)
    status = int(np.asarray(sol.status))
    out: dict = {
        "mechanism": mech.name,
        "t_end_s": _float(ts[-1]),
        "n_samples": int(ts.shape[0]),
        "clearance_joints": [c.name for c in mech.clearance_joints],
    }
    if k:
        fn = _np(sol.normal_force)
        ft = _np(sol.friction_force)
        pen = _np(sol.penetration)
        impacts = np.asarray(sol.memory.impacts)[-1]
        work = _np(sol.memory.work)[-1]
        # running peaks over every accepted solver step (finer than the output grid), and the samples
        peak_fn = np.maximum(np.max(fn, axis=0), _np(sol.memory.peak_force)[-1])
        max_pen = np.maximum(np.maximum(np.max(pen, axis=0), _np(sol.memory.peak_penetration)[-1]), 0.0)
        out.update(
            peak_contact_force_n=_float(np.max(peak_fn)),
            peak_contact_force_per_joint_n=[float(v) for v in peak_fn],
            peak_friction_force_n=_float(np.max(np.abs(ft))),
            max_penetration_m=_float(np.max(max_pen)),
            max_penetration_per_joint_m=[float(v) for v in max_pen],
            impacts=int(round(float(np.sum(impacts)))),
            impacts_per_joint=[int(round(float(v))) for v in impacts],
        )
    else:
        out.update(
            peak_contact_force_n=None,
            peak_contact_force_per_joint_n=[],
            peak_friction_force_n=None,
            max_penetration_m=None,
            max_penetration_per_joint_m=[],
            impacts=None,
            impacts_per_joint=[],
        )
    out["peak_slider_acc_m_s2"] = peak_slider_acceleration(mech, sol)
    drift = _np(sol.drift)
    out["max_constraint_drift"] = _float(np.max(drift)) if drift.size else 0.0
    fractions = mode_fractions(sol)
    out["fraction_free_flight"], out["fraction_impact"], out["fraction_continuous_contact"] = (
        fractions if fractions is not None else (None, None, None)
    )
    out["energy_dissipated_j"] = -_float(np.sum(work)) if k else None
    out.update(
        num_steps=int(np.asarray(sol.num_steps)),
        num_accepted_steps=int(np.asarray(sol.num_accepted_steps)),
        num_rejected_steps=int(np.asarray(sol.num_rejected_steps)),
        status=status,
        status_message=STATUS.get(status, f"unknown status {status}"),
        wall_time_s=None if wall_time_s is None else float(wall_time_s),
    )
    return {key: out[key] for key in SUMMARY_KEYS}


# --------------------------------------------------------------------------------------
# JAX-traceable per-run metrics (sweeps: vmapped over runs, one row per run)
# --------------------------------------------------------------------------------------

#: Keys of :func:`run_metrics`, in output order, with their units. Contact keys appear only for
#: a mechanism with clearance joints, slider keys only with a ``slider`` role, the
#: acceleration-deviation keys only when the ideal-joint acceleration is given, the per-revolution
#: energy only with an :class:`~jaxclear.mechanism.AngleDriver`.
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


def _window_peak(samples, running, start: int):
    """Largest value over the window ``[start:]`` of a quantity known at the samples (T', k)
    and as a running maximum over accepted solver steps (T, k): if the running maximum grew
    inside the window, its final value was reached inside the window (to within the solver step
    that contains sample ``start``); otherwise only the samples are known. Max over joints."""
    import jax.numpy as jnp

    grew = running[-1] > running[start]
    step_peak = jnp.where(grew, running[-1], -jnp.inf)
    return jnp.max(jnp.maximum(jnp.max(samples, axis=0), step_peak))


def run_metrics(mech: Mechanism, sol: Solution, ideal_acc=None, start: int = 0) -> dict:
    """Scalar metrics of one run as JAX arrays (traceable: ``jax.vmap`` it over a batch of
    solutions). Keys and units: :data:`RUN_METRIC_KEYS`.

    The *window* is the output samples ``sol.ts[start:]`` (``start`` static, e.g. the first
    sample after a transient); ``start = 0`` is the whole run. Several clearance joints are
    pooled (maxima over joints, sums of impacts and energies, fractions over joints x samples).

    * ``peak_contact_force_n``, ``max_penetration_m``: largest normal force / penetration in the
      window over the samples and the running peaks of every accepted solver step
      (``memory.peak_force``, ``memory.peak_penetration``; see :func:`_window_peak`); penetration
      floored at 0 (never touched: 0).
    * ``rms_contact_force_n``: root mean square of the normal force over the window's samples
      (free flight counts as 0).
    * ``impacts``: contact onsets inside the window (``memory.impacts`` at the end minus at
      sample ``start``; counted at every solver step).
    * ``fraction_*``: share of the window's samples (x joints) in free flight, impact and
      continuous contact (``Solution.mode`` 0, 1, 2).
    * ``energy_dissipated_j``: minus the contact work over the window [J];
      ``energy_dissipated_per_rev_j``: the same divided by the crank revolutions in the window,
      ``(ts[-1] - ts[start]) |omega| / 2 pi`` of the first AngleDriver.
    * ``peak_slider_acc_m_s2``: largest ``|x''|`` of the slider in the window;
      ``peak_acc_deviation_m_s2``, ``rms_acc_deviation_m_s2``: peak and RMS over the window of
      ``x'' - x''_ideal``, with ``ideal_acc`` (T,) the slider acceleration of the ideal-joint
      mechanism sampled on the same grid ``sol.ts`` (e.g. ``ideal.coordinate(ideal_mech,
      "slider", "x", 2)``).
    * ``max_constraint_drift``: largest ``|Phi|`` over all samples; solver step counts; ``status``.
    """
    import jax.numpy as jnp

    from .model import AngleDriver

    out: dict = {}
    ts = sol.ts
    k = len(mech.clearance_joints)
    if k:
        fn = sol.normal_force[start:]
        pen = sol.penetration[start:]
        mem = sol.memory
        out["peak_contact_force_n"] = _window_peak(fn, mem.peak_force, start)
        out["rms_contact_force_n"] = jnp.sqrt(jnp.mean(fn**2))
        out["max_penetration_m"] = jnp.maximum(_window_peak(pen, mem.peak_penetration, start), 0.0)
        out["impacts"] = jnp.sum(mem.impacts[-1] - mem.impacts[start])
        mode = sol.mode[start:]
        for key, m in (("fraction_free_flight", 0), ("fraction_impact", 1), ("fraction_continuous_contact", 2)):
            out[key] = jnp.mean((mode == m).astype(ts.dtype))
        dissipated = -(jnp.sum(mem.work[-1]) - jnp.sum(mem.work[start]))
        out["energy_dissipated_j"] = dissipated
        drivers = [d for d in mech.drivers if isinstance(d, AngleDriver)]
        if drivers:
            revs = (ts[-1] - ts[start]) * jnp.abs(drivers[0].speed) / (2.0 * jnp.pi)
            out["energy_dissipated_per_rev_j"] = dissipated / revs
    slider = mech.role("slider")
    if slider is not None:
        acc = sol.coordinate(mech, slider, "x", derivative=2)[start:]
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


__all__ = ["summary", "SUMMARY_KEYS", "peak_slider_acceleration", "mode_fractions", "run_metrics", "RUN_METRIC_KEYS"]
