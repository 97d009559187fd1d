"""Integration: settings, the state vector, the equations of motion, consistent initial
conditions, diffrax solver wrappers and :func:`simulate`.

The modules of this package are private (``_settings.py``, ``_solve.py``, ...); what the other
packages of jaxclear and its users need is exported here (:data:`__all__`), and the caches of
compiled and traced programs are the public module :mod:`jaxclear.integrate.caches`
(``jaxclear.caches``). The old module paths (``jaxclear.integrate.settings``, ...) still import for
one release, with a ``DeprecationWarning`` on use."""

import importlib as _importlib
import sys as _sys
import types as _types

from .._results import deprecated

from ._assembly import (ASSEMBLY_TEMPLATE, RANK_TOL, Assembly, assemble, check_assembly, initial_state,
                        minimum_norm_correction)
from ._compile import compiler_options, jit, on_trace
from ._dynamics import Baumgarte, accelerations, energy, flat_vector_field, spd_solve, vector_field
from ._kinematics import is_kinematic, kinematic_solution, kinematics_at
from ._runs import (SAMPLES_PER_REVOLUTION, RunWithIdeal, revolution_settings, revolutions_of, simulate_with_ideal,
                    timed_simulate)
from ._sensitivity import along_run, tangent_system
from ._settings import (MAX_OUT_SAMPLES, OPTION_KEYS, Settings, check_settings, default_settings, deprecated_keywords,
                        option_values, settings, settings_from_options, settings_or_default)
from ._strategies import (ADJOINTS, ONSETS, OUTPUTS, SOLVERS, ExactOnsets, SampleBlock, SampleLoop, Sensitivity,
                          StepOnsets, ThroughLoop, from_names)
from ._simulate import check_status, raise_for_status, simulate, solution_structure
from ._solution import Solution
from ._solve import integrate_system, mechanism_system, start_run, stored_solution
from ._solvers import ImpactMemorySolver, OnsetController, UnrolledExplicitRK
from ._state import State
from . import caches

__all__ = [
    # settings and their strategies
    "Settings", "settings", "default_settings", "settings_from_options", "option_values", "deprecated_keywords",
    "check_settings", "settings_or_default",
    "OPTION_KEYS", "MAX_OUT_SAMPLES", "SOLVERS", "ADJOINTS", "OUTPUTS", "ONSETS", "from_names", "Sensitivity",
    "ThroughLoop", "SampleLoop", "SampleBlock", "ExactOnsets", "StepOnsets",
    # a run and its result
    "simulate", "check_status", "raise_for_status", "Solution", "State", "solution_structure",
    # runs by crank revolutions, the ideal-joint companion, kinematic runs
    "revolution_settings", "revolutions_of", "SAMPLES_PER_REVOLUTION", "simulate_with_ideal", "RunWithIdeal",
    "timed_simulate", "is_kinematic", "kinematic_solution", "kinematics_at",
    # assembly and the equations of motion
    "assemble", "initial_state", "check_assembly", "Assembly", "ASSEMBLY_TEMPLATE", "RANK_TOL",
    "minimum_norm_correction", "Baumgarte", "accelerations", "energy", "vector_field", "flat_vector_field", "spd_solve",
    # solver wrappers
    "ImpactMemorySolver", "OnsetController", "UnrolledExplicitRK",
    # runs of a system from a start (the Lyapunov exponents' tangents, chaos/); a run's sensitivity
    # solve along given directions of its parameters (params.sensitivities)
    "start_run", "mechanism_system", "tangent_system", "integrate_system", "stored_solution", "along_run",
    # compilation
    "jit", "on_trace", "compiler_options",
    # the caches of compiled and traced programs (a module)
    "caches",
]

#: The modules of this package before they became private (issue 40): their old paths import
#: for one release, each name read from them with a DeprecationWarning.
_MOVED = ("assembly", "compile", "dynamics", "element_outputs", "kinematics", "programs", "runs", "sampling",
          "sensitivity", "settings", "simulate", "solution", "solve", "solvers", "state", "strategies", "system",
          "versions")


class _OldPath(_types.ModuleType):
    """``jaxclear.integrate.NAME`` (the old public module): reads and writes go to the private
    module ``jaxclear.integrate._NAME``, each read with the one DeprecationWarning
    (:func:`jaxclear._results.deprecated`) naming the public spelling."""

    def __init__(self, name: str):
        super().__init__(f"{__name__}.{name}")
        object.__setattr__(self, "_target", f"{__name__}._{name}")

    def _module(self):
        return _importlib.import_module(object.__getattribute__(self, "_target"))

    def __getattr__(self, attr: str):
        if attr.startswith("__") and attr.endswith("__"):
            raise AttributeError(attr)
        target = object.__getattribute__(self, "_target")
        deprecated(f"{self.__name__}.{attr}", f"jaxclear.integrate.{attr}" if attr in __all__ else
                   f"{target}.{attr} (private: its module is)", stacklevel=2)
        return getattr(self._module(), attr)

    def __setattr__(self, attr: str, value):
        setattr(self._module(), attr, value)

    def __dir__(self):
        return dir(self._module())


for _name in _MOVED:
    _sys.modules.setdefault(f"{__name__}.{_name}", _OldPath(_name))


def __getattr__(name: str):
    """``jaxclear.integrate.runs`` and the other old module paths (see :data:`_MOVED`)."""
    if name in _MOVED:
        return _sys.modules[f"{__name__}.{name}"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
