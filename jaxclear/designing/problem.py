r"""A design problem as one pure function: unit-cube coordinates ``u`` (P,) -> the objective and
the constraints' residuals, and their Jacobian through the simulations.

The runs of one evaluation are the *members*: every operating point (:class:`OperatingPoint`:
speeds, loads, any :mod:`jaxclear.params` values, with a weight) times every member of the
ensemble (:class:`Ensemble`: periodic starts at crank angles spread over a revolution, or start
offsets of the journals spread over the clearance). They are mapped over in one program
by the lane runner's rule (``jax.lax.map`` on CPU, ``jax.vmap`` on accelerators, as the sweeps do,
:func:`jaxclear.sweep.lanes.over_lanes`); the objective is the finish of the weighted mean
of their statistics (:mod:`.objectives`) and each constraint pools them its way
(:mod:`.constraints`).

Derivatives: ``jax.linearize`` of the whole evaluation, then its linear map applied to the P unit
vectors. Under ``Settings(adjoint="sensitivity")`` linearizing a simulation runs the
error-controlled sensitivity solve once, with one tangent per perturbed scalar leaf of the
mechanism (:mod:`jaxclear.integrate._sensitivity`); the P columns are then linear combinations,
so the whole Jacobian costs one sensitivity solve per member (``jax.jacfwd`` would batch P of
them).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..params.registry import replace_many
from .._errors import ParameterError
from ..integrate import Settings, simulate
from ..integrate import jit
from ..integrate import is_kinematic, kinematic_solution
from ..integrate import settings as make_settings
from ..model import Mechanism, crank_driver, crank_period
from ..sweep.lanes import lanes_one_by_one, over_lanes
from .constraints import AbstractDesignConstraint
from .objectives import AbstractObjective, Run
from .variables import Variable

#: Default output samples per crank revolution of a design's runs (impacts last tens of
#: microseconds: 4000 samples per revolution is 3 us apart at 5000 rpm).
SAMPLES_PER_REVOLUTION = 4000
#: Fewest output samples of a run.
MIN_SAMPLES = 64


@dataclass(frozen=True)
class OperatingPoint:
    """Where the design must work: :mod:`jaxclear.params` values (a crank speed, a load, a
    payload mass...) applied on top of the design, and the point's weight (> 0) in the
    objective's weighted mean."""

    values: dict = dataclasses.field(default_factory=dict)
    weight: float = 1.0


@dataclass(frozen=True)
class Ensemble:
    """Several runs per operating point, their statistics averaged (theory: docs/theory/design.md).

    Attributes:
        starts: members, >= 1.
        kind: ``"angles"``: member ``k`` starts at the crank angle ``angle0 + 2 pi k / starts``
            in the ideal-joint motion with the journals as the mechanism places them (periodic
            starts: short runs that tile a revolution); ``"offsets"``: every member starts at
            ``angle0`` with the journals of revolute-type joints at rest at offsets spread
            uniformly over the disc of radius ``spread`` times the clearance (a seeded sample).
        spread: radius of the offsets' disc as a fraction of the clearance, in (0, 1).
        seed: seed of the offsets' sample.
    """

    starts: int = 1
    kind: str = "angles"
    spread: float = 0.8
    seed: int = 0

    def check(self) -> None:
        if isinstance(self.starts, bool) or not isinstance(self.starts, int) or self.starts < 1:
            raise ParameterError(f"ensemble starts = {self.starts!r} outside the allowed range [1, inf) (an integer)")
        if self.kind not in ("angles", "offsets"):
            raise ParameterError(f"ensemble kind {self.kind!r} is not one of 'angles', 'offsets'")
        if not 0.0 < self.spread < 1.0:
            raise ParameterError(f"ensemble spread = {self.spread:g} outside the allowed range (0, 1)")


