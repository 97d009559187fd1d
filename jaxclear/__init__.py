"""jaxclear: a differentiable JAX engine for planar mechanisms with clearance joints.

Importing jaxclear switches JAX to double precision (contact penetrations are micrometres),
before JAX starts its backends, asks XLA:CPU to compile small loops as single kernels
(``XLA_FLAGS``; see ``jaxclear/_xla_flags.py``), and keeps compiled and traced programs in the
user's cache folder, so that a new process skips tracing and compilation (``jaxclear/integrate/caches.py``;
``JAXCLEAR_CACHE_DIR=off`` switches that off).
This module only re-exports the public API (``__all__``, each name documented in the API
reference); the implementation lives in subpackages by layer: ``model`` (what a mechanism is)
-> ``contact`` (force laws) -> ``elements`` (force elements with state) -> ``integrate``
(equations of motion, solvers, ``simulate``) -> ``params`` (named parameters, derivatives),
``mechanisms`` (files, presets), ``analysis``, ``io``, ``plot`` -> ``sweep``, ``fitting``,
``designing``, ``tolerance``, ``wearing``, ``chaos`` -> ``cli``. See docs/architecture.md.
"""

from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version
import sys as _sys

import jax

from . import _xla_flags
from ._xla_flags import SlowLoopsWarning, request_host_devices

# before any JAX computation: XLA compiles jaxclear's solver loops as single kernels (see
# jaxclear/_xla_flags.py; JAXCLEAR_SMALL_LOOP_BYTES=0 leaves XLA's default)
_xla_flags.apply()
jax.config.update("jax_enable_x64", True)

from ._errors import (  # noqa: E402
    RESULTS,
    STATUS,
    CheckpointError,
    DesignError,
    FitDataError,
    InitialConditionError,
    JaxclearError,
    MechanismError,
    MissingExtraError,
    OutputLockedError,
    ParameterError,
    SolverError,
)
from ._results import AbstractResult  # noqa: E402
from .contact import (  # noqa: E402
    STEEL,
    AbstractFriction,
    AbstractNormalLaw,
    AmbrosioFriction,
    BrownMcPheeFriction,
    ConformalLaw,
    ContactKinematics,
    ContactLaw,
    CoulombFriction,
    CylindricalLaw,
    DahlFriction,
    FourierProfile,
    Friction,
    HybridLaw,
    KarnoppFriction,
    KelvinVoigtLaw,
    LuGreFriction,
    Material,
    NoFriction,
    SmoothCoulombFriction,
    StepDampedImpactLaw,
    StribeckFriction,
    ThrelfallFriction,
    ViscousFriction,
    describe_laws,
    law_names,
    make_law,
    oval,
)
from .elements import (  # noqa: E402
    AbstractForceElement,
    AbstractJournalJoint,
    ClearanceJoint,
    ContactMemory,
    CornerMemory,
    LubricatedJoint,
    PinSlotJoint,
    TranslationalClearanceJoint,
    kinematics,
)
from .integrate import (  # noqa: E402
    SOLVERS,
    Baumgarte,
    ExactOnsets,
    ImpactMemorySolver,
    OnsetController,
    SampleBlock,
    SampleLoop,
    Sensitivity,
    Settings,
    Solution,
    State,
    StepOnsets,
    ThroughLoop,
    UnrolledExplicitRK,
    accelerations,
    assemble,
    energy,
    initial_state,
    settings,
    simulate,
    vector_field,
)
from .model import (  # noqa: E402
    GROUND,
    AbstractConnector,
    AbstractConstraint,
    AbstractCurve,
    AbstractDriver,
    AbstractJoint,
    AbstractLoad,
    AngleDriver,
    Body,
    Bushing,
    DiscreteBeam,
    Fixed,
    ConstantProfile,
    FunctionDriver,
    HarmonicProfile,
    Mechanism,
    PointForce,
    PointOnLine,
    PolynomialCurve,
    ProfileDriver,
    RampProfile,
    Revolute,
    RotationalSpringDamper,
    TableCurve,
    TableProfile,
    Torque,
    Translational,
    TranslationalSpringDamper,
    bent_link,
    crank_period,
    flexible_link,
)
from .mechanisms.presets import preset, preset_file, preset_names  # noqa: E402
from . import integrate, mechanisms, params, plot  # noqa: E402

#: The modules that moved into a package (issue 40) under their old names, the same module objects:
#: ``jc.presets``, ``import jaxclear.caches``, ``from jaxclear.mechanism_files import ...`` keep working
#: without a warning (documented spellings); docs/architecture.md names each one's home.
_HOMES = {"caches": integrate.caches, "derivatives": params.derivatives, "presets": mechanisms.presets,
          "mechanism_files": mechanisms.files, "profile_tables": mechanisms.tables, "drawing": plot.drawing,
          "profile_figures": plot.profiles}
for _old, _module in _HOMES.items():
    _sys.modules[f"{__name__}.{_old}"] = _module
    globals()[_old] = _module
caches = integrate.caches
from .integrate.caches import cache_folder, clear_cache, disable_cache, enable_cache  # noqa: E402

# compiled and traced programs kept across processes by default (JAXCLEAR_CACHE_DIR=off: not)
caches.enable_at_import()

