r"""What the solver integrates: a mechanism's packed state (:class:`MechanismSystem`), or that
state together with its tangents (:class:`~jaxclear.integrate._sensitivity.TangentSystem`).

diffrax gets a system as the ``args`` of its solve. The system's vector field is the term, its
``after_step`` is what :class:`~jaxclear.integrate.ImpactMemorySolver` applies after
every step (the force elements' memory rules), its ``primal`` part is what the step-size
controllers read (contact onsets), and its ``norm`` is the error norm of the step-size
controller. So one set of solver wrappers serves both.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import optimistix as optx

from .._types import Array, BoolScalar, Float
from ..model.mechanism import Mechanism
from ._dynamics import Baumgarte, flat_vector_field
from ._state import State


def memory_step(mech: Mechanism, t0, v0, t1, v1, qdd=None) -> tuple[Float[Array, " N"], BoolScalar]:
    """Every force element's ``after_step`` over the accepted step ``[t0, t1]`` from the packed
    state ``v0`` to ``v1`` (the impact-memory rule of :mod:`jaxclear.elements.memory`): the
    packed state at ``t1`` with the updated element states, and whether any element's force law
    changed within the step (a contact onset). ``qdd``: None, or the accelerations at the
    step's ends (the sensitivity solve's, for the approach speeds' derivatives)."""
    a, b = State.unpack(v0, mech), State.unpack(v1, mech)
    states, changed = [], jnp.zeros((), bool)
    for element, state in zip(mech.clearance_joints, b.elements):
        new, crossed = element.after_step(mech, t0, a.q, a.qdot, t1, b.q, b.qdot, state, qdd)
        states.append(new)
        changed = changed | crossed
    return State(b.q, b.qdot, tuple(states)).pack(), changed


class StateNorm(eqx.Module):
    """Error norm of the packed state on positions and velocities only (the memory is not
    error-controlled): RMS over the first ``2n`` entries."""

    n: int = eqx.field(static=True)

    def __call__(self, v):
        return optx.rms_norm(v[: 2 * self.n])


class AbstractSystem(eqx.Module):
    """The ``args`` of the solve: a vector field on a packed vector, the update after each
    accepted step, the primal (mechanism) state inside the vector, and the error norm."""

    mech: eqx.AbstractVar[Mechanism]
    baumgarte: eqx.AbstractVar[Baumgarte]
    #: whether steps also end at the friction laws' kinks (``AbstractForceElement.kinks``), not
    #: only at contact onsets and separations (``integrate.solvers.OnsetController``)
    split_at_kinks: ClassVar[bool] = False

    @abc.abstractmethod
    def field(self, t, v) -> Float[Array, " M"]:
        """:math:`\\dot v = F(t, v)`."""

    @abc.abstractmethod
    def after_step(self, t0, v0, t1, v1) -> tuple[Float[Array, " M"], BoolScalar]:
        """The vector at ``t1`` after the memory rules, and whether a force law changed."""

    @abc.abstractmethod
    def primal(self, v) -> Float[Array, " N"]:
        """The mechanism's packed state (:meth:`State.pack`) inside ``v``."""

    def primal_rate(self, t, v) -> Float[Array, " N"]:
        """The rate of the mechanism's packed state inside ``v`` (its vector field)."""
        return flat_vector_field(t, self.primal(v), (self.mech, self.baumgarte))

    def dtmin(self):
        """The shortest step the step-size controller proposes (it accepts a step of this length
        whatever its error estimate, and a contact switch closer than this to a step's start is
        not split at), or ``None``: no floor."""
        return None

    @abc.abstractmethod
    def norm(self):
        """The step-size controller's error norm (a callable on the scaled error vector)."""

    def weigh_error(self, v0, v1, error, rtol, atol):
        """The step's error estimate as the step-size controller is to scale it (by ``atol +
        rtol max(|v0|, |v1|)`` per entry): ``error`` itself, unless a system measures some
        entries against another absolute tolerance."""
        return error


class MechanismSystem(AbstractSystem):
    """A mechanism's packed state (:class:`~jaxclear.integrate.State`) under
    :func:`~jaxclear.integrate.flat_vector_field`."""

    mech: Mechanism
    baumgarte: Baumgarte

    def field(self, t, v):
        return flat_vector_field(t, v, (self.mech, self.baumgarte))

    def after_step(self, t0, v0, t1, v1):
        return memory_step(self.mech, t0, v0, t1, v1)

    def primal(self, v):
        return v

    def norm(self):
        return StateNorm(self.mech.n_coordinates)


def system_field(t, v, system: AbstractSystem):
    """The diffrax term's function: ``system.field(t, v)`` (``args`` = the system)."""
    return system.field(t, v)
