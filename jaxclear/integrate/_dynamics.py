r"""Equations of motion of a constrained planar multibody system with clearance joints
(Nikravesh 1988; Baumgarte, Comput. Methods Appl. Mech. Eng. 1 (1972) 1-16):

.. math::
    \begin{bmatrix} M & D^T \\ D & 0 \end{bmatrix}
    \begin{bmatrix} \ddot q \\ \lambda \end{bmatrix} =
    \begin{bmatrix} g(q, \dot q, t) \\ \gamma - 2\alpha\dot\Phi - \beta^2\Phi \end{bmatrix}

``g`` holds gravity, applied loads and the force elements' forces (clearance joints). The
state is :class:`~jaxclear.integrate.State` ``(q, qdot, element states)``; the vector
field is :func:`vector_field`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, Float
from ..elements.base import stack_outputs
from ..model import constraints
from ..model.loads import gravity_force
from ..model.mechanism import Mechanism
from ._state import State, element_states


class Baumgarte(eqx.Module):
    """Baumgarte stabilization gains alpha, beta [1/s] (5, 5 is usual for clearance joints)."""

    alpha: Float[Array, ""]
    beta: Float[Array, ""]


UNROLL_LIMIT = 24  # constraint count up to which the elimination is unrolled
ENTRYWISE_LIMIT = 12  # constraint count up to which it is written entry by entry (spd_solve)


@jax.jit
def _gauss_jordan(a, b):
    """The unrolled elimination of :func:`spd_solve` written on the entries one by one: ``a``
    (m, m), ``b`` (m,); every entry is a scalar (under ``vmap`` a vector over the batch).

    A nested ``jax.jit``: its ~m^3 scalar operations (1,200 at m = 8) are traced once per shape
    and reused at every call of a trace (the vector field is traced several times a program, and
    this solve was three quarters of the operations traced), and lowered once as a function the
    program calls; XLA inlines the call before optimising, so the compiled program is as before."""
    m = a.shape[0]
    rows = [[a[i, j] for j in range(m)] + [b[i]] for i in range(m)]
    for k in range(m):
        pivot = [x / rows[k][k] for x in rows[k]]
        rows = [pivot if i == k else [x - r[k] * p for x, p in zip(r, pivot)] for i, r in enumerate(rows)]
    return jnp.stack([r[m] for r in rows])


@jax.custom_jvp
def _solve_entrywise(a, b):
    return _gauss_jordan(a, b)


@_solve_entrywise.defjvp
def _solve_entrywise_jvp(primals, tangents):
    # a x = b  =>  a dx = db - da x: one more elimination with the same matrix (XLA shares its
    # matrix part with the primal's) instead of the derivative of each of its scalar operations,
    # whose forward-mode programs compiled far more slowly (a fit test 92 s against 53 s)
    a, b = primals
    da, db = tangents
    x = _gauss_jordan(a, b)
    return x, _gauss_jordan(a, db - jnp.sum(da * x[None, :], axis=1))


def spd_solve(a, b, entrywise: bool | None = None):
    r"""Solve ``a x = b`` for a small symmetric positive definite ``a`` (m, m).

    Up to :data:`UNROLL_LIMIT` equations: Gauss-Jordan elimination without pivoting, unrolled
    (no pivoting is needed: every trailing Schur complement of an SPD matrix is SPD, so every
    pivot is positive); for the few-equation systems of planar mechanisms this is several times
    faster than a LAPACK call, and it avoids jaxlib's batched LAPACK path under ``vmap`` (which,
    in jaxlib 0.10, splits large batches over the CPU thread pool and can deadlock when two such
    solves run concurrently). Larger systems use a Cholesky factorization (LAPACK).

    Two forms of the elimination: ``entrywise`` (the default up to :data:`ENTRYWISE_LIMIT`
    equations, ``None``) writes it on the entries one by one, with its derivative as one more
    solve (:math:`a\,\dot x = \dot b - \dot a\,x`, a custom JVP); otherwise each pivot is a
    whole-matrix update :math:`A \leftarrow A - (A_{:k} - e_k) A_{k:} / a_{kk}` (its trace grows
    like m, the entry-wise one's like m^3). Measured 2026-11-25 (Intel Xeon, 2 cores) on the
    benchmark (m = 7): the output post-processing of 24,001 samples 12 ms against 16 ms under
    ``vmap``; inside the integration loop compiled as one kernel (``jaxclear/_xla_flags.py``)
    15-20 % less time per step, 10-30 % less at equal accuracy (``bench_accuracy.py``).
    """
    m = a.shape[0]
    if m > UNROLL_LIMIT:
        return jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(a), b)
    if entrywise is None:
        entrywise = m <= ENTRYWISE_LIMIT
    if entrywise:
        return _solve_entrywise(a, b)
    aug = jnp.concatenate([a, b[:, None]], axis=1)
    unit = jnp.eye(m, dtype=aug.dtype)
    for k in range(m):
        # row k <- row k / a_kk; row i <- row i - a_ik row k / a_kk, as one update
        aug = aug - (aug[:, k : k + 1] - unit[:, k : k + 1]) * (aug[k : k + 1, :] / aug[k, k])
    return aug[:, m]


def applied_forces(mech: Mechanism, t, q, qdot) -> Float[Array, " n"]:
    """Generalized gravity and applied loads (n,)."""
    g = gravity_force(mech, q.dtype)
    for load in mech.loads:
        g = g + load.generalized_force(mech, t, q, qdot)
    return g


def element_forces(mech: Mechanism, t, q, qdot, states: tuple):
    """Sum of the force elements' generalized forces (n,), their state derivatives (tuple, one
    per element) and their outputs stacked along a leading element axis (``None`` without
    elements)."""
    total = jnp.zeros_like(q)
    rates, outs = [], []
    for element, state in zip(mech.clearance_joints, states):
        gen, rate, out = element.forces(mech, t, q, qdot, state)
        total = total + gen
        rates.append(rate)
        outs.append(out)
    return total, tuple(rates), stack_outputs(outs)


def _accelerations(mech: Mechanism, t, q, qdot, states: tuple, baumgarte: Baumgarte):
    """Solve the augmented system. Returns ``(qddot, lambda, Phi, element rates, outputs)``."""
    t = jnp.asarray(t, q.dtype)
    f_e, rates, contact = element_forces(mech, t, q, qdot, states)
    g = applied_forces(mech, t, q, qdot) + f_e
    m_diag = mech.mass_matrix_diagonal().astype(q.dtype)
    if mech.n_constraints == 0:
        return g / m_diag, jnp.zeros((0,), q.dtype), jnp.zeros((0,), q.dtype), rates, contact
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
    return (g - jnp.sum(d * lam[:, None], axis=0)) / m_diag, lam, value, rates, contact


def accelerations(mech: Mechanism, t, q, qdot, states, baumgarte: Baumgarte):
    """Solve the augmented system for the state ``(q, qdot, states)``, ``states`` being the
    force elements' states (a tuple, or a :class:`~jaxclear.elements.memory.ContactMemory`
    stacked over the clearance joints). Returns ``(qddot, lambda, Phi, outputs)``: accelerations
    (n,), Lagrange multipliers (m,), constraint residual (m,) and the elements' outputs stacked
    along a leading element axis (``None`` without elements)."""
    qdd, lam, value, _, contact = _accelerations(mech, t, q, qdot, element_states(mech, states), baumgarte)
    return qdd, lam, value, contact


def vector_field(t, y: State, args) -> State:
    """:math:`\\dot y = f(t, y)`; ``args = (mechanism, baumgarte)``. The elements' states
    change at the rates their :meth:`forces` return (memory entries are constant between
    steps; the contact work integrates the contact power)."""
    mech, baumgarte = args
    qdd, _, _, rates, _ = _accelerations(mech, t, y.q, y.qdot, y.elements, baumgarte)
    return State(y.qdot, qdd, rates)


def flat_vector_field(t, v, args):
    """:func:`vector_field` on the packed state (:meth:`State.pack`); ``args = (mechanism,
    baumgarte)``.

    Jitted so that the several calls of one solver step (one per Runge-Kutta stage) are traced
    and lowered once; XLA inlines the calls. A time given as a Python number is made an array
    first: ``equinox.filter_jit`` would take it as a static argument, one compilation per
    value (every stage time of a solver stepped by hand)."""
    if isinstance(t, (int, float)):
        t = jnp.asarray(t, dtype=float)
    return _flat_vector_field(t, v, args)


@eqx.filter_jit
def _flat_vector_field(t, v, args):
    mech = args[0]
    y = State.unpack(v, mech)
    return vector_field(t, y, args).pack()


def energy(mech: Mechanism, q, qdot):
    """Kinetic plus gravitational potential energy [J] (contact elastic energy excluded)."""
    m = mech.mass_matrix_diagonal()
    kinetic = 0.5 * jnp.sum(m * qdot**2)
    heights = q.reshape(-1, 3)[:, :2]
    masses = m.reshape(-1, 3)[:, 0]
    potential = -jnp.sum(masses * (heights @ mech.gravity))
    return kinetic + potential
