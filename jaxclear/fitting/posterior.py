r"""The posterior of a fit's free parameters and noise level given a record:
:func:`posterior` (API) and ``jaxclear fit ... --posterior`` (command line).

What it does, in order:

1. the least-squares fit (:func:`~jaxclear.fit`, or a :class:`~jaxclear.FitResult` given), whose
   optimum and Gauss-Newton covariance start the chains and set their metric;
2. the log posterior: the fit's own residual model and sensor model as a Gaussian likelihood with
   an unknown (or given) noise level, and stated priors (:mod:`.posterior_model`, :mod:`.priors`);
   NUTS's gradient is ``jax.grad`` through :func:`~jaxclear.simulate`, i.e. the transpose of the
   error-controlled forward sensitivities (one tangent per free parameter);
3. ``chains`` chains of the random-walk Metropolis sampler (default) or of the No-U-Turn sampler
   (:mod:`.sampler`; which one when: :func:`posterior`'s ``sampler``), each started from the
   optimum plus a Gauss-Newton-distributed jitter, ``warmup`` draws tuning the step (discarded),
   then ``draws`` draws in compiled chunks of ``chunk``, the chains' states and every draw so far
   written to ``out/posterior_checkpoint.npz`` after the warm-up and after every chunk; the same
   call resumes from it (a chunk's random key is derived from the seed, chain and chunk index, so
   a resumed run draws the same numbers as an uninterrupted one);
4. the diagnostics (ArviZ: split R-hat, bulk and tail effective sample size; divergences) and
   the outputs (:mod:`.posterior_result`).

Only window 0 (``windows=1``) is modelled: it starts from the known state; later windows' start
states would be sampled too (not done).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from .._errors import CheckpointError, ParameterError
from .._extras import require_extra
from .._interrupt import stop_at_safe_points
from .._checkpoint import Work, key as work_key, locked
from ..analysis.sensor import Accelerometer
from ..integrate import Settings
from ..model import Mechanism
from .driver import fit
from .parameters import DEFAULT_FREE, transform, z_vector
from .posterior_model import LogPosterior, fitted_entries, gauss_newton_covariance
from .posterior_result import PosteriorResult, build_result
from .priors import check_support, default_prior, noise_prior, parse_prior
from .problem import MAX_STEPS, build_problem, given_settings, settings_record
from .result import FitResult
from .sampler import (RANDOM_WALK_ACCEPT, SAMPLERS, TARGET_ACCEPT, ChainState, StepSize, init_states,
                      init_step_size, nuts_chunk, random_walk_chunk)
from .window import evaluate_window_jit

#: The posterior's checkpoint in the output folder.
POSTERIOR_CHECKPOINT = "posterior_checkpoint.npz"
#: The format of the posterior checkpoint (:mod:`jaxclear._checkpoint`'s version rule).
FORMAT = 1
#: Name of the noise level among the samples and in ``priors``.
NOISE = "noise_sigma"
#: Retries of a chain's start whose density is not finite (the jitter halved each time).
_START_TRIES = 6
#: A start whose log density lies this far below the Gauss-Newton approximation's is moved in
#: (:func:`_starts`): a Gaussian's own draws never do (the difference is 0 for a Gaussian), a
#: non-quadratic misfit over one Gauss-Newton std changes it by a few units at most.
START_DROP = 20.0
#: Draws, warm-up draws and chunk per chain where not given, per sampler: the random walk's draws
#: are cheaper (one simulation, no derivative) and less independent (about 0.07-0.1 effective
#: draws a draw in 3 dimensions, measured) than NUTS's; either gives a few hundred effective
#: draws of each quantity with 4 chains, and a checkpoint every 10-60 s at the default window.
DEFAULT_COUNTS = {"random-walk": dict(draws=2000, warmup=500, chunk=250),
                  "nuts": dict(draws=500, warmup=200, chunk=50)}


def posterior(data, mech: Mechanism, free: Sequence[str] = DEFAULT_FREE, start: dict | None = None, *,
              fit_result: FitResult | None = None, priors: dict | None = None, noise_sigma: float | None = None,
              chains: int = 4, draws: int | None = None, warmup: int | None = None, chunk: int | None = None,
              sampler: str = "random-walk", max_tree_depth: int = 8, target_accept: float | None = None,
              seed: int = 0, predictive_draws: int = 100, channels=None, sensor: Accelerometer | None = None,
              window: float | None = None, windows: int = 1, rtol: float | None = None, atol: float | None = None,
              max_steps: int | None = None, settings: Settings | None = None, align: str = "time",
              time_offset: float = 0.0, out=None, resume: bool = True, progress: bool = True,
              **fit_options) -> PosteriorResult:
    """Sample the posterior of the ``free`` parameters and of the noise level given a record
    (method: module docstring and docs/theory/uncertainty.md).

    Args:
        data: the record, as :func:`~jaxclear.fit` (so are ``mech``, ``free``, ``start``,
            ``channels``, ``sensor``, ``window``, ``settings``, ``align``, ``time_offset``: the
            fit's residual and sensor model is the likelihood; ``settings``: how the model is
            integrated, replaced where the fit owns it, as :func:`~jaxclear.fit` documents);
            ``fit_options``: further :func:`~jaxclear.fit` arguments. ``rtol``, ``atol``,
            ``max_steps`` are deprecated (a ``DeprecationWarning``, one release):
            ``settings=jc.settings(1.0, rtol=1e-8, atol=1e-11)``; with ``settings`` too, a
            :class:`~jaxclear.ParameterError`.
        fit_result: the least-squares fit of the same inputs (default: fitted here, with its
            checkpoint in ``out``).
        priors: ``name: prior`` (an :class:`~jaxclear.fitting.priors.AbstractPrior` or
            ``"KIND:A:B"``, :mod:`jaxclear.fitting.priors`) for free parameters and
            ``"noise_sigma"``; the others get the documented defaults.
        noise_sigma: the noise standard deviation [unit of the first fitted column] if known
            (then it is not sampled); default None: sampled.
        chains: chains; ``draws``: kept draws per chain; ``warmup``: warm-up draws per chain
            (step-size tuning, discarded); ``chunk``: draws per compiled chunk (``draws`` and
            ``warmup`` are rounded up to a multiple); None: the sampler's defaults
            (:data:`DEFAULT_COUNTS`: 2000, 500, 250 for the random walk, 500, 200, 50 for NUTS).
        sampler: ``"random-walk"`` (default) or ``"nuts"``, both in the Gauss-Newton-whitened
            coordinates. The random walk (Metropolis, its step scale tuned in the warm-up) needs
            one simulation a draw and no derivative; at the default window the likelihood jumps
            where a contact appears or vanishes inside the window as a parameter moves, which
            costs it rejected proposals only, where NUTS's trajectories diverge (half of them on
            such a record). Measured on records of the independent simulator at 3 ms: 7-17 times
            NUTS's effective draws a second, and 2.3 times at 0.6 ms (docs/theory/uncertainty.md,
            "Sampler"; benchmarks/README.md). NUTS (BlackJAX, the gradient through the simulation)
            for a smooth likelihood with many free parameters, where a random walk's efficiency
            falls like 1 / dimension. ``max_tree_depth``: NUTS's largest number of trajectory
            doublings; ``target_accept``: the acceptance rate the warm-up tunes the step towards
            (None: 0.8 for NUTS, 0.3 for the random walk), in (0, 1).
        seed: random seed; ``predictive_draws``: posterior draws for the predictive band.
        windows: must be 1 (see the module docstring).
        out: folder for the checkpoint and the files (:meth:`PosteriorResult.write`; None: nothing
            written, no resume); ``resume``: continue from a matching checkpoint in ``out``.

    Returns:
        :class:`~jaxclear.fitting.posterior_result.PosteriorResult`; its ``converged`` is False
        (and its summary says so) when a chain did not mix (R-hat above 1.05).

    Raises:
        ParameterError: bad counts, ``windows`` > 1, an unknown name in ``priors``, an improper
            or empty prior, a prior without support at the least-squares optimum, a
            Gauss-Newton matrix that is singular (a parameter not identifiable), and every
            :func:`~jaxclear.fit` error.
    """
    t_wall = time.perf_counter()
    integration, steps = given_settings("posterior", settings, rtol, atol, max_steps)
    require_extra("uncertainty", "posterior")
    target_accept = _check_sampler(sampler, target_accept)
    given = dict(draws=draws, warmup=warmup, chunk=chunk)
    draws, warmup, chunk = (DEFAULT_COUNTS[sampler][k] if v is None else v for k, v in given.items())
    _check_counts(chains=chains, draws=draws, warmup=warmup, chunk=chunk, max_tree_depth=max_tree_depth,
                  predictive_draws=predictive_draws)
    if windows != 1:
        raise ParameterError(f"posterior: windows = {windows}: only window 0, which starts from the known state, is "
                             "modelled (later windows' start states would have to be sampled too); use windows=1")
    if noise_sigma is not None and not (isinstance(noise_sigma, (int, float)) and math.isfinite(noise_sigma)
                                        and noise_sigma > 0):
        raise ParameterError(f"posterior: noise_sigma = {noise_sigma!r} must be a number > 0 (or None: sampled)")
    check_priors(tuple(free), priors or {})
    chunk = min(chunk, draws)
    draws = -(-draws // chunk) * chunk
    warmup = -(-warmup // chunk) * chunk
    # the step limit of before: 200,000 unless given (the fit's own for a known start)
    integration = integration if steps is not None else dataclasses.replace(integration, max_steps=MAX_STEPS)
    common = dict(channels=channels, sensor=sensor, settings=integration, align=align, time_offset=time_offset)
    if fit_result is None:
        fit_result = fit(data, mech, free, start, window=window, out=out, resume=resume, progress=progress,
                         **common, **fit_options)
    lp, info = _log_posterior(data, mech, tuple(free), fit_result, priors or {}, noise_sigma, common)
    settings = dict(chains=chains, draws=draws, warmup=warmup, chunk=chunk, max_tree_depth=max_tree_depth,
                    sampler=sampler, target_accept=target_accept, seed=seed, noise_fixed=noise_sigma is not None)
    key = work_key(info["problem_key"], np.asarray(lp.x0), np.asarray(lp.chol), json.dumps(info["priors"]),
                   json.dumps({k: v for k, v in settings.items() if k != "draws"}), length=32)
    with locked(out, "posterior"):
        run = _sample(lp, settings, key, out, resume, progress)
        res = build_result(lp, run, info, settings, fit_result, predictive_draws, seed,
                           time.perf_counter() - t_wall)
        if out is not None:
            res.write(out)
    return res


def check_priors(free: tuple, priors: dict) -> dict:
    """The given priors parsed (name -> :class:`~.priors.AbstractPrior`), checked before any fit:
    a name that is neither free nor ``noise_sigma``, an unknown kind, an improper or empty
    density: :class:`~jaxclear.ParameterError`."""
    unknown = sorted(set(priors) - set(free) - {NOISE})
    if unknown:
        raise ParameterError(f"posterior: priors given for {unknown}, which are not free parameters (free: "
                             f"{list(free)}, and {NOISE!r} for the noise level)")
    return {name: parse_prior(spec, f"prior of {name!r}") for name, spec in priors.items()}


def _check_sampler(sampler, target_accept) -> float:
    """The target acceptance rate of ``sampler`` (given, or its default); a named error for an
    unknown sampler or a rate outside (0, 1)."""
    if sampler not in SAMPLERS:
        raise ParameterError(f"posterior: sampler = {sampler!r}: expected one of {list(SAMPLERS)}")
    if target_accept is None:
        return TARGET_ACCEPT if sampler == "nuts" else RANDOM_WALK_ACCEPT
    if isinstance(target_accept, bool) or not isinstance(target_accept, (int, float)) or not 0 < target_accept < 1:
        raise ParameterError(f"posterior: target_accept = {target_accept!r}: expected a number in (0, 1)")
    return float(target_accept)


def _check_counts(**counts):
    lows = {"chains": 1, "draws": 1, "warmup": 0, "chunk": 1, "max_tree_depth": 1, "predictive_draws": 0}
    for name, v in counts.items():
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lows[name]:
            raise ParameterError(f"posterior: {name} = {v!r}: expected an integer >= {lows[name]}")


def _log_posterior(data, mech, free, fit_result: FitResult, priors: dict, noise_sigma, common: dict):
    """The :class:`LogPosterior` at the fit's optimum and what the result reports about it."""
    if tuple(fit_result.free) != free:
        raise ParameterError(f"posterior: fit_result fitted {list(fit_result.free)}, not the free {list(free)}")
    priors = check_priors(free, priors)
    s = common["settings"]
    settings = dict(max_iter=1, ftol=1e-6, xtol=1e-5, **settings_record(s, s.max_steps), align=common["align"],
                    time_offset=common["time_offset"], optimizer="levenberg-marquardt")
    problem = build_problem(data, mech, free, fit_result.estimates, common["sensor"], fit_result.window_length_s, 1,
                            (1.0,), None, 1, settings, common["channels"], integration=s)
    win = problem.window_input(0, 1.0, False, [problem.guess0])
    scale = problem.win.scale
    theta = z_vector(free, fit_result.estimates, scale, mech)
    state0 = jnp.asarray(problem.state0)
    r, jt, _, _, extra = evaluate_window_jit(problem.model, jnp.asarray(theta), state0, win)
    r, jt = np.asarray(r), np.asarray(jt)
    if not np.all(np.isfinite(r)):
        raise ParameterError("posterior: the model cannot be simulated at the least-squares optimum "
                             f"(status {int(extra[3])}); check the fit")
    weights = np.asarray(problem.model.weights)
    n = fitted_entries(win, weights)
    sigma_unit = scale / math.sqrt(float(weights[0])) if weights[0] > 0 else scale
    fixed_r = None if noise_sigma is None else float(noise_sigma) / sigma_unit
    cov, sigma_r = gauss_newton_covariance(r, jt, n, fixed_r)
    if cov is None:
        raise ParameterError("posterior: the Gauss-Newton matrix J^T J is singular at the optimum: a free parameter "
                             "is not identifiable from this record (fix it, or give a longer record)")
    prior_objs = []
    for name, value in fit_result.estimates.items():
        pr = priors[name] if name in priors else default_prior(name, transform(name, mech),
                                                                                  problem.values0[name], scale)
        check_support(pr, name, value)
        prior_objs.append(pr)
    npr = priors[NOISE] if NOISE in priors else noise_prior(scale)
    if noise_sigma is None:
        check_support(npr, NOISE, sigma_r * sigma_unit)
    x0 = np.append(theta, math.log(sigma_r)) if noise_sigma is None else theta
    lp = LogPosterior(model=problem.model, win=win, state0=state0, priors=tuple(prior_objs), noise_prior=npr,
                      x0=jnp.asarray(x0), chol=jnp.asarray(np.linalg.cholesky(cov)),
                      noise_log=jnp.asarray(math.log(sigma_r)), n=jnp.asarray(n), sigma_unit=jnp.asarray(sigma_unit),
                      fixed_noise=noise_sigma is not None)
    info = dict(problem=problem, problem_key=problem.checkpoint_key(), free=free, scale=scale, cov=cov,
                priors={**{nm: p.describe() for nm, p in zip(free, prior_objs)},
                        NOISE: (f"fixed at {noise_sigma:g}" if noise_sigma is not None else npr.describe())},
                gn_sigma=sigma_r * sigma_unit, n=n)
    return lp, info


