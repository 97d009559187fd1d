r"""The impact-memory rule: the approach speed :math:`\dot\delta^{(-)}` at the onset of a
contact, which the dissipative laws divide by, is history; an element carries it (with the
onset time, the impact count, the work of its forces and running peaks) in its state and
updates it after every accepted solver step.

Rule (per contact, with penetration :math:`\delta` and rate :math:`\dot\delta` at both ends of
an accepted step ``[t0, t1]``; Flores, Ambrósio, Claro, Lankarani, "Kinematics and Dynamics of
Multibody Systems with Imperfect Joints", Springer 2008, ch. 4):

* :math:`\delta_0 \le 0` and :math:`\delta_1 \le 0` (free over the step): :math:`\dot\delta^{(-)}
  \leftarrow \dot\delta_1`;
* :math:`\delta_0 \le 0 < \delta_1` (the step crossed into contact): :math:`\dot\delta^{(-)}
  \leftarrow \dot\delta(t_c)` at the crossing :math:`t_c` of the cubic Hermite interpolant of
  :math:`\delta` over the step (exact to the step's third order), onset time :math:`t_c`,
  impacts + 1;
* in contact at both ends, or separating (:math:`\delta_0 > 0 \ge \delta_1`): unchanged, so the
  output samples of a separating step read the approach speed their force used.

With exact onsets the step-size controller (``integrate.solvers.OnsetController``) ends steps
just past every onset and separation (:func:`onset_fraction`), so no contact begins and ends
inside a step unseen.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import BoolScalar, Scalar


class ContactMemory(eqx.Module):
    """History of one contact (scalars), or of several stacked along a trailing axis ``(..., k)``.

    Attributes:
        impact_velocity: :math:`\\dot\\delta^{(-)}` [m/s], approach speed at the onset of the
            current contact (out of contact it tracks the current :math:`\\dot\\delta`).
        contact_start: time of the last contact onset [s] (a large negative sentinel before the
            first).
        impacts: number of contact onsets so far.
        work: work done on the mechanism by the contact forces since the start [J]
            (its decrease over a closed contact is the energy the contact dissipated).
        peak_force: largest normal force [N] at any accepted step's end so far (steps are
            short during contact, so this resolves peaks that an output grid misses).
        peak_penetration: largest penetration [m] at any accepted step's end so far.
    """

    impact_velocity: Scalar
    contact_start: Scalar
    impacts: Scalar
    work: Scalar
    peak_force: Scalar
    peak_penetration: Scalar

    @staticmethod
    def initial(shape=(), dtype=float) -> "ContactMemory":
        """Memory before any contact. ``shape`` may be an int (number of contacts)."""
        z = jnp.zeros(shape, dtype)
        # finite sentinels (not -inf): dense interpolation of the state may difference two samples
        return ContactMemory(z, jnp.full(shape, -1e9, dtype), z, z, z, jnp.full(shape, -1.0, dtype))

    def summary(self) -> "ContactMemory":
        """The element's memory as one contact (itself); elements with several contacts (the
        translational clearance joint) reduce theirs to one (``Solution.memory``)."""
        return self

    def zeros_like(self) -> "ContactMemory":
        z = jnp.zeros_like(self.impacts)
        return ContactMemory(z, z, z, z, z, z)

    def rate(self, power: Scalar) -> "ContactMemory":
        """Time derivative of the memory: zero except the work, whose rate is the power [W]."""
        return eqx.tree_at(lambda m: m.work, self.zeros_like(), power)


N_FIELDS = len(ContactMemory.__dataclass_fields__)

#: Margin of the exact-onset step control, as a fraction of a step: a step whose only contact
#: switch lies within ``ONSET_MARGIN`` of its start, or within ``2 ONSET_MARGIN`` of its end, is
#: accepted; otherwise it is retried to end at ``s (1 + ONSET_MARGIN)`` (see :func:`onset_fraction`).
ONSET_MARGIN = 1e-4

#: A contact that begins and ends inside one step, or a free flight inside a contact, shallower
#: than this [m] (jaxclear's default position tolerance ``atol``) is below the integration's
#: resolution and is not split at (a journal resting on its bearing would otherwise chatter).
EXCURSION_DEPTH = 1e-9

#: A step that starts within this distance [m] of a contact switch starts at it: penetrations
#: are differences of coordinates of order 0.01-1 m, whose float64 rounding is ~1e-16 m.
SWITCH_RESOLUTION = 1e-14


def _hermite_cubic(p0, p1, r0, r1, h):
    """Coefficients ``(a, b, c, d)`` of the cubic Hermite interpolant ``a s^3 + b s^2 + c s + d``
    of the penetration over a step, in the step fraction ``s`` in [0, 1]."""
    c = h * r0
    e = h * r1
    return 2 * p0 + c - 2 * p1 + e, -3 * p0 - 2 * c + 3 * p1 - e, c, p0


def _hermite_rate(s, p0, p1, r0, r1, h, accel=None):
    r"""Rate [m/s] of the cubic Hermite interpolant of the penetration at the step fraction ``s``:
    :math:`\dot\delta(s) = (1 - s) r_0 + s r_1 + 6 s (1 - s) D`, with
    :math:`D = (p_1 - p_0)/h - (r_0 + r_1)/2` (the derivative of the interpolant of
    :func:`_hermite_cubic`, written as a linear blend of the end rates plus its curvature term).

    Derivatives: the weight :math:`6 s (1 - s)` of the curvature term is differentiated through
    ``s`` only where the curvature is resolved (below). ``s`` of a switch moves like :math:`1/h`
    with the penetration (:math:`ds = -d\delta / (h\dot\delta)`); where :math:`D` of a short
    step is the rounding of the penetrations (differences of coordinates of order 0.1 m: about
    1e-17 m, divided by ``h``), that term's derivative grows like :math:`1/h^2` and is noise: on
    a step of 0.8 ns it turned the approach speed's derivative from 5e-4 into -1.1e-2 (per unit
    of log stiffness) and the forward-mode Jacobian of a fit 10 to 600 times too large; there
    only the onset time's part :math:`(r_1 - r_0)/h \, dt_c` and the end rates' derivatives
    stay. Where :math:`D` is resolved its part :math:`6(1 - 2s) D \, ds` is kept: with it the
    onset time's part is the interpolant's acceleration at the switch, not its mean over the
    step, which a long step with jerk needs (a cubic penetration's derivative is then exact; on
    the translational clearance joint's benchmark, the mean put the approach speeds' derivatives
    of two onsets 2.2 % and 3.5 % off and the positions' sensitivities 1.7e-3 off after them).

    With ``accel`` (the penetration's accelerations :math:`(\ddot\delta_0, \ddot\delta_1)`
    [m/s^2] at the step's ends, from the vector field: the sensitivity solve's), the switch's
    part is :math:`h\,\ddot\delta(s)\,ds` with :math:`\ddot\delta(s) = (1 - s)\ddot\delta_0 +
    s\,\ddot\delta_1` (error at most :math:`h^2 s(1 - s)\max|\delta^{(4)}|/2`; an onset's step
    ends just past it, :math:`s \approx 1`): the exact :math:`\ddot\delta\,dt_c` of the
    saltation term. The interpolant's slope there is :math:`(r_1 - r_0)/h` plus the curvature
    term: a difference of two rates of order 1 m/s, each a difference of velocities of order
    10 m/s rounded to ~1e-15 m/s, over the steps of 1e-14 - 1e-12 s by which the sensitivity
    solve approaches an onset. Where :math:`\ddot\delta\,dt_c` and the rate's own tangent
    nearly cancel (the benchmark slider-crank, n = 1, onset at 1.57 ms: per unit log
    restitution the onset time moves by 2.2e-3 s, the approach speed by -8.3e-3 m/s) that
    put the approach speed's derivative off by up to 7e-3 m/s, differently at parameter
    values 1e-7 apart, and further off at tighter tolerances (onset at 0.66 ms: 3e-5 m/s at
    rtol 1e-6, 1.8e-3 at 1e-10); with ``accel``, within 6e-5 of central differences of rtol
    1e-12 runs at rtol 1e-8 and 1e-10.

    Values: where :math:`|D h|` (the interpolant's departure from a parabola, in metres) is
    below :data:`SWITCH_RESOLUTION`, it is the rounding of the penetrations, not curvature, and
    :math:`D` is bounded by :math:`|r_1 - r_0|` (for a smooth penetration
    :math:`D = \int_0^1 e(s)\,ds` with :math:`e` the rate's deviation from its linear blend,
    :math:`|e| \le s(1 - s) h^2 \max|\dddot\delta|/2`, far below :math:`|r_1 - r_0| \approx
    h|\ddot\delta|` on a short step), and not differentiated: the error-controlled sensitivities
    (:mod:`jaxclear.integrate._sensitivity`) approach an onset in steps down to 1e-18 s, where the
    unbounded term turned an approach speed of 4.39 m/s into 79 m/s."""
    if accel is not None:  # the switch's part from the penetration's own acceleration
        fixed = jax.lax.stop_gradient(s)
        a = jax.lax.stop_gradient((1.0 - fixed) * accel[0] + fixed * accel[1])
        rate = _hermite_rate(fixed, p0, p1, r0, r1, h)  # the end values' parts at the fixed switch
        return rate + h * a * (s - fixed)
    curvature = (p1 - p0) / h - 0.5 * (r0 + r1)
    bound = jnp.abs(r1 - r0)
    resolved = jnp.abs(curvature * h) > SWITCH_RESOLUTION
    sbar = jnp.where(resolved, s, jax.lax.stop_gradient(s))
    # unresolved, neither the term nor its derivative is used: the derivative of p1 - p0 is the
    # difference of two tangents whose rounding, divided by h, is as large as the value's
    curvature = jnp.where(resolved, curvature, jax.lax.stop_gradient(jnp.clip(curvature, -bound, bound)))
    return r0 + s * (r1 - r0) + 6.0 * sbar * (1.0 - sbar) * curvature


def _root_in(val, slope, lo, hi, rising):
    """Root of a function monotone on ``[lo, hi]`` that changes sign there (``rising``: from
    <= 0 to > 0): eight bisections, then six Newton steps clipped to the bracket."""
    for _ in range(8):
        mid = 0.5 * (lo + hi)
        past = (val(mid) > 0.0) == rising
        lo, hi = jnp.where(past, lo, mid), jnp.where(past, mid, hi)
    s = 0.5 * (lo + hi)
    for _ in range(6):
        sl = slope(s)
        ok = jnp.abs(sl) > 1e-300
        s = jnp.clip(s - jnp.where(ok, val(s) / jnp.where(ok, sl, 1.0), 0.0), lo, hi)
    return s


class Switches(eqx.Module):
    """Sign changes of the penetration inside a step (:func:`contact_switches`).

    Attributes:
        count: number of switches (0 to 3).
        first: step fraction of the first switch (1 where there is none).
        last: step fraction of the last switch (1 where there is none).
        last_rate: penetration rate [m/s] of the interpolant at the last switch.
        excursion: how far [m] the interpolant goes beyond zero on the side opposite to its
            start (the depth of a contact, or of a free flight, that the step holds inside).
    """

    count: Scalar
    first: Scalar
    last: Scalar
    last_rate: Scalar
    excursion: Scalar


@jax.jit  # traced once per shape, reused at each call of a trace (see integrate/_dynamics._gauss_jordan)
def contact_switches(p0, p1, r0, r1, h, accel=None) -> Switches:
    r"""Sign changes of the penetration inside a step: the cubic Hermite interpolant of
    :math:`\delta` (values ``p0, p1`` [m], rates ``r0, r1`` [m/s] at the ends, step ``h`` [s];
    any matching shapes) is monotone between its extrema (roots of its derivative in (0, 1)),
    so its sign changes are counted exactly on the points ``0, e_1, e_2, 1`` and each is found
    in its monotone bracket (:func:`_root_in`). Two switches with equal signs at both ends are a
    free flight or a contact that begins and ends inside the step, which end-point signs alone
    do not see. ``h`` may be 0 (finished members of a ``vmap`` batch take empty steps): a safe
    step keeps the masked branch finite, so reverse mode gets no NaN cotangents. ``accel``:
    None, or the penetration's accelerations at the ends, for the derivative of the rate at the
    last switch (:func:`_hermite_rate`)."""
    p0, p1 = jnp.asarray(p0), jnp.asarray(p1)
    hs = jnp.where(h > 0, h, 1.0)
    a, b, c, d = _hermite_cubic(p0, p1, r0, r1, hs)
    val = lambda s: ((a * s + b) * s + c) * s + d
    slope = lambda s: (3 * a * s + 2 * b) * s + c
    # extrema: 3 a s^2 + 2 b s + c = 0, in the cancellation-free form of the quadratic's roots;
    # they only bracket the roots, so no gradient flows through them (nor through sqrt at 0)
    A, B, C = jax.lax.stop_gradient((3 * a, 2 * b, c))
    disc = B * B - 4 * A * C
    sq = jnp.sqrt(jnp.maximum(disc, 0.0))
    qq = -0.5 * (B + jnp.where(B >= 0, sq, -sq))
    safe = lambda x: jnp.where(x != 0, x, 1.0)
    e1 = jnp.where(A != 0, qq / safe(A), jnp.where(B != 0, -C / safe(B), 0.0))
    e2 = jnp.where(qq != 0, C / safe(qq), 0.0)
    inside = lambda e: (disc >= 0) & jnp.isfinite(e) & (e > 0) & (e < 1)
    e1, e2 = jnp.where(inside(e1), e1, 0.0), jnp.where(inside(e2), e2, 0.0)
    pts = [jnp.zeros_like(e1), jnp.minimum(e1, e2), jnp.maximum(e1, e2), jnp.ones_like(e1)]
    v1, v2 = val(pts[1]), val(pts[2])
    touching = [p0 > 0.0, v1 > 0.0, v2 > 0.0, p1 > 0.0]
    excursion = jnp.where(touching[0], -jnp.minimum(v1, v2), jnp.maximum(v1, v2))
    changes = [touching[k] != touching[k - 1] for k in (1, 2, 3)]
    count = sum(ch.astype(jnp.int32) for ch in changes)
    # brackets of the first and the last switch
    lo_f, hi_f, lo_l, hi_l = pts[2], pts[3], pts[0], pts[1]
    for k in (2, 1):  # first: the lowest interval k whose ends differ in sign
        lo_f, hi_f = jnp.where(changes[k - 1], pts[k - 1], lo_f), jnp.where(changes[k - 1], pts[k], hi_f)
    for k in (2, 3):  # last: the highest
        lo_l, hi_l = jnp.where(changes[k - 1], pts[k - 1], lo_l), jnp.where(changes[k - 1], pts[k], hi_l)
    first = _root_in(val, slope, lo_f, hi_f, ~touching[0])
    last = _root_in(val, slope, lo_l, hi_l, touching[3])
    # the derivative of the last switch by the implicit function theorem, ds = -dval(s) /
    # (h rate(s)), with the bounded rate of _hermite_rate rather than the cubic's own slope: on a
    # very short step the cubic's higher coefficients are the rounding of the penetrations (about
    # 1e-17 m) and its slope is noise, while the derivatives of the end values are not
    last = jax.lax.stop_gradient(last)
    rate = jax.lax.stop_gradient(_hermite_rate(last, p0, p1, r0, r1, hs))
    moved = val(last) - jax.lax.stop_gradient(val(last))
    slope_s = hs * rate
    last = last - jnp.where(jnp.abs(slope_s) > 0, moved / jnp.where(jnp.abs(slope_s) > 0, slope_s, 1.0), 0.0)
    some = count > 0
    return Switches(count, jnp.where(some, first, 1.0), jnp.where(some, last, 1.0),
                    _hermite_rate(last, p0, p1, r0, r1, hs, accel), jax.lax.stop_gradient(excursion))


def onset_fraction(p0, p1, r0, r1, h) -> tuple[Scalar, BoolScalar]:
    r"""Where a step must end for the force law to switch at a step boundary: the fraction
    ``s`` in [0, 1] of the first contact switch (onset or separation, :func:`contact_switches`;
    any matching shapes) and whether the step must be retried to end at ``s (1 +``
    :data:`ONSET_MARGIN` ``)``. With :math:`\epsilon` = :data:`ONSET_MARGIN`:

    * a switch within :math:`2\epsilon` of the step's end is kept (the step already ends there);
    * a switch inside the step is split at, so the step ends just past it;
    * a switch within :math:`\epsilon` of the start is split at too (the retried step ends
      :math:`\epsilon` past it) when it is an onset, whose approach speed the memory rule
      (:func:`onset_update`) would otherwise read off a step spent in contact, or when the
      contact (or the free flight) it begins also ends inside the step; a separation there is
      kept, as is any switch within :math:`\epsilon^2` of the start or with the start's
      penetration within :data:`SWITCH_RESOLUTION` of zero (the limits of the retries);
    * a contact or free flight inside the step shallower than :data:`EXCURSION_DEPTH` is kept.

    ``s = 1`` and ``False`` where nothing switches."""
    sw = contact_switches(p0, p1, r0, r1, h)
    s, n = sw.first, sw.count
    eps = ONSET_MARGIN
    deep = (n > 1) & (sw.excursion > EXCURSION_DEPTH)  # a contact or free flight inside the step
    # a single switch, or an excursion inside the step deep enough to resolve
    resolve = (n == 1) | (n == 3) | deep
    before_end = resolve & (s < 1.0 / (1.0 + 2.0 * eps))
    at_start = s <= eps
    onset_or_several = (jnp.asarray(p0) <= 0.0) | deep
    # at the start only where the step's start is measurably off the switch: below
    # SWITCH_RESOLUTION the penetration is rounding noise of the coordinates, and retrying
    # would shrink the step towards the resolution of t
    off_switch = (s > eps * eps) & (jnp.abs(jnp.asarray(p0)) > SWITCH_RESOLUTION)
    split = before_end & (~at_start | (onset_or_several & off_switch))
    s = jnp.where(at_start, s + eps, s)
    return jnp.where(split, s, 1.0), split


def kink_fraction(g0, g1, rate0, h, active) -> tuple[Scalar, BoolScalar]:
    r"""Where a step must end for a friction law's kink to lie at a step boundary: the earliest
    sign change of the switch functions ``g0``, ``g1`` (``(..., k)`` at the step's two ends,
    :meth:`~jaxclear.contact.base.AbstractFriction.kinks`; ``rate0`` their rates at the start
    [1/s times their unit], ``h`` the step [s]) among the contacts that are ``active``
    (``(...)``: in contact at both ends, where the friction force acts), and whether the step
    must be retried to end at ``s (1 +`` :data:`ONSET_MARGIN` ``)`` (not for a kink within
    :data:`ONSET_MARGIN` of the step's start, nor within twice that of its end).

    The kink is located by Newton's step from the start, :math:`s = -g_0/(\dot g_0 h)`, not by
    the secant through the end values: the slip's rate itself jumps at the kink (the friction
    force changes slope there), so a secant through the step's far end, which lies past the
    kink, misplaces it by a fixed fraction of the distance however short the step (measured on
    the benchmark: 80 % short, each retried step ending before the kink and the next 20 %
    closer: 20 steps down to 5e-14 s per kink). The start's rate belongs to the smooth side.
    Where it does not point towards the kink (its sign), the secant is used."""
    g0, g1, rate0 = jnp.asarray(g0), jnp.asarray(g1), jnp.asarray(rate0)
    change = ((g0 > 0.0) != (g1 > 0.0)) & jnp.asarray(active)[..., None]
    secant = g0 / jnp.where(change, g0 - g1, 1.0)
    towards = rate0 * g0 < 0.0
    newton = -g0 / jnp.where(towards, rate0 * h, 1.0)
    frac = jnp.where(towards & (newton > 0.0) & (newton <= 1.0), newton, secant)
    s = jnp.min(jnp.where(change, frac, 1.0), initial=1.0)
    eps = ONSET_MARGIN
    split = (s > eps) & (s < 1.0 / (1.0 + 2.0 * eps))
    return jnp.where(split, s, 1.0), split


def onset_update(memory: ContactMemory, t0, t1, p0, p1, r0, r1, accel=None) -> tuple[ContactMemory, BoolScalar]:
    """Apply the impact-memory rule (module docstring) to one contact over the step ``[t0, t1]``
    with penetrations ``p0, p1`` [m] and rates ``r0, r1`` [m/s] at its ends. Returns the new
    memory (peaks not yet updated) and whether the step crossed into contact. ``accel``: None,
    or the penetration's accelerations ``(a0, a1)`` [m/s^2] at the ends
    (:func:`penetration_accelerations`), which the approach speed's derivative uses."""
    h = t1 - t0
    crossed = (p0 <= 0.0) & (p1 > 0.0)
    # the contact at the step's end began at the interpolant's last switch (its only one when
    # exact onsets split the steps)
    sw = contact_switches(p0, p1, r0, r1, h, accel)
    s, rate_c = sw.last, sw.last_rate
    # tracks the rate only over steps free at both ends: a step that separates keeps the onset's
    # approach speed, so its output samples before the separation read the speed their force used
    v = jnp.where((p0 <= 0.0) & (p1 <= 0.0), r1, jnp.where(crossed, rate_c, memory.impact_velocity))
    new = ContactMemory(
        impact_velocity=v,
        contact_start=jnp.where(crossed, t0 + s * h, memory.contact_start),
        impacts=memory.impacts + crossed.astype(memory.impacts.dtype),
        work=memory.work,
        peak_force=memory.peak_force,
        peak_penetration=jnp.maximum(memory.peak_penetration, p1),
    )
    return new, crossed


def penetration_accelerations(rate, q0, qd0, q1, qd1, qdd):
    r"""The accelerations ``(a0, a1)`` [m/s^2] of penetrations whose rates are ``rate(q, qdot)``
    [m/s] at a step's two ends, given the coordinates' accelerations ``qdd = (qdd0, qdd1)``:
    :math:`\ddot\delta = \partial\dot\delta/\partial q\,\dot q + \partial\dot\delta/
    \partial\dot q\,\ddot q` (a JVP), values only (no derivative flows through them). None
    where ``qdd`` is None (the values' solve, which needs no derivative of the approach speed)."""
    if qdd is None:
        return None
    sg = jax.lax.stop_gradient
    acc = lambda q, qd, qdd_: sg(jax.jvp(rate, (sg(q), sg(qd)), (sg(qd), sg(qdd_)))[1])  # noqa: E731
    return acc(q0, qd0, qdd[0]), acc(q1, qd1, qdd[1])


def with_peak_force(memory: ContactMemory, force: Scalar) -> ContactMemory:
    """``memory`` with its running peak force raised to ``force`` [N]."""
    return eqx.tree_at(lambda m: m.peak_force, memory, jnp.maximum(memory.peak_force, force))


def ongoing_contact(state, approach_speed: Scalar, onset_time: Scalar):
    """An element state (any pytree holding :class:`ContactMemory` nodes) whose contacts are
    under way: every memory's approach speed :math:`\\dot\\delta^{(-)}` [m/s] set to
    ``approach_speed`` and its onset time to ``onset_time`` [s] (before the run's start).

    A run that starts inside a contact (a fit window cut from a record taken in steady running)
    needs the ongoing impact's approach speed, which the dissipative laws divide by; it is history
    the start state alone does not hold. Out of contact the value is overwritten after the first
    accepted step (the memory rule tracks :math:`\\dot\\delta` there), so it only matters
    for contacts that are closed at the start."""

    def ongoing(m):
        if not isinstance(m, ContactMemory):
            return m
        v = jnp.broadcast_to(jnp.asarray(approach_speed, m.impact_velocity.dtype), jnp.shape(m.impact_velocity))
        t = jnp.broadcast_to(jnp.asarray(onset_time, m.contact_start.dtype), jnp.shape(m.contact_start))
        return eqx.tree_at(lambda x: (x.impact_velocity, x.contact_start), m, (v, t))

    return jax.tree_util.tree_map(ongoing, state, is_leaf=lambda x: isinstance(x, ContactMemory))
