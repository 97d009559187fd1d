r"""Named output channels: any signal of a simulation by name, as a traceable ``(T,)`` array with
its unit (usable in fits: gradients flow through it).

Names are fields separated by ``:``; options ``key=value`` or flags may follow in any order.

* ``time``: output times [s];
* ``body:B:x|y|phi[:pos|vel|acc]``: a body coordinate or its first or second derivative;
* ``point:B:P:pos|vel|acc[:x|y|norm][:frame=F]``: a named point's position, velocity or
  acceleration, components along the global axes or, with ``frame=F``, along body F's axes
  (default component ``x``); ``...:acc:...:specific``: acceleration minus gravity,
  :math:`a - g`, what an accelerometer reads (specific force);
* ``reaction:J[:x|y|moment|norm][:on=B][:frame=F]``: force [N] (or moment about the centroid
  [N m]) of ideal joint or driver ``J`` on body ``B`` (default its second body);
* ``joint:K:ecc_x|ecc_y|ecc|penetration|normal_force|friction_force|mode``: clearance joint ``K``
  as one contact; ``joint:K:NAME`` for a name of the element's own outputs
  (``type(joint).OUTPUTS``, :meth:`~jaxclear.integrate.Solution.element_outputs`), e.g.
  ``joint:0:film_force``, ``joint:0:min_film_thickness`` (lubricated),
  ``joint:0:rear_lower_normal_force`` (translational, per corner), ``joint:0:feature``
  (pin-in-slot).

``J`` is an index into ``mech.constraints`` (joints, then drivers) or a label such as
``Revolute(ground-crank)``; ``K`` an index into ``mech.clearance_joints`` or a joint's name.

* ``load:L:NAME``: output ``NAME`` of force element ``L`` among the loads (an index into
  ``mech.loads`` or its name; ``type(load).OUTPUTS``): ``load:strut:force``,
  ``load:strut:length``, ``load:strut:rate``, ``load:strut:power`` of a spring-damper;
  ``moment``, ``angle``, ``rate``, ``power`` of a rotational one; a bushing's ``force_x``, ``dx``,
  ... in its first body's axes (:mod:`jaxclear.model.connectors`).

Kinematics follow Nikravesh, "Computer-Aided Analysis of Mechanical Systems" (1988): point
acceleration :math:`\ddot r + \ddot\phi\,\mathrm{perp}(A s') - \dot\phi^2 A s'`
(:func:`jaxclear.model.point_acceleration`), components in a body frame
:math:`A(\phi_F)^T v`. Reactions: with the equations of motion
:math:`M\ddot q = g - D^T\lambda` (:mod:`jaxclear.integrate._dynamics`), the constraint force of
joint ``J`` on body ``B`` is :math:`-D_{J,B}^T\lambda_J` (3 generalized components: force x,
y and moment about B's centroid), with :math:`D_{J,B} = \partial\Phi_J/\partial q_B` by
automatic differentiation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ParameterError
from ..integrate import Solution
from ..model import GROUND, AbstractConnector, Mechanism, point_acceleration, point_position, point_velocity
from ..model.drivers import COORDINATES
from ..model.geometry import rotate

DERIVATIVES = {"pos": 0, "vel": 1, "acc": 2}
COMPONENTS = ("x", "y", "norm")
REACTION_COMPONENTS = ("x", "y", "moment", "norm")
JOINT_SIGNALS = {"ecc_x": "m", "ecc_y": "m", "ecc": "m", "penetration": "m", "normal_force": "N",
                 "friction_force": "N", "mode": "-"}
KINDS = ("time", "body", "point", "reaction", "joint", "load")


@dataclass(frozen=True)
class ChannelSpec:
    """A parsed channel name: ``kind``, positional ``fields`` and ``options``."""

    name: str
    kind: str
    fields: tuple[str, ...]
    options: dict


def _fail(name: str, message: str):
    raise ParameterError(f"output channel {name!r}: {message}")


def parse(name: str) -> ChannelSpec:
    """Split a channel name into kind, fields and ``key=value`` options (flags map to True)."""
    parts = [p.strip() for p in str(name).split(":")]
    if not parts or parts[0] not in KINDS:
        _fail(name, f"the first field must be one of {list(KINDS)}")
    fields, options = [], {}
    for p in parts[1:]:
        if "=" in p:
            k, v = p.split("=", 1)
            options[k.strip()] = v.strip()
        elif p == "specific":
            options["specific"] = True
        else:
            fields.append(p)
    return ChannelSpec(str(name), parts[0], tuple(fields), options)


def _option_keys(spec: ChannelSpec, allowed):
    bad = sorted(set(spec.options) - set(allowed))
    if bad:
        _fail(spec.name, f"unknown option(s) {bad}; allowed: {sorted(allowed)}")


def _body(mech: Mechanism, spec: ChannelSpec, body: str) -> str:
    if body != GROUND and body not in mech.body_names:
        _fail(spec.name, f"unknown body {body!r}; bodies are {list(mech.body_names)} and {GROUND!r}")
    return body


def _frame(mech, spec, q, v):
    """Components of global vectors ``v`` (T, 2) in the axes of ``frame=F`` (global without)."""
    frame = spec.options.get("frame")
    if frame is None:
        return v
    i = mech.body_index(_body(mech, spec, frame))
    if i < 0:
        return v
    return jax.vmap(lambda phi, w: rotate(-phi, w))(q[:, 3 * i + 2], v)


def _component(spec: ChannelSpec, v, comp: str, allowed=COMPONENTS):
    if comp not in allowed:
        _fail(spec.name, f"component {comp!r} is not one of {list(allowed)}")
    if comp == "norm":
        return jnp.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2)
    return v[:, allowed.index(comp)]


def _body_channel(mech, sol, spec):
    _option_keys(spec, ())
    if len(spec.fields) not in (2, 3) or spec.fields[1] not in COORDINATES:
        _fail(spec.name, f"expected body:BODY:{'|'.join(COORDINATES)}[:{'|'.join(DERIVATIVES)}]")
    body, coord = spec.fields[0], spec.fields[1]
    der = spec.fields[2] if len(spec.fields) == 3 else "pos"
    if der not in DERIVATIVES:
        _fail(spec.name, f"derivative {der!r} is not one of {list(DERIVATIVES)}")
    i = mech.body_index(_body(mech, spec, body))
    if i < 0:
        return jnp.zeros_like(sol.ts), "m"
    d = DERIVATIVES[der]
    unit = ("m", "m/s", "m/s^2")[d] if coord != "phi" else ("rad", "rad/s", "rad/s^2")[d]
    return (sol.q, sol.qdot, sol.qddot)[d][:, 3 * i + COORDINATES[coord]], unit


def _point_channel(mech, sol, spec):
    _option_keys(spec, ("frame", "specific"))
    if len(spec.fields) not in (3, 4) or spec.fields[2] not in DERIVATIVES:
        _fail(spec.name, "expected point:BODY:POINT:pos|vel|acc[:x|y|norm][:frame=BODY][:specific]")
    body, point, der = spec.fields[:3]
    comp = spec.fields[3] if len(spec.fields) == 4 else "x"
    _body(mech, spec, body)
    mech.point(body, point)  # MechanismError naming the body's points
    if der == "pos":
        v = jax.vmap(lambda q: point_position(mech, q, body, point))(sol.q)
    elif der == "vel":
        v = jax.vmap(lambda q, qd: point_velocity(mech, q, qd, body, point))(sol.q, sol.qdot)
    else:
        v = jax.vmap(lambda q, qd, qdd: point_acceleration(mech, q, qd, qdd, body, point))(sol.q, sol.qdot, sol.qddot)
        if spec.options.get("specific"):
            v = v - mech.gravity[None, :]
    if spec.options.get("specific") and der != "acc":
        _fail(spec.name, "'specific' (acceleration minus gravity) applies to acc only")
    if der == "pos" and "frame" in spec.options:
        _fail(spec.name, "frame=BODY applies to vel and acc (a position in a moving frame is not a point signal)")
    v = _frame(mech, spec, sol.q, v)
    return _component(spec, v, comp), {"pos": "m", "vel": "m/s", "acc": "m/s^2"}[der]


def _constraint_index(mech, spec, key: str) -> int:
    labels = [c.label for c in mech.constraints]
    if key.lstrip("-").isdigit():
        k = int(key)
        if not 0 <= k < len(labels):
            _fail(spec.name, f"constraint index {k} outside [0, {len(labels) - 1}] (joints then drivers: {labels})")
        return k
    if labels.count(key) == 1:
        return labels.index(key)
    _fail(spec.name, f"{key!r} names no single ideal joint or driver; give an index into {labels}")


def _reaction_channel(mech, sol, spec):
    _option_keys(spec, ("on", "frame"))
    if len(spec.fields) not in (1, 2):
        _fail(spec.name, "expected reaction:J[:x|y|moment|norm][:on=BODY][:frame=BODY]")
    k = _constraint_index(mech, spec, spec.fields[0])
    comp = spec.fields[1] if len(spec.fields) == 2 else "norm"
    if comp not in REACTION_COMPONENTS:
        _fail(spec.name, f"component {comp!r} is not one of {list(REACTION_COMPONENTS)}")
    c = mech.constraints[k]
    moving = [b for b in c.bodies() if b != GROUND]
    on = spec.options.get("on", moving[-1] if moving else GROUND)
    if on not in moving:
        _fail(spec.name, f"on={on!r}: the constraint acts on {moving}")
    i = mech.body_index(on)
    start = sum(x.n_equations for x in mech.constraints[:k])
    lam = sol.reactions[:, start: start + c.n_equations]

    def force(q, t, lam_k):
        d = jax.jacfwd(lambda qq: c.equations(mech, qq, t))(q)[:, 3 * i: 3 * i + 3]
        return -(d.T @ lam_k)

    gen = jax.vmap(force)(sol.q, sol.ts, lam)
    if comp == "moment":
        return gen[:, 2], "N m"
    f = _frame(mech, spec, sol.q, gen[:, :2])
    return _component(spec, f, comp, ("x", "y", "norm")), "N"


def _joint_channel(mech, sol, spec):
    _option_keys(spec, ())
    if len(spec.fields) != 2:
        _fail(spec.name, f"expected joint:K:{'|'.join(JOINT_SIGNALS)} or joint:K:NAME of the element's outputs")
    key, what = spec.fields
    names = [j.name for j in mech.clearance_joints]
    if key.isdigit() and int(key) < len(names):
        k = int(key)
    elif names.count(key) == 1:
        k = names.index(key)
    else:
        _fail(spec.name, f"{key!r} is no clearance joint; give an index in [0, {len(names) - 1}] or a name of {names}")
    own = type(mech.clearance_joints[k]).OUTPUTS
    if what in own:
        return sol.element_outputs(mech, k)[what], own[what]
    if what not in JOINT_SIGNALS:
        _fail(spec.name, f"{what!r} is not a signal of clearance joint {k} ({mech.clearance_joints[k].label}); "
                         f"allowed: {[*JOINT_SIGNALS, *own]}")
    series = {"ecc_x": lambda: sol.ecc[:, k, 0], "ecc_y": lambda: sol.ecc[:, k, 1],
              "ecc": lambda: jnp.sqrt(sol.ecc[:, k, 0] ** 2 + sol.ecc[:, k, 1] ** 2),
              "penetration": lambda: sol.penetration[:, k], "normal_force": lambda: sol.normal_force[:, k],
              "friction_force": lambda: sol.friction_force[:, k], "mode": lambda: sol.mode[:, k]}
    return series[what](), JOINT_SIGNALS[what]


def _load_channel(mech, sol, spec):
    _option_keys(spec, ())
    named = {ld.name: i for i, ld in enumerate(mech.loads) if isinstance(ld, AbstractConnector)}
    if len(spec.fields) != 2:
        _fail(spec.name, f"expected load:L:OUTPUT, L a force element among the loads: an index or one of {list(named)}")
    key, what = spec.fields
    k = int(key) if key.isdigit() and int(key) in named.values() else named.get(key)
    if k is None:
        _fail(spec.name, f"{key!r} is no force element among the loads; give one of {list(named)} or its index "
                         f"{list(named.values())}")
    load = mech.loads[k]
    if what not in load.OUTPUTS:
        _fail(spec.name, f"{what!r} is not an output of {load.label}; allowed: {list(load.OUTPUTS)}")
    values = jax.vmap(lambda t, q, qd: load.outputs(mech, t, q, qd)[what])(sol.ts, sol.q, sol.qdot)
    return values, load.OUTPUTS[what]


def channel_with_unit(mech: Mechanism, sol: Solution, name: str):
    """``(values (T,), unit)`` of channel ``name`` (see the module docstring)."""
    spec = parse(name)
    if spec.kind == "time":
        return sol.ts, "s"
    return {"body": _body_channel, "point": _point_channel, "reaction": _reaction_channel,
            "joint": _joint_channel, "load": _load_channel}[spec.kind](mech, sol, spec)


def channel(mech: Mechanism, sol: Solution, name: str):
    """Values (T,) of channel ``name``: traceable in ``sol`` and ``mech`` (usable in fits)."""
    return channel_with_unit(mech, sol, name)[0]


class _Sample(NamedTuple):
    """One sample's view of a :class:`Solution` (what the body and point channels read)."""

    ts: jax.Array
    q: jax.Array
    qdot: jax.Array
    qddot: jax.Array


