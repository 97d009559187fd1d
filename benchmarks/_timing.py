"""Timing shared by the benchmark scripts: the first call of a compiled simulation (compilation plus
one run) and its steady state, reported separately."""

from __future__ import annotations

import statistics

from jaxclear.integrate._runs import timed_simulate


def compile_and_steady(mech, settings, repeats: int, steady=statistics.median):
    """``(solution, first_s, steady_s)``: the first call's wall time (compilation + run) and
    ``steady`` (median by default, or e.g. ``min``) of ``repeats`` further calls [s]."""
    sol, first = timed_simulate(mech, settings)
    times = [timed_simulate(mech, settings)[1] for _ in range(max(int(repeats), 1))]
    return sol, first, steady(times)
