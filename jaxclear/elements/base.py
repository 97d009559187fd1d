r"""The force-element interface: anything that acts between two bodies through forces rather
than constraints (the revolute clearance joint today; lubricated, translational and
pin-in-slot clearance joints next) and owns a slice of the state vector.

The vector field sums every element's generalized force; the solver wrapper calls every
element's :meth:`~AbstractForceElement.after_step` once per accepted step; outputs see an
element only through its :class:`ContactOutput`. The state layout is
``y = [q, qdot, state of element 0, state of element 1, ...]``
(:class:`~jaxclear.integrate.State`); each element's slice is the flat vector of its own
state pytree (:meth:`~AbstractForceElement.state_to_vector`).

Each element declares its named parameters in its class's ``PARAMETERS``
(:class:`~jaxclear._parameters.Parameter`); :meth:`~AbstractForceElement.parameters` adds its
law's and friction's, and :mod:`jaxclear.params` composes them (``name@J`` of clearance joint
``J``).

A new element is one subclass in one file of :mod:`jaxclear.elements`.
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from .._errors import RESULTS, first_failure
from .._parameters import FREE, Parameter, declared, nested
from .._types import Array, BoolScalar, Float, Scalar, Vec2
from ..model.joints import AbstractConstraint
from ..model.mechanism import Mechanism


class ContactOutput(eqx.Module):
    """Contact quantities of one element at one instant (SI): eccentricity (2,) [m],
    penetration [m] (negative = gap), normal and friction force [N], and the power of the
    element's forces on the mechanism [W]."""

    ecc: Vec2
    penetration: Scalar
    normal_force: Scalar
    friction_force: Scalar
    power: Scalar


