r"""Derivatives of a simulation with respect to named parameters: :func:`sensitivities`.

``jax.jvp``, ``jax.jacfwd``, ``jax.grad`` and ``jax.vjp`` of :func:`~jaxclear.simulate` already
give the error-controlled sensitivities (``Settings(adjoint="sensitivity")``, the default;
:mod:`jaxclear.integrate._sensitivity`); this module names what to differentiate by the names of
:mod:`jaxclear.params` and reports how far the derivatives can be trusted:

* :func:`differentiable_names` lists the names of a mechanism (every ``name@J`` of each clearance
  joint, ``mass:BODY`` of each body, ``point_x:BODY.POINT`` of each point, ...);
* :func:`sensitivities` returns the solution (or any output of it) and its derivative with
  respect to each name;
* :func:`amplification` measures how much the state's relative change exceeds the parameter's:
  in a chaotic motion it grows like :math:`e^{\lambda t}` (:math:`\lambda` the largest Lyapunov
  exponent), and once a change of the parameter of the size of the solver's relative tolerance
  moves the state by more than a tenth of its own size, the run is past its horizon of
  predictability: the computed trajectory is no longer reproducible to its tolerance, and
  neither its derivative (:class:`DerivativeHorizonWarning`).
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from typing import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import registry as params
from .._errors import ParameterError
from .._results import deprecated
from ..integrate import Sensitivity, Settings, Solution, along_run, jit, simulate, solution_structure
from ..integrate import check_settings, check_status
from ..model import Mechanism


class DerivativeHorizonWarning(UserWarning):
    """A derivative was requested past the run's horizon of predictability (:func:`amplification`)."""


def differentiable_names(mech: Mechanism) -> list[str]:
    """Every name of :mod:`jaxclear.params` that addresses a number of ``mech`` (suffixed for each
    body, point and clearance joint): the inputs :func:`sensitivities` differentiates
    (:func:`jaxclear.params.names`)."""
    return params.names(mech)


def check_names(mech: Mechanism, names: Sequence[str]) -> tuple:
    """``names`` as a tuple; a :class:`~jaxclear.ParameterError` for an empty list, a repeated name,
    or a name that is not a number of ``mech`` (an unknown name, or a structural field such as a
    law's model or a body's name), listing the differentiable names."""
    names = tuple(names)
    if not names:
        raise ParameterError("no parameter to differentiate with respect to: give at least one name")
    if len(set(names)) != len(names):
        raise ParameterError(f"parameters listed twice: {list(names)}")
    for name in names:  # why, then the closest names (params.closest)
        params.check_name(mech, name, context=f"cannot differentiate with respect to {name!r}")
    return names


def directions(mech: Mechanism, names: Sequence[str]):
    """The mechanism with the named numbers and every derived value set (arrays, at their
    values), and the tangents of its floating-point leaves along each name, stacked ``(k, ...)``
    (``eqx.filter(mech, eqx.is_inexact_array)``'s structure: a leaf's change per unit change of
    ``names[i]``, derived values following their sources:
    :func:`jaxclear.params.replace_following`). Every derived value is set, asked or not, so
    the mechanism's structure, hence a compiled derivative of its run (:func:`sensitivities`,
    :func:`jaxclear.parameter_grad`), does not depend on which names are asked: the names are
    tangent directions given to the program, and a new set of as many names reuses it."""
    names = tuple(names)
    x = jnp.asarray([params.get(mech, n) for n in names], dtype=float)
    derived = {n: params.get(mech, n) for n in params.names(mech) if n not in names and params.is_derived(mech, n)}

    def put(v):
        return params.replace_following(mech, {**dict(zip(names, v)), **derived}, {**dict(zip(names, x)), **derived})

    def floats(v):
        return eqx.filter(put(v), eqx.is_inexact_array)

    tangents = jax.vmap(lambda e: jax.jvp(floats, (x,), (e,))[1])(jnp.eye(x.shape[0], dtype=x.dtype))
    return put(x), tangents