def _starts(lp: LogPosterior, chains: int, seed: int, gradient: bool = True) -> np.ndarray:
    """Chain starts ``(C, D)`` in ``u``: standard normal (the optimum plus a Gauss-Newton jitter),
    halved where the density is not finite or lies more than :data:`START_DROP` below what the
    Gauss-Newton approximation gives there (``log p(0) - |u|^2 / 2``: a start beyond a jump of the
    likelihood, a contact gained or lost, where the density may even rise away from the optimum
    and a chain of NUTS cannot cross back); an optimum without finite density is an error.
    ``gradient``: whether the density's derivative is compiled (NUTS needs it anyway)."""
    d = int(lp.x0.shape[0])
    u = np.random.default_rng(seed).standard_normal((chains, d))
    at = lambda v: np.asarray(init_states(lp, jnp.asarray(v), gradient).logdensity)  # noqa: E731
    top = at(np.zeros((chains, d)))[0]  # the optimum (the chains' shape: one compilation)
    for _ in range(_START_TRIES):
        v = at(u)
        ok = np.isfinite(v) & ~(v < top - 0.5 * np.sum(u**2, axis=1) - START_DROP)
        if ok.all():
            return u
        u[~ok] *= 0.5
    u[~ok] = 0.0
    if not np.isfinite(at(u)).all():
        raise ParameterError("posterior: the log posterior is not finite at the least-squares optimum (a prior "
                             "without support there, or a run that fails)")
    return u


