r"""A rigid link of a mechanism made flexible: :func:`flexible_link` replaces one body by a chain
of rigid finite elements joined by spring-damping elements (:class:`~jaxclear.DiscreteBeam`, whose
docstring states the model and its source: the rigid finite element method of Kruszewski and
Wittbrodt, Wittbrodt, Adamiec-Wojcik and Wojciech 2006).

Why this form in a mechanism: the elements are rigid bodies of the mechanism's own kind, so every
joint, clearance joint, driver, load, output, derivative, sweep and fit of jaxclear works on a
flexible link unchanged; large rotations are exact (each element turns rigidly), and the
centrifugal stiffening of a turning link comes with the joints' reactions. What it gives up
against a finite-element beam (:mod:`jaxclear.flexible`'s ANCF cable, not yet part of a mechanism):
second-order convergence in the element count instead of fourth, and no continuous slope.
"""

from __future__ import annotations

import copy
import dataclasses
import warnings

import equinox as eqx
import numpy as np

from .._errors import MechanismError, ParameterError, check_range
from .bodies import GROUND, Body
from .discrete_beam import AXIAL, DiscreteBeam, node_name
from .geometry import perp, rotate
from .joints import Revolute
from .mechanism import Mechanism

#: most rigid elements of one link (each adds a body; the dynamics solve grows with them)
MAX_ELEMENTS = 64


