r"""The contact layer's interfaces and shared data: the geometry a law sees
(:class:`ContactKinematics`), materials, and the abstract normal-force and friction laws.

Extension points (abstract :class:`equinox.Module` classes in the style of diffrax's solver
hierarchy; concrete laws are final):

* :class:`AbstractNormalLaw`: ``normal_force(kin, deltadot0)`` and, where the law sets its
  own direction (non-circular profiles), ``contact_force``; ``penetration`` decides contact;
  ``profiles`` and ``with_profiles`` (laws that integrate non-circular profiles);
  ``stiffness_parameter`` names the leaf that ``stiffness`` addresses in fits and sweeps and
  ``stiffness_value`` returns its value (derived from materials when the leaf is ``None``).
* :class:`AbstractFriction`: ``__call__(v_t, F_N) -> F_T``; a law with internal (bristle)
  states sets ``state_size`` and implements ``force_and_rate(state, v_t, F_N)``.

Each law declares its named parameters (``restitution``, ``stiffness``, ``friction``, ...) in
its class's ``PARAMETERS`` (:class:`~jaxclear._parameters.Parameter`; :func:`law_parameters`,
:func:`friction_parameters`), which :mod:`jaxclear.params` composes.

A new law is one subclass in one file plus one entry in :mod:`jaxclear.contact.registry`.
"""

from __future__ import annotations

import abc
import warnings
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, ParameterError, Rule, check_range, first_failure
from .._parameters import NONNEGATIVE, POSITIVE, Parameter
from .._types import Array, ArrayLike, Float, Scalar, Vec2


class ContactKinematics(eqx.Module):
    """Geometry and velocities of one journal-in-bearing contact in one configuration
    (all global, SI): what a normal law and a friction law see."""

    ecc: Vec2  # eccentricity vector e = P_j - P_i [m]
    e: Scalar  # |e| [m]
    normal: Vec2  # n = e/|e| (arbitrary but finite at e = 0)
    tangent: Vec2  # t = perp(n)
    delta: Scalar  # e - c [m]
    deltadot: Scalar  # penetration rate [m/s]
    slip: Scalar  # tangential slip v_T [m/s]
    bearing_centre: Vec2
    journal_centre: Vec2
    bearing_velocity: Vec2
    journal_velocity: Vec2
    bearing_angle: Scalar
    journal_angle: Scalar
    bearing_omega: Scalar
    journal_omega: Scalar
    radius_bearing: Scalar
    radius_journal: Scalar
    length: Scalar


def compliance(young, poisson):
    r"""Material compliance :math:`\sigma = (1-\nu^2)/E` [1/Pa]."""
    return (1.0 - poisson**2) / young


class Material(eqx.Module):
    """An isotropic elastic material: Young's modulus ``young`` [Pa], Poisson ratio ``poisson``."""

    young: Scalar
    poisson: Scalar

    def __init__(self, young: ArrayLike = 207e9, poisson: ArrayLike = 0.3):
        check_range("young (Young's modulus)", young, low=0.0, low_open=True, unit="Pa")
        check_range("poisson (Poisson ratio)", poisson, low=-1.0, high=0.5, low_open=True, high_open=True)
        self.young = jnp.asarray(young, dtype=float)
        self.poisson = jnp.asarray(poisson, dtype=float)

    def checks(self, what: str = "material") -> tuple:
        """``invalid_stiffness`` for E <= 0, ``invalid_parameter`` for a Poisson ratio outside
        (-1, 0.5) (:class:`~jaxclear._errors.Rule` s; ``what``: the material's role in the message)."""
        return (Rule(f"{what} young (Young's modulus)", self.young, RESULTS.invalid_stiffness, low=0.0, low_open=True,
                     unit="Pa"),
                Rule(f"{what} poisson (Poisson ratio)", self.poisson, RESULTS.invalid_parameter, low=-1.0, high=0.5,
                     low_open=True, high_open=True))

    def check(self) -> RESULTS:
        """Traceable range check (run time) of :meth:`checks`."""
        return first_failure(*self.checks())

    @property
    def compliance(self):
        """:math:`(1-\\nu^2)/E` [1/Pa]."""
        return compliance(self.young, self.poisson)


