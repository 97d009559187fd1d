r"""Equations of motion of a constrained planar multibody system with clearance joints
(spec section 1; Nikravesh 1988; Baumgarte, Comput. Methods Appl. Mech. Eng. 1 (1972) 1-16):

.. math::
    \begin{bmatrix} M & D^T \\ D & 0 \end{bmatrix}
    \begin{bmatrix} \ddot q \\ \lambda \end{bmatrix} =
    \begin{bmatrix} g(q, \dot q, t) \\ \gamma - 2\alpha\dot\Phi - \beta^2\Phi \end{bmatrix}

``g`` holds gravity, applied loads and the clearance-joint contact forces. The state is
:class:`State` ``(q, qdot, memory)``; the vector field is :func:`vector_field`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import constraints
from .clearance import ContactMemory, ContactOutput, joint_forces
from .mechanism import Mechanism, PointForce, Torque, point_load, point_position


class State(eqx.Module):
    """Solution vector: coordinates q (n,) [m, rad], velocities qdot (n,) and contact memory."""

    q: Float[Array, " n"]
    qdot: Float[Array, " n"]
    memory: ContactMemory


class Baumgarte(eqx.Module):
    """Baumgarte stabilization gains alpha, beta [1/s] (5, 5 is usual for clearance joints)."""

    alpha: Float[Array, ""]
    beta: Float[Array, ""]


def applied_forces(mech: Mechanism, t, q, qdot):
    """Generalized gravity and applied loads (n,)."""
    m = mech.mass_matrix_diagonal()
    grav = jnp.tile(jnp.concatenate([mech.gravity, jnp.zeros(1)]), mech.n_bodies) * m
    g = grav.astype(q.dtype)
    for load in mech.loads:
        i = mech.body_index(load.body)
        if isinstance(load, PointForce):
            f = load.force
            if load.function is not None:
                f = f + load.function(t, q, qdot)
            g = g + point_load(mech, q, load.body, point_position(mech, q, load.body, load.point), f)
        elif isinstance(load, Torque):
            tau = load.torque
            if load.function is not None:
                tau = tau + load.function(t, q, qdot)
            g = g.at[3 * i + 2].add(tau)
    return g


def contact_forces(mech: Mechanism, q, qdot, memory: ContactMemory):
    """Total generalized contact force (n,) and the per-joint :class:`ContactOutput` stacked
    along a leading axis of length ``n_joints`` (``None`` without clearance joints)."""
    total = jnp.zeros_like(q)
    outs = []
    for k, joint in enumerate(mech.clearance_joints):
        gen, out = joint_forces(mech, joint, q, qdot, memory.impact_velocity[k])
        total = total + gen
        outs.append(out)
    if not outs:
        return total, None
    return total, jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *outs)


def accelerations(mech: Mechanism, t, q, qdot, memory: ContactMemory, baumgarte: Baumgarte):
    """Solve the augmented system. Returns ``(qddot, lambda, Phi, contact)``."""
    t = jnp.asarray(t, q.dtype)
    g = applied_forces(mech, t, q, qdot)
    f_c, contact = contact_forces(mech, q, qdot, memory)
    g = g + f_c
    m_diag = mech.mass_matrix_diagonal().astype(q.dtype)
    n = q.shape[0]
    if mech.n_constraints == 0:
        return g / m_diag, jnp.zeros((0,), q.dtype), jnp.zeros((0,), q.dtype), contact
    d = constraints.jacobian(mech, q, t)
    value, rate, gamma = constraints.velocity_terms(mech, q, qdot, t)
    rhs_c = gamma - 2.0 * baumgarte.alpha * rate - baumgarte.beta**2 * value
    m = d.shape[0]
    a = jnp.block([[jnp.diag(m_diag), d.T], [d, jnp.zeros((m, m), q.dtype)]])
    sol = jnp.linalg.solve(a, jnp.concatenate([g, rhs_c]))
    return sol[:n], sol[n:], value, contact


def vector_field(t, y: State, args) -> State:
    """:math:`\\dot y = f(t, y)`; ``args = (mechanism, baumgarte)``. The memory is constant
    between steps except the contact work, whose rate is the contact power."""
    mech, baumgarte = args
    qdd, _, _, contact = accelerations(mech, t, y.q, y.qdot, y.memory, baumgarte)
    dmem = y.memory.zeros_like()
    if contact is not None:
        dmem = eqx.tree_at(lambda m: m.work, dmem, contact.power)
    return State(y.qdot, qdd, dmem)


def energy(mech: Mechanism, q, qdot):
    """Kinetic plus gravitational potential energy [J] (contact elastic energy excluded)."""
    m = mech.mass_matrix_diagonal()
    kinetic = 0.5 * jnp.sum(m * qdot**2)
    heights = q.reshape(-1, 3)[:, :2]
    masses = m.reshape(-1, 3)[:, 0]
    potential = -jnp.sum(masses * (heights @ mech.gravity))
    return kinetic + potential


__all__ = ["State", "Baumgarte", "accelerations", "vector_field", "energy", "ContactOutput"]
