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

    def pack(self) -> Float[Array, " 2n+6k"]:
        """One flat vector ``[q, qdot, memory fields (each (k,), in declaration order)]``.

        The solver integrates this vector: a single array leaf keeps its per-step bookkeeping
        (stage combinations, error norm, dense output) to one kernel per operation instead of
        one per field."""
        return jnp.concatenate([self.q, self.qdot, *jax.tree_util.tree_leaves(self.memory)])

    @staticmethod
    def unpack(v: Float[Array, " 2n+6k"], n: int, k: int) -> "State":
        """Inverse of :meth:`pack` for ``n`` coordinates and ``k`` clearance joints."""
        fields = [v[2 * n + i * k : 2 * n + (i + 1) * k] for i in range(len(ContactMemory.__dataclass_fields__))]
        return State(v[:n], v[n : 2 * n], ContactMemory(*fields))


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


UNROLL_LIMIT = 24  # constraint count up to which the elimination is unrolled


def spd_solve(a, b):
    r"""Solve ``a x = b`` for a small symmetric positive definite ``a`` (m, m).

    Up to :data:`UNROLL_LIMIT` equations: Gauss-Jordan elimination without pivoting, unrolled
    (no pivoting is needed: every trailing Schur complement of an SPD matrix is SPD, so every
    pivot is positive). Each pivot is a whole-matrix update
    :math:`A \leftarrow A - (A_{:k} - e_k) A_{k:} / a_{kk}` that XLA compiles to one or two small
    elementwise kernels; for the few-equation systems of planar mechanisms this is several times
    faster than a LAPACK call, and it avoids jaxlib's batched LAPACK path under ``vmap`` (which,
    in jaxlib 0.10, splits large batches over the CPU thread pool and can deadlock when two such
    solves run concurrently). Larger systems use a Cholesky factorization (LAPACK).
    """
    m = a.shape[0]
    if m > UNROLL_LIMIT:
        return jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(a), b)
    aug = jnp.concatenate([a, b[:, None]], axis=1)
    unit = jnp.eye(m, dtype=aug.dtype)
    for k in range(m):
        # row k <- row k / a_kk; row i <- row i - a_ik row k / a_kk, as one update
        aug = aug - (aug[:, k : k + 1] - unit[:, k : k + 1]) * (aug[k : k + 1, :] / aug[k, k])
    return aug[:, m]


def accelerations(mech: Mechanism, t, q, qdot, memory: ContactMemory, baumgarte: Baumgarte):
    """Solve the augmented system. Returns ``(qddot, lambda, Phi, contact)``."""
    t = jnp.asarray(t, q.dtype)
    g = applied_forces(mech, t, q, qdot)
    f_c, contact = contact_forces(mech, q, qdot, memory)
    g = g + f_c
    m_diag = mech.mass_matrix_diagonal().astype(q.dtype)
    if mech.n_constraints == 0:
        return g / m_diag, jnp.zeros((0,), q.dtype), jnp.zeros((0,), q.dtype), contact
    d = constraints.jacobian(mech, q, t)
    value, rate, gamma = constraints.velocity_terms(mech, q, qdot, t)
    rhs_c = gamma - 2.0 * baumgarte.alpha * rate - baumgarte.beta**2 * value
    # M is diagonal: eliminate qddot (Schur complement) and solve the symmetric positive definite
    # system (D M^-1 D^T) lambda = D M^-1 g - rhs_c, then qddot = M^-1 (g - D^T lambda). This is
    # the augmented system above, solved exactly; redundant constraints make it singular (NaN,
    # reported as a non-finite state).
    dm = d / m_diag
    # products written as broadcast-multiply-and-sum: XLA fuses them with their neighbours
    lam = spd_solve(jnp.sum(dm[:, None, :] * d[None, :, :], axis=-1), jnp.sum(dm * g, axis=-1) - rhs_c)
    return (g - jnp.sum(d * lam[:, None], axis=0)) / m_diag, lam, value, contact


def vector_field(t, y: State, args) -> State:
    """:math:`\\dot y = f(t, y)`; ``args = (mechanism, baumgarte)``. The memory is constant
    between steps except the contact work, whose rate is the contact power."""
    mech, baumgarte = args
    qdd, _, _, contact = accelerations(mech, t, y.q, y.qdot, y.memory, baumgarte)
    dmem = y.memory.zeros_like()
    if contact is not None:
        dmem = eqx.tree_at(lambda m: m.work, dmem, contact.power)
    return State(y.qdot, qdd, dmem)


@eqx.filter_jit
def flat_vector_field(t, v, args):
    """:func:`vector_field` on the packed state (:meth:`State.pack`); ``args = (mechanism,
    baumgarte)``.

    Jitted so that the several calls of one solver step (one per Runge-Kutta stage) are traced
    and lowered once; XLA inlines the calls."""
    mech = args[0]
    y = State.unpack(v, mech.n_coordinates, len(mech.clearance_joints))
    return vector_field(t, y, args).pack()


def energy(mech: Mechanism, q, qdot):
    """Kinetic plus gravitational potential energy [J] (contact elastic energy excluded)."""
    m = mech.mass_matrix_diagonal()
    kinetic = 0.5 * jnp.sum(m * qdot**2)
    heights = q.reshape(-1, 3)[:, :2]
    masses = m.reshape(-1, 3)[:, 0]
    potential = -jnp.sum(masses * (heights @ mech.gravity))
    return kinetic + potential


__all__ = ["State", "Baumgarte", "accelerations", "vector_field", "flat_vector_field", "energy", "ContactOutput"]
