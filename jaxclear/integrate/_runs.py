"""How long to simulate and what to compare with: run settings in crank revolutions, and a
simulation paired with its ideal-joint reference.

* :func:`revolution_settings`: :class:`~jaxclear.integrate.Settings` for ``revolutions`` crank
  revolutions (or a time ``t_end`` [s]), with :data:`SAMPLES_PER_REVOLUTION` output samples per
  revolution unless ``n_out`` is given.
* :func:`simulate_with_ideal`: the simulation of a mechanism and, when it has clearance
  joints, of its ideal-joint counterpart (:meth:`~jaxclear.model.Mechanism.ideal`) on the
  same settings and output grid, with wall times; the reference that the clearance perturbs
  (e.g. the overlay of the slider-acceleration plot).
"""

from __future__ import annotations

import dataclasses
import time
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import jax

from .._errors import check_range
from ..model import Mechanism, crank_driver, crank_period
from ._settings import Settings, settings
from ._kinematics import is_kinematic, kinematic_solution
from ._simulate import prepare_simulate, simulate
from ._solution import Solution

#: Output samples per crank revolution of :func:`revolution_settings` (plus one for the end).
SAMPLES_PER_REVOLUTION = 2000
#: Fewest output samples from the revolutions rule (plus one for the end), for short runs.
MIN_SAMPLES = 100
#: Output samples when the revolutions are undefined (no crank, or a crank at rest) and
#: ``n_out`` is not given.
DEFAULT_SAMPLES = 2001


def revolutions_of(mech: Mechanism, t_end: float) -> float | None:
    """Crank revolutions [-] in ``t_end`` seconds, or None when the mechanism has no crank
    driver (:func:`~jaxclear.model.crank_driver`) or its crank is at rest."""
    crank = crank_driver(mech)
    if crank is None or float(crank[1].speed) == 0.0:
        return None
    return float(t_end) / float(crank_period(mech))


def revolution_settings(mech: Mechanism, revolutions: float | None = 3.0, *, t_end: float | None = None,
                        n_out: int | None = None, samples_per_revolution: int = SAMPLES_PER_REVOLUTION,
                        **settings_kwargs) -> Settings:
    """:class:`~jaxclear.integrate.Settings` for ``revolutions`` crank revolutions.

    Args:
        mech: the mechanism; its crank driver's speed sets the period ``2 pi / |omega|`` [s].
        revolutions: simulated time in crank revolutions [-], > 0 (ignored when ``t_end`` is
            given). Needs a crank driver with a non-zero speed.
        t_end: simulated time [s], > 0, instead of ``revolutions`` (works without a crank).
        n_out: number of output samples [-], >= 2, uniform in time; default
            ``max(round(samples_per_revolution * revolutions), MIN_SAMPLES) + 1``, or
            :data:`DEFAULT_SAMPLES` when the revolutions are undefined.
        samples_per_revolution: output samples per crank revolution [-] for the default ``n_out``.
        **settings_kwargs: the other fields of :func:`jaxclear.integrate.settings` (``solver``,
            ``rtol``, ``atol``, ``max_steps``, ``progress``...).

    Raises:
        ParameterError: ``revolutions`` or ``t_end`` not > 0, or no crank speed for
            ``revolutions`` (no crank driver, or a crank at rest: :func:`~jaxclear.model.crank_period`).
    """
    if t_end is not None:
        check_range("t_end", t_end, low=0.0, low_open=True, unit="s")
        t_end = float(t_end)
        revolutions = revolutions_of(mech, t_end)
    else:
        check_range("revolutions", revolutions, low=0.0, low_open=True)
        t_end = float(revolutions) * float(crank_period(mech))
    if n_out is None:
        n_out = DEFAULT_SAMPLES if revolutions is None else (
            max(int(round(samples_per_revolution * revolutions)), MIN_SAMPLES) + 1)
    return settings(t_end, n_out=int(n_out), **settings_kwargs)


class RunWithIdeal(NamedTuple):
    """A simulation and its ideal-joint reference (see :func:`simulate_with_ideal`)."""

    sol: Solution
    #: the solution of ``ideal_mech`` on the same settings, or None
    ideal_sol: Solution | None
    #: ``mech.ideal()``, or None when no reference was simulated
    ideal_mech: Mechanism | None
    #: wall time of ``sol`` [s], including JIT compilation on the first call
    wall_time_s: float
    #: wall time of ``ideal_sol`` [s], or None
    ideal_wall_time_s: float | None


def timed_simulate(mech: Mechanism, s: Settings, run=simulate) -> tuple[Solution, float]:
    """``run(mech, s)`` (:func:`jaxclear.integrate.simulate` by default) and its wall time [s]
    (until the results are ready, including JIT compilation on the first call)."""
    t0 = time.perf_counter()
    sol = jax.block_until_ready(run(mech, s))
    return sol, time.perf_counter() - t0


def simulate_with_ideal(mech: Mechanism, s: Settings, ideal: bool = True) -> RunWithIdeal:
    """Simulate ``mech`` and, if ``ideal`` and it has clearance joints, its ideal-joint
    counterpart ``mech.ideal()`` (every clearance joint an ideal revolute joint) with the same
    settings, so both solutions share the output grid. Errors of either run propagate
    (:class:`jaxclear.JaxclearError`).

    When the drivers determine the ideal mechanism's motion (:func:`~jaxclear.integrate.is_kinematic`,
    e.g. a crank-driven slider-crank or four-bar), its solution is the kinematic analysis at the
    samples (:func:`~jaxclear.integrate.kinematic_solution`): no integration, a small
    program, exact to the Newton tolerance. Otherwise it is integrated with ``s``. Either way it
    is another program than the clearance run's. The clearance run is traced (or loaded from the
    store of traced programs) first; the ideal run then starts in a second thread, so that its
    tracing (which holds Python's lock) overlaps the clearance run's XLA compilation (which does
    not) rather than competing with its tracing. ``wall_time_s`` includes that tracing."""
    if not (ideal and mech.clearance_joints):
        sol, wall = timed_simulate(mech, s)
        return RunWithIdeal(sol, None, None, wall, None)
    ideal_mech = mech.ideal()
    t0 = time.perf_counter()
    prepare_simulate(mech, s)  # traced first: the ideal run's tracing then overlaps its compilation
    prepared = time.perf_counter() - t0
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="jaxclear-ideal") as pool:
        pending = pool.submit(timed_simulate, ideal_mech, dataclasses.replace(s, progress=False),
                              kinematic_solution if is_kinematic(ideal_mech) else simulate)
        sol, wall = timed_simulate(mech, s)
        ideal_sol, ideal_wall = pending.result()
    return RunWithIdeal(sol, ideal_sol, ideal_mech, prepared + wall, ideal_wall)


__all__ = [
    "DEFAULT_SAMPLES", "MIN_SAMPLES", "SAMPLES_PER_REVOLUTION", "RunWithIdeal", "revolution_settings",
    "revolutions_of", "simulate_with_ideal", "timed_simulate",
]
