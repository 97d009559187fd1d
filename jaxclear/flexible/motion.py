r"""The motion of a lone supported beam: the equations of motion of the ANCF coordinates under
their supports, integrated by diffrax.

With the constant mass matrix :math:`M`, the elastic and damping forces
:math:`Q_e(e) + Q_d(e, \dot e)` (:class:`~jaxclear.flexible.beam.AncfBeam`), the constant
applied force :math:`f` (gravity and point loads) and the supports :math:`\Phi(e, t) = 0`
(:mod:`jaxclear.flexible.supports`), the accelerations and multipliers solve the augmented
system of the mechanism's equations (:mod:`jaxclear.integrate._dynamics`; Nikravesh 1988,
Baumgarte 1972)

.. math::
    \begin{bmatrix} M & D^T \\ D & 0 \end{bmatrix}
    \begin{bmatrix} \ddot e \\ \lambda \end{bmatrix} =
    \begin{bmatrix} Q_e + Q_d + f \\ \gamma - 2\alpha\dot\Phi - \beta^2\Phi \end{bmatrix},

by the Schur complement: :math:`M` is factored once per run (Cholesky), then
:math:`(D M^{-1} D^T)\lambda = D M^{-1} Q - \gamma_B` and :math:`\ddot e = M^{-1}(Q - D^T\lambda)`;
:math:`D`, :math:`\dot\Phi` and :math:`\gamma` come from forward-mode differentiation of
:math:`\Phi` as in :mod:`jaxclear.model.constraints`. The state is
:math:`[e, \dot e, W_d]` with the dissipated energy :math:`W_d` [J], :math:`\dot W_d = 2\mathcal{D}`
(Kelvin-Voigt), so the energy balance :math:`E(t) + W_d(t) = E(0) + W_{\mathrm{supports}}` is
checkable (a fixed support does no work; a driven one, :class:`~jaxclear.flexible.supports.SpinUp`, does).

Solvers: ``"tsit5"`` (explicit, Tsitouras 5(4)) or ``"kvaerno5"`` (implicit ESDIRK 5(4),
Kvaerno 2004; Newton on the stage equations with the vector field's Jacobian). A beam's axial
and high bending frequencies lie far above the motion's (a steel element of length h vibrates
axially at about :math:`2\sqrt{3}\,c/h`, :math:`c = \sqrt{E/\rho}`), so an explicit solver's
step is held by stability, not accuracy: the implicit one takes steps the motion allows
(docs/theory/flexible-links.md: what each costs).
"""

from __future__ import annotations

from typing import Sequence

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError, check_range
from .._types import Array, Float, Scalar
from .beam import AncfBeam
from .statics import applied_force, support_equations
from .supports import AbstractSupport, BeamLoad, check_supports

SOLVERS = {"tsit5": diffrax.Tsit5, "kvaerno5": diffrax.Kvaerno5}


class BeamSystem(eqx.Module):
    """A beam, its supports and loads, gravity [m/s^2] and the Baumgarte gains alpha, beta [1/s]."""

    beam: AncfBeam
    supports: tuple
    loads: tuple
    gravity: Float[Array, "2"]
    alpha: Scalar
    beta: Scalar

    def __init__(self, beam: AncfBeam, supports: Sequence[AbstractSupport] = (), loads: Sequence[BeamLoad] = (),
                 gravity=(0.0, -9.81), alpha=5.0, beta=5.0):
        check_supports(beam, supports, loads)
        check_range("Baumgarte alpha", alpha, low=0.0, unit="1/s")
        check_range("Baumgarte beta", beta, low=0.0, unit="1/s")
        self.beam, self.supports, self.loads = beam, tuple(supports), tuple(loads)
        self.gravity = jnp.asarray(gravity, float)
        self.alpha, self.beta = jnp.asarray(alpha, float), jnp.asarray(beta, float)

    def accelerations(self, t, e, edot, factor, force) -> tuple[Float[Array, " n"], Float[Array, " m"]]:
        """``(e_ddot, lambda)`` (module docstring); ``factor``: the Cholesky factor of M
        (``jax.scipy.linalg.cho_factor``), ``force``: the constant applied force (n,)."""
        q = self.beam.elastic_force(e) + self.beam.damping_force(e, edot) + force
        minv_q = jax.scipy.linalg.cho_solve(factor, q)
        if not self.supports:
            return minv_q, jnp.zeros((0,), e.dtype)
        one = jnp.ones((), e.dtype)

        def along(s):
            return support_equations(self.beam, self.supports, e + s * edot, t + s)

        def first(s):
            return jax.jvp(along, (s,), (one,))

        (value, rate), (_, second) = jax.jvp(first, (jnp.zeros((), e.dtype),), (one,))
        d = jax.jacfwd(lambda ee: support_equations(self.beam, self.supports, ee, t))(e)
        rhs = -second - 2.0 * self.alpha * rate - self.beta**2 * value
        minv_dt = jax.scipy.linalg.cho_solve(factor, d.T)
        lam = jnp.linalg.solve(d @ minv_dt, d @ minv_q - rhs)
        return minv_q - minv_dt @ lam, lam