from .params.derivatives import (  # noqa: E402
    DerivativeHorizonWarning,
    amplification,
    derivative_horizon,
    differentiable_names,
    sensitivities,
)
from .mechanisms.files import load_mechanism, save_mechanism  # noqa: E402
from .plot.drawing import animate, plot_mechanism  # noqa: E402
from .analysis.channels import channel  # noqa: E402
from .analysis.structure import check_mechanism  # noqa: E402
from .sweep import SweepConfig, SweepResult, load_config, read_results, run_sweep  # noqa: E402
from .io import Measurements, read_measurements, timeseries_frame  # noqa: E402
from .analysis import Accelerometer  # noqa: E402
from .fitting import FitChannel, FitResult, fit, levenberg_marquardt, parameter_grad, synthetic_record  # noqa: E402
from .fitting import PosteriorResult, posterior  # noqa: E402
from .fitting import StatisticsFitResult, fit_statistics  # noqa: E402
from .tolerance import Inputs, ToleranceResult, inputs_from_dict, tolerance_study  # noqa: E402
from .wearing import WearHistory, WearOptions, plot_wear, wear  # noqa: E402
from .designing import DesignResult, Ensemble, OperatingPoint, RuggedObjectiveWarning, SteadyOperation, design  # noqa: E402
from . import chaos  # noqa: E402
from .analysis.sections import detect_period, period_name, section as poincare_section  # noqa: E402
from .chaos import (  # noqa: E402
    LyapunovError,
    LyapunovMap,
    LyapunovResult,
    lyapunov,
    lyapunov_map,
    psd,
    rosenstein,
    steady_derivatives,
    zero_one_test,
)

#: The public API: every name here is documented in the API reference (docs/api/index.md lists them by
#: page; tests/test_docs.py checks both). Grouped by the page that documents them.
__all__ = [
    # Model (docs/api/model.md)
    "Body", "Revolute", "Translational", "Fixed", "PointOnLine", "AngleDriver", "FunctionDriver", "ProfileDriver",
    "ConstantProfile", "RampProfile", "HarmonicProfile", "TableProfile", "PointForce", "Torque",
    "TranslationalSpringDamper", "PolynomialCurve", "TableCurve", "RotationalSpringDamper", "Bushing", "DiscreteBeam",
    "flexible_link", "bent_link",
    "Mechanism",
    "GROUND", "crank_period", "AbstractConstraint", "AbstractJoint", "AbstractDriver", "AbstractLoad",
    "AbstractConnector", "AbstractCurve",
    # Contact laws (contact.md)
    "make_law", "law_names", "describe_laws", "ContactLaw", "KelvinVoigtLaw", "CylindricalLaw", "ConformalLaw",
    "StepDampedImpactLaw", "HybridLaw", "FourierProfile", "oval", "Material", "STEEL", "ContactKinematics",
    "AbstractNormalLaw", "Friction", "AmbrosioFriction", "CoulombFriction", "SmoothCoulombFriction", "NoFriction",
    "ViscousFriction", "StribeckFriction", "ThrelfallFriction", "BrownMcPheeFriction", "KarnoppFriction",
    "DahlFriction", "LuGreFriction", "AbstractFriction",
    # Force elements (elements.md)
    "ClearanceJoint", "LubricatedJoint", "TranslationalClearanceJoint", "PinSlotJoint", "ContactMemory",
    "CornerMemory", "kinematics", "AbstractForceElement", "AbstractJournalJoint",
    # Integration (integrate.md)
    "simulate", "settings", "Settings", "Solution", "State", "SOLVERS", "Baumgarte", "ImpactMemorySolver",
    "OnsetController", "UnrolledExplicitRK", "Sensitivity", "ThroughLoop", "SampleLoop", "SampleBlock",
    "ExactOnsets", "StepOnsets", "initial_state", "assemble", "accelerations", "vector_field", "energy",
    "enable_cache", "disable_cache", "clear_cache", "cache_folder",
    # Parameters, derivatives, presets, mechanism files (params.md)
    "preset", "preset_names", "preset_file", "sensitivities", "differentiable_names", "amplification",
    "derivative_horizon", "DerivativeHorizonWarning", "load_mechanism", "save_mechanism",
    # Analysis (analysis.md)
    "Accelerometer", "channel", "check_mechanism",
    # Input/output and plots (io.md)
    "timeseries_frame", "read_measurements", "Measurements", "plot_mechanism", "animate",
    # Sweeps (sweep.md)
    "SweepConfig", "load_config", "run_sweep", "read_results", "SweepResult",
    # Fitting (fit.md)
    "fit", "FitResult", "FitChannel", "synthetic_record", "levenberg_marquardt", "parameter_grad", "fit_statistics",
    "StatisticsFitResult",
    # Uncertainty (uncertainty.md)
    "posterior", "PosteriorResult", "tolerance_study", "ToleranceResult", "Inputs", "inputs_from_dict",
    # Wear (wear.md)
    "wear", "WearOptions", "WearHistory", "plot_wear",
    # Design (design.md)
    "design", "DesignResult", "OperatingPoint", "Ensemble", "SteadyOperation", "RuggedObjectiveWarning",
    # Chaos (chaos.md)
    "lyapunov", "lyapunov_map", "LyapunovResult", "LyapunovMap", "LyapunovError", "steady_derivatives", "psd",
    "zero_one_test",
    "rosenstein", "poincare_section", "detect_period", "period_name",
    # Errors, status codes, host devices (index.md)
    "JaxclearError", "ParameterError", "FitDataError", "DesignError", "MechanismError", "InitialConditionError",
    "SolverError", "CheckpointError", "OutputLockedError", "MissingExtraError", "RESULTS", "STATUS",
    "SlowLoopsWarning", "request_host_devices",
    # The protocol of every driver's result (index.md)
    "AbstractResult",
]

try:
    __version__ = _version("jaxclear")
except _PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0+unknown"