def sample_channel(mech: Mechanism, name: str, t, q, qdot, qddot):
    """The value (scalar) of channel ``name`` at one state: time ``t`` [s], ``q``, ``qdot``,
    ``qddot`` ``(n,)``; channels of kind body or point only (:data:`OVERLAY_KINDS`: functions
    of the coordinates alone; the others read a run's forces). Traceable (the objectives of
    steady operation, :mod:`jaxclear.designing.steady`)."""
    if parse(name).kind not in OVERLAY_KINDS:
        _fail(name, f"one sample is read of channels of kind {' or '.join(OVERLAY_KINDS)} only")
    view = _Sample(jnp.asarray(t)[None], q[None], qdot[None], qddot[None])
    return channel(mech, view, name)[0]


def unit(mech: Mechanism, name: str) -> str:
    """Unit of channel ``name`` (checks the name against ``mech`` without a simulation)."""
    return _unit_only(mech, name)


def output_body(mech: Mechanism) -> str:
    """The body whose motion a mechanism file reports by default: role ``output``, else
    ``rocker``, else ``slider``, else the last body."""
    for role in ("output", "rocker", "slider"):
        if mech.role(role) is not None:
            return mech.role(role)
    return mech.body_names[-1]


def default_channels(mech: Mechanism) -> list[str]:
    """The output link's motion: ``x`` and its derivatives for a slider (role ``slider``, or an
    output body that a translational joint guides), else ``phi`` and its derivatives."""
    body = output_body(mech)
    coord = "x" if body == mech.role("slider") else "phi"
    return [f"body:{body}:{coord}:{d}" for d in DERIVATIVES]


