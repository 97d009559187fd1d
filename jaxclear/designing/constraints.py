r"""What a design must satisfy: constraints, each a dimensionless residual in SciPy's convention
(an inequality is met where its residual is :math:`\ge 0`, an equality where it is 0), smooth in
the design variables (theory: docs/theory/design.md).

Offered by name (``constraint("...")``, the command line's ``--constraint``):

``total-mass`` / ``total-mass<=M`` (:class:`TotalMass`)
    the sum of the bodies' masses equals its value at the start design (or stays below ``M``
    [kg]): :math:`(M - \sum m_i)/M`. No simulation.
``assembles`` / ``assembles:margin=F`` (:class:`Assembles`)
    the ideal-joint mechanism still assembles at every crank angle and stays away from a
    singular position: the smallest singular value of its constraint Jacobian over one crank
    revolution (kinematic analysis, :func:`~jaxclear.integrate.kinematic_solution`),
    soft-minimised over the angles, is at least ``F`` (default 0.2) times its value at the start
    design. At a dead centre or where the loop no longer closes that value reaches 0.
``peak-force<=N`` (:class:`PeakForce`)
    the largest contact force over the samples of every run, joint and operating point is at most
    ``N`` [N], through the log-sum-exp :math:`\tau\ln\sum e^{F/\tau}` with
    :math:`\tau = N/100`, which is never below the largest sample and at most :math:`\tau\ln n`
    above it (:math:`n` the samples near the largest): conservative.
``penetration<=D`` (:class:`PeakPenetration`)
    the same for the penetration [m].

Any callable: :class:`UserConstraint` (``fn(solution, mechanism) -> scalar`` with an upper or a
lower bound).
"""

from __future__ import annotations

import re
from typing import Callable, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError
from ..integrate import is_kinematic, kinematic_solution
from ..integrate import settings
from ..model import Mechanism, constraints as equations, crank_driver, crank_period
from .objectives import Run


def log_sum_exp(values, tau):
    """:math:`\\tau \\ln \\sum e^{v/\\tau}`: a smooth maximum, never below ``max(values)``."""
    return tau * jax.nn.logsumexp(jnp.ravel(values) / tau)


class AbstractDesignConstraint(eqx.Module):
    """A constraint: :meth:`residual` of the design mechanism and, for constraints on the runs
    (``uses_runs``), of the pooled :meth:`statistic` of every run."""

    name: eqx.AbstractClassVar[str]
    #: an equality (residual = 0) rather than an inequality (residual >= 0)
    equality: ClassVar[bool] = False
    #: whether :meth:`statistic` is computed on every run
    uses_runs: ClassVar[bool] = False

    def statistic(self, run: Run):
        raise NotImplementedError

    def pool(self, stats, weights):
        """The runs' statistics (B,) combined (default: the weighted mean)."""
        return jnp.sum(weights * stats)

    def residual(self, mech: Mechanism, pooled):
        raise NotImplementedError

    def calibrated(self, mech: Mechanism) -> "AbstractDesignConstraint":
        """This constraint with what it takes from the start design filled in (default: itself)."""
        return self

    def check(self, mech: Mechanism) -> None:
        """A :class:`~jaxclear.ParameterError` if the constraint does not apply to ``mech``."""

    def describe(self) -> str:
        return self.name


class TotalMass(AbstractDesignConstraint):
    """The sum of the masses of ``bodies`` (None: every body) equals ``total`` [kg] (None: its
    value at the start design) or, with ``at_most``, stays at or below it."""

    bodies: tuple | None = eqx.field(static=True, default=None)
    total: float | None = eqx.field(static=True, default=None)
    at_most: bool = eqx.field(static=True, default=False)
    name: ClassVar[str] = "total-mass"

    @property
    def equality(self) -> bool:  # type: ignore[override]
        return not self.at_most

    def _masses(self, mech: Mechanism):
        names = self.bodies or mech.body_names
        return jnp.stack([jnp.asarray(mech.body(b).mass, dtype=float) for b in names])

    def check(self, mech: Mechanism) -> None:
        for b in self.bodies or ():
            mech.body_index(b)  # a named error for an unknown body
        if self.total is not None and not self.total > 0:
            raise ParameterError(f"constraint 'total-mass': total = {self.total:g} kg outside the allowed range (0, inf)")

    def calibrated(self, mech: Mechanism) -> "TotalMass":
        if self.total is not None:
            return self
        return TotalMass(self.bodies, float(jnp.sum(self._masses(mech))), self.at_most)

    def residual(self, mech: Mechanism, pooled=None):
        return (self.total - jnp.sum(self._masses(mech))) / self.total

    def describe(self) -> str:
        which = "the bodies" if self.bodies is None else ", ".join(self.bodies)
        return f"total mass of {which} {'<=' if self.at_most else '='} {self.total:.6g} kg"


