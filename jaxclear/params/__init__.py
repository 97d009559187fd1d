"""Named parameters and derivatives with respect to them.

:mod:`jaxclear.params.registry`: the one map from a parameter's name (``"joint.c"``,
``"crank.omega"``, ...) to its leaf, composed from the classes' ``PARAMETERS`` declarations
(``names``, ``address``, ``check_name``, ``get``, ``replace``, ``validate``, ...);
:mod:`jaxclear.params.derivatives`: a run's derivatives with respect to named parameters
(``sensitivities``) and the horizon of a derivative. Everything here is what those two modules
export: ``jc.params.replace(mech, "joint.c", 1e-4)``, ``jc.params.names(mech)``."""

from .registry import (BODY_NAMES, COMPONENTS, CONNECTOR_NAMES, DEPRECATED, DERIVED, FRICTION_FIELDS, INFO, LOAD_NAMES,
                       REGISTERED, Address, Parameter, ParameterInfo, address, check_name, closest, from_unconstrained,
                       get, info, is_derived, names, parameter_names, replace, replace_following, replace_many,
                       split_name, to_unconstrained, validate)
from .derivatives import (DerivativeHorizonWarning, amplification, check_names, derivative_horizon,
                          differentiable_names, directions, sensitivities)

__all__ = [
    # the registry
    "Address", "BODY_NAMES", "COMPONENTS", "CONNECTOR_NAMES", "DEPRECATED", "DERIVED", "FRICTION_FIELDS", "INFO",
    "LOAD_NAMES", "Parameter", "ParameterInfo", "REGISTERED", "address", "check_name", "closest", "from_unconstrained",
    "get", "info", "is_derived", "names", "parameter_names", "replace", "replace_following", "replace_many",
    "split_name", "to_unconstrained", "validate",
    # derivatives with respect to named parameters
    "sensitivities", "differentiable_names", "check_names", "directions", "amplification", "derivative_horizon",
    "DerivativeHorizonWarning",
]