class Members(eqx.Module):
    """The runs of one evaluation (leading axis B): operating-point values (B, V) of ``names``,
    crank-angle shifts (B,) [rad], journal offsets as fractions of the clearance (B, 2), weights
    (B,) summing to 1, position and velocity guesses (B, n)."""

    values: jax.Array
    shift: jax.Array
    offset: jax.Array
    weight: jax.Array
    guess_q: jax.Array
    guess_qd: jax.Array
    names: tuple = eqx.field(static=True)

    @property
    def count(self) -> int:
        return int(self.weight.shape[0])


class DesignProblem(eqx.Module):
    """Everything one evaluation needs; its arrays are the mechanism's leaves and the members'."""

    mech: Mechanism
    members: Members
    names: tuple = eqx.field(static=True)
    low: jax.Array
    high: jax.Array
    objective: AbstractObjective = eqx.field(static=True)
    constraints: tuple = eqx.field(static=True)
    revolutions: float = eqx.field(static=True)
    n_out: int = eqx.field(static=True)
    base: Settings
    one_by_one: bool = eqx.field(static=True)

    @property
    def rtol(self) -> float:
        return float(self.base.rtol)

    @property
    def atol(self) -> float:
        return float(self.base.atol)

    @property
    def max_steps(self) -> int:
        return self.base.max_steps

    @property
    def variables(self) -> tuple[Variable, ...]:
        """The variables' names and ranges (host side; the bounds are arrays of the problem, so
        that designs over other ranges of the same names share the compiled programs)."""
        lo, hi = np.asarray(self.low), np.asarray(self.high)
        return tuple(Variable(n, float(lo[i]), float(hi[i]), float("nan"), "") for i, n in enumerate(self.names))

    def values(self, u):
        """Unit-cube coordinates -> variable values (traceable)."""
        return self.low + u * (self.high - self.low)

    @property
    def run_constraints(self) -> tuple:
        return tuple(c for c in self.constraints if c.uses_runs)

    @property
    def needs_ideal(self) -> bool:
        return bool(self.objective.needs_ideal) and bool(self.mech.clearance_joints)

    def design_values(self, x) -> dict:
        """``{name: value}`` of design values ``x`` (values, not unit coordinates)."""
        return {n: x[i] for i, n in enumerate(self.names)}

    def design_mechanism(self, x) -> Mechanism:
        """The mechanism at design values ``x`` (values, not unit coordinates)."""
        return replace_many(self.mech, self.design_values(x))

    def member_mechanism(self, x, k) -> Mechanism:
        """Member ``k``'s mechanism: the design, its operating point, start angle, guesses, offsets."""
        mb = self.members
        values = self.design_values(x)  # the design's values, then the member's (one replace_many)
        values.update({n: mb.values[k, i] for i, n in enumerate(mb.names)})
        m = replace_many(self.mech, values)
        return _start(m, mb.shift[k], mb.offset[k], mb.guess_q[k], mb.guess_qd[k])

    def settings_of(self, m: Mechanism, throw: bool = False) -> Settings:
        """The run's settings: the design's settings over ``revolutions`` of ``m``'s crank
        (traced speed) from t = 0, ``n_out`` samples, no progress bar."""
        t_end = crank_period(m, self.revolutions)
        return dataclasses.replace(self.base, t_start=0.0, t_end=t_end, n_out=self.n_out, throw=throw, progress=False)

    def run(self, m: Mechanism, s: Settings) -> Run:
        """Simulate ``m`` (and its ideal-joint counterpart when the objective reads it). A
        mechanism without force elements whose drivers determine its motion is not integrated:
        its run is the kinematic analysis (exact to the Newton tolerance, a far smaller program)."""
        sol = kinematic_solution(m, s) if is_kinematic(m) else simulate(m, s)
        ideal = ideal_mech = None
        if self.needs_ideal:
            ideal_mech = m.ideal()
            ideal = kinematic_solution(ideal_mech, s) if is_kinematic(ideal_mech) else simulate(ideal_mech, s)
        return Run(sol, m, ideal, ideal_mech, jnp.asarray(self.revolutions, dtype=float))

    def member_statistics(self, x, k, trajectory: bool = False):
        """``(statistics (1 + R,), status)`` of member ``k``: the objective's statistic, then each
        run constraint's; status the run's (or, if that is ok, the ideal run's) code. With
        ``trajectory``, also the run's ``(ts, q, qdot)`` (what the derivative horizon reads)."""
        m = self.member_mechanism(x, k)
        run = self.run(m, self.settings_of(m))
        stats = [self.objective.statistic(run)] + [c.statistic(run) for c in self.run_constraints]
        status = run.sol.status if run.ideal is None else jnp.where(run.sol.status != 0, run.sol.status,
                                                                     run.ideal.status)
        out = (jnp.stack([jnp.asarray(v, dtype=float) for v in stats]), status)
        return out + ((run.sol.ts, run.sol.q, run.sol.qdot),) if trajectory else out

    def outputs(self, u, trajectory: bool = False):
        """``(values (1 + C,), statuses (B,))``: the objective and the constraints' residuals at
        unit coordinates ``u``; NaN where a member's run failed. With ``trajectory``, also the
        first member's ``(ts, q, qdot)``."""
        x = self.values(u)
        ks = jnp.arange(self.members.count)
        mapped = over_lanes(lambda k: self.member_statistics(x, k, trajectory), ks, one_by_one=self.one_by_one)
        stats, status = mapped[:2]
        w = self.members.weight
        values = [self.objective.finish(jnp.sum(w * stats[:, 0]))]
        design = self.design_mechanism(x)
        i = 1
        for c in self.constraints:
            pooled = None
            if c.uses_runs:
                pooled = c.pool(stats[:, i], w)
                i += 1
            values.append(c.residual(design, pooled))
        out = jnp.stack([jnp.asarray(v, dtype=float) for v in values])
        result = (jnp.where(jnp.all(status == 0), out, jnp.nan), status)
        return result + (jax.tree_util.tree_map(lambda a: a[0], mapped[2]),) if trajectory else result


