r"""Markov chains on a log density, run in compiled chunks of draws (warm-up and draws alike)
whose end states are returned, so that a driver can checkpoint between chunks and resume:

* the No-U-Turn sampler of BlackJAX (Hoffman and Gelman, *The No-U-Turn sampler*, JMLR 15,
  2014), its step size tuned by dual averaging during the warm-up (:func:`nuts_chunk`);
* random-walk Metropolis (:func:`random_walk_chunk`): Gaussian steps in the whitened
  coordinates, their scale tuned by the same dual averaging during the warm-up towards
  :data:`RANDOM_WALK_ACCEPT` (from ``2.38 / sqrt(D)``, the optimal scaling of Roberts, Gelman
  and Gilks, Ann. Appl. Probab. 7, 1997). It needs no gradient and one simulation a draw, and
  a log density with jumps (a contact that appears or vanishes inside the window as a parameter
  moves) costs it rejected proposals only, where NUTS's trajectories diverge and its step-size
  adaptation suffers (docs/theory/uncertainty.md, "Sampler").

Several chains run one after another on a CPU device with single-kernel loops (``jax.lax.map``:
there the lanes of a ``vmap`` would run one after another inside the loop's kernel anyway, and a
batch of NUTS trajectories would wait for the longest; :func:`jaxclear.sweep.lanes.lanes_one_by_one`)
and side by side (``jax.vmap``) on accelerators.

The mass matrix is the identity: the density is given in whitened coordinates
(:mod:`.posterior_model`: the Gauss-Newton covariance is the metric), and it is not adapted.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp

from ..sweep.lanes import over_lanes

#: Acceptance rate NUTS's warm-up aims at (Stan's and BlackJAX's default).
TARGET_ACCEPT = 0.8
#: Acceptance rate the random walk's warm-up aims at: about the optimum of a Gaussian target in
#: 2-5 dimensions (0.44 in one, 0.35 in three, 0.234 in many: Gelman, Roberts and Gilks 1996).
RANDOM_WALK_ACCEPT = 0.3
#: The samplers of :func:`jaxclear.posterior` (its ``sampler``).
SAMPLERS = ("random-walk", "nuts")


class ChainState(NamedTuple):
    """Per chain (leading axis: chains): position ``(C, D)``, log density ``(C,)``, gradient ``(C, D)``."""

    position: jax.Array
    logdensity: jax.Array
    grad: jax.Array




@eqx.filter_jit
def init_states(logdensity, positions, gradient: bool = True) -> ChainState:
    """The chains' states at ``positions`` ``(C, D)`` (log density and its gradient; without
    ``gradient`` zeros, and no derivative program is compiled)."""
    def one(u):
        if not gradient:
            return ChainState(u, logdensity(u), jnp.zeros_like(u))
        v, g = jax.value_and_grad(logdensity)(u)
        return ChainState(u, v, g)
    return over_lanes(one, positions)


def _blackjax():
    """BlackJAX, imported on first use (at trace time), so that ``import jaxclear`` does not load it."""
    import blackjax
    import blackjax.adaptation.step_size  # noqa: F401 - the dual averaging of the warm-up

    return blackjax


def _nuts_step(logdensity, key, state: ChainState, step_size, max_doublings: int):
    blackjax = _blackjax()
    kernel = blackjax.nuts.build_kernel()
    hmc = blackjax.mcmc.hmc.HMCState(state.position, state.logdensity, state.grad)
    new, info = kernel(key, hmc, logdensity, step_size, jnp.ones_like(state.position), max_doublings)
    return ChainState(new.position, new.logdensity, new.logdensity_grad), info


class StepSize(NamedTuple):
    """Dual-averaging state per chain (leading axis: chains), BlackJAX's
    ``DualAveragingAdaptationState`` fields: ``log_step_size`` (the step during warm-up),
    ``log_step_size_avg`` (the tuned step, used after the warm-up), ``step``, ``avg_error``, ``mu``."""

    log_step_size: jax.Array
    log_step_size_avg: jax.Array
    step: jax.Array
    avg_error: jax.Array
    mu: jax.Array


def _dual_averaging(target: float):
    return _blackjax().adaptation.step_size.dual_averaging_adaptation(target)


def init_step_size(step0: float, chains: int) -> StepSize:
    """The dual averaging's start (Hoffman and Gelman 2014, section 3.2.1: ``mu = log(10 step0)``)."""
    da = _dual_averaging(TARGET_ACCEPT)[0](step0)
    return StepSize(*(jnp.broadcast_to(jnp.asarray(a, dtype=float), (chains,)) for a in da))


