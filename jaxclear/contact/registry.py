"""Every normal contact law selectable by one name (``make_law``), with its parameters and
reference (``describe_laws``, used by ``jaxclear models``)."""

from __future__ import annotations

import inspect

from .._errors import ParameterError
from .base import AbstractNormalLaw, Material
from .conformal import ConformalLaw
from .cylindrical import CylindricalLaw
from .hertz import ContactLaw
from .hybrid import HybridLaw
from .impact import StepDampedImpactLaw
from .kelvin_voigt import KelvinVoigtLaw

_CONFORMAL = ("; F_N = F(delta)(1 + chi_LN(c_r) deltadot/deltadot0); dR = R_B - R_J, E* [Pa] from E, nu if not "
              "given")
_NEWTON = " (F from delta(F) by Newton)"
_HERTZ = "F_N = K delta^n (1 + chi(c_r) deltadot/deltadot0), F_N >= 0; K [N/m^n] from E, nu, radii if not given"

#: name -> (constructor, reference, formula in plain text)
LAWS = {
    "hertz": (ContactLaw, "Hertz (1882)", _HERTZ + "; chi = 0 (elastic)"),
    "hunt-crossley": (ContactLaw, "Hunt & Crossley, J. Appl. Mech. 42 (1975) 440", _HERTZ + "; chi = 3(1 - c_r)/2"),
    "herbert-mcwhannell": (ContactLaw, "Herbert & McWhannell, J. Eng. Ind. 99 (1977) 513",
                           _HERTZ + "; chi = 6(1 - c_r)/((2 c_r - 1)^2 + 3)"),
    "lee-wang": (ContactLaw, "Lee & Wang, J. Eng. Ind. 105 (1983) 292", _HERTZ + "; chi = 3(1 - c_r)/4"),
    "lankarani-nikravesh": (ContactLaw, "Lankarani & Nikravesh, J. Mech. Des. 112 (1990) 369",
                            _HERTZ + "; chi = 3(1 - c_r^2)/4"),
    "gonthier": (ContactLaw, "Gonthier et al., Multibody Syst. Dyn. 11 (2004) 209", _HERTZ + "; chi = (1 - c_r^2)/c_r"),
    "qin-lu": (ContactLaw, "Qin & Lu (Zhiying & Qishao), J. Dyn. Control 4 (2006) 294; as in Machado et al., "
                         "Mech. Mach. Theory 53 (2012) 99",
               _HERTZ + "; chi = 3(1 - c_r^2) exp(2(1 - c_r))/4"),
    "flores": (ContactLaw, "Flores et al., Multibody Syst. Dyn. 25 (2011) 357", _HERTZ + "; chi = 8(1 - c_r)/(5 c_r)"),
    "hu-guo": (ContactLaw, "Hu & Guo, Multibody Syst. Dyn. 35 (2015) 131", _HERTZ + "; chi = 3(1 - c_r)/(4 c_r)"),
    "carvalho-martins": (ContactLaw, "Carvalho & Martins, Mech. Mach. Theory 139 (2019) 174",
                         _HERTZ + "; chi = 3(1 - c_r)(11 - c_r)/(2(1 + 9 c_r))"),
    "impact": (StepDampedImpactLaw, "MSC Adams/Solver IMPACT and STEP functions (step-damped impact force)",
               "F_N = max(K delta^n + step(delta; 0, 0, d_max, c_max) deltadot, 0), cubic step; "
               "restitution not used (c_max [N s/m], d_max [m] set the damping)"),
    "kelvin-voigt": (KelvinVoigtLaw, "Goldsmith, Impact (1960); Machado et al., Mech. Mach. Theory 53 (2012) 99",
                     "F_N = max(k delta + d deltadot, 0), k [N/m], d = 2 zeta sqrt(k m_eff) from c_r"),
    "liu": (CylindricalLaw, "Liu, Zhang, Yang, Mech. Mach. Theory 42 (2007) 183",
            "F_N = (pi/2) E* delta sqrt(delta/(2(c + delta))) L (1 + chi(c_r) deltadot/deltadot0), E* [Pa]"),
    "bai-zhao": (CylindricalLaw, "Bai & Zhao, Int. J. Mech. Sci. 54 (2012) 190",
                 "F_N = K_n(delta) delta^1.5 (1 + chi_QinLu deltadot/deltadot0), "
                 "K_n = (pi E*/8) sqrt(2 delta (3c + 2 delta)^2/(c + delta)^3)"),
    "hybrid": (HybridLaw, "Ma, Qian, Chen, Li, Dynamic analysis of mechanical systems with planar revolute joints "
               "with clearance, Mech. Mach. Theory 94 (2015) 148 (hybrid LN / elastic-foundation Gauss-point model)",
               "F_N = |sum_k w_k (K_f delta_k/h) R_J L u_k| (1 + chi_QinLu deltadot/deltadot0) over Gauss points "
               "on the pin surface, K_f = E(1 - nu)/((1 + nu)(1 - 2 nu)) [Pa]"),
    **{name: (ConformalLaw, ref, formula + _CONFORMAL) for name, (ref, formula) in {
        "johnson": ("Johnson, Contact Mechanics (1985); Pereira et al., Nonlinear Dyn. 63 (2011) 681",
                    "delta = F/(pi L E*) [ln(4 pi L E* dR/F) - 1]" + _NEWTON),
        "radzimovsky": ("Radzimovsky, Univ. Illinois Bull. 408 (1953); Pereira et al. (2011)",
                        "delta = F/(pi L E*) [2/3 + ln(4 R_B/b) + ln(4 R_J/b)], b = 2 sqrt(F R*/(pi L E*))" + _NEWTON),
        "goldsmith": ("Goldsmith, Impact (1960); Pereira et al. (2011)",
                      "delta = F/(pi L E*) [ln(pi E* L^3/(F dR)) + 1]" + _NEWTON),
        "dubowsky-freudenstein": ("Dubowsky & Freudenstein, J. Eng. Ind. 93 (1971) 305; Pereira et al. (2011)",
                                  "delta = F/(pi L E*) [ln(pi E* L^3 dR/(F R_B R_J)) + 1]" + _NEWTON),
        "esdu-78035": ("ESDU-78035 (1978); Pereira et al. (2011)",
                       "delta = F/(L E*) [ln(4 pi L E* dR/F) + 1]" + _NEWTON),
        "pereira": ("Pereira, Ramalho, Ambrosio, Nonlinear Dyn. 63 (2011) 681",
                    "F = K delta^n, K = (0.965 dR + 0.0965) L E*/dR, n = Y dR^-0.005, fitted in mm, N, MPa "
                    "(SI: K [N/m^n] = the fitted K [N/mm^n] x 1000^n)"),
        "persson": ("Persson, PhD thesis, Chalmers (1964); Ciavarella & Decuzzi, Int. J. Solids Struct. 38 (2001) "
                    "4507; Pereira et al. (2011)",
                    "F = pi L E* dR b^2/(1 - b^2), b = tan(eps/2) of the contact arc, arc from the rigid overlap "
                    "cos(eps) = dR/(dR + delta): F = (pi/2) L E* delta; one material (elastic similarity)"),
    }.items()},
}


