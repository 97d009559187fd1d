r"""Design on steady operation: the objective a long-time average over the machine's steady
running, its gradient by least-squares shadowing (theory: docs/theory/design.md, "Steady
operation"; docs/theory/shadowing.md).

A machine runs for hours; what its designer cares about is an average over that running, not
over the first revolution from a chosen start. With ``jc.design(..., steady=SteadyOperation(...))`` an
evaluation is

* **the value**: one run of the design from its start through ``transient_revolutions``
  (left out), ``discard_revolutions`` (left out) and ``revolutions`` (averaged), sampled
  ``segments_per_revolution x samples_per_segment`` times a revolution at fixed crank angles
  (the settings' ``max_steps`` a revolution);
  the objective's per-sample quantity (:class:`SteadyRms`: the squared deviation of a channel
  from the ideal joint's at the same time; or a callable objective, given per sample as
  ``fn(t, q, qdot, qddot, mech)``) averaged over those samples, then its finish (for the RMS the
  square root of the mean square):

  .. math:: f(x) = \sqrt{\langle (y(t) - y_\mathrm{ideal}(t))^2\rangle_T};

* **the gradient**: :func:`jaxclear.steady_derivatives` (NILSS on the engine's tangents) of the
  mean square with respect to every design variable on the same grid, chained through the
  finish, :math:`df/dx = \langle J\rangle' / (2 f)`, and the unit cube's spans. Its blocks' spread
  is the gradient's standard error, journaled with every gradient and reported
  (``DesignResult.chaos["steady"]``). The objective that comes with a gradient is the shadowing
  run's own average: another finite-time average of the same chaotic motion than the value's,
  apart by its noise (percents over 100 revolutions of the benchmark slider-crank).

Where the motion is chaotic and its shadowing tangents have heavy tails (the benchmark
slider-crank at 5000 rpm, benchmarks/README.md, "Shadowing derivatives of steady running") the
gradient is unresolved: every such gradient is counted and the design warns once with
:class:`~jaxclear.chaos.ShadowingWarning`, naming the fraction unresolved. Only constraints on the
design alone (total mass) apply; constraints on runs need a run's statistic, not an average.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError, SolverError, check_integer
from ..analysis.channels import OVERLAY_KINDS, parse, sample_channel
from ..chaos import ShadowingWarning, steady_derivatives
from ..chaos.shadowing import check_options
from ..integrate import is_kinematic, kinematics_at, simulate
from ..model import Mechanism, crank_period
from .objectives import AbstractObjective, RmsDeviation, UserObjective
from .problem import DesignProblem


@dataclass(frozen=True)
class SteadyOperation:
    """How a design's objective is averaged over steady operation (:mod:`.steady`): after
    ``transient_revolutions`` and ``discard_revolutions`` of the crank, ``revolutions`` averaged;
    the grid and the shadowing's options are :func:`jaxclear.steady_derivatives`' (segments a
    revolution, samples a segment, homogeneous tangents ``n_unstable``, ``blocks`` for the
    errors)."""

    revolutions: int = 50
    transient_revolutions: int = 20
    discard_revolutions: int = 2
    segments_per_revolution: int = 16
    samples_per_segment: int = 8
    n_unstable: int = 1
    blocks: int = 4

    def check(self) -> None:
        """The options' ranges (:func:`jaxclear.chaos.shadowing.check_options`, the shadowing's own
        rules; ``n_unstable``'s upper bound, the phase space's dimension, when the gradient runs)."""
        check_options(self.revolutions, self.transient_revolutions, self.segments_per_revolution,
                      self.samples_per_segment, self.blocks, self.discard_revolutions, prefix="steady.")
        check_integer("steady.n_unstable", self.n_unstable, 1, None, "homogeneous tangents")

    def describe(self, gradients: bool = True) -> str:
        """What the average is, appended to the objective's description (``gradients``: the
        method uses them, by least-squares shadowing)."""
        return (f", averaged over {self.revolutions} revolutions of steady operation after {self.skipped}"
                + (" (gradients by least-squares shadowing)" if gradients else ""))

    @property
    def per_revolution(self) -> int:
        return self.segments_per_revolution * self.samples_per_segment

    @property
    def skipped(self) -> int:
        """Revolutions left out before the average."""
        return self.transient_revolutions + self.discard_revolutions


@dataclass(frozen=True)
class SteadyRms:
    """The squared deviation ``(y - y_ideal)^2`` of channel ``channel`` (kind body or point) from
    the ideal joint's at one sample ``(t, q, qdot, qddot, mech)`` [unit^2]: the ideal joint's
    motion at ``t`` by Newton's method from the clearance mechanism's coordinates (within a
    clearance of it; :func:`jaxclear.integrate.kinematics_at`). Hashable: designs of the same
    channel share the compiled programs."""

    channel: str

    def __call__(self, t, q, qdot, qddot, mech):
        ideal = mech.ideal()
        qi, qdi, qddi = kinematics_at(ideal, q, t)
        return (sample_channel(mech, self.channel, t, q, qdot, qddot)
                - sample_channel(ideal, self.channel, t, qi, qdi, qddi)) ** 2


def sample_objective(obj: AbstractObjective, mech: Mechanism):
    """The per-sample quantity ``J(t, q, qdot, qddot, mech)`` whose average ``obj`` finishes:
    :class:`SteadyRms` for ``rms-deviation``; a callable objective (:class:`UserObjective`) is
    itself that quantity on steady operation (its average is the objective, no finish)."""
    if isinstance(obj, UserObjective) and not obj.with_ideal:
        return obj.fn
    if not isinstance(obj, RmsDeviation) or obj.skip:
        raise ParameterError(f"design(steady=...): objective {obj.name!r} has no steady form; give 'rms-deviation' "
                             "(without skip: the transient is steady.transient_revolutions) or a callable "
                             "fn(t, q, qdot, qddot, mech) -> scalar, averaged over the samples")
    name = obj.channel_name(mech)
    if parse(name).kind not in OVERLAY_KINDS:
        raise ParameterError(f"design(steady=...): channel {name!r} is not of kind {' or '.join(OVERLAY_KINDS)}")
    if not is_kinematic(mech.ideal()):
        raise ParameterError(f"design(steady=...): {mech.name!r} with ideal joints is not kinematically driven; the "
                             "steady rms-deviation needs the ideal joint's motion at every sample")
    return SteadyRms(name)


@partial(jax.jit, static_argnames=("objective", "skip"))
def _average(mech, s, objective, skip: int):
    """``(mean of objective over the samples after the first skip but the last, status)``."""
    sol = simulate(mech, s)
    J = jax.vmap(lambda t, q, qd, qdd: objective(t, q, qd, qdd, mech))(sol.ts, sol.q, sol.qdot, sol.qddot)
    return jnp.mean(J[skip:-1]), sol.status


class SteadyEvaluation:
    """The design's evaluations on steady operation: ``value(u)`` -> ``(values (1 + C,), status
    (1,))`` and ``with_jacobian(u)`` -> ``(values, jacobian (1 + C, P), status)``, as
    :func:`~.problem.evaluate` and :func:`~.problem.evaluate_with_jacobian` give them; each
    gradient's standard error and growth rates in a fourth item (the journal's ``extra``)."""

    def __init__(self, problem: DesignProblem, steady: SteadyOperation):
        if problem.members.count != 1:
            raise ParameterError("design(steady=...): operating points and ensembles do not apply (the steady "
                                 "average holds every start); give neither")
        if problem.run_constraints:
            raise ParameterError("design(steady=...): constraints on runs do not apply to steady averages; give "
                                 "constraints on the design only (total-mass)")
        self.problem, self.steady = problem, steady
        self.objective = sample_objective(problem.objective, problem.mech)

    def _design(self, u) -> Mechanism:
        return self.problem.design_mechanism(self.problem.values(jnp.asarray(u, dtype=float)))

    def _constraints(self, u):
        m = self._design(u)
        return jnp.stack([jnp.asarray(c.residual(m, None), dtype=float) for c in self.problem.constraints]) if (
            self.problem.constraints) else jnp.zeros((0,))

    def value(self, u):
        st = self.steady
        m = self._design(u)
        total = st.skipped + st.revolutions
        n = total * st.per_revolution + 1
        # the step limit per revolution, as the gradient has it per segment: a long average is not
        # refused for its length
        s = dataclasses.replace(self.problem.base, t_start=0.0, t_end=crank_period(m, total), n_out=n, throw=False,
                                progress=False, max_steps=self.problem.base.max_steps * total)
        mean, status = _average(m, s, self.objective, st.skipped * st.per_revolution)
        f = self.problem.objective.finish(mean)
        values = jnp.concatenate([jnp.asarray(f, dtype=float)[None], self._constraints(u)])
        return jnp.where(status == 0, values, jnp.nan), jnp.asarray(status)[None]

    def with_jacobian(self, u):
        st, p = self.steady, self.problem
        m = self._design(u)
        base = dataclasses.replace(p.base, t_start=0.0, throw=False, progress=False)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ShadowingWarning)
            try:
                r = steady_derivatives(m, p.names, self.objective, base, revolutions=st.revolutions,
                                       transient_revolutions=st.transient_revolutions,
                                       segments_per_revolution=st.segments_per_revolution,
                                       samples_per_segment=st.samples_per_segment, n_unstable=st.n_unstable,
                                       blocks=st.blocks, discard_revolutions=st.discard_revolutions)
            except SolverError as err:
                n = 1 + len(p.constraints)
                return (np.full(n, np.nan), np.full((n, len(u)), np.nan), np.asarray([1]), {"failed": str(err)})
        mean = jnp.asarray(r.average)
        slope = jax.grad(lambda J: p.objective.finish(J))(mean)  # the finish's chain rule
        span = np.asarray(p.high) - np.asarray(p.low)
        row = np.asarray(r.derivative) * float(slope) * span
        error = np.asarray(r.derivative_error) * abs(float(slope)) * span
        cons_u = jnp.asarray(u, dtype=float)
        jac = np.vstack([row[None], np.asarray(jax.jacfwd(self._constraints)(cons_u)).reshape(-1, len(u))])
        values = np.concatenate([[float(p.objective.finish(mean))], np.asarray(self._constraints(cons_u))])
        unresolved = any(issubclass(w.category, ShadowingWarning) for w in caught)
        report = {"error": error.tolist(), "exponents": np.asarray(r.exponents).ravel().tolist(),
                  "unresolved": unresolved}
        return values, jac, np.asarray([0]), report

    def summary(self, entries) -> dict:
        """What the shadowing gradients of a design were, from its journal's gradient ``entries``
        (each with its ``extra``: replayed ones too): their count, how many unresolved, each
        one's standard error relative to its size (median over gradients and variables)."""
        reports = [dict(e["extra"], u=e["u"], gradient=e["jacobian"][0]) for e in entries if "error" in e.get(
            "extra", {})]
        ratios = [abs(e) / abs(g) for r in reports for g, e in zip(r["gradient"], r["error"]) if g]
        return {"gradients": len(reports), "unresolved": sum(r["unresolved"] for r in reports),
                "failed": sum("failed" in e.get("extra", {}) for e in entries),
                "median_relative_error": float(np.median(ratios)) if ratios else math.nan,
                "config": dataclasses.asdict(self.steady), "reports": reports}

    def message(self, name: str, summary: dict) -> str | None:
        """The design's one warning: the share of its gradients that the shadowing left unresolved."""
        s = summary  # short for the message below
        if not s["unresolved"]:
            return None
        return (f"design of {name!r} on steady operation: {s['unresolved']} of {s['gradients']} shadowing gradients "
                f"unresolved (median standard error {s['median_relative_error']:.2g} of the gradient): the optimiser "
                "followed noise where they were; check the average's slope with finite differences of long runs, or "
                "use a gradient-free search on the steady average (method 'differential-evolution'; "
                "docs/theory/shadowing.md, 'Mechanisms')")


__all__ = ["SteadyOperation", "SteadyEvaluation", "SteadyRms", "sample_objective"]
