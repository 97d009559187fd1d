"""One status family and one result protocol for every driver (issue 40, item 5).

Statuses: every run status is a member of ``jaxclear.RESULTS`` (a Lyapunov run's overflow
too), ``jaxclear.STATUS`` gives every message, one ``raise_for_status`` raises them, and the
old spellings still work with a DeprecationWarning.
"""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest

import jaxclear as jc
from jaxclear.chaos import LyapunovError
from jaxclear.integrate.simulate import raise_for_status


# ---- the one status family ----------------------------------------------------------------


def test_results_is_the_one_status_family():
    """The codes a file may hold keep their meaning (members are only appended); the chaos
    overflow is a member; STATUS maps every member's code to its message."""
    names = list(jc.RESULTS._name_to_item)
    assert names[:12] == ["successful", "max_steps_reached", "nonfinite_state", "solver_failed", "assembly_failed",
                          "invalid_restitution", "invalid_stiffness", "invalid_clearance", "invalid_friction",
                          "invalid_mass", "invalid_parameter", "penetration_too_deep"]
    code = int(jc.RESULTS.tangent_overflow._value)
    assert code == 12 and jc.STATUS[code].startswith("the tangents overflowed within the shortest")
    assert sorted(jc.STATUS) == list(range(len(names)))


class _Result:
    """Any result with a status and a renormalisation interval (the one raise_for_status reads
    only ``status``)."""

    def __init__(self, status):
        self.status = np.asarray(status)
        self.interval = np.asarray(1.0)


def test_one_raise_for_status_for_every_result():
    s = jc.Settings(t_end=1.0, max_steps=77)
    raise_for_status(_Result(0), s)  # ok: nothing
    with pytest.raises(jc.SolverError, match=r"max_steps.*now 77"):
        raise_for_status(_Result(int(jc.RESULTS.max_steps_reached._value)), s)
    with pytest.raises(LyapunovError, match=r"tangents overflowed.*\(lyapunov\)"):
        raise_for_status(_Result(int(jc.RESULTS.tangent_overflow._value)), s, " (lyapunov)", error=LyapunovError)
    with pytest.raises(jc.ParameterError, match=r"restitution"):
        raise_for_status(_Result(int(jc.RESULTS.invalid_restitution._value)), s, error=LyapunovError)


def test_old_status_spellings_warn_and_still_work():
    with pytest.warns(DeprecationWarning, match=r"jaxclear.chaos.STATUS is deprecated"):
        old = jc.chaos.STATUS
    assert old is jc.STATUS
    from jaxclear.chaos import benettin

    with pytest.warns(DeprecationWarning, match=r"benettin.STATUS is deprecated"):
        assert benettin.STATUS is jc.STATUS
    lyapunov_module = importlib.import_module("jaxclear.chaos.lyapunov")  # the package's name is the function

    with pytest.warns(DeprecationWarning, match=r"raise_for_status is deprecated"):
        old_raise = lyapunov_module.raise_for_status
    with pytest.raises(LyapunovError, match=r"tangents overflowed"):
        old_raise(_Result(int(jc.RESULTS.tangent_overflow._value)), jc.Settings(t_end=1.0))
    import jaxclear.designing as designing

    with pytest.warns(DeprecationWarning, match=r"STATUSES is deprecated"):
        assert designing.STATUSES == designing.OUTCOMES == ("converged", "max_iter", "infeasible", "stopped")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "STATUS" not in jc.chaos.__all__ and "STATUSES" not in designing.__all__