class Assembles(AbstractDesignConstraint):
    """The ideal-joint mechanism assembles over a whole crank revolution, the smallest singular
    value of its constraint Jacobian (soft-minimised over ``samples`` crank angles) at least
    ``margin`` times its value at the start design (``reference``)."""

    margin: float = eqx.field(static=True, default=0.2)
    samples: int = eqx.field(static=True, default=181)
    reference: float | None = eqx.field(static=True, default=None)
    name: ClassVar[str] = "assembles"

    def check(self, mech: Mechanism) -> None:
        if not 0.0 < self.margin < 1.0:
            raise ParameterError(f"constraint 'assembles': margin = {self.margin:g} outside the allowed range (0, 1)")
        ideal = mech.ideal() if mech.clearance_joints else mech
        if crank_driver(mech) is None or not is_kinematic(ideal):
            raise ParameterError(f"constraint 'assembles' needs a mechanism whose crank driver determines the motion of "
                                 f"its ideal-joint counterpart; {mech.name!r} does not")

    def singular_values(self, mech: Mechanism):
        """Smallest singular value of the ideal mechanism's constraint Jacobian at ``samples``
        crank angles over one revolution (NaN where the loop does not close)."""
        ideal = mech.ideal() if mech.clearance_joints else mech
        s = settings(crank_period(ideal), n_out=self.samples, throw=False)
        sol = kinematic_solution(ideal, s)
        sig = jax.vmap(lambda q, t: jnp.linalg.svd(equations.jacobian(ideal, q, t), compute_uv=False)[-1])(sol.q, sol.ts)
        return jnp.where(sol.status == 0, sig, jnp.nan)

    def calibrated(self, mech: Mechanism) -> "Assembles":
        if self.reference is not None:
            return self
        ref = float(jnp.min(self.singular_values(mech)))
        if not ref > 0:
            raise ParameterError(f"constraint 'assembles': the start design of {mech.name!r} does not assemble over a "
                                 "whole crank revolution (or passes a singular position)")
        return Assembles(self.margin, self.samples, ref)

    def residual(self, mech: Mechanism, pooled=None):
        r = self.singular_values(mech) / self.reference
        ok = jnp.all(jnp.isfinite(r))
        safe = jnp.where(ok, r, 1.0)
        soft_min = -log_sum_exp(-safe, 0.01)
        return jnp.where(ok, soft_min - self.margin, -1.0)

    def describe(self) -> str:
        return f"assembles over a revolution, smallest singular value >= {self.margin:g} x start"


class _Limit(AbstractDesignConstraint):
    limit: eqx.AbstractVar[float]
    sharpness: eqx.AbstractVar[float]
    uses_runs: ClassVar[bool] = True
    unit: ClassVar[str] = ""

    @property
    def tau(self) -> float:
        return self.limit / self.sharpness

    def samples(self, run: Run):
        raise NotImplementedError

    def check(self, mech: Mechanism) -> None:
        if not mech.clearance_joints:
            raise ParameterError(f"constraint {self.name!r} needs a clearance joint; {mech.name!r} has none")
        if not self.limit > 0 or not self.sharpness > 0:
            raise ParameterError(f"constraint {self.name!r}: limit = {self.limit:g} {self.unit} and sharpness = "
                                 f"{self.sharpness:g} must be > 0")

    def statistic(self, run: Run):
        return log_sum_exp(self.samples(run), self.tau)

    def pool(self, stats, weights):
        return log_sum_exp(stats, self.tau)

    def residual(self, mech: Mechanism, pooled):
        return 1.0 - pooled / self.limit

    def describe(self) -> str:
        return f"largest {self.name.split('-')[-1]} <= {self.limit:.6g} {self.unit} (log-sum-exp, tau = limit/{self.sharpness:g})"


