"""The posterior at the fit's own window (issue 39, point 6): a log density with a jump.

At the default window (3 ms, a quarter revolution at 5000 rpm) a contact appears or vanishes
inside the window as the stiffness moves by a fraction of a per cent, and the likelihood drops
by about a thousand log units there. The random-walk sampler (the default) crosses such a jump by
rejected proposals only; NUTS's step-size adaptation collapses on it (benchmarks/README.md,
"Samplers at the fit's own window"). Checked here: the random-walk driver against a truncated
Gaussian in closed form (``scipy.stats.truncnorm``), and ``jc.posterior`` on a record of the
independent simulator (benchmarks/lab_record.py) whose likelihood has such a jump.
"""

from __future__ import annotations

import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear import ParameterError
from jaxclear.fitting.posterior_result import RHAT_LIMIT, _summaries

#: Where the test density's jump lies (whitened units): inside the bulk, as on record 18 (0.8).
CLIFF = 0.8


class _Cliff(eqx.Module):
    """A standard normal in 2-D (the whitening exact) truncated at ``u_0 = CLIFF`` by a drop of
    1000 log units, beyond which the density *rises* away from the mode for about two std (as on
    record 18 of benchmarks/bench_profile.py: -1725 at the jump, -1487 2.2 std further; here
    -1000 and -860) before it falls again (a proper density whose mass beyond the jump is
    below e^-800), the interface of
    :class:`~jaxclear.fitting.posterior_model.LogPosterior` that the driver uses."""

    x0: jax.Array
    chol: jax.Array

    def __call__(self, u):
        base = -0.5 * jnp.sum(u**2)
        return jnp.where(u[0] < CLIFF, base, base - 1000.0 + 150.0 * jnp.tanh(u[0] - CLIFF))


def _cliff():
    return _Cliff(jnp.zeros(2), jnp.eye(2))


def test_random_walk_samples_a_density_with_a_jump(tmp_path):
    """4 chains x 6000 draws (about 2500 effective): the truncated coordinate's mean, sd, 5 % and
    95 % quantiles against scipy.stats.truncnorm within 4 Monte Carlo standard errors (mean
    sd/sqrt(ESS) = 0.02 sd, quantile sqrt(p(1-p))/(f(q) sqrt(ESS)) <= 0.05 sd: tolerances 0.08 sd
    and 0.15 sd), the free coordinate's sd within 8 % (4 x 1/sqrt(2 ESS)); no draw beyond the jump;
    R-hat within 1.01; the warm-up tuned the acceptance to about its target 0.3. Chains whose
    start lands beyond the jump are moved in before sampling (posterior._starts). Stopped after
    the warm-up and 2 chunks and resumed from its checkpoint, it draws the same numbers; seconds."""
    from scipy import stats

    from jaxclear.fitting.posterior import _sample, _starts

    jitter = np.random.default_rng(0).standard_normal((4, 2))  # _starts' jitter of seed 0
    assert jitter[3, 0] > CLIFF  # chain 3 would start beyond the jump (at 1.3)
    starts = _starts(_cliff(), 4, 0, gradient=False)
    assert np.all(starts[:, 0] < CLIFF) and starts[3, 0] == 0.5 * jitter[3, 0]
    s = dict(chains=4, chunk=1000, draws=6000, warmup=1000, max_tree_depth=1, seed=0, sampler="random-walk")
    run = _sample(_cliff(), s, "k", None, True, False)
    x = run["x"]
    assert x[..., 0].max() < CLIFF
    ref = stats.truncnorm(-np.inf, CLIFF)
    a = x[..., 0].ravel()
    assert abs(a.mean() - ref.mean()) < 0.08 * ref.std()
    assert abs(a.std() / ref.std() - 1) < 0.08
    for p in (0.05, 0.95):
        assert abs(np.quantile(a, p) - ref.ppf(p)) < 0.15 * ref.std(), p
    assert abs(x[..., 1].std() - 1) < 0.08
    summary = _summaries({"a": x[..., 0], "b": x[..., 1]})
    assert max(v["r_hat"] for v in summary.values()) < 1.01
    assert min(v["ess_bulk"] for v in summary.values()) > 1500
    assert abs(run["acceptance_rate"].mean() - 0.3) < 0.05
    assert run["diverging"].sum() == 0 and run["n_steps"].sum() == 0
    short = _sample(_cliff(), {**s, "draws": 2000}, "k", tmp_path, True, False)
    resumed = _sample(_cliff(), s, "k", tmp_path, True, False)
    assert resumed["resumed"] and not short["resumed"]
    np.testing.assert_array_equal(resumed["x"], x)


def test_sampler_and_target_accept_are_checked():
    with pytest.raises(ParameterError, match=r"sampler = 'gibbs': expected one of \['random-walk', 'nuts'\]"):
        jc.posterior(None, jc.preset("flores-slider-crank"), sampler="gibbs")
    for bad in (0.0, 1.0, 1.5, "0.8", True):
        with pytest.raises(ParameterError, match=r"target_accept = .*: expected a number in \(0, 1\)"):
            jc.posterior(None, jc.preset("flores-slider-crank"), target_accept=bad)