def _start(m: Mechanism, shift, offset, guess_q, guess_qd) -> Mechanism:
    """``m`` started ``shift`` [rad] further along its crank, from the guesses, its force
    elements' starts moved by ``offset`` of their clearance (:meth:`Mechanism.started`)."""
    return m.started(angle0=crank_driver(m)[1].angle0 + shift, q=guess_q, qdot=guess_qd, within=offset)


@jit
def evaluate(problem: DesignProblem, u):
    """The objective and constraints at ``u`` (one compiled program per problem structure)."""
    return problem.outputs(u)


def _with_tangents(problem: DesignProblem, u):
    """``(values (1 + C,), jacobian (1 + C, P), statuses (B,), ts, q, qdot, tangent q (P, ...),
    tangent qdot (P, ...))`` at ``u``: one linearization (one sensitivity solve per member), the
    Jacobian's columns and the first member's state tangents its linear map on the unit vectors
    (each a full range of a variable). The values are those of the sensitivity solve (its steps are
    sized for the tangents too). A flat tuple of arrays: the store of traced programs keeps it."""

    def f(uu):
        values, status, (ts, q, qdot) = problem.outputs(uu, trajectory=True)
        return (values, q, qdot), (status, ts)

    (values, q, qdot), lin, (status, ts) = jax.linearize(f, u, has_aux=True)
    columns, dq, dqdot = jax.vmap(lin)(jnp.eye(u.shape[0], dtype=u.dtype))  # (P, 1 + C), (P, T, n) x 2
    return values, columns.T, status, ts, q, qdot, dq, dqdot


_evaluate_with_tangents = jit(_with_tangents)


