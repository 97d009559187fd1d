"""Integration: settings, the state vector, the equations of motion, consistent initial
conditions, diffrax solver wrappers and :func:`simulate`."""

from .assembly import Assembly, assemble, check_assembly, initial_state, minimum_norm_correction
from .compile import compiler_options, jit
from .dynamics import Baumgarte, accelerations, energy, flat_vector_field, spd_solve, vector_field
from .settings import Settings, settings
from .strategies import SOLVERS, ExactOnsets, SampleBlock, SampleLoop, Sensitivity, StepOnsets, ThroughLoop
from .simulate import simulate
from .solution import Solution
from .solvers import ImpactMemorySolver, OnsetController, UnrolledExplicitRK
from .state import State
