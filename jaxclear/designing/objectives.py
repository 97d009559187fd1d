r"""What a design minimises: objectives of a simulation, each smooth in the design variables
wherever the motion itself is (theory: docs/theory/design.md).

An objective is an :class:`AbstractObjective`: a *statistic* of one run (one operating point,
one member of an ensemble), the weighted mean of the statistics over the runs, and a *finish*
applied to that mean. So an RMS pools the mean squares of all runs before its square root, and
a p-norm the p-th powers, which keeps the objective one number of the same kind whatever the
number of runs.

Offered by name (:data:`OBJECTIVES`, ``objective("name:option=value,...")``):

``rms-deviation`` (:class:`RmsDeviation`)
    the RMS over the run's samples of an output channel minus the same channel of the ideal-joint
    mechanism on the same grid (default channel: the output link's acceleration, the slider's
    :math:`\ddot x` or the rocker's :math:`\ddot\phi`):
    :math:`\sqrt{\overline{(y - y_{ideal})^2}}`. What the clearance adds to the motion; the
    Varedi et al. (2015) and Erkaya and Uzmay (2008) objective.
``peak-force`` (:class:`SmoothPeakForce`)
    a smooth maximum of the contact force, the mean p-norm
    :math:`(\overline{F_N^p})^{1/p}` over the samples and joints (``p = 8``: at most the largest
    sample, at least :math:`N^{-1/p}` of it, differentiable where the largest is not).
``dissipated-energy`` (:class:`DissipatedEnergy`)
    the energy the contacts dissipate per crank revolution [J]: minus the contact work stored
    in every joint's impact memory (integrated at every solver step), over the run.
``free-flight-fraction`` (:class:`FreeFlightFraction`)
    the fraction of the samples (x joints) out of contact, smoothed: the mean of
    :math:`\sigma(-\delta/w)` (:math:`\delta` the penetration, negative in a gap, :math:`\sigma`
    the logistic function, :math:`w` a hundredth of the joint's clearance by default).
any callable
    :class:`UserObjective`: ``fn(solution, mechanism)`` (or ``fn(solution, mechanism,
    ideal_solution)``) -> a scalar, traceable with JAX.

All statistics are computed on the output samples: a peak shorter than the sample spacing is
seen only in part (choose ``samples_per_revolution`` accordingly).
"""

from __future__ import annotations

from typing import Callable, ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError
from ..analysis import channels
from ..integrate import Solution
from ..model import Mechanism


class Run(NamedTuple):
    """One simulated run as the objectives and constraints see it."""

    sol: Solution
    mech: Mechanism
    #: the ideal-joint mechanism's solution on the same grid (None when nothing needs it)
    ideal: Solution | None
    ideal_mech: Mechanism | None
    #: crank revolutions the run covers (for per-revolution quantities)
    revolutions: jax.Array


def first_sample(sol: Solution, skip: float) -> int:
    """Index of the first sample counted when a fraction ``skip`` of the run is left out (static)."""
    return int(round(skip * (sol.ts.shape[-1] - 1)))


class AbstractObjective(eqx.Module):
    """An objective: :meth:`statistic` of each run, weighted mean over the runs, :meth:`finish`."""

    name: eqx.AbstractClassVar[str]
    #: whether :meth:`statistic` reads the ideal-joint run
    needs_ideal: ClassVar[bool] = False

    def statistic(self, run: Run):
        raise NotImplementedError

    def finish(self, pooled):
        """The objective from the weighted mean of the statistics (default: itself)."""
        return pooled

    def unit(self, mech: Mechanism) -> str:
        return ""

    def describe(self, mech: Mechanism) -> str:
        return self.name

    def check(self, mech: Mechanism) -> None:
        """A :class:`~jaxclear.ParameterError` if the objective does not apply to ``mech``."""


def _need_contact(name: str, mech: Mechanism) -> None:
    if not mech.clearance_joints:
        raise ParameterError(f"objective {name!r} needs a clearance joint; mechanism {mech.name!r} has none")