def _show(value):
    if value is None or isinstance(value, (int, float, str)):
        return repr(value)
    if isinstance(value, Material):
        return f"Material(E={float(value.young):.4g} Pa, nu={float(value.poisson):.3g})"
    return type(value).__name__


def law_names() -> list[str]:
    """Names accepted by :func:`make_law`."""
    return sorted(LAWS)


def make_law(name: str, **kwargs):
    """Build a normal contact law by name; keyword arguments are its parameters. ``stiffness``
    is accepted by every law and goes to the law's stiffness leaf (``K`` of the Hertz family,
    ``k`` of Kelvin-Voigt, ``E*`` of Liu and Bai-Zhao, ``K_f`` of the hybrid model)."""
    if name not in LAWS:
        raise ParameterError(f"unknown contact law {name!r}; valid laws: {law_names()}")
    cls = LAWS[name][0]
    if "stiffness" in kwargs and kwargs["stiffness"] is None:
        del kwargs["stiffness"]
    if "stiffness" in kwargs and cls.stiffness_parameter != "stiffness":
        kwargs[cls.stiffness_parameter] = kwargs.pop("stiffness")
    try:
        return cls(model=name, **kwargs) if cls in (ContactLaw, CylindricalLaw, ConformalLaw) else cls(**kwargs)
    except TypeError as err:
        params = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
        raise ParameterError(f"contact law {name!r}: {err}; its parameters are {params}") from None


def describe_laws() -> list[dict]:
    """One record per law: name, parameters with defaults, reference, formula (plain text)."""
    out = []
    for name, (cls, ref, formula) in sorted(LAWS.items()):
        sig = inspect.signature(cls.__init__)
        params = {k: _show(v.default) for k, v in sig.parameters.items()
                  if k not in ("self", "model") and v.default is not inspect._empty}
        out.append({"name": name, "formula": formula, "reference": ref, "parameters": params,
                    "stiffness_parameter": cls.stiffness_parameter})
    return out