def flexible_link(mech: Mechanism, body: str, *, youngs_modulus, second_moment, elements: int = 4,
                  area=None, shear_modulus=None, shear_factor=5.0 / 6.0, damping=0.0, axial: str = "rigid",
                  ends: tuple[str, str] | None = None, name: str | None = None) -> Mechanism:
    r"""``mech`` with its rigid body ``body`` made a flexible link of ``elements`` sdes
    (:class:`~jaxclear.DiscreteBeam`: ``elements + 1`` rigid elements named ``BODY_0`` ..
    ``BODY_m`` from end ``a`` to end ``b``).

    The link is the straight line between its two ends (``ends``: two of the body's points; by
    default the two farthest apart), of length L; its mass m is spread evenly over it (mass
    m L_k / L and inertia (m/L) L_k^3 / 12 for an element of length L_k: the chain's total mass,
    centroid and inertia are a uniform bar's, m L^2 / 12; a warning says when the body's own
    inertia or centroid differ from those by more than 1 %). Every point of the body goes to the
    element that holds it (its coordinate along the link; beyond an end, the end element), with
    its offset from the line; every joint, clearance joint, load and role that named ``body``
    and a point names that element. Each element carries the points ``node{k}`` of the nodes
    at its ends and the element holding the link's middle a point ``middle``. With
    ``axial="rigid"`` (default) the elements are pinned at the nodes by revolute joints.

    Args:
        mech: the mechanism.
        body: the body to make flexible.
        youngs_modulus: E [Pa] > 0.
        second_moment: I [m^4] > 0, of the section about its bending axis.
        elements: m, the number of sdes (1 .. :data:`MAX_ELEMENTS`); frequencies converge like
            1 / m^2 (4 gives the first bending frequency of a pinned link within about 1 %).
        area, shear_modulus: A [m^2] and G [Pa], needed with ``axial="elastic"``.
        shear_factor: kappa (``"elastic"``), 5/6 for a rectangle, 0.9 for a circle.
        damping: Kelvin-Voigt eta [s] >= 0.
        axial: ``"rigid"`` or ``"elastic"``.
        name: the force element's name (default ``body``): parameters ``beam_modulus:NAME``,
            channels ``load:NAME:deflection``.

    A body-only reference to ``body`` (an angle driver, a torque, a rotational spring, a driver's
    ``relative_to``) has no point to say which element it means: a
    :class:`~jaxclear.MechanismError` asks to attach it to an element instead."""
    if body == GROUND:
        raise MechanismError("flexible_link: the ground cannot be made flexible; name a body of the mechanism")
    rigid = mech.body(body)
    if isinstance(elements, bool) or not isinstance(elements, (int, np.integer)):
        raise ParameterError(f"flexible_link: elements must be an integer in [1, {MAX_ELEMENTS}], got {elements!r}")
    check_range("flexible_link: elements", int(elements), low=1, high=MAX_ELEMENTS, unit="")
    if axial not in AXIAL:
        raise ParameterError(f"flexible_link: axial = {axial!r} is not allowed; allowed: {list(AXIAL)}")
    if axial == "elastic" and (area is None or shear_modulus is None):
        raise ParameterError("flexible_link: axial='elastic' needs area [m^2] and shear_modulus [Pa]")
    m = int(elements)
    label = body if name is None else name
    a_name, b_name, pa, axis, length = _ends(rigid, ends)
    bounds = np.concatenate([[0.0], (np.arange(1, m + 1) - 0.5) * length / m, [length]])
    centres = 0.5 * (bounds[:-1] + bounds[1:])
    lengths = np.diff(bounds)
    names = [f"{body}_{k}" for k in range(m + 1)]
    taken = set(mech.body_names) - {body}
    clash = [n for n in names if n in taken]
    if clash:
        raise MechanismError(f"flexible_link: the rigid elements' names {clash} are taken by other bodies; rename them")

    reserved = [p for p in rigid.points if p == "middle" or p in {node_name(k) for k in range(1, m + 1)}]
    if reserved:
        raise MechanismError(f"flexible_link: body {body!r} has points named {reserved}, the names the link gives its "
                             "nodes and middle; rename them")

    def element_of(s: float) -> int:
        return int(np.clip(np.searchsorted(bounds, s, side="right") - 1, 0, m))

    mass = float(rigid.mass)
    along = {p: float(np.dot(np.asarray(v) - pa, axis)) for p, v in rigid.points.items()}
    _warn_not_uniform(body, rigid, pa, axis, length)
    centre_points = [pa + c * axis for c in centres]  # in the body's frame (about its centroid)
    points = [dict() for _ in range(m + 1)]
    home = {}
    for p, v in rigid.points.items():
        k = element_of(along[p])
        home[p] = k
        points[k][p] = np.asarray(v) - centre_points[k]
    for k in range(1, m + 1):
        node = pa + bounds[k] * axis
        points[k - 1][node_name(k)] = node - centre_points[k - 1]
        points[k][node_name(k)] = node - centre_points[k]
    mid = element_of(0.5 * length) if m % 2 == 0 else (m - 1) // 2
    points[mid]["middle"] = pa + 0.5 * length * axis - centre_points[mid]
    pose, twist = np.asarray(rigid.position, float), np.asarray(rigid.velocity, float)
    bodies = []
    for k in range(m + 1):
        arm = np.asarray(rotate(pose[2], centre_points[k]))  # the element's centre from the body's, global axes
        bodies.append(Body(names[k], mass * lengths[k] / length, mass / length * lengths[k] ** 3 / 12.0,
                           {p: v.tolist() for p, v in points[k].items()},
                           position=(*(pose[:2] + arm), pose[2]),
                           velocity=(*(twist[:2] + twist[2] * np.asarray(perp(arm))), twist[2])))
    index = mech.body_index(body)
    new_bodies = [*mech.bodies[:index], *bodies, *mech.bodies[index + 1:]]

    def moved(item, where):
        return _renamed(item, body, lambda point: names[home[point]], where)

    joints = [moved(j, f"joints[{i}]") for i, j in enumerate(mech.joints)]
    if axial == "rigid":
        joints += [Revolute(names[k - 1], node_name(k), names[k], node_name(k)) for k in range(1, m + 1)]
    drivers = [moved(d, f"drivers[{i}]") for i, d in enumerate(mech.drivers)]
    elements_ = [moved(e, f"clearance_joints[{i}]") for i, e in enumerate(mech.clearance_joints)]
    loads = [moved(ld, f"loads[{i}]") for i, ld in enumerate(mech.loads)]
    beam = DiscreteBeam(label, names, (names[home[a_name]], a_name), (names[home[b_name]], b_name), (names[mid], "middle"),
                        length / m, youngs_modulus, second_moment, area=1.0 if area is None else area,
                        shear_modulus=1.0 if shear_modulus is None else shear_modulus, shear_factor=shear_factor,
                        damping=damping, axial=axial)
    roles = {role: (names[mid] if value == body else value) for role, value in mech.roles}
    return Mechanism(new_bodies, joints, drivers, elements_, [*loads, beam], gravity=mech.gravity,
                     ground_points=dict(mech.ground_points), name=f"{mech.name}-flexible-{body}", roles=roles)


