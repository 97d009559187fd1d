r"""The unknown start of a fit window: how a window's free start-state numbers ``s`` become the
force elements' start, in two layouts.

Every force element starts at the coordinates ``a0`` its initial assembly holds and their rates
(:meth:`~jaxclear.elements.AbstractForceElement.start_state`: a journal's eccentricity and its
rate; a translational joint's lateral offset and tilt), each scaled by the element's
:meth:`~jaxclear.elements.AbstractForceElement.start_scale` ``S`` (``(e,)``, ``e =
n_equations``; the radial clearance ``c`` for a journal) and by a velocity scale ``v_s`` (the
crank speed [rad/s], or ``1 / T_w``).

* **contact-free** (a record that begins at start-up: windows after the first, whose state
  follows the previous window): ``2 e`` numbers ``(u, w)`` per element,
  ``a0 = S u / sqrt(1 + |u|^2)``, ``a0dot = v_s S w``; the start lies inside the ellipse of
  half-axes ``S`` (the clearance circle of a journal), so it is never in contact.
* **anywhere** (``start_state="free"``: a record that begins mid-run, every window's start
  unknown, the first included): ``2 e + 1`` numbers ``(u, w, m)`` per element,
  ``a0 = S u rho(|u|) / |u|``, ``a0dot = v_s S w``, with ``rho(n) = n`` inside the clearance
  (``n <= 1``: linear, free flight) and ``rho(n) = 1 + p tanh((n - 1) / p)`` beyond it (pressed
  in by at most ``p`` = :data:`MAX_START_PENETRATION` of the clearance; ``rho`` is twice
  continuously differentiable at 1). The bound matters: the first ``2 / f_c`` of a window are
  not fitted (the sensor filter's history is unknown), and on a record of the independent
  simulator a fit without it moved the first window's journal 0.28 mm into its bearing (truth:
  7.6 micrometres), a violent start hidden in those unfitted samples. The last number gives
  the ongoing contact's approach speed ``v^-`` [m/s], which the dissipative laws divide by
  (:func:`jaxclear.elements.memory.ongoing_contact`; it acts only where the start is in
  contact), as ``v^- = nu chi(c_r)``, ``nu = v_s mean(S) exp(m)`` [m/s] the approach speed
  per unit hysteresis factor ``chi`` of the element's law
  (:meth:`~jaxclear.contact.AbstractNormalLaw.hysteresis_factor`; ``v^- = nu`` for laws without
  one). Inside a contact that began before the window the Hertz-family damping is
  ``F_e(delta) chi deltadot / v^- = F_e(delta) deltadot / nu``: the restitution and the approach
  speed act only through ``nu``, so freeing both makes the least-squares problem singular.
  ``m`` is chosen by the way in (:mod:`jaxclear.fitting.way_in`) and then **held** (its
  derivative is stopped, its column of the Jacobian is zero), chosen again over the longer
  horizon at each step of the joint stages' continuation
  (:func:`jaxclear.fitting.way_in.rechoose_approach`: over a window's first half it is hardly
  seen), and the restitution is identified from the impacts that begin inside a window. Holding ``nu`` rather than ``v^-`` keeps that
  damping what the way in found while the restitution moves; held as ``v^-``, every window
  starting in contact pulled the restitution back to its start value (on a record of the
  independent simulator, 99 % of it in contact: 0.938 for a true 0.75, 10 std off, from 0.9).
  Freed, ``m`` ran away: the fit drove ``v^-`` to 3800 m/s (no damping at all), where its
  column is 2e-8 of the others and its Marquardt-scaled step, 7e6, shrank every joint step to
  nothing.
"""

from __future__ import annotations

import math
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..integrate import ASSEMBLY_TEMPLATE, assemble, jit

