"""Channels are differentiable through the simulation: stiffness and restitution of the four-bar
with the clearance at the rocker pivot, fitted from the rocker channel alone (velocity, then
acceleration) on a record made by another solver configuration (dopri8 at rtol 1e-10 against
the model's tsit5 at 1e-6) with noise, by Levenberg-Marquardt on forward-mode Jacobians."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear import params

ROOT = Path(__file__).resolve().parents[1]
FREE = ("stiffness", "restitution")


def _levenberg_marquardt(f_and_jac, z, iterations: int):
    r, J = f_and_jac(z)
    damping = 1e-2
    for _ in range(iterations):
        A = J.T @ J
        step = jnp.linalg.solve(A + damping * jnp.diag(jnp.diag(A)), -J.T @ r)
        r_new, J_new = f_and_jac(z + step)
        if float(r_new @ r_new) < float(r @ r):
            z, r, J, damping = z + step, r_new, J_new, damping / 3
        else:
            damping *= 5
    return z


@pytest.mark.slow
def test_four_bar_fit_from_rocker_channel():
    mech = jc.load_mechanism(ROOT / "examples" / "four-bar-rocker-pivot.toml")
    truth = {"stiffness": float(params.get(mech, "stiffness")), "restitution": 0.9}
    window, n = 0.005, 501  # from the known start through the first impact (2.95 ms) and its contact
    record = jc.simulate(mech, jc.settings(window, n_out=n, solver="dopri8", rtol=1e-10, atol=1e-13))
    rng = np.random.default_rng(0)
    settings = jc.settings(window, n_out=n, adjoint="forward")
    z = jnp.array([params.to_unconstrained("stiffness", 2 * truth["stiffness"]),
                   params.to_unconstrained("restitution", 0.7)])
    for name in ("body:rocker:phi:vel", "body:rocker:phi:acc"):
        clean = np.asarray(jc.channel(mech, record, name))
        data = clean + 0.02 * np.std(clean) * rng.standard_normal(clean.shape)  # 2 % noise (SNR 34 dB)

        def residual(z, name=name, data=data):
            values = {p: params.from_unconstrained(p, z[i]) for i, p in enumerate(FREE)}
            sol = jc.simulate(params.replace_many(mech, values), settings)
            return (jc.channel(mech, sol, name) - data) / np.std(data)

        z = _levenberg_marquardt(jax.jit(lambda z, f=residual: (f(z), jax.jacfwd(f)(z))), z, 15)
    est = {p: float(params.from_unconstrained(p, z[i])) for i, p in enumerate(FREE)}
    assert abs(est["stiffness"] / truth["stiffness"] - 1) < 0.05
    assert abs(est["restitution"] - truth["restitution"]) < 0.02