class RmsDeviation(AbstractObjective):
    """RMS of ``channel`` minus its ideal-joint counterpart, over the samples after the first
    fraction ``skip`` of each run. ``channel`` None: the output link's acceleration
    (:func:`jaxclear.analysis.channels.default_channels`)."""

    channel: str | None = eqx.field(static=True, default=None)
    skip: float = eqx.field(static=True, default=0.0)
    name: ClassVar[str] = "rms-deviation"
    needs_ideal: ClassVar[bool] = True

    def channel_name(self, mech: Mechanism) -> str:
        return self.channel or channels.default_channels(mech)[2]

    def check(self, mech: Mechanism) -> None:
        name = self.channel_name(mech)
        channels.unit(mech, name)  # a named error for a bad channel
        if channels.parse(name).kind not in channels.OVERLAY_KINDS:
            raise ParameterError(f"objective 'rms-deviation': channel {name!r} has no ideal-joint counterpart; give a "
                                 f"channel of kind {' or '.join(channels.OVERLAY_KINDS)} (e.g. body:BODY:x:acc)")
        if not 0.0 <= self.skip < 1.0:
            raise ParameterError(f"objective 'rms-deviation': skip = {self.skip:g} outside the allowed range [0, 1)")

    def statistic(self, run: Run):
        name = self.channel_name(run.mech)
        start = first_sample(run.sol, self.skip)
        dev = channels.channel(run.mech, run.sol, name) - channels.channel(run.ideal_mech, run.ideal, name)
        return jnp.mean(dev[start:] ** 2)

    def finish(self, pooled):
        return jnp.sqrt(pooled)

    def unit(self, mech: Mechanism) -> str:
        return channels.unit(mech, self.channel_name(mech))

    def describe(self, mech: Mechanism) -> str:
        skip = f" after the first {self.skip:g} of each run" if self.skip else ""
        return f"RMS deviation of {self.channel_name(mech)} from the ideal joint{skip}"


class SmoothPeakForce(AbstractObjective):
    """Mean p-norm of the normal contact force over the samples and joints [N]."""

    p: float = eqx.field(static=True, default=8.0)
    name: ClassVar[str] = "peak-force"

    def check(self, mech: Mechanism) -> None:
        _need_contact(self.name, mech)
        if not self.p >= 1.0:
            raise ParameterError(f"objective 'peak-force': p = {self.p:g} outside the allowed range [1, inf)")

    def statistic(self, run: Run):
        return jnp.mean(jnp.maximum(run.sol.normal_force, 0.0) ** self.p)

    def finish(self, pooled):
        safe = jnp.where(pooled > 0, pooled, 1.0)  # 0 without contact, with a finite derivative
        return jnp.where(pooled > 0, safe ** (1.0 / self.p), 0.0)

    def unit(self, mech: Mechanism) -> str:
        return "N"

    def describe(self, mech: Mechanism) -> str:
        return f"smooth peak contact force (mean {self.p:g}-norm over samples and joints)"


class DissipatedEnergy(AbstractObjective):
    """Energy dissipated by the contacts per crank revolution [J], summed over the joints."""

    name: ClassVar[str] = "dissipated-energy"

    def check(self, mech: Mechanism) -> None:
        _need_contact(self.name, mech)

    def statistic(self, run: Run):
        work = run.sol.memory.work
        return -jnp.sum(work[-1] - work[0]) / run.revolutions

    def unit(self, mech: Mechanism) -> str:
        return "J"

    def describe(self, mech: Mechanism) -> str:
        return "energy dissipated by the contacts per crank revolution"