def _chain_keys(seed: int, chains: int, index: int):
    """Random keys ``(C, 2)`` of phase ``index`` (0: warm-up, c + 1: chunk c) of every chain."""
    base = jax.random.split(jax.random.PRNGKey(seed), chains)
    return jax.vmap(lambda k: jax.random.fold_in(k, index))(base)


_DRAW_FIELDS = ("x", "lp", "diverging", "acceptance_rate", "n_steps", "tree_depth")


def _load(work: Work, resume: bool):
    """The checkpoint's arrays (:meth:`jaxclear._checkpoint.Work.read_npz`: the protocol's rules;
    none without one or without ``resume``), checked to be finite and consistent (else a
    :class:`~jaxclear.CheckpointError` naming the file)."""
    saved = work.read_npz(POSTERIOR_CHECKPOINT, restart=not resume)
    if saved is None:
        return None
    try:
        for name in ("position", "logdensity", "grad", *StepSize._fields, *_DRAW_FIELDS):
            if not np.all(np.isfinite(saved[name])):
                raise ValueError(f"{name} holds a value that is not finite")
        if saved["x"].shape[:2] != saved["lp"].shape:
            raise ValueError("the draws and their log densities differ in shape")
        return saved
    except (ValueError, KeyError) as exc:
        raise CheckpointError(f"the posterior checkpoint {work.path(POSTERIOR_CHECKPOINT)!r} is damaged ({exc}); "
                              "delete it, or start over with --restart (API: resume=False)") from None


