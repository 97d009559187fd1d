r"""Archard wear of a journal bearing, from the hybrid model's contact field.

Archard's law (Archard, "Contact and rubbing of flat surfaces", J. Appl. Phys. 24 (1953) 981-988)
gives the wear depth rate at a surface point as

.. math::  \dot h = k_w\,p\,v_s

with :math:`p` the contact pressure [Pa], :math:`v_s` the sliding speed there [m/s] and
:math:`k_w` the dimensional wear coefficient [m^2/N] (the dimensionless coefficient over the
hardness; 1e-17 to 1e-14 m^2/N for lubricated to dry steel pairs). The hybrid Gauss-point
model (:class:`~jaxclear.HybridLaw`) resolves the pressure point by point
(:meth:`~jaxclear.HybridLaw.surface`: each point's normal force :math:`f_k = p_k A_k`, its slip
speed and its angle :math:`\beta_k` in the bearing body), so the worn volume rate is
:math:`\dot V = k_w\sum_k f_k |v_{s,k}|`. It is deposited on ``n_nodes`` bearing-fixed nodes
(uniform in :math:`\beta`, periodic linear hat functions, so the deposited volume equals
:math:`\dot V` exactly) and turned into depth by the node's area :math:`R_B\,\Delta\beta\,L`;
the time integral over a window uses the trapezoid rule on the output samples. This is the
scheme of Flores, "Modeling and simulation of wear in revolute clearance joints in multibody
systems", Mech. Mach. Theory 44 (2009) 1211-1222, and Mukras, Kim, Mauntler, Schmitz, Sawyer,
"Analysis of planar multibody systems with revolute joint wear", Wear 268 (2010) 643-652, with
the hybrid model's pressure field in place of a Hertzian strip.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError
from .._types import Array, Float, Scalar
from ..contact.hybrid import HybridLaw
from ..elements.revolute_clearance import AbstractJournalJoint
from ..integrate import Solution
from ..model.mechanism import Mechanism


def wear_element(mech: Mechanism, joint: int | str | None) -> int:
    """Index of the clearance joint to wear (by index or name; ``None``: the only one), checked to
    be a journal joint with the hybrid law at body-fixed points (``placement="fixed"``): the
    pressure field Archard's law needs, on a profile that can change."""
    elements = mech.elements
    if joint is None:
        if len(elements) != 1:
            raise ParameterError(f"joint: the mechanism has {len(elements)} force elements; name the one to wear "
                                 f"(one of {[e.label for e in elements]})")
        index = 0
    elif isinstance(joint, str):
        names = [e.label for e in elements]
        if joint not in names:
            raise ParameterError(f"joint = {joint!r} is not a force element of the mechanism (one of {names})")
        index = names.index(joint)
    else:
        index = int(joint)
        if not 0 <= index < len(elements):
            raise ParameterError(f"joint = {index} is outside the allowed range [0, {len(elements) - 1}]")
    element = elements[index]
    if not isinstance(element, AbstractJournalJoint) or not isinstance(element.law, HybridLaw):
        raise ParameterError(
            f"joint {element.label!r}: wear needs a journal joint with the hybrid Gauss-point law "
            "(law 'hybrid', placement 'fixed'): Archard's law needs the contact pressure point by point")
    if element.law.placement != "fixed":
        raise ParameterError(f"joint {element.label!r}: wear needs the hybrid law's placement 'fixed' (got "
                             f"{element.law.placement!r}): a worn bearing is not a circle")
    return index


def point_wear_rates(element: AbstractJournalJoint, mech: Mechanism, q, qdot, impact_velocity: Scalar):
    r"""Angles :math:`\beta_k` in the bearing body [rad] ``(N,)`` and worn-volume rates per unit
    wear coefficient :math:`f_k|v_{s,k}|` [N m/s] ``(N,)`` of the hybrid law's points at one
    state (``impact_velocity``: the joint's impact memory, floored as the force path floors it)."""
    kin = element.kinematics(mech, q, qdot)
    speed0 = jnp.maximum(impact_velocity, element.impact_velocity_floor)
    beta, force, slip = element.law.surface(kin, speed0)
    return beta, force * jnp.abs(slip)


def deposit(beta: Float[Array, " N"], amount: Float[Array, " N"], n_nodes: int) -> Float[Array, " n_nodes"]:
    r"""Share ``amount`` (N,) among ``n_nodes`` uniform periodic nodes :math:`\beta_j = 2\pi j/n`
    by linear hat functions of the angles ``beta`` (N,) [rad]; the sum is conserved exactly."""
    step = 2.0 * jnp.pi / n_nodes
    x = jnp.mod(beta, 2.0 * jnp.pi) / step
    j0 = jnp.floor(x)
    frac = x - j0
    j0 = j0.astype(jnp.int32) % n_nodes
    nodes = jnp.zeros((n_nodes,), amount.dtype)
    nodes = nodes.at[j0].add((1.0 - frac) * amount)
    return nodes.at[(j0 + 1) % n_nodes].add(frac * amount)


def trapezoid_weights(ts: Float[Array, " T"], t_from: Scalar) -> Float[Array, " T"]:
    """Trapezoid weights [s] of the samples ``ts`` over the samples at or after ``t_from`` (a
    sample within rounding, 1e-9 of the span, of ``t_from`` counts as at it)."""
    inside = ts >= t_from - 1e-9 * (ts[-1] - ts[0])
    dt = jnp.where(inside[1:] & inside[:-1], jnp.diff(ts), 0.0)
    return jnp.concatenate([0.5 * dt, jnp.zeros(1, ts.dtype)]) + jnp.concatenate([jnp.zeros(1, ts.dtype), 0.5 * dt])


class WindowWear(eqx.Module):
    """Wear of one simulated window.

    Attributes:
        depth: wear depth at the bearing nodes [m] ``(n_nodes,)`` (node ``j`` at angle
            :math:`2\\pi j/n` in the bearing body).
        volume: worn volume [m^3] (:math:`k_w\\int\\sum_k f_k|v_{s,k}|\\,dt`).
        duration: integrated time [s].
    """

    depth: Float[Array, " n_nodes"]
    volume: Scalar
    duration: Scalar


def window_wear(mech: Mechanism, sol: Solution, index: int, coefficient, n_nodes: int, t_from=None) -> WindowWear:
    """Archard wear of clearance joint ``index`` over the output samples of ``sol`` at or after
    ``t_from`` [s] (default: all), with wear coefficient ``coefficient`` [m^2/N]."""
    element = mech.elements[index]
    memory = sol.element_states[index]
    ts = sol.ts
    t_from = ts[0] if t_from is None else t_from
    beta, rate = jax.vmap(lambda q, qd, v0: point_wear_rates(element, mech, q, qd, v0))(
        sol.q, sol.qdot, memory.impact_velocity)
    per_node = jax.vmap(lambda b, r: deposit(b, r, n_nodes))(beta, rate)  # (T, n_nodes) [N m/s]
    weights = trapezoid_weights(ts, t_from)
    volume_nodes = coefficient * jnp.einsum("t,tn->n", weights, per_node)  # [m^3]
    area = element.bearing_radius * (2.0 * jnp.pi / n_nodes) * element.length
    return WindowWear(depth=volume_nodes / area, volume=jnp.sum(volume_nodes), duration=jnp.sum(weights))