class FreeFlightFraction(AbstractObjective):
    """Smoothed fraction of the samples (x joints) out of contact: the mean of
    :math:`\\sigma(-\\delta / (w\\,c))`, ``w`` = ``width`` times each joint's clearance ``c``."""

    width: float = eqx.field(static=True, default=0.01)
    name: ClassVar[str] = "free-flight-fraction"

    def check(self, mech: Mechanism) -> None:
        _need_contact(self.name, mech)
        if not self.width > 0.0:
            raise ParameterError(f"objective 'free-flight-fraction': width = {self.width:g} outside the allowed "
                                 "range (0, inf) (a fraction of the clearance)")

    def statistic(self, run: Run):
        c = jnp.stack([jnp.asarray(j.clearance, dtype=float) for j in run.mech.clearance_joints])
        return jnp.mean(jax.nn.sigmoid(-run.sol.penetration / (self.width * c)))

    def describe(self, mech: Mechanism) -> str:
        return f"fraction of time out of contact (logistic, width {self.width:g} of the clearance)"


class UserObjective(AbstractObjective):
    """``fn(solution, mechanism) -> scalar`` (``with_ideal``: ``fn(solution, mechanism,
    ideal_solution)``), averaged over the runs with their weights."""

    fn: Callable = eqx.field(static=True)
    label: str = eqx.field(static=True, default="user objective")
    units: str = eqx.field(static=True, default="")
    with_ideal: bool = eqx.field(static=True, default=False)
    name: ClassVar[str] = "user"

    @property
    def needs_ideal(self) -> bool:  # type: ignore[override]
        return self.with_ideal

    def statistic(self, run: Run):
        out = self.fn(run.sol, run.mech, run.ideal) if self.with_ideal else self.fn(run.sol, run.mech)
        return jnp.asarray(out, dtype=float).reshape(())

    def unit(self, mech: Mechanism) -> str:
        return self.units

    def describe(self, mech: Mechanism) -> str:
        return self.label


#: objective name -> class (the names of the command line and of :func:`objective`)
OBJECTIVES = {cls.name: cls for cls in (RmsDeviation, SmoothPeakForce, DissipatedEnergy, FreeFlightFraction)}

#: options of each named objective: option -> type
OPTIONS = {"rms-deviation": {"channel": str, "skip": float}, "peak-force": {"p": float},
           "dissipated-energy": {}, "free-flight-fraction": {"width": float}}


def objective(spec) -> AbstractObjective:
    """An objective from an :class:`AbstractObjective`, a callable (:class:`UserObjective`) or a
    name with options, ``"NAME"`` or ``"NAME:OPTION=VALUE,..."`` (e.g. ``"rms-deviation"``,
    ``"rms-deviation:channel=body:rocker:phi:acc,skip=0.5"``, ``"peak-force:p=16"``)."""
    if isinstance(spec, AbstractObjective):
        return spec
    if callable(spec):
        return UserObjective(spec, label=getattr(spec, "__name__", "user objective"))
    if not isinstance(spec, str):
        raise ParameterError(f"objective {spec!r}: give a name ({', '.join(OBJECTIVES)}), an objective or a callable")
    name, _, rest = spec.partition(":")
    name = name.strip()
    if name not in OBJECTIVES:
        raise ParameterError(f"unknown objective {name!r}; the objectives: {', '.join(OBJECTIVES)} (or a callable)")
    kwargs = {}
    for item in _options(rest):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in OPTIONS[name]:
            raise ParameterError(f"objective {name!r}: option {item!r} is not one of "
                                 f"{sorted(OPTIONS[name]) or 'none'} (write OPTION=VALUE)")
        try:
            kwargs[key] = OPTIONS[name][key](value.strip())
        except ValueError:
            raise ParameterError(f"objective {name!r}: option {key} = {value!r} is not a number") from None
    return OBJECTIVES[name](**kwargs)


def _options(text: str) -> list[str]:
    """Options ``K=V`` separated by commas (a channel name holds ``:`` and ``=`` but no comma)."""
    return [part.strip() for part in text.split(",") if part.strip()]


__all__ = [
    "AbstractObjective", "DissipatedEnergy", "FreeFlightFraction", "OBJECTIVES", "RmsDeviation", "Run",
    "SmoothPeakForce", "UserObjective", "first_sample", "objective",
]
