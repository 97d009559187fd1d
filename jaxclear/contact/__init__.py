"""Contact laws: normal-force laws (Hertz family, Kelvin-Voigt, cylindrical, the hybrid
Gauss-point model), friction laws, and the registry that names them."""

from .base import STEEL, AbstractFriction, AbstractNormalLaw, ContactKinematics, Material, effective_modulus
from .bristle import DahlFriction, LuGreFriction
from .conformal import ConformalLaw
from .cylindrical import CylindricalLaw
from .friction import (
    AmbrosioFriction,
    CoulombFriction,
    Friction,
    NoFriction,
    SmoothCoulombFriction,
)
from .friction_laws import (
    BrownMcPheeFriction,
    KarnoppFriction,
    StribeckFriction,
    ThrelfallFriction,
    ViscousFriction,
)
from .hertz import HYSTERESIS_FACTORS, ContactLaw
from .impact import StepDampedImpactLaw
from .hybrid import FourierProfile, HybridLaw, matched_thickness, oval
from .kelvin_voigt import KelvinVoigtLaw
from .registry import describe_laws, law_names, make_law
