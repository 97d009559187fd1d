"""Output of a simulation: the post-processing at the output samples, evaluated in batches,
equals one evaluation per sample; the compiled simulation holds no host callback (so JAX's
persistent compilation cache can store it)."""

import dataclasses
import importlib

import jax
import numpy as np

import jaxclear as jc
from jaxclear.integrate._dynamics import accelerations

simulate_module = importlib.import_module("jaxclear.integrate._simulate")

from conftest import free_journal


def test_batched_postprocess_equals_per_sample():
    """A free journal striking its bearing, sampled on a grid longer than one batch and not a
    multiple of it (padding dropped). Reference: accelerations, reactions and contact outputs
    evaluated at each sample on its own (``jaxclear.integrate.accelerations``, one call per
    sample). Same formulas, differently batched: equal to 1e-12 relative."""
    mech = free_journal(speed=1.0)
    n = simulate_module.POSTPROCESS_BATCH + 45
    sol = jc.simulate(mech, jc.settings(2e-3, n_out=n))
    assert int(sol.impacts[0]) >= 1
    s = jc.settings(2e-3, n_out=n)
    for i in (0, 1, n // 2, simulate_module.POSTPROCESS_BATCH, n - 1):
        states = jax.tree_util.tree_map(lambda x: x[i], sol.element_states)
        qdd, lam, _, contact = accelerations(mech, sol.ts[i], sol.q[i], sol.qdot[i], states, s.baumgarte)
        for ours, ref in ((sol.qddot[i], qdd), (sol.reactions[i], lam), (sol.normal_force[i], contact.normal_force),
                          (sol.penetration[i], contact.penetration)):
            ref = np.asarray(ref)
            np.testing.assert_allclose(np.asarray(ours), ref, rtol=1e-12, atol=1e-12 * (np.max(np.abs(ref), initial=0.0) + 1e-30))


def test_simulation_program_has_no_host_callback():
    """JAX writes no program with a host callback to its persistent cache; the compiled
    simulation must hold none (diffrax's input checks are left out of the trace)."""
    mech = free_journal()
    s = dataclasses.replace(jc.settings(1e-3, n_out=11), throw=False)
    text = simulate_module._simulate.lower(mech, s, None).as_text()
    assert "callback" not in text