def _unit_only(mech, name):
    spec = parse(name)
    if spec.kind == "time":
        return "s"
    fake = _FakeSolution.for_mechanism(mech)
    return channel_with_unit(mech, fake, name)[1]


class _FakeSolution:
    """Two samples of zeros shaped like a :class:`Solution` (to check a name and read its unit)."""

    @staticmethod
    def for_mechanism(mech: Mechanism):
        n, m, k, t = mech.n_coordinates, mech.n_constraints, len(mech.clearance_joints), 2
        z = jnp.zeros
        return Solution(ts=z(t), q=z((t, n)), qdot=z((t, n)), qddot=z((t, n)), reactions=z((t, m)), drift=z(t),
                        ecc=z((t, k, 2)), penetration=z((t, k)), normal_force=z((t, k)), friction_force=z((t, k)),
                        mode=z((t, k), int), element_states=tuple(
                            jax.tree_util.tree_map(lambda x: jnp.zeros((t, *jnp.shape(x))), j.state_init())
                            for j in mech.clearance_joints), num_steps=z(()), num_accepted_steps=z(()),
                        num_rejected_steps=z(()), status=z((), int))


#: channel kinds that mean the same on the ideal-joint mechanism (same bodies, same points)
OVERLAY_KINDS = ("body", "point")


def channel_table(mech: Mechanism, sol: Solution, names, ideal_mech: Mechanism | None = None,
                  ideal_sol: Solution | None = None) -> dict:
    """Columns ``"NAME [UNIT]"`` -> (T,) NumPy arrays for the channels ``names``, each followed by
    its ideal-joint counterpart ``"NAME:ideal [UNIT]"`` (body and point channels) when
    ``ideal_sol`` (of ``ideal_mech``, on the same output grid) is given."""
    cols = {}
    for name in names:
        values, u = channel_with_unit(mech, sol, name)
        cols[f"{name} [{u}]"] = np.asarray(values, dtype=float)
        if ideal_sol is not None and parse(name).kind in OVERLAY_KINDS:
            cols[f"{name}:ideal [{u}]"] = np.asarray(channel(ideal_mech or mech, ideal_sol, name), dtype=float)
    return cols
