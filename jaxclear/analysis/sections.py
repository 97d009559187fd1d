r"""Poincare sections on named channels and the period of the orbit they show: the one place
that sweeps (:mod:`jaxclear.sweep`) and the chaos tools (:mod:`jaxclear.chaos`) take a
section from.

A periodically forced or driven mechanism (a crank at constant speed, a harmonic load) has a
stroboscopic Poincare section: the state once per forcing period :math:`T`,
:math:`x_k = x(t_0 + kT)` (Guckenheimer and Holmes, *Nonlinear Oscillations, Dynamical Systems,
and Bifurcations of Vector Fields*, Springer 1983, sec. 1.5). On a uniform output grid with a
whole number of samples per period it is every ``stride``-th sample. A period-``n`` orbit
(a subharmonic of order ``n``) returns to the same point every ``n`` sections; a quasi-periodic
or chaotic one never does. Any named channel (:mod:`jaxclear.analysis.channels`) is a
coordinate of the section: a bifurcation diagram plots one against a swept parameter.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from ..integrate import Solution
from ..model import Mechanism
from .channels import channel, unit

#: Longest period :func:`detect_period` looks for.
MAX_PERIOD = 16


def at_samples(sol: Solution, index) -> Solution:
    """``sol`` at the output samples ``index`` (an integer array or slice): every field with a
    leading time axis is indexed, the run's statistics and status are kept."""
    n = sol.ts.shape[0]
    return jax.tree_util.tree_map(lambda x: x[index] if jnp.ndim(x) and x.shape[0] == n else x, sol)


def section_indices(n_samples: int, stride: int, offset: int = 0) -> np.ndarray:
    """Indices of the section samples: ``offset, offset + stride, ...`` below ``n_samples``
    (``stride`` samples per forcing period)."""
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise ParameterError(f"stride = {stride!r} samples per period is outside the allowed range [1, inf)")
    if not 0 <= offset < max(n_samples, 1):
        raise ParameterError(f"offset = {offset!r} is outside the allowed range [0, {n_samples})")
    return np.arange(offset, n_samples, stride)


def check_channels(mech: Mechanism, channels) -> tuple[str, ...]:
    """``channels`` as a tuple of names, each checked against ``mech`` (a
    :class:`~jaxclear.ParameterError` naming a channel that does not exist)."""
    channels = (channels,) if isinstance(channels, str) else tuple(str(c) for c in channels)
    if not channels:
        raise ParameterError("no channel given: name at least one (e.g. 'joint:0:ecc_x', 'body:slider:x:vel')")
    for c in channels:
        unit(mech, c)
    return channels


def section(mech: Mechanism, sol: Solution, channels, index):
    """The channels at the section samples ``index``: (K, C), traceable (channels evaluated on
    the section samples only)."""
    sub = at_samples(sol, jnp.asarray(index))
    return jnp.stack([channel(mech, sub, c) for c in check_channels(mech, channels)], axis=-1)


def detect_period(points, max_period: int = MAX_PERIOD, rtol: float = 1e-3, scale=None) -> int:
    r"""The period ``n`` of a sequence of section points ``points`` (K,) or (K, C): the smallest
    ``n <= max_period`` with :math:`|x_{k+n} - x_k| \le` ``rtol`` times the channel's size for
    every ``k`` and channel; 0 when there is none (not periodic within ``max_period``:
    quasi-periodic, chaotic, or still in its transient). The size is ``scale`` (a number or one
    per channel: e.g. the channel's largest magnitude over the whole run, the right measure
    where the section lies near zero, such as a slider's velocity at a dead centre), by default
    the largest magnitude over the points. Needs ``K > 2 n`` points to call a period ``n`` (two
    repeats)."""
    p = np.asarray(points, dtype=float)
    p = p[:, None] if p.ndim == 1 else p
    if not np.all(np.isfinite(p)):
        return 0
    size = np.max(np.abs(p), axis=0) if scale is None else np.broadcast_to(np.abs(np.asarray(scale, float)),
                                                                            p.shape[1:])
    size = np.where(size > 0, size, 1.0)
    for n in range(1, max_period + 1):
        if p.shape[0] <= 2 * n:
            break
        if np.all(np.max(np.abs(p[n:] - p[:-n]), axis=0) <= rtol * size):
            return n
    return 0


def period_name(n: int, max_period: int = MAX_PERIOD) -> str:
    """``"period-1"``, ``"period-2"``, ... or ``"not periodic (n > 16)"`` (``max_period``: the
    longest period looked for; below 1, too few points to tell)."""
    if n > 0:
        return f"period-{n}"
    return f"not periodic (n > {max_period})" if max_period >= 1 else "too few section points to tell"