def _sample(lp: LogPosterior, s: dict, key: str, out, resume: bool, progress: bool) -> dict:
    """Warm-up and draws in chunks of ``chunk`` with a checkpoint after each (one compilation serves
    both: :func:`.sampler.random_walk_chunk` or :func:`.sampler.nuts_chunk`, by ``s["sampler"]``,
    NUTS where it is absent); returns the draws (``x`` ``(C, draws, D)``, ...)."""
    work = Work(out, "posterior", key, {k: v for k, v in s.items() if k != "draws"}, version=FORMAT)
    path = work.path(POSTERIOR_CHECKPOINT)
    saved = _load(work, resume)
    chains, chunk, depth = s["chains"], s["chunk"], s["max_tree_depth"]
    nuts = s.get("sampler", "nuts") == "nuts"
    target = s.get("target_accept") or (TARGET_ACCEPT if nuts else RANDOM_WALK_ACCEPT)
    n_warm = s["warmup"] // chunk  # warm-up chunks (warmup is a multiple of chunk)
    d = int(lp.x0.shape[0])
    if saved is None:
        states = init_states(lp, jnp.asarray(_starts(lp, chains, s["seed"], nuts)), nuts)
        step0 = 0.5 if nuts else 2.38 / math.sqrt(d)  # NUTS: BlackJAX's; the walk: Roberts et al.'s scale
        saved = dict(position=np.asarray(states.position), logdensity=np.asarray(states.logdensity),
                     grad=np.asarray(states.grad), **{f: np.asarray(a) for f, a in
                                                      zip(StepSize._fields, init_step_size(step0, chains))},
                     warmup_divergences=np.zeros(chains), warm_done=np.asarray(0),
                     x=np.zeros((chains, 0, d)), **{f: np.zeros((chains, 0)) for f in _DRAW_FIELDS[1:]},
                     wall_s=np.asarray(0.0))
    elif progress:
        tqdm.write(f"jaxclear posterior: resuming from {path} after {int(saved['warm_done'])} warm-up chunk(s) and "
                   f"{saved['x'].shape[1]} draws per chain")
    resumed = float(saved["wall_s"]) > 0
    total = n_warm + s["draws"] // chunk
    done = int(saved["warm_done"]) + saved["x"].shape[1] // chunk
    bar = tqdm(total=total * chunk, initial=min(done, total) * chunk, desc="posterior (warm-up + draws)",
               unit="draw", disable=not progress)
    try:
        with stop_at_safe_points("the current chunk of draws") as interrupt:
            while done < total:
                t1 = time.perf_counter()
                states = ChainState(*(jnp.asarray(saved[f]) for f in ("position", "logdensity", "grad")))
                step = StepSize(*(jnp.asarray(saved[f]) for f in StepSize._fields))
                adapt = done < n_warm
                keys = _chain_keys(s["seed"], chains, done + 1)
                if nuts:
                    states, step, draws_ = nuts_chunk(lp, states, step, keys, jnp.asarray(adapt), chunk, depth, target)
                else:
                    states, step, draws_ = random_walk_chunk(lp, states, step, keys, jnp.asarray(adapt), chunk, target)
                saved.update(position=np.asarray(states.position), logdensity=np.asarray(states.logdensity),
                             grad=np.asarray(states.grad), **{f: np.asarray(a) for f, a in zip(StepSize._fields, step)})
                if adapt:
                    saved["warmup_divergences"] = saved["warmup_divergences"] + np.asarray(draws_[2]).sum(axis=1)
                    saved["warm_done"] = np.asarray(int(saved["warm_done"]) + 1)
                else:
                    x = np.asarray(lp.x0) + np.asarray(draws_[0]) @ np.asarray(lp.chol).T
                    new = dict(zip(_DRAW_FIELDS, (x, *[np.asarray(a, dtype=float) for a in draws_[1:]])))
                    for f in _DRAW_FIELDS:
                        saved[f] = np.concatenate([saved[f], new[f]], axis=1)
                saved["wall_s"] = np.asarray(float(saved["wall_s"]) + time.perf_counter() - t1)
                work.write_npz(POSTERIOR_CHECKPOINT, saved, finished=done + 1 >= total)
                done += 1
                bar.update(chunk)
                interrupt.check()
    finally:
        bar.close()
    run = {f: saved[f][:, : s["draws"]] for f in _DRAW_FIELDS}
    run.update(step_size=np.exp(saved["log_step_size_avg"]), warmup_divergences=saved["warmup_divergences"],
               sampling_wall_s=float(saved["wall_s"]), resumed=resumed)
    return run