def _numpy_material(young: float, poisson: float) -> Material:
    """A :class:`Material` whose leaves are NumPy scalars (0-d arrays), for module constants:
    creating a JAX array at import would start JAX's backends, after which XLA no longer reads
    ``XLA_FLAGS`` (``jaxclear/_xla_flags.py``); JAX converts the leaves when it traces them."""
    material = object.__new__(Material)
    for name, value in (("young", young), ("poisson", poisson)):
        leaf = np.array(value, dtype=np.float64)
        leaf.flags.writeable = False  # a constant: the store of programs keeps its device copy
        object.__setattr__(material, name, leaf)
    return material


STEEL = _numpy_material(207e9, 0.3)
"""Structural steel as used in the Flores benchmark: a :class:`Material` with E = 207 GPa, nu = 0.3."""


def effective_modulus(bearing: Material, journal: Material):
    r""":math:`E^* = 1/(\sigma_i + \sigma_j)` [Pa]."""
    return 1.0 / (bearing.compliance + journal.compliance)


def law_parameters(stiffness: str = "stiffness", derived: bool = True, exponent: bool = False) -> dict[str, Parameter]:
    """A law's named parameters: ``restitution``, ``stiffness`` (the leaf ``stiffness``, the
    class's ``stiffness_parameter``; ``derived``: the leaf may be ``None``, the value then derived
    from the materials) and, with ``exponent``, ``exponent``."""
    table = {"restitution": Parameter("restitution", "", 0.0, True, "logit", "nominal coefficient of restitution",
                                      high=1.0),
             "stiffness": Parameter(stiffness, "law unit", **POSITIVE, doc="contact stiffness of the law",
                                    derived=derived)}
    if exponent:
        table["exponent"] = Parameter("exponent", "", **POSITIVE, doc="force exponent n")
    return table


class AbstractNormalLaw(eqx.Module):
    r"""A normal contact force law :math:`F_N(\delta, \dot\delta, \dot\delta^{(-)}) \ge 0` [N].

    Subclasses implement :meth:`normal_force` and :meth:`stiffness_value` and set the class
    variable ``stiffness_parameter``; they may override :meth:`contact_force` (laws that set
    their own direction), :meth:`penetration`, :meth:`check_geometry`, and :attr:`profiles` with
    :meth:`with_profiles` (laws that integrate non-circular journal and bearing profiles)."""

    restitution: eqx.AbstractVar[Scalar]
    stiffness_parameter: ClassVar[str] = "stiffness"
    #: named parameters (:mod:`jaxclear.params`): base name -> :class:`~jaxclear._parameters.Parameter`
    PARAMETERS: ClassVar[dict[str, Parameter]] = law_parameters()

    @property
    @abc.abstractmethod
    def name(self) -> str:
        """The name the registry (:func:`~jaxclear.make_law`) knows this law by."""

    @abc.abstractmethod
    def normal_force(self, kin: ContactKinematics, deltadot0: Scalar) -> Scalar:
        """Normal force [N] for the kinematics ``kin`` and the (floored) impact speed [m/s]."""

    @abc.abstractmethod
    def stiffness_value(self, radius_bearing, radius_journal) -> Scalar:
        """Value of the stiffness leaf (``stiffness_parameter``), derived when it is ``None``."""

    def contact_force(self, kin: ContactKinematics, deltadot0: Scalar) -> tuple[Scalar, Vec2]:
        """``(F_N, direction)``: magnitude [N] and the unit vector from the bearing towards the
        journal along which the force pushes the bearing (``kin.normal`` for circles)."""
        return self.normal_force(kin, deltadot0), kin.normal

    def penetration(self, kin: ContactKinematics) -> Scalar:
        """Penetration that decides contact [m]; for a circular pin and hole it is ``e - c``."""
        return kin.delta

    def hysteresis_factor(self) -> Scalar | None:
        r"""The factor :math:`\hat\chi(c_r)` [-] of laws whose damping is
        :math:`F_e(\delta)\,\hat\chi\,\dot\delta/\dot\delta^{(-)}` (the dissipative Hertz family and
        its cylindrical and conformal relatives), else None. Inside a contact that began before a
        fit window only the ratio :math:`\dot\delta^{(-)}/\hat\chi` acts, which a fit holds
        (:mod:`jaxclear.fitting.window_start`)."""
        return None

    @property
    def profiles(self) -> tuple:
        """``(journal_profile, bearing_profile)``: the radial deviations the law contacts on
        (:class:`~jaxclear.FourierProfile` or ``None`` each); ``(None, None)``: circles."""
        return None, None

    def with_profiles(self, journal_profile, bearing_profile) -> AbstractNormalLaw:
        """This law on a non-circular journal and/or bearing. The default law assumes circles
        (its force is a function of ``e - c``) and raises :class:`~jaxclear.ParameterError`;
        laws that integrate the contact point by point override it."""
        raise ParameterError(
            f"contact law {self.name!r} assumes a circular journal and bearing; non-circular profiles need a "
            "law that integrates the contact over the profile: HybridLaw(placement='fixed')")

    def check(self) -> RESULTS:
        """Traceable range check of the law's numbers, evaluated at run time under ``jit`` and
        ``vmap`` by :func:`~jaxclear.simulate`: the first failing :class:`~jaxclear.RESULTS`
        ``invalid_*`` entry of :meth:`checks`, or ``successful``."""
        return first_failure(*self.checks())

    def checks(self) -> tuple:
        """The law's range checks in order (:class:`~jaxclear._errors.Rule` s, materials): the
        default checks the restitution in (0, 1]; laws with more numbers extend it (one method
        per class). On a concrete law whose check failed, the first failing one says why."""
        return (Rule("restitution", self.restitution, RESULTS.invalid_restitution, low=0.0, high=1.0, low_open=True),)

    def check_geometry(self, radius_bearing: float, radius_journal: float) -> None:
        """Raise :class:`~jaxclear.ParameterError` if the law cannot serve these radii."""

    def stiffness_for(self, radius_bearing, radius_journal):
        """Deprecated spelling of :meth:`stiffness_value`."""
        warnings.warn("law.stiffness_for(...) is deprecated; use law.stiffness_value(...)", DeprecationWarning,
                      stacklevel=2)
        return self.stiffness_value(radius_bearing, radius_journal)