@jit
def evaluate_with_jacobian(problem: DesignProblem, u):
    """``(values (1 + C,), jacobian (1 + C, P), statuses)`` at ``u``: one linearization (one
    sensitivity solve per member), the Jacobian's columns its linear map on the unit vectors.
    The values are those of the sensitivity solve (its steps are sized for the tangents too)."""
    return _with_tangents(problem, u)[:3]


#: The output structures of :func:`evaluate` and of the Jacobian's program (flat tuples of arrays),
#: which the store of traced programs needs without tracing.
_VALUES, _WITH_TANGENTS = jax.tree_util.tree_structure((0, 0)), jax.tree_util.tree_structure((0,) * 8)
#: The Jacobian's program's name in the store (:func:`prepare_jacobian` traces what
#: :func:`jacobian_at` runs).
_JACOBIAN = "design-jacobian"


def values_at(problem: DesignProblem, u):
    """:func:`evaluate` through the store of traced programs (a new process neither traces nor,
    with JAX's cache, compiles it again; a problem holding a Python function of the user's is
    traced as usual)."""
    return evaluate.stored("design-values", lambda: _VALUES, problem, u)


#: The last call of the Jacobian's program: ``(problem, u's bytes, outputs)``. The design's
#: derivative horizon (:func:`tangents_at`) and its first gradient (:func:`jacobian_at`) ask at the
#: same point one after the other: the second reads the first's outputs instead of running again.
_LAST: list = [None]


def _jacobian_program(problem: DesignProblem, u) -> tuple:
    """:func:`_with_tangents` at ``u`` through the store of traced programs, the last call's
    outputs again where the problem (the same object) and ``u`` are the same."""
    u = jnp.asarray(u, dtype=float)
    at = np.asarray(u).tobytes()
    last = _LAST[0]
    if last is not None and last[0] is problem and last[1] == at:
        return last[2]
    out = _evaluate_with_tangents.stored(_JACOBIAN, lambda: _WITH_TANGENTS, problem, u)
    _LAST[0] = (problem, at, out)
    return out


def prepare_jacobian(problem: DesignProblem, u) -> None:
    """Trace (or load from the store) the Jacobian's program of :func:`jacobian_at` at ``u`` without
    compiling it: tracing holds Python's lock, so a caller that compiles it on another thread
    traces it first, and its compilation then overlaps what the caller does next."""
    _evaluate_with_tangents.prepare(_JACOBIAN, problem, jnp.asarray(u, dtype=float))


def jacobian_at(problem: DesignProblem, u):
    """:func:`evaluate_with_jacobian`'s ``(values, jacobian, statuses)`` through the store of traced
    programs (as :func:`values_at`), from the one program that also gives :func:`tangents_at`."""
    return _jacobian_program(problem, u)[:3]


def tangents_at(problem: DesignProblem, u):
    """``(ts, q, qdot, tangent q (P, T, n), tangent qdot (P, T, n))``: the first member's run at
    ``u`` and its tangents along each variable's full range (what the derivative horizon reads),
    from the Jacobian's program (:func:`jacobian_at`): the design's first gradient, asked at the
    same point, neither compiles nor runs anything more."""
    return _jacobian_program(problem, u)[3:]


def n_samples(revolutions: float, per_revolution: int) -> int:
    """Output samples of a run of ``revolutions``: ``per_revolution`` each, at least :data:`MIN_SAMPLES`."""
    return max(int(round(per_revolution * revolutions)), MIN_SAMPLES) + 1