class PeakForce(_Limit):
    """The largest normal contact force of every run and joint at most ``limit`` [N]."""

    limit: float = eqx.field(static=True)
    sharpness: float = eqx.field(static=True, default=100.0)
    name: ClassVar[str] = "peak-force"
    unit: ClassVar[str] = "N"

    def samples(self, run: Run):
        return run.sol.normal_force


class PeakPenetration(_Limit):
    """The largest penetration of every run and joint at most ``limit`` [m]."""

    limit: float = eqx.field(static=True)
    sharpness: float = eqx.field(static=True, default=100.0)
    name: ClassVar[str] = "penetration"
    unit: ClassVar[str] = "m"

    def samples(self, run: Run):
        return run.sol.penetration


class UserConstraint(AbstractDesignConstraint):
    """``fn(solution, mechanism) -> scalar`` at most ``upper`` or at least ``lower`` (one of
    them), averaged over the runs with their weights; the residual is divided by the bound's
    magnitude (1 for a bound of 0)."""

    fn: Callable = eqx.field(static=True)
    upper: float | None = eqx.field(static=True, default=None)
    lower: float | None = eqx.field(static=True, default=None)
    label: str = eqx.field(static=True, default="user constraint")
    name: ClassVar[str] = "user"
    uses_runs: ClassVar[bool] = True

    def check(self, mech: Mechanism) -> None:
        if (self.upper is None) == (self.lower is None):
            raise ParameterError(f"constraint {self.label!r}: give exactly one of upper and lower")

    def statistic(self, run: Run):
        return jnp.asarray(self.fn(run.sol, run.mech), dtype=float).reshape(())

    def residual(self, mech: Mechanism, pooled):
        bound = self.upper if self.upper is not None else self.lower
        scale = abs(bound) if bound else 1.0
        return (bound - pooled) / scale if self.upper is not None else (pooled - bound) / scale

    def describe(self) -> str:
        return f"{self.label} {'<=' if self.upper is not None else '>='} {self.upper if self.upper is not None else self.lower:g}"


_LIMIT = re.compile(r"^\s*([a-z-]+)\s*<=\s*([^\s]+)\s*$")


def constraint(spec) -> AbstractDesignConstraint:
    """A constraint from an :class:`AbstractDesignConstraint` or a text: ``total-mass``,
    ``total-mass<=M``, ``assembles``, ``assembles:margin=F``, ``peak-force<=N``,
    ``penetration<=D``."""
    if isinstance(spec, AbstractDesignConstraint):
        return spec
    text = str(spec).strip()
    if text == "total-mass":
        return TotalMass()
    if text == "assembles" or text.startswith("assembles:margin="):
        margin = text.partition("=")[2]
        try:
            return Assembles(float(margin)) if margin else Assembles()
        except ValueError:
            raise ParameterError(f"constraint {text!r}: margin {margin!r} is not a number") from None
    m = _LIMIT.match(text)
    kinds = {"total-mass": lambda v: TotalMass(total=v, at_most=True), "peak-force": PeakForce,
             "penetration": PeakPenetration}
    if m and m.group(1) in kinds:
        try:
            value = float(m.group(2))
        except ValueError:
            raise ParameterError(f"constraint {text!r}: {m.group(2)!r} is not a number") from None
        return kinds[m.group(1)](value)
    raise ParameterError(f"unknown constraint {text!r}; the constraints: total-mass, total-mass<=KG, assembles, "
                         "assembles:margin=F, peak-force<=N, penetration<=M (or a constraint object)")


__all__ = [
    "AbstractDesignConstraint", "Assembles", "PeakForce", "PeakPenetration", "TotalMass", "UserConstraint",
    "constraint", "log_sum_exp",
]