class AbstractModulusLaw(AbstractNormalLaw):
    """A law whose stiffness is the effective modulus :math:`E^*` of the two materials (the line
    contacts of :mod:`.cylindrical` and :mod:`.conformal`): the modulus given, or from the
    materials; its checks."""

    modulus: eqx.AbstractVar[Scalar | None]
    bearing_material: eqx.AbstractVar["Material"]
    journal_material: eqx.AbstractVar["Material"]

    stiffness_parameter: ClassVar[str] = "modulus"
    PARAMETERS: ClassVar[dict[str, Parameter]] = law_parameters("modulus")

    def checks(self) -> tuple:
        """Restitution in (0, 1], E* > 0 (when given), the materials."""
        modulus = 1.0 if self.modulus is None else self.modulus
        return (*super().checks(), Rule("modulus E*", modulus, RESULTS.invalid_stiffness, low=0.0, low_open=True,
                                         unit="Pa"),
                *self.bearing_material.checks("bearing_material"), *self.journal_material.checks("journal_material"))

    def modulus_value(self):
        """:math:`E^*` [Pa]: the given one, or from the materials."""
        return effective_modulus(self.bearing_material, self.journal_material) if self.modulus is None else self.modulus

    def stiffness_value(self, radius_bearing, radius_journal):
        return self.modulus_value()


#: every friction law's named parameters (:func:`friction_parameters` picks a law's)
FRICTION_PARAMETERS = {
    "friction": Parameter("coefficient", "", **NONNEGATIVE, doc="friction coefficient mu"),
    "friction_static": Parameter("static", "", **NONNEGATIVE, doc="static friction coefficient mu_s"),
    "friction_viscous": Parameter("viscous", "s/m", **NONNEGATIVE,
                                  doc="viscous friction coefficient mu_v (per newton of normal force)"),
    "v_stribeck": Parameter("v_stribeck", "m/s", **POSITIVE, doc="Stribeck speed"),
    "stribeck_exponent": Parameter("stribeck_exponent", "", **POSITIVE, doc="exponent of the Stribeck curve"),
    "v_threlfall": Parameter("v_threlfall", "m/s", **POSITIVE, doc="Threlfall speed"),
    "v_transition": Parameter("v_transition", "m/s", **POSITIVE, doc="Brown-McPhee transition speed"),
    "bristle_stiffness": Parameter("bristle_stiffness", "1/m", **POSITIVE,
                                   doc="bristle stiffness sigma_0 (per newton of normal force)"),
    "bristle_damping": Parameter("bristle_damping", "s/m", **NONNEGATIVE,
                                 doc="bristle damping sigma_1 (per newton of normal force)"),
}


