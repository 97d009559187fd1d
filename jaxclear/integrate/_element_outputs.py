"""The force elements' own named outputs on a solution's samples (film force of a lubricated
joint, the corners of a translational joint, the active feature of a pin-in-slot joint, ...):
each element's :meth:`~jaxclear.elements.base.AbstractForceElement.outputs` evaluated at every
output sample from the sampled coordinates and the element's sampled state (its memories), so
they need nothing stored beyond :class:`~jaxclear.integrate.Solution`. Traceable:
fits and sweeps can use them through the channels ``joint:K:NAME``."""

from __future__ import annotations

import jax

from ._settings import CONTINUOUS_CONTACT_AFTER


def element_outputs(mech, sol, k: int, continuous_after: float | None = None) -> dict:
    """Clearance joint ``k``'s named outputs on the samples of ``sol``: name -> (T,) array (the
    names and units of ``type(joint).OUTPUTS``; an element without any gives ``{}``).
    ``continuous_after`` [s] (default: the :class:`~jaxclear.Settings` default) splits contact modes into
    impact (1) and continuous contact (2)."""
    joint = mech.clearance_joints[k]
    if not joint.OUTPUTS:
        return {}
    after = CONTINUOUS_CONTACT_AFTER if continuous_after is None else continuous_after
    state = sol.element_states[k]
    return jax.vmap(lambda t, q, qd, st: joint.outputs(mech, t, q, qd, st, after))(sol.ts, sol.q, sol.qdot, state)
