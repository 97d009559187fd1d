"""Gradients of a scalar of a simulation with respect to named parameters, and the scalar
the gradient tests and benchmarks share."""

from __future__ import annotations

import dataclasses
from typing import Callable, Sequence

import equinox as eqx
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
    sensitivities (:mod:`jaxclear.integrate._sensitivity`): ``mode="forward"`` by
    ``jax.linearize``, ``mode="reverse"`` by ``jax.grad`` (their transpose), the same numbers.
    Through diffrax's loop (:class:`~jaxclear.ThroughLoop`), ``mode="reverse"`` uses
    ``s.derivatives``' adjoint (``"forward"`` is replaced by ``"recursive"``) and
    ``mode="forward"`` uses ``"forward"``
    (:meth:`~jaxclear.integrate._strategies.AbstractDerivatives.for_mode`). Returns ``(value,
    {name: d loss / d name})``. Each derivative means what :func:`jaxclear.sensitivities`'
    does: the change of the loss as that one number changes, derived values (a stiffness left to
    the preset) following their sources, whichever other names are asked
    (:func:`jaxclear.params.directions`). The names are tangent directions given to one
    compiled program per ``loss`` function, settings and mode: in reverse mode the gradient with
    respect to every floating-point leaf of the mechanism, projected on the directions after the
    program (any set of names), in forward mode :func:`jaxclear.sensitivities`' own program with
    ``loss`` as its output (one tangent per name; any set of as many names, shared with
    ``jc.sensitivities(mech, names, settings, output=loss)``). Under the default sensitivities
    reverse mode integrates one tangent per scalar of the mechanism (63 on the benchmark
    slider-crank) and forward mode one per name: with few names forward mode is the cheaper.
    """
    names = tuple(names)
    for n in names:
        check_name(mech, n)
    if mode not in ("reverse", "forward"):
        raise ParameterError(f"mode = {mode!r}; valid: 'reverse', 'forward'")
    s = dataclasses.replace(s, derivatives=s.derivatives.for_mode(mode))
    if mode == "forward":  # the program of jc.sensitivities with ``loss`` as its output: shared with it
        value, derivatives = params.sensitivities(mech, names, s, output=loss, warn=False)
        return float(value), {n: float(derivatives[n]) for n in names}
    at, along = params.directions(mech, names)
    value, grad = _value_and_grad(loss, at, s)
    g = sum(np.tensordot(np.asarray(t), np.asarray(d), axes=np.ndim(d)) for t, d in
            zip(jax.tree_util.tree_leaves(along), jax.tree_util.tree_leaves(grad)))
    return float(value), {n: float(g[i]) for i, n in enumerate(names)}


@jit
def _value_and_grad(loss, mech, s):
    """The loss and its gradient over every floating-point leaf of the mechanism (a pytree of
    ``eqx.filter(mech, eqx.is_inexact_array)``'s structure): one program for any set of names."""
    dynamic, static = eqx.partition(mech, eqx.is_inexact_array)

    def f(d):
        m = eqx.combine(d, static)
        return loss(simulate(m, s), m)

    return jax.value_and_grad(f)(dynamic)


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