def friction_parameters(*names: str) -> dict[str, Parameter]:
    """A friction law's named parameters: ``friction`` (its coefficient) and ``names`` of
    :data:`FRICTION_PARAMETERS`."""
    return {n: FRICTION_PARAMETERS[n] for n in ("friction", *names)}


class AbstractFriction(eqx.Module):
    r"""A tangential (friction) law: :math:`F_T(v_T, F_N)` [N] on the journal along the tangent,
    with :math:`F_T v_T \le 0` (friction never does positive work)."""

    coefficient: eqx.AbstractVar[Scalar]
    #: number of internal states (bristle deflections) the law needs carried in the element's
    #: state; 0 for a memoryless law
    state_size: ClassVar[int] = 0
    #: True for a law that needs the tangential load on the sliding body (Karnopp's stick band),
    #: which no force element knows: the elements refuse such a law (:func:`element_friction`)
    needs_applied_load: ClassVar[bool] = False
    #: named parameters (:mod:`jaxclear.params`): base name -> :class:`~jaxclear._parameters.Parameter`
    PARAMETERS: ClassVar[dict[str, Parameter]] = friction_parameters()

    def state_init(self, dtype=float):
        """Internal state at the start, shape ``(state_size,)`` (zeros: unloaded bristles)."""
        return jnp.zeros((self.state_size,), dtype)

    def force_and_rate(self, state, v_t: Scalar, normal_force: Scalar):
        """``(F_T [N], d state/dt)`` for internal state ``state`` ``(state_size,)``; a memoryless
        law returns ``(self(v_t, normal_force), 0)``."""
        return self(v_t, normal_force), jnp.zeros_like(state)

    def check(self) -> RESULTS:
        """Traceable range check (run time) of :meth:`checks`."""
        return first_failure(*self.checks())

    def checks(self) -> tuple:
        """``invalid_friction`` unless the coefficient is finite and >= 0; laws with more numbers
        extend it (:class:`~jaxclear._errors.Rule` s, in order)."""
        return (Rule("friction coefficient mu", self.coefficient, RESULTS.invalid_friction, low=0.0),)

    def kinks(self, v_t: Scalar) -> Float[Array, " k"]:
        """Switch functions of the slip ``v_t`` [m/s] ``(k,)`` whose sign changes mark the slip
        speeds where the force or its derivative with respect to the slip jumps (a sign
        function, the ends of a dead band or of a linear ramp). The error-controlled
        sensitivities end a step at each (:func:`~jaxclear.elements.memory.kink_fraction`), so
        that no step integrates the tangents across a jump of the law's derivative. Default: a
        smooth law, none."""
        return jnp.zeros((0,), jnp.result_type(v_t))

    @abc.abstractmethod
    def __call__(self, v_t: Scalar, normal_force: Scalar) -> Scalar:
        """Tangential force on the journal [N] for slip ``v_t`` [m/s] and normal force [N]."""


def element_friction(friction: AbstractFriction | None, element: str, default: AbstractFriction) -> AbstractFriction:
    """The friction law a force element ``element`` (its class name, for the message) will use:
    ``default`` for ``None``; a law that needs the tangential load on the sliding body
    (``needs_applied_load``) raises :class:`~jaxclear.ParameterError`. A force element computes
    its contact from its own kinematics only: the sum of the other forces on the journal or
    slider (loads, the constraint reactions, the inertia of the bodies it is linked to, itself
    dependent on the friction force) is known only to the solve of the whole system."""
    if friction is None:
        return default
    if friction.needs_applied_load:
        raise ParameterError(
            f"friction law {type(friction).__name__} cannot be used in a {element}: its stick band balances the "
            "tangential load on the sliding body, which a force element does not know (it depends on the rest of "
            "the mechanism and on the friction force itself). Use 'stribeck', 'brown-mcphee' or the bristle law "
            "'lugre' (which sticks under a load below its static limit) instead")
    return friction
