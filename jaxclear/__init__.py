"""jaxclear: a differentiable JAX engine for planar mechanisms with revolute clearance joints.

Importing jaxclear switches JAX to double precision (contact penetrations are micrometres).
"""

import jax

jax.config.update("jax_enable_x64", True)

from .clearance import ClearanceJoint, ContactKinematics, ContactMemory, kinematics  # noqa: E402
from .contact.friction import Friction  # noqa: E402
from .contact.hybrid import FourierProfile, HybridLaw, oval  # noqa: E402
from .contact.laws import STEEL, ContactLaw, CylindricalLaw, KelvinVoigtLaw, Material  # noqa: E402
from .contact.registry import describe_laws, law_names, make_law  # noqa: E402
from .dynamics import Baumgarte, State, accelerations, energy, vector_field  # noqa: E402
from .errors import (  # noqa: E402
    InitialConditionError,
    JaxclearError,
    MechanismError,
    ParameterError,
    SolverError,
)
from .mechanism import (  # noqa: E402
    GROUND,
    AngleDriver,
    Body,
    Fixed,
    FunctionDriver,
    Mechanism,
    PointForce,
    Revolute,
    Torque,
    Translational,
)
from .presets import preset, preset_names  # noqa: E402
from .solve import (  # noqa: E402
    SOLVERS,
    STATUS,
    ImpactMemorySolver,
    Settings,
    Solution,
    UnrolledExplicitRK,
    assemble,
    crank_period,
    initial_state,
    settings,
    simulate,
)
from .sweep import SweepConfig, SweepResult, load_config, read_results, run_sweep  # noqa: E402
from .io import Measurements, read_measurements  # noqa: E402
from .sensor import Accelerometer  # noqa: E402
from .fitting import FitResult, fit, levenberg_marquardt, parameter_grad, synthetic_record  # noqa: E402

__version__ = "0.1.0"