def bent_link(mech: Mechanism, name: str, deflection, rate=None) -> Mechanism:
    """``mech`` whose flexible link ``name`` (its :class:`~jaxclear.DiscreteBeam`'s name: the
    body's name by default) starts bent by ``deflection(s)`` [m] and bending at ``rate(s)`` [m/s]
    (None: zero), ``s`` [m] the distance from the link's end ``a`` along it, positive to the left
    of the line from end ``a`` to end ``b`` (:meth:`~jaxclear.DiscreteBeam.with_shape`). The
    start's assembly then holds the link in that shape instead of straight: a link that starts
    vibrating (its first mode's shape, say), or a run that continues from a measured deflection.
    A :class:`~jaxclear.MechanismError` names the flexible links when none is called ``name``."""
    beams = [ld for ld in mech.loads if isinstance(ld, DiscreteBeam)]
    if not any(b.name == name for b in beams):
        raise MechanismError(f"bent_link: no flexible link named {name!r}; this mechanism's: "
                             f"{[b.name for b in beams] or 'none (make one with jc.flexible_link)'}")
    loads = tuple(ld.with_shape(deflection, rate) if isinstance(ld, DiscreteBeam) and ld.name == name else ld
                  for ld in mech.loads)
    return eqx.tree_at(lambda m: m.loads, mech, loads)


def _ends(rigid: Body, ends):
    """The link's ends: ``(name_a, name_b, p_a, unit axis, length)`` in the body's frame."""
    pts = {p: np.asarray(v, float) for p, v in rigid.points.items()}
    if ends is None:
        if len(pts) < 2:
            raise MechanismError(f"flexible_link: body {rigid.name!r} needs two points for the link's ends; it has "
                                 f"{sorted(pts)}")
        keys = sorted(pts)
        a_name, b_name = max(((a, b) for i, a in enumerate(keys) for b in keys[i + 1:]),
                             key=lambda ab: float(np.linalg.norm(pts[ab[1]] - pts[ab[0]])))
    else:
        a_name, b_name = ends
        for p in (a_name, b_name):
            if p not in pts:
                raise MechanismError(f"flexible_link: ends: no point {p!r} on body {rigid.name!r}; its points are "
                                     f"{sorted(pts)}")
    length = float(np.linalg.norm(pts[b_name] - pts[a_name]))
    if not length > 0.0:
        raise MechanismError(f"flexible_link: the ends {a_name!r} and {b_name!r} of body {rigid.name!r} coincide")
    return a_name, b_name, pts[a_name], (pts[b_name] - pts[a_name]) / length, length


def _warn_not_uniform(body: str, rigid: Body, pa, axis, length: float) -> None:
    mass, inertia = float(rigid.mass), float(rigid.inertia)
    uniform = mass * length**2 / 12.0
    centroid = pa + 0.5 * length * axis  # the uniform link's centroid in the body's frame (its centroid is 0)
    if abs(inertia - uniform) > 0.01 * inertia or np.linalg.norm(centroid) > 0.01 * length:
        warnings.warn(f"flexible_link: body {body!r} is not a uniform bar between its ends: inertia {inertia:.6g} "
                      f"kg m^2 against m L^2 / 12 = {uniform:.6g}, centroid {np.linalg.norm(centroid):.3g} m from the "
                      "link's middle; the flexible link spreads the mass evenly (its inertia and centroid are the "
                      "uniform bar's)", stacklevel=3)


def _renamed(item, body: str, element_of_point, where: str):
    """``item`` (a joint, driver, clearance joint or load) with every ``(..body.., ..point..)`` pair
    of static fields naming ``body`` moved to the element holding that point. Body-only
    references refuse (which element would they mean?)."""
    changes = {}
    for f in dataclasses.fields(item):
        if not f.metadata.get("static", False) or "body" not in f.name and f.name != "relative_to":
            continue
        if getattr(item, f.name, None) != body:
            continue
        pair = f.name.replace("body", "point")
        if f.name == "relative_to" or pair == f.name or not hasattr(item, pair):
            raise MechanismError(f"flexible_link: {where} ({getattr(item, 'label', type(item).__name__)}) refers to body "
                                 f"{body!r} by its {f.name!r} alone, with no point saying which rigid element it means: "
                                 "make the link flexible first, then attach it to one of its elements")
        changes[f.name] = element_of_point(getattr(item, pair))
    if not changes:
        return item
    new = copy.copy(item)
    for field, value in changes.items():
        object.__setattr__(new, field, value)  # static structure: no array leaf changes
    return new
