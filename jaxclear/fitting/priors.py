r"""Priors of the posterior (:mod:`jaxclear.fitting.posterior`): stated densities of the free
parameters and of the noise level, in their own units (SI).

Each prior is a density :math:`p(\theta)` of the value; the sampler works in the fit's
unconstrained coordinate :math:`z` (:mod:`.parameters`), so the log density it sees is
:math:`\log p(\theta(z)) + \log|d\theta/dz|` (the change of variables), and a stated prior is
the prior of the value, whatever the coordinate.

Defaults (weakly informative: wide enough that a record of a few impacts dominates them, narrow
enough to be proper):

* a positive parameter (log transform: stiffness, clearance, friction, masses, ``sensor_gain``):
  log-normal with median the start value and :math:`\sigma_{\log} = \ln 10` (a factor 10 at one
  standard deviation, 100 at two);
* restitution (logit transform): uniform on (0, 1);
* ``sensor_bias``: normal, mean 0, standard deviation the data RMS;
* any other parameter: no default (give one; a :class:`~jaxclear.ParameterError` says so);
* the noise standard deviation :math:`\sigma` [unit of the first fitted column]: half-normal with
  scale the data RMS (Gelman, *Prior distributions for variance parameters in hierarchical
  models*, Bayesian Analysis 1, 2006: a proper, weakly informative prior on a scale).

A prior is given as a string ``KIND:A[:B]`` (the command line's ``--prior NAME=KIND:A:B``) or
an object: ``normal:MEAN:SD``, ``lognormal:MEDIAN:FACTOR`` (:math:`\sigma_{\log} = \ln`
FACTOR), ``uniform:LOW:HIGH``, ``halfnormal:SCALE``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import ParameterError

#: The log-normal default's factor at one standard deviation.
DEFAULT_LOG_FACTOR = 10.0
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def _array(x):
    """A prior's number as a float64 array leaf (records of one structure share a compilation)."""
    return jnp.asarray(x, dtype=float)


class AbstractPrior(eqx.Module):
    """A prior density of one value (SI)."""

    def logpdf(self, value):
        """Log density at ``value`` (traceable; ``-inf`` outside the support)."""
        raise NotImplementedError

    def describe(self) -> str:
        raise NotImplementedError


class Normal(AbstractPrior):
    """Normal density, ``mean``, standard deviation ``sd`` > 0."""

    mean: jax.Array = eqx.field(converter=_array)
    sd: jax.Array = eqx.field(converter=_array)

    def logpdf(self, value):
        return -0.5 * ((value - self.mean) / self.sd) ** 2 - jnp.log(self.sd) - _LOG_SQRT_2PI

    def describe(self) -> str:
        return f"normal(mean={float(self.mean):g}, sd={float(self.sd):g})"


class LogNormal(AbstractPrior):
    """Log-normal density: ``log(value)`` normal with mean ``log(median)``, sd ``log(factor)``."""

    median: jax.Array = eqx.field(converter=_array)
    factor: jax.Array = eqx.field(converter=_array)

    def logpdf(self, value):
        s = jnp.log(self.factor)
        safe = jnp.where(value > 0, value, 1.0)
        lp = -0.5 * ((jnp.log(safe) - jnp.log(self.median)) / s) ** 2 - jnp.log(safe) - jnp.log(s) - _LOG_SQRT_2PI
        return jnp.where(value > 0, lp, -jnp.inf)

    def describe(self) -> str:
        return f"lognormal(median={float(self.median):g}, factor={float(self.factor):g})"


class Uniform(AbstractPrior):
    """Uniform density on ``[low, high]``."""

    low: jax.Array = eqx.field(converter=_array)
    high: jax.Array = eqx.field(converter=_array)

    def logpdf(self, value):
        inside = (value >= self.low) & (value <= self.high)
        return jnp.where(inside, -jnp.log(self.high - self.low), -jnp.inf)

    def describe(self) -> str:
        return f"uniform(low={float(self.low):g}, high={float(self.high):g})"