@jit
def _linearized(mech, s, along, values, output):
    """``(value, tangents, status)`` of the run of ``mech`` and its derivatives along the stacked
    directions ``along`` of its floating-point leaves (:func:`directions`; ``values`` ``(k,)`` the
    named numbers' values): tangent directions are arguments, so one program serves every set
    of as many names. Under the default :class:`~jaxclear.integrate.Sensitivity` one sensitivity
    solve of ``k`` tangents (:func:`~jaxclear.integrate.along_run`; ``output`` then differentiated
    along the run's tangents and the directions by ``jax.jvp``); under another strategy
    ``jax.linearize`` of the run. The run's status is returned, not raised here (``s`` without
    ``throw``), so that the program holds no host callback and JAX's persistent compilation cache
    keeps it; :func:`sensitivities` raises for it after the program returns. Without ``output`` it
    goes through the store of traced programs (:func:`_linearized_run`): a new process loads it
    instead of tracing it."""
    quiet = dataclasses.replace(s, throw=False)
    if isinstance(s.derivatives, Sensitivity):
        sol, basis = along_run(mech, quiet, along, values)
        if output is None:
            return sol, basis, sol.status
        floats = jax.tree_util.tree_map(eqx.is_inexact_array, sol)
        sd, ss = eqx.partition(sol, floats)
        md, ms = eqx.partition(mech, eqx.is_inexact_array)

        def g(a, b):
            return output(eqx.combine(a, ss), eqx.combine(b, ms))

        tangents = jax.vmap(lambda ta, tb: jax.jvp(g, (sd, md), (ta, tb))[1])(eqx.filter(basis, floats), along)
        return g(sd, md), tangents, sol.status
    dynamic, static = eqx.partition(mech, eqx.is_inexact_array)

    def f(d):
        m = eqx.combine(d, static)
        sol = simulate(m, quiet)
        return (sol if output is None else output(sol, m)), sol.status

    value, lin, status = jax.linearize(f, dynamic, has_aux=True)
    return value, jax.vmap(lin)(along), status


def _linearized_run(mech, s, along, values, output):
    """:func:`_linearized`, through the store of traced programs where its output's structure is
    known without tracing (the whole solution: ``output`` None), else as a plain call."""
    if output is not None:
        return _linearized(mech, s, along, values, output)

    def structure():  # found once per program (an eval_shape of the state's layout)
        sol = solution_structure(mech)
        return jax.tree_util.treedef_tuple([sol, sol, jax.tree_util.tree_structure(0)])

    return _linearized.stored("sensitivities", structure, mech, s, along, values, None)


@functools.partial(jax.jit, static_argnums=1)
def _unstacked(stacked: list, k: int) -> list:
    """``[[x[i] for x in stacked] for i in range(k)]`` in one program (one per shapes, whatever
    the names: eagerly, each slice compiled a program of its own in a new process)."""
    return [[x[i] for x in stacked] for i in range(k)]


def _is_float(x) -> bool:
    return hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.inexact)


def sensitivities(mech: Mechanism, names: Sequence[str], s: Settings, output: Callable | None = None,
                  warn: bool = True):
    r"""The run and its derivatives with respect to the named parameters.

    The arguments come in the order of :func:`jaxclear.parameter_grad` (``loss, mech, names,
    s``): the mechanism, the names, the settings. The old order ``sensitivities(mech, s, names)``
    still works for one release, with a :class:`DeprecationWarning` (told apart by the type of
    the second argument, a :class:`~jaxclear.Settings`).

    Args:
        mech: the mechanism.
        s: the settings; with ``adjoint="sensitivity"`` (the default) the derivatives are the
            error-controlled forward sensitivities (their steps are sized for the derivatives
            too); the other adjoints differentiate through the solver's loop.
        names: names of :mod:`jaxclear.params` (:func:`differentiable_names`). Each derivative
            is the change of the output as that one number changes, the other named numbers
            held and the derived values following their sources
            (:func:`jaxclear.params.replace_following`): its meaning does not depend on which
            other names are asked. A stiffness left to the preset (derived from the materials
            and the radii, :func:`jaxclear.params.is_derived`) follows ``clearance``, asked
            with ``stiffness`` or not; ``d["stiffness"]`` is the change of the stiffness alone.
            For the derivative at a fixed stiffness, set it first:
            ``params.replace(mech, "stiffness", params.get(mech, "stiffness"))``.
        output: ``output(solution, mechanism) -> array`` to differentiate; ``None``: the whole
            :class:`~jaxclear.Solution`.
        warn: issue :class:`DerivativeHorizonWarning` when a derivative is past the run's horizon
            of predictability (:func:`amplification`; with ``output=None``, for the parameters
            whose value is not zero).

    Returns:
        ``(value, derivatives)``: ``value`` the solution (or the output), ``derivatives`` a dict
        name -> its derivative with respect to that parameter [unit of the value per SI unit of the
        parameter; ``speed_rpm`` per rpm], of the same structure as ``value`` (a
        :class:`~jaxclear.Solution` whose float fields are derivatives and whose integer fields,
        status and counts, are the run's).
    """
    if isinstance(names, Settings) and not isinstance(s, Settings):  # the old order (mech, s, names)
        deprecated("jc.sensitivities(mech, settings, names)",
                   "jc.sensitivities(mech, names, settings), the order of jc.parameter_grad(loss, mech, names, settings)")
        names, s = s, names
    check_settings("sensitivities", s, required=True, name="s")
    names = check_names(mech, names)
    at, along = directions(mech, names)
    values = jnp.asarray([params.get(at, n) for n in names], dtype=float)
    value, tangents, status = _linearized_run(at, s, along, values, output)
    # a failed run (or sensitivity solve) raises here, after the program (or, inside a user's
    # jit or vmap, through equinox.error_if in the user's program): never a silent NaN
    value, tangents = check_status((value, tangents), status, s, " (the run of jaxclear.sensitivities)", mech)
    flat, treedef = jax.tree_util.tree_flatten(value)
    floats = [i for i, v in enumerate(flat) if _is_float(v)]
    stacked = treedef.flatten_up_to(tangents)
    per_name = _unstacked([stacked[i] for i in floats], len(names))
    derivatives = {}
    for name, leaves in zip(names, per_name):
        mixed = list(flat)  # the value's integer leaves (status, counts), the derivative's float ones
        for i, t in zip(floats, leaves):
            mixed[i] = t
        derivatives[name] = jax.tree_util.tree_unflatten(treedef, mixed)
    if warn and output is None and isinstance(value, Solution):
        for name in names:
            size = abs(float(params.get(mech, name)))
            if size == 0.0:  # a parameter at zero has no relative change to amplify
                continue
            a = float(amplification(value, derivatives[name], size))
            if a * s.rtol > 0.1:
                warnings.warn(
                    f"the derivative with respect to {name!r} is past the run's horizon of predictability: a relative "
                    f"change of {name!r} as small as the solver's tolerance (rtol = {s.rtol:g}) moves the state by "
                    f"{a * s.rtol:.2g} of its own size (amplification {a:.3g}); the motion is this sensitive (a "
                    "chaotic or grazing regime) and the derivative describes only parameter changes far below the "
                    "tolerance. Use a shorter horizon, or average over windows or start states "
                    "(docs: theory/sensitivities.md)", DerivativeHorizonWarning, stacklevel=2)
    return value, derivatives


