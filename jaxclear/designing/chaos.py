r"""Whether a design's derivatives mean anything: the horizon of predictability of its runs.

In a chaotic motion (a journal rattling in its bearing at high speed) the tangents of the state
grow like :math:`e^{\lambda t}` (:math:`\lambda` the largest Lyapunov exponent), and an objective
over a long horizon is a landscape of narrow wells whose gradient describes only changes far
below the solver's tolerance. :func:`horizon_report` measures it on the first run of a design:
the state's tangents with respect to every variable (one sensitivity solve), their
amplification (:func:`jaxclear.amplification`: the relative change of the state per full range
of the variable) and the derivative horizon (:func:`jaxclear.derivative_horizon`: the first time
at which a change of ``rtol`` times the range moves the state by a tenth of its size). A run
longer than a variable's horizon is past it: the report says so and
:func:`jaxclear.design` warns with :class:`jaxclear.DerivativeHorizonWarning`, naming
what works instead (an ensemble of shorter runs, :class:`~jaxclear.designing.Ensemble`).

A second, free sign is the spread between the objective of the plain run and of the sensitivity
solve (whose steps are sized for the tangents too): both are within the tolerance of the same
trajectory where the motion is predictable, and differ by far more where it is not.
"""

from __future__ import annotations

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from ..derivatives import amplification, derivative_horizon
from ..integrate.compile import jit
from .problem import DesignProblem


@jit
def _tangents(problem: DesignProblem, u):
    """The first member's solution and its tangents (P, ...) along the unit vectors of ``u``
    (each a full range of a variable)."""

    def run(uu):
        m = problem.member_mechanism(problem.values(uu), 0)
        return problem.run(m, problem.settings_of(m)).sol

    sol, lin = jax.linearize(run, u)
    return sol, jax.vmap(lin)(jnp.eye(u.shape[0], dtype=u.dtype))


def horizon_report(problem: DesignProblem, u) -> dict:
    """``{"run_s", "amplification": {name: A}, "horizon_s": {name: t}, "past_horizon": [names]}``
    of the first member at unit coordinates ``u`` (``horizon_s`` None where it is never reached)."""
    sol, tangents = _tangents(problem, jnp.asarray(u, dtype=float))
    run_s = float(np.asarray(sol.ts)[-1] - np.asarray(sol.ts)[0])
    amp, horizon, past = {}, {}, []
    for i, v in enumerate(problem.variables):
        t_i = SimpleNamespace(q=tangents.q[i], qdot=tangents.qdot[i])  # what the horizon reads
        a = float(amplification(sol, t_i, 1.0))
        h = derivative_horizon(sol, t_i, problem.rtol, 1.0)
        amp[v.name] = a
        horizon[v.name] = None if not np.isfinite(h) else h - float(np.asarray(sol.ts)[0])
        if np.isfinite(h) or not np.isfinite(a):
            past.append(v.name)
    return {"run_s": run_s, "amplification": amp, "horizon_s": horizon, "past_horizon": past}


__all__ = ["horizon_report"]