class BeamRun(eqx.Module):
    """Samples of a run: times ``ts`` (k,), coordinates ``e`` (k, n), velocities ``edot``
    (k, n), dissipated energy ``dissipated`` (k,) [J], the solver's ``steps`` (accepted) and
    ``rejected`` counts and diffrax's ``result``."""

    ts: Float[Array, " k"]
    e: Float[Array, "k n"]
    edot: Float[Array, "k n"]
    dissipated: Float[Array, " k"]
    steps: Array
    rejected: Array
    result: diffrax.RESULTS


@eqx.filter_jit
def simulate_beam(system: BeamSystem, ts, solver: str = "kvaerno5", e0=None, edot0=None, rtol=1e-6, atol=1e-8,
                  dt0=1e-4, max_steps: int = 200_000) -> BeamRun:
    """Integrate from ``ts[0]`` to ``ts[-1]``, sampling at ``ts`` [s]; start at ``e0`` (default
    the beam's reference) with ``edot0`` (default rest). ``solver``: a name of :data:`SOLVERS`;
    ``rtol``, ``atol``: the PID controller's tolerances on ``e`` [m, -] and ``edot`` [m/s, 1/s].
    The start must satisfy the supports (it is not assembled)."""
    if solver not in SOLVERS:
        raise ParameterError(f"solver {solver!r} is not one of {sorted(SOLVERS)}")
    beam = system.beam
    n = beam.n_coordinates
    e0 = beam.reference() if e0 is None else jnp.asarray(e0, float)
    edot0 = jnp.zeros(n) if edot0 is None else jnp.asarray(edot0, float)
    mass = beam.mass_matrix()
    factor = jax.scipy.linalg.cho_factor(mass)
    force = applied_force(beam, system.loads, system.gravity, mass)

    def field(t, y, args):
        e, edot = y[:n], y[n:2 * n]
        edd, _ = system.accelerations(t, e, edot, factor, force)
        return jnp.concatenate([edot, edd, 2.0 * beam.dissipation(e, edot)[None]])

    ts = jnp.asarray(ts, float)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(field), SOLVERS[solver](), ts[0], ts[-1], dt0, jnp.concatenate([e0, edot0, jnp.zeros(1)]),
        saveat=diffrax.SaveAt(ts=ts), stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps, throw=False)
    y = sol.ys
    return BeamRun(sol.ts, y[:, :n], y[:, n:2 * n], y[:, 2 * n], sol.stats["num_accepted_steps"],
                   sol.stats["num_rejected_steps"], sol.result)


def energies(system: BeamSystem, run: BeamRun) -> Float[Array, " k"]:
    """Kinetic + strain + gravitational potential energy [J] at each sample (point loads'
    potential left out)."""
    mass = system.beam.mass_matrix()
    return jax.vmap(lambda e, v: system.beam.energy(e, v, system.gravity, mass))(run.e, run.edot)
