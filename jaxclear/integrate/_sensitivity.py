r"""Error-controlled forward sensitivities: the derivatives of a simulation with respect to its
parameters, integrated with the state and held to the values' tolerances times
the :class:`~jaxclear.integrate.Sensitivity` ``tolerance`` (0.1 by default).

For a state :math:`y(t; \theta)` with :math:`\dot y = f(t, y, \theta)`, the tangent
:math:`S_j = \partial y/\partial\theta_j` obeys the variational equation

.. math:: \dot S_j = f_y\,S_j + f_{\theta_j}, \qquad S_j(t_0) = \partial y_0/\partial\theta_j

(Hairer, Norsett, Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993,
sec. I.14). The solver integrates the vector :math:`[y, \bar\theta_1 S_1, \dots,
\bar\theta_P S_P]` with the same Runge-Kutta method, so a step advances the tangents exactly as
the derivative of the step itself (forward-mode differentiation of a fixed step sequence); what
differs from differentiating the solver's loop is the step sequence: the step-size controller's
error norm is the largest of the values' norm and every tangent's norm, as SUNDIALS CVODES does
with ``errconS`` (Serban and Hindmarsh, "CVODES: the sensitivity-enabled ODE solver in
SUNDIALS", ASME IDETC 2005). The tangents are scaled by :math:`\bar\theta_j = |\theta_j|` (1
where a parameter is 0; CVODES's ``pbar``) so that each is of the order of the state and is
measured with the state's tolerances: the derivative with respect to :math:`\ln\theta_j`.

At every accepted step the force elements' memory rules run on the values and their
derivative on the tangents (:class:`TangentSystem`): the stored approach speed at an onset
:math:`\dot\delta(t_c)` gets :math:`\partial\dot\delta/\partial y\,S + \ddot\delta\,\partial
t_c/\partial\theta` (the onset time's part: the saltation term of an event whose time moves with
the parameters; Corner, Sandu and Sandu, "Modeling and sensitivity analysis methodology for hybrid
dynamical system", Nonlinear Analysis: Hybrid Systems 31 (2019) 19-40; Serban and Recuero,
"Sensitivity analysis for hybrid systems and systems with memory", J. Comput. Nonlinear Dyn. 14
(2019) 091006). The contact forces themselves are continuous at an onset and a separation (zero
at zero penetration), so the positions' and velocities' tangents do not jump; what is not smooth
there is the derivative of the force (:math:`K\delta^{n}`: unbounded curvature for
:math:`n < 2`), and the error control shortens the steps there as far as the tangents need.

:func:`tangent_run` is the JVP rule of :func:`~jaxclear.simulate` under
``Settings(derivatives=Sensitivity())`` (the default): the sensitivity solve runs with the values
(its primal part), for the perturbed inputs only, and the output tangent is the linear
combination of the computed sensitivities with the input tangents. So ``jax.jvp``,
``jax.jacfwd``, ``jax.grad``/``jax.vjp`` (the transpose of that combination) and ``jax.vmap``
of them all get the error-controlled derivatives; reverse mode costs as many tangents as there
are perturbed scalar inputs.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from .._types import Array, Float
from ..model.mechanism import Mechanism
from . import _solve as solve
from ._dynamics import Baumgarte, flat_vector_field
from ._settings import Settings
from ._state import State
from ._system import AbstractSystem, memory_step


class Rebuild(eqx.Module):
    """The inputs ``(mech, settings, y0)`` rebuilt from the values of their perturbed leaves
    (every other leaf as given)."""

    leaves: list
    treedef: object = eqx.field(static=True)
    perturbed: tuple = eqx.field(static=True)

    def __call__(self, point):
        leaves = list(self.leaves)
        for i, x in zip(self.perturbed, point):
            leaves[i] = x
        return jax.tree_util.tree_unflatten(self.treedef, leaves)


class TangentNorm(eqx.Module):
    """Error norm of a packed state with ``count`` tangents: the largest of the RMS norms of the
    positions and velocities (first ``2n`` entries) of the values and of each tangent."""

    n: int = eqx.field(static=True)
    size: int = eqx.field(static=True)
    count: int = eqx.field(static=True)

    def __call__(self, v):
        values = optx.rms_norm(v[: 2 * self.n])
        tangents = v[self.size:].reshape(self.count, self.size)[:, : 2 * self.n]
        return jnp.maximum(values, jnp.max(jnp.sqrt(jnp.mean(tangents**2, axis=1))))


#: The sensitivity solve's shortest step, as a fraction of the run (:meth:`TangentSystem.dtmin`).
DTMIN_FRACTION = 1e-12


class TangentSystem(AbstractSystem):
    """The packed state ``y`` (N,) of a mechanism followed by its ``count`` tangents (P, N) along
    ``directions`` (each perturbed leaf's tangents, leading axis P) at ``point`` (the perturbed
    leaves' values)."""

    mech: Mechanism
    baumgarte: Baumgarte
    rebuild: Rebuild
    point: tuple
    directions: tuple
    min_step: jax.Array
    size: int = eqx.field(static=True)
    count: int = eqx.field(static=True)
    #: None, or the size ``(,)`` (largest magnitude of its positions and velocities) of a tangent
    #: at which its absolute tolerance is ``atol``: above it, that tangent is held to ``atol``
    #: times its size over this (:meth:`weigh_error`)
    tangent_reference: jax.Array | None = None
    #: the tangents' rates jump where a friction law's derivative does: steps end there
    split_at_kinks: ClassVar[bool] = True

    def _split(self, v):
        return v[: self.size], v[self.size:].reshape(self.count, self.size)

    def _pack(self, y, tangents):
        return jnp.concatenate([y, tangents.reshape(-1)])

    def field(self, t, v):
        y, tangents = self._split(v)

        def f(yy, point):
            mech, s, _ = self.rebuild(point)
            return flat_vector_field(t, yy, (mech, s.baumgarte))

        fy, lin = jax.linearize(f, y, self.point)
        return self._pack(fy, jax.vmap(lin)(tangents, self.directions))

    def after_step(self, t0, v0, t1, v1):
        """The memory rules on the values and their derivative on the tangents; where the step
        crossed into contact, the approach speed's derivative takes the penetration's
        acceleration at the onset from the vector field at the step's ends (two evaluations,
        values only; :func:`~jaxclear.elements.memory.penetration_accelerations`)."""
        (y0, s0), (y1, s1) = self._split(v0), self._split(v1)
        _, changed = memory_step(self.mech, t0, y0, t1, y1)
        rates = lambda: tuple(State.unpack(self.primal_rate(t, y), self.mech).qdot for t, y in ((t0, y0), (t1, y1)))  # noqa: E731
        zeros = lambda: (jnp.zeros(self.mech.n_coordinates, y0.dtype),) * 2  # noqa: E731
        qdd = jax.lax.cond(changed, rates, zeros)
        y1_new, lin = jax.linearize(lambda a, b, p: memory_step(self.rebuild(p)[0], t0, a, t1, b, qdd)[0], y0, y1,
                                    self.point)
        return self._pack(y1_new, jax.vmap(lin)(s0, s1, self.directions)), changed

    def primal(self, v):
        return v[: self.size]

    def dtmin(self):
        """:data:`DTMIN_FRACTION` of the run (``min_step``). Where a contact law's derivative jumps at zero
        penetration (a force exponent of 1, a damping that starts at full strength), the step that
        ends just past the onset evaluates its last stages on the other side, so the tangents' error
        estimate holds a spurious part of about ``0.02 h |jump| |S|``: the controller would halve the
        step until that part is below the tolerance, at rtol 1e-11 down to 1e-19 s (one rounding
        unit of t), where the onset's derivative is noise. The floor stops that descent; the error
        of a step of that length is negligible, and an onset closer than it to a step's start is
        taken at the start."""
        return self.min_step

    def norm(self):
        return TangentNorm(self.mech.n_coordinates, self.size, self.count)

    def weigh_error(self, v0, v1, error, rtol, atol):
        r"""With a ``tangent_reference`` :math:`\bar s`, tangent :math:`j` is measured against
        the absolute tolerance :math:`a_j = \mathrm{atol}\,\max(1, \sigma_j/\bar s)`, with
        :math:`\sigma_j` the largest magnitude of its positions and velocities at the step's start: the error
        is returned times :math:`(\mathrm{atol} + \mathrm{rtol}\,m)/(a_j + \mathrm{rtol}\,m)`
        (:math:`m = \max(|v_0|, |v_1|)` per entry), which the controller's scaling turns into
        :math:`e/(a_j + \mathrm{rtol}\,m)`. The tangents of a Lyapunov run
        (:mod:`jaxclear.chaos.benettin`) solve a linear equation and grow like
        :math:`e^{\lambda t}` between renormalisations: a fixed ``atol`` would ask a component
        that passes through zero for an accuracy relative to the whole tangent of ever smaller
        size, and the steps shrank to the floor (measured: 400,000 steps not enough for one
        revolution of the benchmark at 5000 rpm, rtol 1e-8, over which the tangent grew about
        1e10-fold; 12,000 with renormalisations 64 times a revolution). Scaled this way the
        control is invariant under a scaling of the tangents, as the equation is."""
        if self.tangent_reference is None:
            return error
        n = self.mech.n_coordinates
        _, s0 = self._split(v0)
        sigma = jnp.max(jnp.abs(s0[:, : 2 * n]), axis=1)  # (P,); not squared: they reach 1e300
        a = atol * jnp.maximum(1.0, sigma / self.tangent_reference)
        m = jnp.maximum(jnp.abs(v0), jnp.abs(v1))
        y_err, t_err = self._split(error)
        _, t_m = self._split(m)
        t_err = t_err * ((atol + rtol * t_m) / (a[:, None] + rtol * t_m))  # the ratio first: no overflow
        return self._pack(y_err, t_err)


def tangent_system(mech: Mechanism, s: Settings, *, size: int, count: int, span, reference=None,
                   along=None) -> TangentSystem:
    r"""The packed state (``size`` entries) of ``mech`` followed by ``count`` tangents: the
    variational equations along the motion, whose tangents the Lyapunov exponents follow
    (:mod:`jaxclear.chaos`; the tangents' start and renormalisation are the caller's). ``span``
    [s]: the length of the runs it integrates (the shortest step is :data:`DTMIN_FRACTION` of
    it); ``reference``: the size of a tangent at which its absolute tolerance is ``atol``
    (:attr:`TangentSystem.tangent_reference`), None: ``atol`` always. ``along``: None (free
    tangents, :math:`\dot S = f_y S`), or each tangent's direction in the mechanism's parameters,
    a pytree of ``eqx.filter(mech, eqx.is_inexact_array)``'s structure whose leaves have a leading
    axis ``count`` (:func:`jaxclear.params.derivatives.directions`): tangent ``j`` then obeys
    :math:`\dot S_j = f_y S_j + f_\theta\,\theta'_j` (a row of zeros: a free tangent), as the
    inhomogeneous tangents of least-squares shadowing do (:mod:`jaxclear.chaos.shadowing`)."""
    leaves, treedef = jax.tree_util.tree_flatten((mech, s, None))
    perturbed, dirs = ((), ()) if along is None else _aligned(mech, along)
    point = tuple(jnp.asarray(leaves[i]) for i in perturbed)
    return TangentSystem(mech, s.baumgarte, Rebuild(leaves, treedef, perturbed), point, dirs, DTMIN_FRACTION * span,
                         size, count, reference)


def _aligned(mech: Mechanism, along) -> tuple[tuple, tuple]:
    """``(perturbed, dirs)``: the indices of the leaves of ``(mech, s, None)`` that ``along`` (of
    ``eqx.filter(mech, eqx.is_inexact_array)``'s structure, None where a leaf is not
    differentiated) moves, and its leaves there (the mechanism's leaves come first)."""
    try:  # one slot per leaf of the mechanism (a field that is None has none, in along too)
        slots = jax.tree_util.tree_structure(mech).flatten_up_to(along)
    except (ValueError, TypeError) as err:
        raise ValueError(f"along does not have the mechanism's structure ({err}): give "
                         "eqx.filter(mech, eqx.is_inexact_array)'s structure") from None
    perturbed = tuple(i for i, d in enumerate(slots) if d is not None)
    return perturbed, tuple(slots[i] for i in perturbed)


def tangent_scale(values):
    r""":math:`\bar\theta = |\theta|`, or 1 where :math:`\theta = 0` (CVODES's ``pbar``): the size
    by which the tangent along a parameter of value :math:`\theta` is multiplied in the solve, so
    that it is of the order of the state and measured with the state's tolerances."""
    return jnp.where(values != 0, jnp.abs(values), 1.0)


def directions(point) -> tuple[tuple, Float[Array, " P"]]:
    r"""One direction per scalar entry of the perturbed leaves ``point``: ``(tangents, scale)``
    with ``tangents`` per leaf ``(P, *shape)`` (the scale :math:`\bar\theta` at that entry's row,
    zero elsewhere) and ``scale`` ``(P,)``: :math:`|\theta|`, or 1 where :math:`\theta = 0`."""
    flat = [jnp.ravel(jnp.asarray(x)) for x in point]
    values = jnp.concatenate(flat)
    scale = tangent_scale(values)
    count = values.shape[0]
    out, start = [], 0
    for x, f in zip(point, flat):
        rows = jnp.zeros((count, f.shape[0]), values.dtype).at[start + jnp.arange(f.shape[0]),
                                                               jnp.arange(f.shape[0])].set(
            scale[start:start + f.shape[0]])
        out.append(rows.reshape((count,) + jnp.shape(x)))
        start += f.shape[0]
    return tuple(out), scale


def _is_float(x) -> bool:
    return jnp.issubdtype(jnp.result_type(x), jnp.inexact)


def sensitivity_solve(primals, perturbed: tuple, dirs: tuple, begin=None):
    """The sensitivity solve of the run of ``primals = (mech, settings, y0)`` along ``dirs``
    (one entry per perturbed leaf of ``primals``, whose indices ``perturbed`` gives: that leaf's
    change along each of the ``P`` directions, shaped ``(P, *leaf)``): ``(solution, basis)``,
    ``basis`` the solution's derivative along each direction (every leaf with a leading axis P;
    zero-size ``float0`` for the integer leaves). One solve of ``P`` tangents, its steps sized
    for the values and every tangent (:class:`TangentSystem`, held to ``Sensitivity.tolerance``
    times the tolerances); ``begin``: the run's start (:func:`~jaxclear.integrate._solve.start_run`),
    if the caller has it."""
    leaves, treedef = jax.tree_util.tree_flatten(primals)
    mech, s, y0 = primals
    begin = solve.start_run(mech, s, y0) if begin is None else begin
    rebuild = Rebuild(leaves, treedef, perturbed)
    point = tuple(leaves[i] for i in perturbed)
    dtype = begin.packed.dtype
    size = begin.packed.shape[0]
    count = dirs[0].shape[0]

    v0, start_tangent = jax.linearize(lambda p: solve.start_run(*rebuild(p)).packed, point)
    t0, t1, ts = solve.grid(s, begin, dtype)
    system = TangentSystem(mech, s.baumgarte, rebuild, point, dirs, DTMIN_FRACTION * (t1 - t0), size, count)
    rtol, atol = s.derivatives.tolerances(s.rtol, s.atol)
    tight = dataclasses.replace(s, rtol=rtol, atol=atol)
    run = solve.integrate_system(system, tight, t0, t1, ts,
                                 jnp.concatenate([v0, jax.vmap(start_tangent)(dirs).reshape(-1)]))
    samples = run.samples[:, :size]
    tangent_samples = jnp.moveaxis(run.samples[:, size:].reshape(-1, count, size), 1, 0)  # (P, T, N)

    def grid_of(p):
        return solve.grid(rebuild(p)[1], begin, dtype)[2]

    if any(leaves[i] is s.t_end for i in perturbed):
        # the samples move with t_end: their tangents take the state's rate times the times' shift
        dts = jax.vmap(jax.linearize(grid_of, point)[1])(dirs)  # (P, T)
        rates = jax.vmap(lambda t, v: flat_vector_field(t, v, (mech, s.baumgarte)))(ts, samples)
        tangent_samples = tangent_samples + dts[:, :, None] * rates[None]

    def solution_of(p, packed):
        m, ss, _ = rebuild(p)
        return solve.solution(m, ss, grid_of(p), packed, run, begin)

    (sol, _), lin = jax.linearize(solution_of, point, samples)
    return sol, jax.vmap(lambda d, v: lin(d, v)[0])(dirs, tangent_samples)


def tangent_run(primals, tangents):
    """The JVP rule of :func:`~jaxclear.simulate` (``Settings(derivatives=Sensitivity())``):
    ``primals = (mech, settings, y0)``, ``tangents`` the same with ``None`` for the inputs that
    are not perturbed. Returns the solution (of the sensitivity solve: its steps are controlled
    on the values and the tangents, at ``Sensitivity.tolerance`` times the tolerances)
    and its tangent: one tangent a perturbed scalar (:func:`directions`), combined with the
    input tangents at the end."""
    leaves, treedef = jax.tree_util.tree_flatten(primals)
    tleaves = treedef.flatten_up_to(tangents)
    perturbed = tuple(i for i, (x, t) in enumerate(zip(leaves, tleaves))
                      if t is not None and eqx.is_inexact_array(x))
    mech, s, y0 = primals
    begin = solve.start_run(mech, s, y0)
    if not perturbed:
        return solve.run(mech, s, begin)[0], None
    dirs, scale = directions(tuple(leaves[i] for i in perturbed))
    sol, basis = sensitivity_solve(primals, perturbed, dirs, begin)
    coeff = jnp.concatenate([jnp.ravel(tleaves[i]) for i in perturbed]) / scale
    tangent = jax.tree_util.tree_map(lambda b: jnp.tensordot(coeff, b, axes=1) if _is_float(b) else None, basis)
    return sol, tangent


def along_run(mech: Mechanism, s: Settings, along, values):
    r"""``(solution, derivatives)`` of the run of ``mech`` along ``k`` directions of its
    parameters in one sensitivity solve of ``k`` tangents: ``along`` has
    ``eqx.filter(mech, eqx.is_inexact_array)``'s structure, each leaf ``(k, *leaf)`` (a leaf's
    change per unit change of direction ``j``: :func:`jaxclear.params.directions`; None where a
    leaf is not moved), ``values`` ``(k,)`` the named numbers' values: each tangent is multiplied
    in the solve by :func:`tangent_scale` of its value (as :func:`directions` does for
    :func:`tangent_run`).
    ``derivatives`` has the solution's structure, every leaf with a leading axis ``k`` (``float0``
    for the integer leaves). Where ``jax.linearize`` of :func:`~jaxclear.simulate` over every
    floating-point leaf followed by the directions integrates one tangent per scalar of the
    mechanism (63 for the benchmark slider-crank), this integrates ``k``."""
    perturbed, dirs = _aligned(mech, along)
    scale = tangent_scale(jnp.asarray(values))

    def scaled(x, power):
        return x * scale.reshape((-1,) + (1,) * (x.ndim - 1)) ** power

    sol, basis = sensitivity_solve((mech, s, None), perturbed, tuple(scaled(jnp.asarray(d), 1) for d in dirs))
    return sol, jax.tree_util.tree_map(lambda b: scaled(b, -1) if _is_float(b) else b, basis)
