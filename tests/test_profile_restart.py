"""The profile likelihood's restart (``jaxclear.fitting.profile``): a walk that finds a better fit
than the estimate begins the fit again from it, takes it and walks again, at most ``RESTARTS``
times. The control flow on stand-ins for the model (the walk, the refit and the loss); the
measured case, acceptance record 2 of the independent simulator, is in benchmarks/README
("Records that begin mid-run")."""

from dataclasses import dataclass, field
from types import SimpleNamespace

import pytest

from jaxclear.fitting import profile as prof
from jaxclear.fitting.state import FitState


@dataclass(frozen=True)
class Problem:
    free: tuple = ("stiffness", "restitution")
    windows: int = 1
    anywhere: bool = True
    stages: list = field(default_factory=list)
    win: object = field(default_factory=lambda: SimpleNamespace(scale=1.0))
    mech: object = None


class Checkpoint:
    def __init__(self):
        self.saved = []

    def save(self, st):
        self.saved.append(st)


def point(deviance, theta, loss):
    return {"name": "restitution", "side": 1, "dz": 0.1, "deviance": deviance, "loss": loss, "theta": theta,
            "states": [[0.3]], "reason": "converged"}


@pytest.fixture
def stand_ins(monkeypatch):
    walks, refits = [], []
    monkeypatch.setattr(prof, "evaluate_all", lambda problem, theta, states, guesses: None)
    monkeypatch.setattr(prof, "sum_of_squares", lambda problem, evals: 1.0)  # the estimate's loss
    monkeypatch.setattr(prof, "from_z", lambda name, z, scale, mech: float(z))

    def fit_point(single, opt, st, theta, states, on_iteration):
        refits.append((single.stages[0].held, list(theta)))
        return {"loss": 0.4, "theta": [0.1, 1.1], "states": [[0.2]], "reason": "ftol"}

    monkeypatch.setattr(prof, "fit_point", fit_point)
    return walks, refits


def test_a_better_point_begins_the_fit_again_and_the_profile_is_walked_anew(stand_ins, monkeypatch):
    walks, refits = stand_ins

    def walk(problem, opt, st, ckpt, names, on_iteration, on_point):
        walks.append(st.theta)  # the first walk finds a better fit at 1.0; the second, from the refit, none
        new = point(-3.0, [0.0, 1.0], 0.6) if len(walks) == 1 else point(4.0, [0.1, 1.3], 1.2)
        return st.replace(profile=st.profile + (new,))

    monkeypatch.setattr(prof, "_walk", walk)
    ckpt, told = Checkpoint(), []
    st = prof.run_profiles(Problem(), None, FitState(theta=(0.0, 0.8), states=((0.0,),)), ckpt, ("restitution",),
                           lambda r, s: None, told.append)
    assert walks == [(0.0, 0.8), (0.1, 1.1)]  # walked again from the refit's optimum
    assert refits == [((), [0.0, 1.0])]  # every unknown free (nothing held), from the better point
    assert st.theta == (0.1, 1.1) and st.states == ((0.2,),) and st.stop_reason == "ftol"
    restart, walked = st.profile
    assert restart["kind"] == "restart" and restart["taken"] and restart["from"] == 1.0 and restart["loss"] == 0.4
    assert walked["deviance"] == 4.0  # the first walk's points were dropped
    assert ckpt.saved[-1].theta == (0.1, 1.1)
    assert "a better fit at 1; fitted again from it: loss 0.4 (taken: 1)" in told[0]


def test_restarts_are_limited_and_a_better_point_left_is_reported(stand_ins, monkeypatch):
    walks, refits = stand_ins

    def walk(problem, opt, st, ckpt, names, on_iteration, on_point):
        walks.append(st.theta)
        return st.replace(profile=st.profile + (point(-3.0, [0.0, 1.0 + len(walks)], 0.3),))

    monkeypatch.setattr(prof, "_walk", walk)
    st = prof.run_profiles(Problem(), None, FitState(theta=(0.0, 0.8), states=((0.0,),)), Checkpoint(),
                           ("restitution",), lambda r, s: None)
    assert len(walks) == prof.RESTARTS + 1 and len(refits) == prof.RESTARTS
    assert prof._better_point(st, ("restitution",)) is not None  # still there: the verdict fails the fit


def test_a_refit_that_climbs_takes_the_better_point_itself(stand_ins, monkeypatch):
    walks, _ = stand_ins
    monkeypatch.setattr(prof, "fit_point", lambda *a: {"loss": 0.9, "theta": [5.0, 5.0], "states": [[5.0]],
                                                        "reason": "max_iter"})

    def walk(problem, opt, st, ckpt, names, on_iteration, on_point):
        walks.append(st.theta)
        return st.replace(profile=st.profile + (point(-3.0 if len(walks) == 1 else 2.0, [0.0, 1.0], 0.6),))

    monkeypatch.setattr(prof, "_walk", walk)
    st = prof.run_profiles(Problem(), None, FitState(theta=(0.0, 0.8), states=((0.0,),)), Checkpoint(),
                           ("restitution",), lambda r, s: None)
    assert st.theta == (0.0, 1.0) and st.states == ((0.3,),) and st.profile[0]["loss"] == 0.6