def amplification(sol: Solution, tangent: Solution, scale: float = 1.0):
    r"""How much a relative change of a parameter is amplified in the state:
    :math:`A = \max_t \|\bar\theta\,\partial y(t)/\partial\theta\| / \max_t \|y(t)\|`, with
    :math:`y = (q, \dot q)` in RMS over the coordinates (per kind: positions and velocities each
    relative to their own largest RMS), ``tangent`` the derivative of ``sol`` and ``scale``
    :math:`\bar\theta` the parameter's size (its value). Dimensionless: the relative change of
    the state per relative change of the parameter. Once :math:`A\,\mathrm{rtol} > 0.1`, a
    change as small as the solver's own relative error moves the state by a tenth of its size."""
    return _amplification(sol.q, sol.qdot, tangent.q, tangent.qdot, scale)


@jax.jit
def _amplification(q, qdot, dq, dqdot, scale):
    """:func:`amplification` of the coordinates and velocities, in one program."""
    def ratio(y, dy):
        size = jnp.max(jnp.sqrt(jnp.mean(y**2, axis=-1)))
        return jnp.max(jnp.sqrt(jnp.mean((scale * dy) ** 2, axis=-1))) / jnp.where(size > 0, size, 1.0)

    return jnp.maximum(ratio(q, dq), ratio(qdot, dqdot))


def derivative_horizon(sol: Solution, tangent: Solution, rtol: float, scale: float = 1.0) -> float:
    """The first output time [s] at which the amplification (:func:`amplification`, up to that
    time) times ``rtol`` exceeds 0.1; ``inf`` if it never does within the run."""
    q = np.asarray(sol.q)
    qd = np.asarray(sol.qdot)
    sq = np.sqrt(np.mean(q**2, axis=-1))
    sqd = np.sqrt(np.mean(qd**2, axis=-1))
    dq = scale * np.sqrt(np.mean(np.asarray(tangent.q) ** 2, axis=-1))
    dqd = scale * np.sqrt(np.mean(np.asarray(tangent.qdot) ** 2, axis=-1))
    a = np.maximum(np.maximum.accumulate(dq) / np.maximum(np.maximum.accumulate(sq), 1e-300),
                   np.maximum.accumulate(dqd) / np.maximum(np.maximum.accumulate(sqd), 1e-300))
    past = np.flatnonzero(a * rtol > 0.1)
    return float(np.asarray(sol.ts)[past[0]]) if past.size else float("inf")