#: Offset of a contact-free window start as a fraction of the element's start scale: the map keeps it inside.
OFFSET_RADIUS = 1.0
#: Deepest start of the anywhere layout beyond the clearance, as a fraction of it: 0.12 of the
#: benchmark's 0.5 mm is 60 micrometres (20 kN of steel contact). In steady running at 5000 rpm
#: the independent simulator's journal is pressed in up to 22-28 micrometres within a revolution
#: and 55 over three (8 kN); a bound of 0.03 (15 micrometres) left a window that began 21
#: micrometres deep unrepresentable: from the nearest start it allowed, the window's misfit at
#: the true parameters was 30 times the noise, and the fit bent the stiffness by -46 % to follow it.
MAX_START_PENETRATION = 0.12


def pressed(u):
    """``u rho(|u|) / |u|`` ``(e,)``: the anywhere layout's offset in units of the start scale
    (module docstring): ``u`` inside the unit ellipse, at most :data:`MAX_START_PENETRATION`
    beyond it."""
    p = MAX_START_PENETRATION
    n = jnp.sqrt(jnp.maximum(u @ u, 1e-30))
    beyond = (1.0 + p * jnp.tanh((n - 1.0) / p)) / n
    return u * jnp.where(n > 1.0, beyond, 1.0)


def unpressed(a: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pressed` (an offset deeper than the bound is clipped to 0.999 of it)."""
    a = np.asarray(a, dtype=float)
    r = float(np.linalg.norm(a))
    return a if r <= 1.0 else a / r * float(unpressed_radius(r))


def pressed_radius(n):
    """``rho(n)`` of :func:`pressed` (NumPy, any shape): the radius of an offset, in units of the
    start scale, whose number ``u`` has the norm ``n``."""
    n = np.asarray(n, dtype=float)
    p = MAX_START_PENETRATION
    return np.where(n > 1.0, 1.0 + p * np.tanh((n - 1.0) / p), n)


def unpressed_radius(r):
    """Inverse of :func:`pressed_radius` (a radius deeper than the bound is clipped to 0.999 of it)."""
    r = np.asarray(r, dtype=float)
    p = MAX_START_PENETRATION
    deep = np.minimum(r, 1.0 + 0.999 * p)
    return np.where(r > 1.0, 1.0 + p * np.arctanh((np.maximum(deep, 1.0) - 1.0) / p), r)


def approach_speed(m, unit):
    """``nu`` [m/s] (the approach speed per unit hysteresis factor; module docstring) of the
    unconstrained ``m`` (``unit``: ``v_s mean(S)`` [m/s]): ``unit exp(m)``."""
    return unit * jnp.exp(m)


def approach_to_z(v: float, unit: float) -> float:
    """Inverse of :func:`approach_speed`."""
    return math.log(max(v, 1e-12) / unit)


def state_size(mech, anywhere: bool) -> int:
    """Numbers of one window's start state: ``sum(2 e (+ 1))`` over the force elements."""
    return sum(2 * el.n_equations + (1 if anywhere else 0) for el in mech.clearance_joints)


def element_starts(mech, state_z, velocity_scale, anywhere: bool):
    """The force elements with their start set from ``state_z`` ``(S,)`` and, for the anywhere
    layout, the approach speeds ``v^- = nu chi`` ``(n_elements,)`` [m/s] of their ongoing contacts
    (else None)."""
    elements, speeds, i = [], [], 0
    for element in mech.clearance_joints:
        e = element.n_equations
        u, w = state_z[i: i + e], state_z[i + e: i + 2 * e]
        scale = element.start_scale()
        if anywhere:
            offset = scale * pressed(u)
            nu = approach_speed(jax.lax.stop_gradient(state_z[i + 2 * e]), velocity_scale * jnp.mean(scale))
            chi = element.law.hysteresis_factor() if hasattr(element, "law") else None
            speeds.append(nu if chi is None else nu * chi)
            i += 2 * e + 1
        else:
            offset = scale * OFFSET_RADIUS * u / jnp.sqrt(1.0 + u @ u)
            i += 2 * e
        elements.append(element.with_start(offset, velocity_scale * scale * w))
    return elements, (speeds if anywhere else None)


def state_to_z(state: np.ndarray, scales: Sequence[np.ndarray], velocity_scale: float,
               approach_speeds: Sequence[float] | None = None) -> np.ndarray:
    """Inverse of :func:`element_starts`: the elements' start states
    (:func:`jaxclear.elements.start_states`, ``(sum 2 e,)``) to ``s``, given each element's
    start scale ``(e,)``. Contact-free layout (``approach_speeds`` None): the offset is clipped
    to 0.999 of its ellipse. Anywhere layout: ``nu`` [m/s] of the ongoing contacts, their
    approach speeds over the hysteresis factor of the element's law (module docstring)."""
    out, i = [], 0
    for j, scale in enumerate(scales):
        scale = np.asarray(scale, dtype=float)
        e = scale.shape[0]
        w = np.asarray(state[i: i + e]) / (scale * OFFSET_RADIUS)
        if approach_speeds is None:
            n = float(np.linalg.norm(w))
            if n >= 0.999:
                w = w * 0.999 / n
                n = 0.999
            out.append(w / math.sqrt(1.0 - n * n))
        else:
            out.append(unpressed(np.asarray(state[i: i + e]) / scale))
        out.append(np.asarray(state[i + e: i + 2 * e]) / (velocity_scale * scale))
        if approach_speeds is not None:
            out.append(np.array([approach_to_z(float(approach_speeds[j]), velocity_scale * float(np.mean(scale)))]))
        i += 2 * e
    return np.concatenate(out) if out else np.zeros(0)


#: The candidate starts of the anywhere layout (:func:`candidates`), per element: directions
#: around the start ellipse, radii in units of it (two free, three pressed in: 1.004, 1.015 and
#: 1.04 of the benchmark's 0.5 mm clearance are 2, 7.5 and 19 micrometres after :func:`pressed`,
#: contact forces of 150, 1100 and 4400 N on its steel journal, the range of a revolution in
#: steady running at 5000 rpm), and relative velocities along
#: the wall in units of ``v_s S`` (``omega c`` is 0.26 m/s on the benchmark, where in steady
#: running at 5000 rpm the independent simulator's journal, while in contact, slides round its
#: bearing at a median 4.4-5.4 of them, 10-12 at the 90th percentile and up to 21; a grid that
#: stopped at 3 could not start the window of a record that began sliding at 16, and its best
#: candidate left 70 times the noise).
CANDIDATE_DIRECTIONS = 24
CANDIDATE_RADII = (0.6, 0.95, 1.004, 1.015, 1.04)
CANDIDATE_SLIDING = (-18.0, -11.0, -6.5, -3.5, -1.5, -0.5, 0.0, 0.5, 1.5, 3.5, 6.5, 11.0, 18.0)
#: ``nu`` (approach speed per unit hysteresis factor) of the candidates' ongoing contacts, in
#: units of ``v_s mean(S)`` (0.26 m/s on the benchmark), while their geometry is scored; then the
#: best geometries' ``nu`` are scored over :data:`APPROACH_SPAN` (a log grid, 0.05 to 26 m/s on
#: the benchmark: approach speeds of 0.025 to 1.3 m/s at hysteresis factors of Lankarani and
#: Nikravesh's 0.5, 0.005 to 0.26 m/s at 0.1; restitution 0.57 and 0.93). The independent
#: simulator's contacts began at 0.06 to 0.5 m/s, nu 0.2 to 3.5 m/s. The span began at 0.013 m/s
#: before: on the short scored part of a window in continuous contact, such heavy damping matched
#: the filtered record as well as the true start (below the noise), and the window's Jacobian
#: then stopped on the step limit (a stiff contact at the derivative's tighter tolerance).
CANDIDATE_APPROACH = 2.0
APPROACH_SPAN = (0.2, 100.0)


def approach_candidates(best: np.ndarray, mech, count: int) -> np.ndarray:
    """``count`` copies of the start ``best`` ``(S,)`` whose ongoing contacts' approach speeds
    (every element's) run over a log grid of :data:`APPROACH_SPAN` (``(count, S)``)."""
    out = np.repeat(best[None, :], count, axis=0)
    out[:, approach_columns(mech)] = np.log(np.geomspace(*APPROACH_SPAN, count))[:, None]
    return out


def approach_columns(mech) -> list:
    """Indices of the numbers ``m`` (log ``nu``) in a start ``(S,)`` of the anywhere layout, one
    per force element."""
    out, i = [], 0
    for el in mech.clearance_joints:
        i += 2 * el.n_equations
        out.append(i)
        i += 1
    return out


def candidates(mech) -> np.ndarray:
    """Candidate window starts ``(M, S)`` of the anywhere layout, in contact or not: for each
    element a grid of directions x radii x sliding velocities (:data:`CANDIDATE_DIRECTIONS`,
    :data:`CANDIDATE_RADII`, :data:`CANDIDATE_SLIDING`); with several elements the other
    elements start centred at rest while one element's grid is scored (their combinations would
    grow as a product)."""
    per_element = []
    for element in mech.clearance_joints:
        e = element.n_equations
        rows = []
        if e == 2:
            for k in range(CANDIDATE_DIRECTIONS):
                phi = 2.0 * math.pi * k / CANDIDATE_DIRECTIONS
                n = np.array([math.cos(phi), math.sin(phi)])
                t = np.array([-n[1], n[0]])
                for rho in CANDIDATE_RADII:
                    for slide in CANDIDATE_SLIDING:
                        rows.append(np.concatenate([rho * n, slide * t, [approach_to_z(CANDIDATE_APPROACH, 1.0)]]))
        else:  # other layouts: the corners and axes of the box of half-axes S, at rest
            grid = np.array(np.meshgrid(*[[-1.0, 0.0, 1.0]] * e)).reshape(e, -1).T
            for rho in CANDIDATE_RADII:
                for g in grid:
                    rows.append(np.concatenate([rho * g, np.zeros(e), [approach_to_z(CANDIDATE_APPROACH, 1.0)]]))
        per_element.append(np.array(rows))
    rest = [np.concatenate([np.zeros(2 * el.n_equations), [approach_to_z(CANDIDATE_APPROACH, 1.0)]]) for el in mech.clearance_joints]
    out = []
    for j, rows in enumerate(per_element):
        for row in rows:
            out.append(np.concatenate([row if i == j else rest[i] for i in range(len(rest))]))
    return np.array(out)


#: Largest crank-angle step [rad] between two assemblies of :func:`crank_guesses` (15 degrees):
#: Newton's iteration from the last configuration then stays on the same assembly branch.
GUESS_STEP = math.radians(15.0)
#: :func:`crank_guesses`' assembly, compiled once per process, through the store of traced programs.
_assemble = jit(assemble)


def crank_guesses(mech, driver: int, angles: Sequence[float]) -> list:
    """Position and velocity guesses ``[(q (3 n_b,), qdot (3 n_b,)), ...]`` of the ideal
    assembly at each crank angle of ``angles`` [rad] (increasing from the driver's ``angle0``),
    reached by continuation from the mechanism's own guesses in steps of at most
    :data:`GUESS_STEP`, so that every window's assembly starts on the branch of the first."""
    import equinox as eqx

    n_b = len(mech.bodies)

    def at(m, angle, q, qd):
        m = eqx.tree_at(lambda x: x.drivers[driver].angle0, m, jnp.asarray(angle, dtype=float))
        m = eqx.tree_at(lambda x: [b.position for b in x.bodies], m, [q[3 * i: 3 * i + 3] for i in range(n_b)])
        m = eqx.tree_at(lambda x: [b.velocity for b in x.bodies], m, [qd[3 * i: 3 * i + 3] for i in range(n_b)])
        asm = _assemble.stored("fit-crank-guess", lambda: jax.tree_util.tree_structure(ASSEMBLY_TEMPLATE), m, 0.0)
        return np.asarray(asm.q), np.asarray(asm.qdot)

    q, qd = (np.asarray(a) for a in mech.guess())
    current = float(mech.drivers[driver].angle0)
    out = []
    for angle in angles:
        steps = max(int(math.ceil(abs(angle - current) / GUESS_STEP)), 1)
        for a in np.linspace(current, angle, steps + 1)[1:]:
            q, qd = at(mech, a, jnp.asarray(q), jnp.asarray(qd))
        current = angle
        out.append((q, qd))
    return out
