"""Consistent initial conditions: positions and velocities that satisfy the constraints, with
every force element held at its initial configuration, and the eager checks that name what is
wrong with a mechanism that cannot be assembled."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InitialConditionError, MechanismError
from .._types import Array, Float
from ..model import constraints
from ..model.mechanism import Mechanism
from ._compile import jit
from ._dynamics import spd_solve
from ._settings import Settings
from ._state import State

#: How a user allows a driven mechanism's free motion, in each place a run is set up.
FREE_DOF_OPTION = ("Settings(allow_free_dof=True) in Python, --allow-free-dof on the command line (jaxclear check, "
                   "simulate, animate)")
NEWTON_ITERATIONS = 30
NEWTON_TOL = 1e-10  # [m or rad], residual norm of Phi
#: Steps of the continuation in the crank angle (:func:`assemble`): the angle drivers' misfit at
#: the guess is closed in this many equal steps, each followed by :data:`CONTINUATION_ITERATIONS`
#: Newton iterations, before the final :data:`NEWTON_ITERATIONS`. 16 steps move a crank half a
#: turn by 0.2 rad a step.
CONTINUATION_STEPS = 16
CONTINUATION_ITERATIONS = 6
RANK_TOL = 1e-9  # relative singular value below which constraints count as dependent


class Assembly(eqx.Module):
    """Result of the position/velocity solve (all arrays)."""

    q: Float[Array, " n"]
    qdot: Float[Array, " n"]
    residual: Float[Array, ""]
    jacobian: Float[Array, "m n"]


def minimum_norm_correction(d, r):
    r"""Minimum-norm :math:`x` with :math:`D x = r`: :math:`x = D^T (D D^T + \epsilon I)^{-1} r`
    (m, n) x (m,) -> (n,).

    The small Tikhonov term :math:`\epsilon = 10^{-13}\,\mathrm{tr}(D D^T)/m` keeps the solve
    finite for redundant (rank-deficient but consistent) constraints, which the eager checks
    then name; for independent constraints it changes the result by a relative
    :math:`\epsilon/\sigma_{min}^2`, removed by the Newton iterations (positions) and by one
    refinement step (velocities). The solve is :func:`~jaxclear.integrate.spd_solve`, an unrolled
    elimination: no LAPACK call, so a vmapped batch of assemblies (sweeps) never reaches jaxlib's
    batched CPU LAPACK kernels."""
    dd = jnp.sum(d[:, None, :] * d[None, :, :], axis=-1)
    m = dd.shape[0]
    eps = 1e-13 * jnp.trace(dd) / m
    y = spd_solve(dd + eps * jnp.eye(m, dtype=dd.dtype), r)
    return jnp.sum(d * y[:, None], axis=0)


def assemble(mech: Mechanism, t0=0.0) -> Assembly:
    r"""Consistent ``(q, qdot)`` at ``t0``.

    Positions: Newton iterations :math:`q \leftarrow q - D^+\Phi` (minimum-norm steps, so
    coordinates the constraints leave free stay at their guesses) on the joints, the drivers,
    every clearance joint held at its ``initial_offset`` (centred by default) and every flexible
    link held undeformed (``Mechanism.held_at_start``).
    Velocities: the guess corrected (minimum-norm) to :math:`D\dot q = -\Phi_t` on joints and
    drivers and to the prescribed relative velocity ``initial_velocity`` on every clearance
    joint (zero by default: the ideal-joint kinematics, journal moving with its bearing).
    :math:`D^+` is applied by :func:`minimum_norm_correction` (no LAPACK).

    **Continuation in the crank angle.** Where an angle driver's angle at ``t0`` differs from the
    guess's (a preset built at crank angle 0 started at ``angle0 = pi``), Newton from the guess
    can land on the linkage's other assembly branch: the benchmark slider-crank at ``angle0``
    near pi assembled with its slider at x = -0.17 m, the mirror image, instead of the
    0.07 m of the motion through 0. The drivers' misfit at the guess is therefore closed in
    :data:`CONTINUATION_STEPS` steps (each driver's ``angle0`` moved from where the guess
    satisfies it to its value, Newton iterations after each step), so that the branch is the
    guess's, as when the crank is turned by hand from the guess to ``angle0`` (Allgower and Georg
    1990, natural-parameter continuation).
    """
    q, qd = mech.guess()
    t0 = jnp.asarray(t0, q.dtype)
    extra = mech.held_at_start

    def newton_of(m):
        def newton(_, q):
            r = constraints.phi(m, q, t0, extra)
            d = constraints.jacobian(m, q, t0, extra)
            return q - minimum_norm_correction(d, r)
        return newton

    if mech.n_constraints + sum(c.n_equations for c in extra) == 0:
        return Assembly(q, qd, jnp.zeros((), q.dtype), jnp.zeros((0, q.shape[0]), q.dtype))
    turned = [i for i, d in enumerate(mech.drivers) if isinstance(getattr(d, "angle0", None), jax.Array)]
    if turned:
        misfit = jnp.stack([mech.drivers[i].equations(mech, q, t0)[0] for i in turned])

        def step(k, q):
            left = (1.0 - (k + 1.0) / CONTINUATION_STEPS) * misfit  # the part of the misfit not yet closed
            m = eqx.tree_at(lambda mm: [mm.drivers[i].angle0 for i in turned], mech,
                            [mech.drivers[i].angle0 + left[j] for j, i in enumerate(turned)])
            return jax.lax.fori_loop(0, CONTINUATION_ITERATIONS, newton_of(m), q)

        q = jax.lax.fori_loop(0, CONTINUATION_STEPS - 1, step, q)
    q = jax.lax.fori_loop(0, NEWTON_ITERATIONS, newton_of(mech), q)
    r = constraints.phi(mech, q, t0, extra)
    d = constraints.jacobian(mech, q, t0, extra)
    phit = constraints.time_derivative(mech, q, t0, extra)
    # clearance joints: prescribed relative journal velocity (zero by default); flexible links: none
    target = jnp.concatenate([jnp.zeros(mech.n_constraints, q.dtype)] + [c.assembly_velocity() for c in extra])
    for _ in range(2):  # one projection and one refinement step
        qd = qd - minimum_norm_correction(d, d @ qd + phit - target)
    return Assembly(q, qd, jnp.linalg.norm(r), d)


_assemble_jit = jit(assemble)
#: An :class:`Assembly` whose pytree structure is that of every assembly (for stored programs).
ASSEMBLY_TEMPLATE = Assembly(0, 0, 0, 0)


def _dependent_rows(d: np.ndarray, tol: float) -> list[int]:
    rows, kept = [], []
    scale = max(np.abs(d).max(), 1.0)
    for k in range(d.shape[0]):
        trial = d[kept + [k]]
        if np.linalg.matrix_rank(trial, tol=tol * scale) < len(kept) + 1:
            rows.append(k)
        else:
            kept.append(k)
    return rows


def check_assembly(mech: Mechanism, s: Settings, asm: Assembly | None = None) -> Assembly:
    """Eager checks with detailed messages (concrete inputs only): Newton convergence,
    redundant constraints, too few constraints for the drivers. Returns the assembly.

    ``asm``: the assembly at ``s.t_start`` if already computed (:func:`~jaxclear.simulate`
    returns it from its own program, so a first call compiles one program, not two); else it is
    computed here."""
    if asm is None:
        asm = _assemble_jit.stored("assemble", lambda: jax.tree_util.tree_structure(ASSEMBLY_TEMPLATE), mech,
                                   s.t_start)
    extra = mech.held_at_start
    d = np.asarray(asm.jacobian)
    m, n = d.shape
    if m > n:  # never assembled: named before Newton's failure, which it causes
        held = sum(c.n_equations for c in extra)
        labels = constraints.constraint_labels(mech, extra=extra)
        # the clearance joints' rows first: the joints and drivers that conflict with them are named
        order = list(range(m - held, m)) + list(range(m - held))
        names = ", ".join(labels[order[k]] for k in _dependent_rows(d[order], RANK_TOL))
        raise MechanismError(
            f"redundant or conflicting constraints: {m} equations for {n} coordinates at assembly "
            f"({m - held} of joints and drivers, {held} of the clearance joints "
            f"{[c.name for c in extra]} held at their initial offsets); rows {names} depend on the others; remove "
            "joints or drivers (allowed: at most one independent equation per coordinate)"
        )
    if not np.isfinite(float(asm.residual)) or float(asm.residual) > NEWTON_TOL:
        raise InitialConditionError(
            f"the Newton solve of Phi(q, {s.t_start:g}) = 0 did not converge: residual "
            f"{float(asm.residual):.3g} > {NEWTON_TOL:g} after {NEWTON_ITERATIONS} iterations from the "
            "bodies' position guesses; improve Body.position (or check that the links can be assembled)"
        )
    dependent = _dependent_rows(d, RANK_TOL) if m else []
    if dependent:
        labels = constraints.constraint_labels(mech, extra=extra)
        names = ", ".join(labels[k] for k in dependent)
        raise MechanismError(
            f"redundant or conflicting constraints: rows {names} depend on the others at the initial "
            f"configuration (rank {m - len(dependent)} < {m} equations); remove them (allowed: "
            "independent constraint equations only)"
        )
    if mech.drivers and m < n and not s.allow_free_dof:
        raise MechanismError(
            f"too few constraints for the drivers: {n} coordinates but only {m} independent equations "
            f"(joints, drivers, clearance joints held centred), so {n - m} degree(s) of freedom are neither "
            f"driven nor constrained; add joints or drivers, or allow the free motion: {FREE_DOF_OPTION}"
        )
    return asm


def initial_state(mech: Mechanism, s: Settings | None = None, assembly: Assembly | None = None) -> State:
    """The start state: assembled ``(q, qdot)`` and every force element's initial state."""
    asm = assemble(mech, 0.0 if s is None else s.t_start) if assembly is None else assembly
    return State(asm.q, asm.qdot, tuple(el.state_init(asm.q.dtype) for el in mech.clearance_joints))
