r"""Optimal design through impacts: minimise an objective of simulations of a mechanism with
clearance joints over named design variables, within bounds and under constraints, with
gradients through the simulations (theory: docs/theory/design.md).

:func:`design` (``jaxclear design`` on the command line) works like this:

* the variables are :mod:`jaxclear.params` names with intervals (masses, centroid offsets
  ``centroid_x:BODY``, point coordinates, clearance, contact-law and friction parameters,
  crank speed), mapped to the unit cube (:mod:`.variables`);
* an evaluation simulates every operating point times every ensemble member in one program
  (mapped; :mod:`.problem`) and reduces them to the objective (:mod:`.objectives`) and the
  constraints' residuals (:mod:`.constraints`);
* its Jacobian is one linearisation: under the default ``Settings(derivatives=Sensitivity())`` an
  error-controlled forward-sensitivity solve per run, through the impacts;
* SciPy's L-BFGS-B (bounds) or SLSQP (bounds and constraints) drive it (:mod:`.optimize`);
  every evaluation goes to a journal first, so a design resumes bit for bit (:mod:`.journal`);
* the result reports the design, the objective and each constraint, the gradient norm, the
  sensitivity of the optimum to each variable, the horizon of predictability (:mod:`.chaos`)
  and a before/after figure (:mod:`.report`, :mod:`.figures`, :mod:`.result`);
* ``steady=SteadyOperation(...)``: the objective averaged over steady operation, its gradient by
  least-squares shadowing (:mod:`.steady`).
"""

from .chaos import RuggedObjectiveWarning
from .constraints import (AbstractDesignConstraint, Assembles, PeakForce, PeakPenetration, TotalMass,
                          UserConstraint, constraint)
from .driver import design
from .journal import JOURNAL_NAME
from .objectives import (OBJECTIVES, AbstractObjective, DissipatedEnergy, FreeFlightFraction, RmsDeviation,
                         SmoothPeakForce, UserObjective, objective)
from .optimize import METHODS
from .problem import DesignProblem, Ensemble, OperatingPoint, evaluate, evaluate_with_jacobian
from .result import OUTCOMES, DesignResult
from .steady import SteadyOperation
from .variables import Variable, check_variables, design_names

__all__ = [
    "AbstractDesignConstraint", "AbstractObjective", "Assembles", "DesignProblem", "DesignResult", "DissipatedEnergy",
    "Ensemble", "FreeFlightFraction", "JOURNAL_NAME", "METHODS", "OBJECTIVES", "OUTCOMES", "OperatingPoint", "PeakForce",
    "PeakPenetration", "RmsDeviation", "RuggedObjectiveWarning", "SmoothPeakForce", "SteadyOperation", "TotalMass", "UserConstraint", "UserObjective",
    "Variable", "check_variables", "constraint", "design", "design_names", "evaluate", "evaluate_with_jacobian",
    "objective",
]


def __getattr__(name: str):
    """``STATUSES``, deprecated (:data:`~jaxclear.designing.result.OUTCOMES`)."""
    if name == "STATUSES":
        from . import result

        return result.__getattr__(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
