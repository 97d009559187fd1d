r"""The impact-memory rule: the approach speed :math:`\dot\delta^{(-)}` at the onset of a
contact, which the dissipative laws divide by, is history; an element carries it (with the
onset time, the impact count, the work of its forces and running peaks) in its state and
updates it after every accepted solver step.

Rule (per contact, with penetration :math:`\delta` and rate :math:`\dot\delta` at both ends of
an accepted step ``[t0, t1]``; Flores, Ambrósio, Claro, Lankarani, "Kinematics and Dynamics of
Multibody Systems with Imperfect Joints", Springer 2008, ch. 4):

* :math:`\delta_1 \le 0` (free at the step's end): :math:`\dot\delta^{(-)} \leftarrow \dot\delta_1`;
* :math:`\delta_0 \le 0 < \delta_1` (the step crossed into contact): :math:`\dot\delta^{(-)}
  \leftarrow \dot\delta(t_c)` at the crossing :math:`t_c` of the cubic Hermite interpolant of
  :math:`\delta` over the step (exact to the step's third order), onset time :math:`t_c`,
  impacts + 1;
* in contact at both ends: unchanged.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._types import BoolScalar, Scalar


class ContactMemory(eqx.Module):
    """History of one contact (scalars), or of several stacked along a trailing axis ``(..., k)``.

    Attributes:
        impact_velocity: :math:`\\dot\\delta^{(-)}` [m/s], approach speed at the onset of the
            current contact (out of contact it tracks the current :math:`\\dot\\delta`).
        contact_start: time of the last contact onset [s] (a large negative sentinel before the
            first).
        impacts: number of contact onsets so far.
        work: work done on the mechanism by the contact forces since the start [J]
            (its decrease over a closed contact is the energy the contact dissipated).
        peak_force: largest normal force [N] at any accepted step's end so far (steps are
            short during contact, so this resolves peaks that an output grid misses).
        peak_penetration: largest penetration [m] at any accepted step's end so far.
    """

    impact_velocity: Scalar
    contact_start: Scalar
    impacts: Scalar
    work: Scalar
    peak_force: Scalar
    peak_penetration: Scalar

    @staticmethod
    def initial(shape=(), dtype=float) -> "ContactMemory":
        """Memory before any contact. ``shape`` may be an int (number of contacts)."""
        z = jnp.zeros(shape, dtype)
        # finite sentinels (not -inf): dense interpolation of the state may difference two samples
        return ContactMemory(z, jnp.full(shape, -1e9, dtype), z, z, z, jnp.full(shape, -1.0, dtype))

    def summary(self) -> "ContactMemory":
        """The element's memory as one contact (itself); elements with several contacts (the
        translational clearance joint) reduce theirs to one (``Solution.memory``)."""
        return self

    def zeros_like(self) -> "ContactMemory":
        z = jnp.zeros_like(self.impacts)
        return ContactMemory(z, z, z, z, z, z)

    def rate(self, power: Scalar) -> "ContactMemory":
        """Time derivative of the memory: zero except the work, whose rate is the power [W]."""
        return eqx.tree_at(lambda m: m.work, self.zeros_like(), power)


N_FIELDS = len(ContactMemory.__dataclass_fields__)


def hermite_crossing(p0, p1, r0, r1, h, crossed):
    """Root ``s`` in [0, 1] of the cubic Hermite interpolant of the penetration over a step
    (values ``p0, p1`` [m], rates ``r0, r1`` [m/s], step ``h`` [s]) and the interpolated rate
    there; six Newton iterations from the secant root.

    ``h`` may be 0 (under ``vmap`` the members of a batch that have finished take empty steps
    while the others go on): a safe step keeps the masked branch finite, so reverse mode gets no
    NaN cotangents."""
    h = jnp.where(h > 0, h, 1.0)
    denom = jnp.where(crossed, p0 - p1, 1.0)
    s = jnp.clip(jnp.where(crossed, p0 / denom, 0.5), 0.0, 1.0)

    def value_and_slope(s):
        s2, s3 = s * s, s * s * s
        val = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * r0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * h * r1
        slope = (6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * h * r0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * h * r1
        return val, slope

    for _ in range(6):
        val, slope = value_and_slope(s)
        ok = jnp.abs(slope) > 1e-300
        s = jnp.clip(s - jnp.where(ok, val / jnp.where(ok, slope, 1.0), 0.0), 0.0, 1.0)
    _, slope = value_and_slope(s)
    return s, slope / h


def onset_fraction(p0, p1, r0, r1, h) -> tuple[Scalar, BoolScalar]:
    r"""Fraction ``s`` in [0, 1] of a step ``h`` [s] at which the penetration (``p0, p1`` [m],
    rates ``r0, r1`` [m/s] at its ends; any matching shapes) crosses into contact, and whether
    it does (:math:`\delta_0 \le 0 < \delta_1`); ``s = 1`` where it does not."""
    crossed = (p0 <= 0.0) & (p1 > 0.0)
    s, _ = hermite_crossing(p0, p1, r0, r1, h, crossed)
    return jnp.where(crossed, s, 1.0), crossed


def onset_update(memory: ContactMemory, t0, t1, p0, p1, r0, r1) -> tuple[ContactMemory, BoolScalar]:
    """Apply the impact-memory rule (module docstring) to one contact over the step ``[t0, t1]``
    with penetrations ``p0, p1`` [m] and rates ``r0, r1`` [m/s] at its ends. Returns the new
    memory (peaks not yet updated) and whether the step crossed into contact."""
    h = t1 - t0
    crossed = (p0 <= 0.0) & (p1 > 0.0)
    s, rate_c = hermite_crossing(p0, p1, r0, r1, h, crossed)
    v = jnp.where(p1 <= 0.0, r1, jnp.where(crossed, rate_c, memory.impact_velocity))
    new = ContactMemory(
        impact_velocity=v,
        contact_start=jnp.where(crossed, t0 + s * h, memory.contact_start),
        impacts=memory.impacts + crossed.astype(memory.impacts.dtype),
        work=memory.work,
        peak_force=memory.peak_force,
        peak_penetration=jnp.maximum(memory.peak_penetration, p1),
    )
    return new, crossed


def with_peak_force(memory: ContactMemory, force: Scalar) -> ContactMemory:
    """``memory`` with its running peak force raised to ``force`` [N]."""
    return eqx.tree_at(lambda m: m.peak_force, memory, jnp.maximum(memory.peak_force, force))