def build_members(mech: Mechanism, points: tuple[OperatingPoint, ...], ensemble: Ensemble) -> Members:
    """The members: every operating point times every ensemble member, with the guesses of its
    start (the ideal-joint kinematics of the point at the member's crank angle)."""
    names = tuple(sorted({n for p in points for n in p.values}))
    for p in points:
        missing = set(names) - set(p.values)
        if missing:
            raise ParameterError(f"operating point {p.values}: every point must set the same names; missing "
                                 f"{sorted(missing)}")
    total = sum(p.weight for p in points)
    k = ensemble.starts
    rows, shifts, offsets, weights, gq, gqd = [], [], [], [], [], []
    periodic = ensemble.kind == "angles" and k > 1
    for p in points:
        m = replace_many(mech, p.values)
        q, qd = _start_guesses(m, k) if periodic else _own_guesses(m)
        sign = 1.0 if float(crank_driver(m)[1].speed) >= 0 else -1.0
        disc = _offsets(ensemble) if ensemble.kind == "offsets" else np.zeros((k, 2))
        for j in range(k):
            a = j if periodic else 0
            rows.append([float(p.values[n]) for n in names])
            shifts.append(sign * 2.0 * math.pi * a / k if ensemble.kind == "angles" else 0.0)
            offsets.append(disc[j])
            weights.append(p.weight / total / k)
            gq.append(q[a])
            gqd.append(qd[a])
    f = lambda a: jnp.asarray(np.asarray(a, dtype=float))  # noqa: E731
    return Members(f(rows).reshape(len(rows), len(names)), f(shifts), f(offsets), f(weights), f(gq), f(gqd), names)


def _start_guesses(m: Mechanism, k: int):
    """Positions and velocities (k, n) of ``m``'s ideal-joint motion at ``k`` crank angles
    spread over a revolution (from the assembly at each angle where the motion is not kinematic)."""
    ideal = m.ideal() if m.clearance_joints else m
    if not is_kinematic(ideal):
        raise ParameterError(f"design runs start from the ideal-joint kinematics; the ideal-joint counterpart of "
                             f"{m.name!r} is not kinematically driven (its crank driver does not determine its motion)")
    period = float(crank_period(m))
    # 32 samples between members: the analysis continues each Newton solve from the last sample,
    # and a quarter revolution apart is too far for it to converge (the slider-crank)
    sol = kinematic_solution(ideal, make_settings(period, n_out=32 * k + 1))
    return np.asarray(sol.q)[: 32 * k: 32], np.asarray(sol.qdot)[: 32 * k: 32]


def _own_guesses(m: Mechanism):
    """The mechanism's own position and velocity guesses (1, n)."""
    q = np.concatenate([np.asarray(b.position, dtype=float) for b in m.bodies])
    qd = np.concatenate([np.asarray(b.velocity, dtype=float) for b in m.bodies])
    return q[None], qd[None]


def _offsets(ensemble: Ensemble) -> np.ndarray:
    """``starts`` offsets (k, 2) uniform over the disc of radius ``spread`` (fractions of the clearance)."""
    rng = np.random.default_rng(ensemble.seed)
    r = ensemble.spread * np.sqrt(rng.uniform(size=ensemble.starts))
    a = rng.uniform(0.0, 2.0 * math.pi, size=ensemble.starts)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def build_problem(mech: Mechanism, variables: tuple[Variable, ...], objective: AbstractObjective,
                  constraints: tuple[AbstractDesignConstraint, ...], points: tuple[OperatingPoint, ...],
                  ensemble: Ensemble, revolutions: float, samples_per_revolution: int, base: Settings) -> DesignProblem:
    """The :class:`DesignProblem` (inputs checked by :func:`jaxclear.design`)."""
    f = lambda a: jnp.asarray(np.asarray(a, dtype=float))  # noqa: E731
    return DesignProblem(mech, build_members(mech, points, ensemble), tuple(v.name for v in variables),
                         f([v.low for v in variables]), f([v.high for v in variables]), objective, constraints,
                         float(revolutions), n_samples(revolutions, samples_per_revolution), base, lanes_one_by_one())


__all__ = [
    "DesignProblem", "Ensemble", "Members", "OperatingPoint", "SAMPLES_PER_REVOLUTION", "build_members",
    "build_problem", "evaluate", "evaluate_with_jacobian", "n_samples",
]