class AbstractForceElement(eqx.Module):
    """A force element between two bodies with its own state.

    Subclasses implement the abstract methods below and set ``state_size`` (class variable: the
    length of the element's slice of the state vector). During the initial assembly an element
    is held as an ideal joint with ``n_equations`` equations (:meth:`equations`) and a
    prescribed relative velocity (:meth:`assembly_velocity`)."""

    name: eqx.AbstractVar[str]
    state_size: ClassVar[int]
    n_equations: ClassVar[int]
    #: named parameters (:mod:`jaxclear.params`, ``name@J``): base name ->
    #: :class:`~jaxclear._parameters.Parameter`; here the start within the clearance
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "offset_x": Parameter("initial_offset", "m", **FREE, component=0,
                              doc="initial offset of the clearance joint, first component"),
        "offset_y": Parameter("initial_offset", "m", **FREE, component=1,
                              doc="initial offset of the clearance joint, second component"),
        "velocity_x": Parameter("initial_velocity", "m/s", **FREE, component=0,
                                doc="initial relative velocity of the clearance joint, first component"),
        "velocity_y": Parameter("initial_velocity", "m/s", **FREE, component=1,
                                doc="initial relative velocity of the clearance joint, second component"),
    }

    def parameters(self) -> dict[str, Parameter]:
        """The element's named parameters: its class's ``PARAMETERS``, its contact law's and its
        friction law's (``law.*``, ``friction.*``; :func:`~jaxclear._parameters.nested`)."""
        table = dict(type(self).PARAMETERS)
        for part in ("law", "friction"):
            if getattr(self, part, None) is not None:
                table.update(nested(part, declared(getattr(self, part))))
        return table

    def describe(self) -> str:
        """One line for ``jaxclear check`` (:func:`~jaxclear.analysis.structure.check_mechanism`):
        its label, bodies and laws. Elements override it to add their geometry."""
        return f"{self.label}: bodies {' and '.join(self.bodies())}"

    def laws_text(self) -> str:
        """``law NAME, c_r = ..., mu = ...`` of its contact and friction laws (:meth:`describe`)."""
        return (f"law {self.law.name}, c_r = {float(self.law.restitution):.3g}, "
                f"mu = {float(self.friction.coefficient):.3g}")

    def started_within(self, fraction) -> "AbstractForceElement":
        """A copy whose start is moved by ``fraction`` (``(n_equations,)``) of its clearance (the
        design ensembles' start offsets). Default: itself (an element whose start the ensembles
        leave as given)."""
        return self

    # ---- structure ------------------------------------------------------------------
    @abc.abstractmethod
    def bodies(self) -> tuple[str, str]:
        """The two bodies it acts between."""

    @abc.abstractmethod
    def points(self) -> tuple[tuple[str, str], ...]:
        """``(body, point)`` pairs it uses (validated by the mechanism)."""

    @property
    def label(self) -> str:
        return f"{type(self).__name__} {self.name!r}"

    # ---- validity (run time) -----------------------------------------------------------
    def checks(self) -> tuple:
        """The element's range checks in order: :class:`~jaxclear._errors.Rule` s of its own
        numbers and its laws' ``check()`` results. :meth:`check` combines them traceably; on a
        concrete element :func:`~jaxclear._errors.failed_check` says which failed. Default: none."""
        return ()

    def check(self) -> RESULTS:
        """Traceable range check of the element's numbers (its laws included): the first
        failing :class:`~jaxclear.RESULTS` ``invalid_*`` entry of :meth:`checks`, or
        ``successful``. Evaluated by :func:`~jaxclear.simulate` under ``jit``/``vmap``."""
        return first_failure(*self.checks())

    def penetration_limit(self) -> Scalar:
        """Deepest physically meaningful penetration [m]; a run whose penetration exceeds it at
        any accepted step (the memory's running peak) or output sample gets status
        ``penetration_too_deep``. Default: no limit (``inf``)."""
        return jnp.inf

    # ---- state ----------------------------------------------------------------------
    @abc.abstractmethod
    def state_init(self, dtype=float) -> Any:
        """The element's state at the start (a pytree of arrays)."""

    @abc.abstractmethod
    def state_to_vector(self, state) -> Float[Array, " s"]:
        """Flatten a state to its slice ``(state_size,)`` of the state vector."""

    @abc.abstractmethod
    def state_from_vector(self, v: Float[Array, " s"]) -> Any:
        """Inverse of :meth:`state_to_vector`."""

    # ---- physics --------------------------------------------------------------------
    @abc.abstractmethod
    def forces(self, mech: Mechanism, t: Scalar, q, qdot, state) -> tuple[Float[Array, " n"], Any, ContactOutput]:
        """``(generalized force (n,), state derivative (same tree as state), outputs)``."""

    @abc.abstractmethod
    def after_step(self, mech: Mechanism, t0, q0, qd0, t1, q1, qd1, state, qdd=None) -> tuple[Any, BoolScalar]:
        """The state's update after an accepted step ``[t0, t1]`` (memory rules) and whether
        the force law changed within the step (the solver then re-evaluates its first stage).
        ``qdd``: None, or the accelerations ``(qdd0, qdd1)`` (n,) at the step's ends, which the
        sensitivity solve gives for the derivative of an approach speed stored at an onset
        (:func:`~jaxclear.elements.memory.penetration_accelerations`)."""

    def onset(self, mech: Mechanism, t0, q0, qd0, t1, q1, qd1, state) -> tuple[Scalar, BoolScalar]:
        """Where a candidate step ``[t0, t1]`` must be split for the element's force law to
        switch at a step boundary: ``(s, split)`` with the fraction ``s`` in [0, 1] of the step at
        the earliest contact onset or separation among the element's contacts that the step
        cannot keep inside it (sign changes of the cubic Hermite interpolant of the penetration,
        :func:`~jaxclear.elements.memory.onset_fraction`) and whether there is one. The
        step-size controller (:class:`~jaxclear.integrate.OnsetController`) uses it to end
        a step just past the switch, so the impact memory is taken at the onset and a free
        flight between contacts is never stepped over. Default: never a switch (elements
        without a memory of the approach speed)."""
        return jnp.ones((), jnp.result_type(t1)), jnp.zeros((), bool)

    def kinks(self, mech: Mechanism, t0, q0, qd0, qdd0, t1, q1, qd1, state) -> tuple[Scalar, BoolScalar]:
        """Where a candidate step ``[t0, t1]`` must be split for its friction law's kinks (the
        slip speeds where the friction force's derivative jumps,
        :meth:`~jaxclear.contact.base.AbstractFriction.kinks`) to lie at step boundaries:
        ``(s, split)`` as :meth:`onset`, for the contacts in contact at both ends
        (:func:`~jaxclear.elements.memory.kink_fraction`; ``qdd0`` the accelerations at ``t0``,
        for the slips' rates there). Used by the error-controlled sensitivities, whose tangents
        jump in rate there. Default: none."""
        return jnp.ones((), jnp.result_type(t1)), jnp.zeros((), bool)

    # ---- named outputs (Solution.element_outputs, channels joint:K:NAME, timeseries.csv) ----
    #: the element's own output channels: name -> unit (``"-"``: dimensionless or a code), in the
    #: order :meth:`outputs` returns them
    OUTPUTS: ClassVar[dict[str, str]] = {}

    def outputs(self, mech: Mechanism, t: Scalar, q, qdot, state, continuous_after: float) -> dict[str, Scalar]:
        """The element's named outputs at one instant (:data:`OUTPUTS`: film force, corners,
        active feature, ...), each a scalar, from the state at that instant (``state``: the
        element's memories). ``continuous_after`` [s]: a contact longer than this counts as
        continuous (mode 2) rather than an impact (mode 1), as for ``Solution.mode``. Default:
        none."""
        return {}

    @abc.abstractmethod
    def relative_state(self, mech: Mechanism, q, qdot) -> Float[Array, "4"]:
        """``[x, y, v_x, v_y]`` of the element's moving part relative to its seat (the journal
        centre relative to the bearing centre; the slider relative to the guide) [m, m/s]."""

    # ---- start state (the initial assembly's coordinates; fit windows) -------------------
    def start_state(self, mech: Mechanism, q, qdot) -> Float[Array, " 2e"]:
        """The coordinates :meth:`equations` holds at the start and their rates at ``(q, qdot)``
        ``(2 n_equations,)``: :math:`[a(q), \\dot a(q, \\dot q)]` with :math:`a(q)` =
        ``equations(q) + initial_offset`` (a journal's eccentricity [m]; a translational joint's
        lateral offset [m] and tilt [rad]). :meth:`with_start` of this vector starts a simulation
        at the same relative configuration (windows of :mod:`jaxclear.fitting` chain this way).
        Default: the rate by forward-mode differentiation of :meth:`equations` along ``qdot``."""
        e, edot = jax.jvp(lambda qq: self.equations(mech, qq, jnp.zeros((), q.dtype)), (q,), (qdot,))
        return jnp.concatenate([e + self.initial_offset, edot])

    def with_start(self, offset, velocity) -> "AbstractForceElement":
        """A copy starting at the coordinates ``offset`` ``(n_equations,)`` and their rates
        ``velocity`` (layout of :meth:`start_state`; default: ``initial_offset`` and
        ``initial_velocity`` replaced)."""
        return eqx.tree_at(lambda e: (e.initial_offset, e.initial_velocity), self, (offset, velocity))

    @abc.abstractmethod
    def start_scale(self) -> Float[Array, " e"]:
        """Per coordinate of :meth:`start_state` the half-axis ``(n_equations,)`` of an ellipse
        inside which the element is free of contact (a journal: the radial clearance ``c`` twice;
        a translational joint: ``c / sqrt 2`` [m] and ``sqrt 2 c / l`` [rad]). The fit maps its
        window unknowns into this ellipse."""

    #: axis labels of the orbit plot of :attr:`ContactOutput.ecc` (without unit)
    orbit_labels: ClassVar[tuple[str, str]] = ("eccentricity x", "eccentricity y")

    @abc.abstractmethod
    def clearance_region(self, n: int = 361) -> Float[Array, "n 2"]:
        """Boundary (closed polyline, (n, 2), [m]) of the region that :attr:`ContactOutput.ecc`
        stays in without contact (the orbit plot draws it to scale)."""

    @abc.abstractmethod
    def ideal_joint(self) -> AbstractConstraint:
        """The ideal joint that replaces this element in :meth:`Mechanism.ideal` (zero clearance)."""

    # ---- initial assembly -----------------------------------------------------------
    @abc.abstractmethod
    def equations(self, mech: Mechanism, q, t) -> Float[Array, " e"]:
        """Equations holding the element at its initial configuration during assembly."""

    @abc.abstractmethod
    def assembly_velocity(self) -> Float[Array, " e"]:
        """Prescribed rate of :meth:`equations` at the start (e.g. zero: moves with its partner)."""


def contact_mode(t, penetration, contact_start, continuous_after):
    """Contact mode as ``Solution.mode`` counts it: 0 free flight, 1 impact, 2 continuous contact
    (in contact for longer than ``continuous_after`` [s] since the memory's onset)."""
    long = (t - contact_start) > continuous_after
    return jnp.where(penetration > 0.0, jnp.where(long, 2, 1), 0).astype(jnp.int32)


def stack_outputs(outputs: list[ContactOutput]) -> ContactOutput | None:
    """Per-element outputs stacked along a leading axis (``None`` for no element)."""
    if not outputs:
        return None
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *outputs)


def start_states(mech: Mechanism, q, qdot) -> Float[Array, " s"]:
    """Every force element's :meth:`~AbstractForceElement.start_state` at ``(q, qdot)``, stacked
    (``(sum of 2 n_equations,)``; the fit's window states)."""
    rows = [element.start_state(mech, q, qdot) for element in mech.clearance_joints]
    return jnp.concatenate(rows) if rows else jnp.zeros((0,), q.dtype)