# --------------------------------------------------------------------------------------
# jc.posterior at the default window of a record with a jump
# --------------------------------------------------------------------------------------

#: Record 18 of benchmarks/bench_profile.py (its truths, seed 100; 0-based): stiffness 0.751 x
#: Hertz, restitution 0.783, 3 ms from start-up at 200 kHz through the 20 kHz sensor, 20 dB. Its
#: least-squares fit at the default window (measured 2026-11-29, bench_uncertainty.py --samplers):
#: the chains' whitening and start; the posterior does not depend on it otherwise.
RECORD = 18
FIT = {"stiffness": 49505857036.81609, "restitution": 0.7832941219238165}
FIT_STD = {"stiffness": 216446338.58743525, "restitution": 0.0002485032656895633}


# slow (95 s on 2 cores, 60 of them the posterior's setup); the sampler at a jump is checked fast by
# test_random_walk_samples_a_density_with_a_jump against scipy.stats.truncnorm
@pytest.mark.slow
def test_posterior_at_the_default_window_of_a_record_with_a_jump():
    """The likelihood of this record drops by more than 1000 log units between +0.3 % and +0.5 %
    of the fitted stiffness (a contact of the 3 ms window appears); the default sampler (the random
    walk) at small settings, 2 chains x (150 warm-up + 450 draws), about 25 effective draws of the
    slowest quantity: R-hat finite and below 1.1 (split R-hat of so few effective draws scatters by
    a few hundredths about 1; a chain stuck beyond the jump gives 1.5 and more), no draw beyond the
    jump, and the truth where the posterior puts it: restitution and noise level in the 90 %
    interval (the truth lies 0.6 and 0.3 std from the estimate), the stiffness (truth +0.23 %,
    just below the jump, which cuts the posterior's upper tail: its 95 % quantile lay only 0.015-
    0.03 % above the truth in the benchmark's runs, 49.629 and 49.636 against 49.621 GN/m^1.5, too
    close for so short a chain) between the 5 % quantile and the largest draw."""
    import bench_profile  # benchmarks/ (on sys.path by conftest.py)
    import lab_record

    from jaxclear.fitting.parameters import to_z
    from jaxclear.fitting.posterior import _log_posterior
    from jaxclear.fitting.result import FitResult
    from jaxclear.fitting.sampler import init_states

    case = bench_profile.truths(RECORD + 1, 100)[RECORD]
    rec = lab_record.make_record(**case, revolutions_before=0, start_angle_deg=0.0, duration=3e-3, fs=200e3,
                                 cutoff_hz=20e3, order=2, gain=1.0, bias=0.0, snr_db=20.0)
    data = {"time_s": rec["time_s"], "slider_acc_m_s2": rec["slider_acc_m_s2"]}
    truth = {"stiffness": rec["truth"]["stiffness"], "restitution": case["c_r"], "noise_sigma": rec["truth"]["noise_std"]}
    mech, free, sensor = jc.preset("flores-slider-crank"), ("stiffness", "restitution"), jc.Accelerometer(20e3)
    fr = FitResult(estimates=dict(FIT), std=dict(FIT_STD), loss=0.0098, iterations=0, wall_time_s=0.0, free=free,
                   window_length_s=2.995e-3, failures=())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        post = jc.posterior(data, mech, free, fit_result=fr, sensor=sensor, chains=2, warmup=150, draws=450, chunk=150,
                            seed=1, predictive_draws=0, progress=False)
    assert post.settings["sampler"] == "random-walk" and post.gradient_evaluations == 0
    rhat = max(v["r_hat"] for v in post.statistics.values())
    assert math.isfinite(rhat) and rhat < 1.1 and rhat < 2 * RHAT_LIMIT
    k = post.samples["stiffness"]
    for name in ("restitution", "noise_sigma"):
        lo, hi = post.interval(name)
        assert lo <= truth[name] <= hi, (name, lo, truth[name], hi)
    assert post.interval("stiffness")[0] <= truth["stiffness"] <= k.max()
    # the jump: the log density along the stiffness (restitution and noise at the optimum)
    common = dict(channels=None, sensor=sensor, settings=_settings(), align="time", time_offset=0.0)
    lp, _ = _log_posterior(data, mech, free, fr, {}, None, common)
    chol = np.asarray(lp.chol)
    dz = [float(to_z("stiffness", FIT["stiffness"] * (1 + f), mech=mech) - to_z("stiffness", FIT["stiffness"], mech=mech))
          for f in (0.0, 0.003, 0.005)]
    u = [np.linalg.solve(chol, np.r_[d, 0.0, 0.0]) for d in dz]
    at = np.asarray(init_states(lp, jnp.asarray(np.stack(u[:2])), False).logdensity)
    beyond = float(init_states(lp, jnp.asarray(np.stack(u[1:])), False).logdensity[1])
    assert at[0] - at[1] < 20 and at[0] - beyond > 1000, (at, beyond)
    assert k.max() < FIT["stiffness"] * 1.005


def _settings():
    """The posterior's integration settings (its default: the fit's, step limit 200,000)."""
    import dataclasses

    from jaxclear.fitting.problem import MAX_STEPS, given_settings

    return dataclasses.replace(given_settings("posterior", None)[0], max_steps=MAX_STEPS)
