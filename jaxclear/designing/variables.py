"""Design variables: named numbers of a mechanism (:mod:`jaxclear.params` names, including the
derived ``centroid_x:BODY`` / ``centroid_y:BODY``) with the interval each may take.

The optimiser works on the unit cube: variable ``i`` is ``x_i = low_i + u_i (high_i - low_i)``
with ``u_i`` in [0, 1], so that every variable has the same scale whatever its unit (a mass in
kg, a centroid shift in m, a clearance in um) and the bounds are the cube's faces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from ..params.registry import check_name, replace_many
from .._errors import ParameterError
from ..params.derivatives import differentiable_names
from ..model import Mechanism


@dataclass(frozen=True)
class Variable:
    """One design variable: its :mod:`jaxclear.params` name, its interval ``[low, high]`` (SI;
    ``speed_rpm`` in rpm) and its start value."""

    name: str
    low: float
    high: float
    start: float
    unit: str

    @property
    def span(self) -> float:
        return self.high - self.low

    def to_unit(self, value) -> float:
        """The value as a coordinate of the unit cube."""
        return (value - self.low) / self.span

    def from_unit(self, u):
        """The unit-cube coordinate ``u`` as a value (traceable)."""
        return self.low + u * self.span


def design_names(mech: Mechanism) -> list[str]:
    """Every name a design may vary: :func:`jaxclear.differentiable_names` (which includes the
    derived ``centroid_x:BODY`` and ``centroid_y:BODY``)."""
    return differentiable_names(mech)


def _interval(name: str, bounds) -> tuple[float, float]:
    """``(low, high)`` from ``bounds``: two finite numbers with ``low < high``."""
    try:
        low, high = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise ParameterError(f"design variable {name!r}: bounds must be two numbers (low, high), got {bounds!r}") from None
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ParameterError(f"design variable {name!r}: bounds ({low:g}, {high:g}) must be finite")
    if not low < high:
        what = "empty" if low == high else "inverted"
        raise ParameterError(f"design variable {name!r}: the range [{low:g}, {high:g}] is {what}; give low < high")
    return low, high


def check_variables(mech: Mechanism, variables: dict, start: dict | None = None) -> tuple[Variable, ...]:
    """The design variables of ``variables`` (``{name: (low, high)}``) as :class:`Variable`, in
    the order given.

    Raises:
        ParameterError: no variable; a name that is not a number of ``mech`` (unknown, or a
            structural field such as a law's name; the message lists the names that are); a
            range that is empty or inverted, not finite, or outside the parameter's own range
            (a mass bound <= 0, a clearance bound >= the bearing radius); a start value outside
            its range; a start value for a name that is not a variable.
    """
    if not isinstance(variables, dict) or not variables:
        raise ParameterError("no design variable: give variables={name: (low, high)} with at least one name")
    start = dict(start or {})
    extra = sorted(set(start) - set(variables))
    if extra:
        raise ParameterError(f"start values for {extra}, which are not design variables ({list(variables)})")
    out = []
    for name, bounds in variables.items():
        # why, then the closest names (params.closest)
        at = check_name(mech, name, context=f"design variable {name!r} is not a number of mechanism {mech.name!r}")
        low, high = _interval(name, bounds)
        try:
            at.check([low, high])
        except ParameterError as err:
            raise ParameterError(f"design variable {name!r}: the range [{low:g}, {high:g}] leaves the parameter's own "
                                 f"range ({err})") from None
        value = float(start[name]) if name in start else float(np.asarray(at.value()))
        if math.isfinite(value) and abs(value - min(max(value, low), high)) <= 1e-9 * (high - low):
            value = min(max(value, low), high)  # a bound written in other digits (0.5e-3 against R - r)
        if not (math.isfinite(value) and low <= value <= high):
            where = "the start value given" if name in start else "its value in the mechanism (the start)"
            raise ParameterError(f"design variable {name!r}: {where}, {value:g}, lies outside its range [{low:g}, "
                                 f"{high:g}]; widen the range or give a start inside it")
        unit = at.parameter.unit
        out.append(Variable(name, low, high, value, "" if unit == "law unit" else unit))
    return tuple(out)


def apply(mech: Mechanism, variables: tuple[Variable, ...], x) -> Mechanism:
    """``mech`` with variable ``i`` set to ``x[i]`` (values, not unit-cube coordinates;
    traceable: ``x`` may be a tracer under ``grad``/``vmap``)."""
    return replace_many(mech, {v.name: x[i] for i, v in enumerate(variables)})


def to_unit(variables: tuple[Variable, ...], x) -> np.ndarray:
    """Values -> unit-cube coordinates (NumPy)."""
    return np.asarray([v.to_unit(float(xi)) for v, xi in zip(variables, x)], dtype=float)


def from_unit(variables: tuple[Variable, ...], u):
    """Unit-cube coordinates -> values (traceable)."""
    return jnp.stack([v.from_unit(u[i]) for i, v in enumerate(variables)])


__all__ = ["Variable", "apply", "check_variables", "design_names", "from_unit", "to_unit"]
