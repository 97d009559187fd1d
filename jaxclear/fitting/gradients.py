"""Gradients of a scalar of a simulation with respect to named parameters, and the scalar
the gradient tests and benchmarks share."""

from __future__ import annotations

import dataclasses
from typing import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .. import params
from .._errors import ParameterError
from ..model import Mechanism
from ..integrate import Settings, jit, simulate
from .parameters import check_name


def parameter_grad(loss: Callable, mech: Mechanism, names: Sequence[str], s: Settings, mode: str = "reverse"):
    """Value and gradient of ``loss(solution, mechanism)`` (a scalar) with respect to the named
    parameters (:mod:`jaxclear.params`).

    With ``s.derivatives = Sensitivity()`` (the default) both modes give the error-controlled
    sensitivities (:mod:`jaxclear.integrate._sensitivity`): ``mode="forward"`` by ``jax.jacfwd``,
    ``mode="reverse"`` by ``jax.grad`` (their transpose), the same numbers. Through diffrax's loop
    (:class:`~jaxclear.ThroughLoop`), ``mode="reverse"`` uses ``s.derivatives``' adjoint
    (``"forward"`` is replaced by ``"recursive"``) and ``mode="forward"`` uses ``"forward"``
    (:meth:`~jaxclear.integrate._strategies.AbstractDerivatives.for_mode`). Returns ``(value, {name: d
    loss / d name})``. Compiles on every call: for repeated use, build your own
    ``eqx.filter_jit`` of the same function.
    """
    names = tuple(names)
    for n in names:
        check_name(mech, n)
    if mode not in ("reverse", "forward"):
        raise ParameterError(f"mode = {mode!r}; valid: 'reverse', 'forward'")
    s = dataclasses.replace(s, derivatives=s.derivatives.for_mode(mode))
    x0 = jnp.asarray([params.get(mech, n) for n in names], dtype=float)

    def f(x):
        m = params.replace_many(mech, dict(zip(names, x)))
        value = loss(simulate(m, s), m)
        return value, value

    if mode == "reverse":
        g, value = jit(jax.grad(f, has_aux=True))(x0)
    else:
        g, value = jit(jax.jacfwd(f, has_aux=True))(x0)
    return float(value), {n: float(g[i]) for i, n in enumerate(names)}


def slider_power_loss(mech: Mechanism, names: Sequence[str], units, s: Settings, slider: str = "slider",
                      scale: float = 1e8) -> Callable:
    r"""``f(x)``: the mean square slider acceleration of a simulation, divided by ``scale``
    [m^2/s^4], as a function of the scaled parameters ``x`` ``(len(names),)``: parameter ``i``
    is ``x[i] * units[i]`` (SI), so that ``x`` is of order 1.

    .. math:: f(x) = \frac{1}{T\,s} \sum_{t=0}^{T-1} \ddot x_{slider}(t)^2

    over the ``T = s.n_out`` output times. A scalar that depends smoothly on every parameter
    through the impacts; used to compare reverse mode, forward mode and finite differences
    (tests) and to time them (benchmarks). Differentiate it with ``jax.grad`` or ``jax.jacfwd``
    (the default adjoint, or through the loop: ``jax.grad`` with ``"recursive"``, ``jax.jacfwd``
    with ``"forward"``)."""
    names = tuple(names)
    units = np.asarray(units, dtype=float)

    def f(x):
        m = params.replace_many(mech, {n: x[i] * units[i] for i, n in enumerate(names)})
        sol = simulate(m, s)
        return jnp.mean(sol.coordinate(m, slider, "x", derivative=2) ** 2) / scale

    return f
