"""Output samples written a block per accepted step (jaxclear.integrate.sampling.SampleWriter).

Truths: diffrax's own saving (``SaveAt(ts=...)``, one sample per iteration of its save loop) on
the same solve, and the rule that a step holds at most ``block`` samples.
"""

import jaxclear  # noqa: F401  (float64 first)

import math
import sys

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.integrate import _sampling as sampling
from jaxclear.integrate._assembly import assemble, initial_state
from jaxclear.integrate._solvers import ImpactMemorySolver, OnsetController, StopOnNonFinite
from jaxclear.integrate._system import MechanismSystem, StateNorm, system_field

SIM = sys.modules["jaxclear.integrate._simulate"]  # the module (jaxclear.integrate.simulate is the function)


def _solve(mech, s, block=None):
    """The four-bar's packed states at the output samples and the step count: diffrax's
    ``SaveAt(ts)`` (``block`` None) or a SampleWriter of that block size, the rest as simulate."""
    y0 = initial_state(mech, s, assemble(mech, s.t_start))
    t0, t1, ts = SIM.output_grid(s, y0.q.dtype)
    controller = OnsetController(StopOnNonFinite(diffrax.PIDController(
        rtol=s.rtol, atol=s.atol, norm=StateNorm(mech.n_coordinates))))
    solver = ImpactMemorySolver(SIM.solve._inner_solver(s), dense_to_controller=block is not None)
    kw = dict(args=MechanismSystem(mech, s.baumgarte), max_steps=s.max_steps, throw=False)
    if block is None:
        sol = diffrax.diffeqsolve(diffrax.ODETerm(system_field), solver, t0, t1, None, y0.pack(),
                                  saveat=diffrax.SaveAt(ts=ts), stepsize_controller=controller, **kw)
        return sol.ys, sol.stats["num_accepted_steps"]
    writer = sampling.SampleWriter(controller, ts, solver.interpolation_cls, block)
    sol = diffrax.diffeqsolve(diffrax.ODETerm(system_field), solver, t0, t1, None, y0.pack(),
                              saveat=diffrax.SaveAt(t1=True, controller_state=True), stepsize_controller=writer,
                              adjoint=sampling.adjoint("recursive"), **kw)
    return writer.samples(sol.controller_state, y0.pack(), True), sol.stats["num_accepted_steps"]


@pytest.fixture(scope="module")
def four_bar():
    """The four-bar, its settings and diffrax's own saving of its run (the reference of both
    tests below, compiled once)."""
    mech, s = jc.preset("four-bar"), jc.settings(0.02, n_out=401)
    return mech, s, jax.jit(lambda m: _solve(m, s))(mech)


@pytest.mark.extended
def test_block_samples_equal_diffrax_saving(four_bar):
    """With a block as large as the grid no step is cut, so the steps are diffrax's: every
    sample (coordinates, velocities and the impact memory of the clearance joint, onsets
    included) equals diffrax's own saving to rounding (1e-12 relative; the interpolant is
    evaluated vectorised instead of one time at a time)."""
    mech, s, (ref, steps_ref) = four_bar
    out, steps = jax.jit(lambda m: _solve(m, s, block=s.n_out))(mech)
    assert int(steps) == int(steps_ref)
    ref, out = np.asarray(ref), np.asarray(out)
    assert np.all(np.isfinite(out))
    scale = np.maximum(np.abs(ref), 1e-3)
    assert np.max(np.abs(out - ref) / scale) < 1e-12


def test_a_step_holds_at_most_a_block(four_bar):
    """With a block of 4 samples (a grid 100x denser than the steps would need) every sample is
    written, the run takes at least (T - 1) / 4 accepted steps, and the samples agree with the
    uncut run to the integration's tolerance (rtol 1e-6 on positions of ~0.1 m; measured 2e-8)."""
    mech, s, (ref, _) = four_bar
    out, steps = jax.jit(lambda m: _solve(m, s, block=4))(mech)
    n = mech.n_coordinates
    assert int(steps) >= (s.n_out - 1) / 4
    out, ref = np.asarray(out), np.asarray(ref)
    assert np.all(np.isfinite(out))
    assert np.max(np.abs(out[:, :n] - ref[:, :n])) < 1e-5


@pytest.mark.extended
def test_zero_length_and_failed_runs():
    """A member that is not integrated (its restitution outside its range: a zero-length run)
    reads its start at every sample; a run stopped by max_steps leaves the samples after its
    last step at inf (as diffrax does), which the status reports."""
    mech = jc.preset("flores-slider-crank")
    s = jc.settings(2e-3, n_out=51, throw=False, sampling="block")
    bad = jc.params.replace(mech, "restitution", 1.5)
    sol = jc.simulate(bad, s)
    assert int(sol.status) != 0
    q = np.asarray(sol.q)
    assert np.all(np.isfinite(q)) and np.all(q == q[0])
    short = jc.simulate(mech, jc.settings(2e-3, n_out=51, throw=False, max_steps=5, sampling="block"))
    assert int(short.status) == int(jc.RESULTS.max_steps_reached._value)
    assert np.isinf(np.asarray(short.q)[-1]).all()


def _loss(mech, adjoint, sampling):
    s = jc.settings(1.5e-3, n_out=41, throw=False, adjoint=adjoint, sampling=sampling)

    def f(k):
        sol = jc.simulate(jc.params.replace(mech, "stiffness", k), s)
        return jnp.sum(sol.qddot[:, 6] ** 2) * 1e-12 + jnp.sum(sol.q[:, 6])

    return f


@pytest.mark.slow  # 74 s on 2 cores; reverse mode through the loop is no longer the default adjoint
def test_reverse_mode_equals_diffrax_saving():
    """With fewer samples than a block, "block" takes diffrax's steps, so the reverse-mode
    derivative of a scalar of the samples equals that of "loop" to rounding (1e-9 relative):
    the buffer's reverse-mode semantics (each row written once, rows of rejected attempts
    never) carry the right cotangents."""
    mech = jc.preset("flores-slider-crank")
    k0 = jc.params.get(mech, "stiffness")
    a, b = (float(jax.jit(jax.grad(_loss(mech, "recursive", m)))(k0)) for m in ("loop", "block"))
    assert math.isfinite(a) and a != 0.0 and abs(a - b) <= 1e-9 * abs(a), (a, b)


@pytest.mark.slow
def test_forward_mode_and_vmap_equal_diffrax_saving():
    """The same for forward mode (what the fits use) and for a vmap over the stiffness."""
    mech = jc.preset("flores-slider-crank")
    k0 = jc.params.get(mech, "stiffness")
    a, b = (float(jax.jit(lambda k: jax.jvp(_loss(mech, "forward", m), (k,), (1.0,))[1])(k0))
            for m in ("loop", "block"))
    assert math.isfinite(a) and a != 0.0 and abs(a - b) <= 1e-9 * abs(a), (a, b)
    ks = k0 * jnp.asarray([0.5, 1.0, 2.0])
    a, b = (np.asarray(jax.jit(jax.vmap(_loss(mech, "recursive", m)))(ks)) for m in ("loop", "block"))
    np.testing.assert_allclose(b, a, rtol=1e-9)