def _tuned(da: StepSize, acceptance, adapt, target: float) -> StepSize:
    """One dual-averaging update of ``da`` by a draw's acceptance rate where ``adapt``, else ``da``."""
    state = _blackjax().adaptation.step_size.DualAveragingAdaptationState(*da)
    new = StepSize(*_dual_averaging(target)[1](state, acceptance))
    return jax.tree.map(lambda a, b: jnp.where(adapt, a, b), new, da)


@eqx.filter_jit
def nuts_chunk(logdensity, states: ChainState, step: StepSize, keys, adapt, n_draws: int, max_doublings: int,
               target: float = TARGET_ACCEPT):
    """``n_draws`` NUTS draws per chain. With ``adapt`` (a traced bool: warm-up and draws share one
    compilation, the expensive part when the density runs a simulation and its derivative) the
    step size is tuned by dual averaging (Hoffman and Gelman 2014, section 3.2.1) towards the
    acceptance rate ``target``; without it the tuned step (``log_step_size_avg``) is used and not
    changed. Returns the end states, the step-size states and per draw ``(C, n_draws)``:
    positions ``(C, n, D)``, log density, divergence, acceptance rate, leapfrog steps, tree depth."""
    def chain(state, da, key):
        def body(carry, k):
            st, da = carry
            eps = jnp.exp(jnp.where(adapt, da.log_step_size, da.log_step_size_avg))
            st, info = _nuts_step(logdensity, k, st, eps, max_doublings)
            da = _tuned(da, info.acceptance_rate, adapt, target)
            return (st, da), (st.position, st.logdensity, info.is_divergent, info.acceptance_rate,
                              info.num_integration_steps, info.num_trajectory_expansions)
        (st, da), out = jax.lax.scan(body, (state, da), jax.random.split(key, n_draws))
        return st, da, out

    return over_lanes(chain, states, step, keys)


@eqx.filter_jit
def random_walk_chunk(logdensity, states: ChainState, step: StepSize, keys, adapt, n_draws: int,
                      target: float = RANDOM_WALK_ACCEPT):
    """``n_draws`` random-walk Metropolis draws per chain: Gaussian steps in the whitened
    coordinates whose standard deviation is the step-size state's (``log_step_size`` during the
    warm-up, tuned by the dual averaging of :func:`nuts_chunk` towards the acceptance rate
    ``target`` where ``adapt``; ``log_step_size_avg`` after it, not changed). One log density a
    draw, no gradient (the states' ``grad`` is passed through). Returns what :func:`nuts_chunk`
    returns: the end states, the step-size states and per draw ``(C, n_draws)``: positions
    ``(C, n, D)``, log density, divergence (always False), the acceptance probability
    ``min(1, p(proposal) / p(current))``, gradient evaluations (0) and tree depth (0)."""
    blackjax = _blackjax()
    kernel = blackjax.mcmc.random_walk.build_additive_step()

    def chain(state, da, key):
        def body(carry, k):
            st, da = carry
            scale = jnp.exp(jnp.where(adapt, da.log_step_size, da.log_step_size_avg))
            rw = blackjax.mcmc.random_walk.RWState(st.position, st.logdensity)
            new, info = kernel(k, rw, logdensity, lambda kk, x: scale * jax.random.normal(kk, x.shape, x.dtype))
            st = ChainState(new.position, new.logdensity, st.grad)
            da = _tuned(da, info.acceptance_rate, adapt, target)
            zero = jnp.zeros((), dtype=int)
            return (st, da), (st.position, st.logdensity, jnp.zeros((), dtype=bool), info.acceptance_rate, zero, zero)
        (st, da), out = jax.lax.scan(body, (state, da), jax.random.split(key, n_draws))
        return st, da, out

    return over_lanes(chain, states, step, keys)
