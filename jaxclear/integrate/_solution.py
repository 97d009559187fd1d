"""What a simulation returns: time series on a uniform grid, the force elements' states, solver
statistics and the run status."""

from __future__ import annotations

import equinox as eqx
import jax

from .._errors import ParameterError
from .._types import Array, Float
from ..elements.memory import ContactMemory
from ..model.drivers import COORDINATES
from ..model.mechanism import Mechanism
from ._element_outputs import element_outputs
from ._state import stack_memory


class Solution(eqx.Module):
    """Outputs on the uniform grid ``ts`` (leading axis ``n_out``; joint axis ``k``).

    Attributes:
        ts: times [s] (T,).
        q, qdot, qddot: coordinates and derivatives (T, n) [m, rad, /s, /s^2].
        reactions: Lagrange multipliers (T, m) of the joints then drivers
            (for a driver: minus the driving torque/force).
        drift: :math:`|\\Phi|` (T,).
        ecc: eccentricity vectors (T, k, 2) [m]; penetration (T, k) [m] (negative = gap).
        normal_force, friction_force: contact forces (T, k) [N].
        mode: contact mode (T, k): 0 free flight, 1 impact, 2 continuous contact.
        element_states: each force element's state at the samples (a tuple; leading axis T).
            Each element's own named outputs: :meth:`element_outputs`.
        memory: (property) the clearance joints' memories stacked ``(T, k)`` (impact speeds,
            onsets, impacts, work, running peaks).
        num_steps, num_accepted_steps, num_rejected_steps: solver statistics.
        status: integer code of :class:`~jaxclear.RESULTS` (0 ok; messages in :data:`STATUS`).
    """

    ts: Float[Array, " T"]
    q: Float[Array, "T n"]
    qdot: Float[Array, "T n"]
    qddot: Float[Array, "T n"]
    reactions: Float[Array, "T m"]
    drift: Float[Array, " T"]
    ecc: Float[Array, "T k 2"]
    penetration: Float[Array, "T k"]
    normal_force: Float[Array, "T k"]
    friction_force: Float[Array, "T k"]
    mode: Array
    element_states: tuple
    num_steps: Array
    num_accepted_steps: Array
    num_rejected_steps: Array
    status: Array

    @property
    def ok(self):
        return self.status == 0

    @property
    def memory(self) -> ContactMemory:
        """The clearance joints' memories, fields shaped ``(..., T, k)``."""
        return stack_memory(self.element_states, self.drift[..., None])

    @property
    def impacts(self):
        """Number of contact onsets per joint over the run (counted at every solver step)."""
        return self.memory.impacts[..., -1, :]

    @property
    def peak_force(self):
        """Largest normal force per joint [N] over all accepted steps (not only output samples)."""
        return self.memory.peak_force[..., -1, :]

    @property
    def peak_penetration(self):
        """Largest penetration per joint [m] over all accepted steps."""
        return self.memory.peak_penetration[..., -1, :]

    def element_outputs(self, mech: Mechanism, k: int = 0, continuous_after: float | None = None) -> dict:
        """Clearance joint ``k``'s own named outputs on the samples: name -> (..., T) array, the
        names and units of ``type(mech.clearance_joints[k]).OUTPUTS`` (a lubricated joint's film
        force, eccentricity ratio and minimum film thickness; a translational joint's forces,
        penetration and contact mode per corner; a pin-in-slot joint's active feature and its
        penetration), recomputed from the samples and the element's sampled memories
        (:func:`~jaxclear.integrate._element_outputs.element_outputs`)."""
        if self.ts.ndim > 1:  # a batch of runs (vmap over simulate): one call per run
            return jax.vmap(lambda sol: sol.element_outputs(mech, k, continuous_after))(self)
        return element_outputs(mech, self, k, continuous_after)

    def coordinate(self, mech: Mechanism, body: str, which: str, derivative: int = 0):
        """Time series of one coordinate (``x``, ``y`` or ``phi``) of a body; ``derivative`` 0, 1
        or 2 (position, velocity, acceleration)."""
        if which not in COORDINATES or derivative not in (0, 1, 2):
            raise ParameterError(f"coordinate {which!r}, derivative {derivative!r}: expected one of "
                                 f"{list(COORDINATES)} and a derivative 0, 1 or 2")
        i = 3 * mech.body_index(body) + COORDINATES[which]
        return (self.q, self.qdot, self.qddot)[derivative][..., i]