class HalfNormal(AbstractPrior):
    """Half-normal density on ``[0, inf)`` with ``scale`` (the sd of the normal it folds)."""

    scale: jax.Array = eqx.field(converter=_array)

    def logpdf(self, value):
        lp = -0.5 * (value / self.scale) ** 2 - jnp.log(self.scale) + math.log(2.0) - _LOG_SQRT_2PI
        return jnp.where(value >= 0, lp, -jnp.inf)

    def describe(self) -> str:
        return f"halfnormal(scale={float(self.scale):g})"


#: Prior kinds of the string form: kind -> (class, number of numbers, their names).
KINDS = {"normal": (Normal, ("mean", "sd")), "lognormal": (LogNormal, ("median", "factor")),
         "uniform": (Uniform, ("low", "high")), "halfnormal": (HalfNormal, ("scale",))}


def make_prior(kind: str, *numbers: float, where: str = "prior") -> AbstractPrior:
    """A prior of ``kind`` (:data:`KINDS`) with its numbers checked: an improper or empty density
    (sd <= 0, factor <= 1, low >= high, a number that is not finite) is a
    :class:`~jaxclear.ParameterError` naming ``where`` and the allowed range."""
    if kind not in KINDS:
        raise ParameterError(f"{where}: unknown prior kind {kind!r}; allowed: {', '.join(KINDS)}")
    cls, names = KINDS[kind]
    if len(numbers) != len(names):
        raise ParameterError(f"{where}: a {kind} prior takes {len(names)} number(s) ({', '.join(names)}), got "
                             f"{len(numbers)}: write {kind}:{':'.join(n.upper() for n in names)}")
    values = []
    for n, v in zip(names, numbers):
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise ParameterError(f"{where}: {kind} {n} = {v!r} is not a number") from None
        if not math.isfinite(v):
            raise ParameterError(f"{where}: {kind} {n} = {v!r} must be finite")
        values.append(v)
    checks = {"normal": (values[-1] > 0, "sd must be > 0 (an improper density otherwise)"),
              "lognormal": (values[0] > 0 and values[-1] > 1, "median must be > 0 and factor > 1"),
              "uniform": (values[0] < values[-1], "low must be < high (the interval is empty otherwise)"),
              "halfnormal": (values[0] > 0, "scale must be > 0")}
    ok, rule = checks[kind]
    if not ok:
        raise ParameterError(f"{where}: {kind}({', '.join(f'{n}={v:g}' for n, v in zip(names, values))}): {rule}")
    return cls(*values)


def parse_prior(spec, where: str = "prior") -> AbstractPrior:
    """An :class:`AbstractPrior` as is, or the string form ``KIND:A[:B]`` (module docstring)."""
    if isinstance(spec, AbstractPrior):
        return spec
    if not isinstance(spec, str):
        raise ParameterError(f"{where}: expected a prior (e.g. 'lognormal:1e10:10'), got {spec!r}")
    kind, *numbers = [s.strip() for s in spec.split(":")]
    return make_prior(kind.lower(), *numbers, where=where)


def default_prior(name: str, transform: str, start: float, data_rms: float) -> AbstractPrior:
    """The default prior of a free parameter (module docstring)."""
    if transform == "log":
        return LogNormal(float(start), DEFAULT_LOG_FACTOR)
    if transform == "logit":
        return Uniform(0.0, 1.0)
    if name == "sensor_bias":
        return Normal(0.0, float(data_rms))
    raise ParameterError(f"the posterior has no default prior for {name!r} (a parameter of any sign): give one, "
                         f"e.g. priors={{{name!r}: 'normal:MEAN:SD'}} (CLI: --prior {name}=normal:MEAN:SD)")


def noise_prior(data_rms: float) -> AbstractPrior:
    """The default prior of the noise standard deviation: half-normal, scale the data RMS."""
    return HalfNormal(float(data_rms))


def check_support(prior: AbstractPrior, name: str, value: float):
    """A :class:`~jaxclear.ParameterError` when ``prior`` has no density at the start ``value``."""
    lp = float(prior.logpdf(jnp.asarray(value, dtype=float)))
    if not math.isfinite(lp):
        raise ParameterError(f"the prior of {name!r}, {prior.describe()}, has no support at the start value "
                             f"{name} = {value:g} (the least-squares optimum): widen the prior or start inside it")
