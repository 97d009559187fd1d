r"""The state vector and its layout.

``y = [q (n), qdot (n), state of element 0, state of element 1, ...]``: coordinates [m, rad],
velocities, then each force element's slice (:class:`~jaxclear.elements.base.AbstractForceElement`:
``state_size`` entries, the raveled leaves of its state pytree in tree order). A revolute
clearance joint's slice is its :class:`~jaxclear.elements.memory.ContactMemory`
``[impact_velocity, contact_start, impacts, work, peak_force, peak_penetration]``.

The solver integrates the packed vector: a single array leaf keeps its per-step bookkeeping
(stage combinations, error norm, dense output) to one kernel per operation instead of one per
field.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, Float
from ..elements.memory import ContactMemory
from ..model.mechanism import Mechanism


class State(eqx.Module):
    """Solution state: coordinates ``q`` (n,), velocities ``qdot`` (n,) and the force elements'
    states (a tuple, one pytree per element of ``mech.clearance_joints``)."""

    q: Float[Array, " n"]
    qdot: Float[Array, " n"]
    elements: tuple

    @property
    def memory(self) -> ContactMemory:
        """The clearance joints' memories stacked along a trailing joint axis ``(..., k)``."""
        return stack_memory(self.elements, self.q)

    def pack(self) -> Float[Array, " N"]:
        """One flat vector ``[q, qdot, element slices]`` (module docstring)."""
        leaves = [jnp.reshape(x, (-1,)) for x in jax.tree_util.tree_leaves(self.elements)]
        return jnp.concatenate([self.q, self.qdot, *leaves])

    @staticmethod
    def unpack(v: Float[Array, " N"], mech: Mechanism) -> "State":
        """Inverse of :meth:`pack` for the layout of ``mech``."""
        n = mech.n_coordinates
        states, start = [], 2 * n
        for element in mech.clearance_joints:
            states.append(element.state_from_vector(v[start : start + element.state_size]))
            start += element.state_size
        return State(v[:n], v[n : 2 * n], tuple(states))

    @staticmethod
    def size(mech: Mechanism) -> int:
        """Length of the packed vector of ``mech``."""
        return 2 * mech.n_coordinates + sum(e.state_size for e in mech.clearance_joints)


def stack_memory(states: tuple, like) -> ContactMemory:
    """The elements' memories (each state's ``summary()``, a :class:`ContactMemory`) stacked
    along a trailing axis; shaped ``like.shape[:-1] + (0,)`` when there are none."""
    memories = [s.summary() for s in states]
    if not memories:
        z = jnp.zeros(like.shape[:-1] + (0,), like.dtype)
        return ContactMemory(z, z, z, z, z, z)
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs, axis=-1), *memories)


def element_states(mech: Mechanism, states) -> tuple:
    """The elements' states as a tuple: ``states`` itself, or split from a
    :class:`ContactMemory` stacked over the clearance joints (``(k,)`` fields)."""
    if isinstance(states, ContactMemory):
        return tuple(jax.tree_util.tree_map(lambda x: x[..., i], states) for i in range(len(mech.clearance_joints)))
    return tuple(states)
