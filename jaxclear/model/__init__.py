"""What a mechanism is: bodies, ideal joints, drivers, loads and the mechanism itself, with
the constraint equations and point kinematics, and the stateless force elements (springs, dampers,
bushings) among the loads (data and formulas; no integration)."""

from .bodies import GROUND, Body
from .drivers import AbstractDriver, AngleDriver, FunctionDriver, ProfileDriver, crank_driver, crank_period
from .geometry import cross2, dot2, perp, rotate, safe_normal
from .joints import AbstractConstraint, AbstractJoint, Fixed, PointOnLine, Revolute, Translational
from .loads import AbstractLoad, PointForce, Torque, gravity_force
from .._parameters import Parameter
from .connectors import AbstractConnector
from .curves import AbstractCurve, PolynomialCurve, TableCurve
from .spring_damper import TranslationalSpringDamper
from .rotational_spring import RotationalSpringDamper
from .bushing import Bushing
from .discrete_beam import DiscreteBeam
from .profiles import (PROFILE_KINDS, AbstractProfile, ConstantProfile, HarmonicProfile, RampProfile,
                       TableProfile)
from .mechanism import Mechanism, point_acceleration, point_load, point_position, point_velocity
from .flexible_link import bent_link, flexible_link
