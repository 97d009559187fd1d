"""Every normal contact law selectable by one name (``make_law``), with its parameters and
reference (``describe_laws``, used by ``jaxclear models``)."""

from __future__ import annotations

import inspect

from ..errors import ParameterError
from .hybrid import HybridLaw
from .laws import HYSTERESIS_FACTORS, BaiZhaoLaw, ContactLaw, KelvinVoigtLaw, LiuLaw

#: name -> (constructor, one-line reference)
LAWS = {
    "hertz": (ContactLaw, "Hertz (1882), elastic, chi = 0"),
    "hunt-crossley": (ContactLaw, "Hunt & Crossley, J. Appl. Mech. 42 (1975) 440"),
    "herbert-mcwhannell": (ContactLaw, "Herbert & McWhannell, J. Eng. Ind. 99 (1977) 513"),
    "lee-wang": (ContactLaw, "Lee & Wang, J. Eng. Ind. 105 (1983) 292"),
    "lankarani-nikravesh": (ContactLaw, "Lankarani & Nikravesh, J. Mech. Des. 112 (1990) 369"),
    "gonthier": (ContactLaw, "Gonthier et al., Multibody Syst. Dyn. 11 (2004) 209"),
    "qin-lu": (ContactLaw, "Zhiying & Qishao, Sci. China Ser. E 49 (2006) 600"),
    "flores": (ContactLaw, "Flores et al., Multibody Syst. Dyn. 25 (2011) 357"),
    "kelvin-voigt": (KelvinVoigtLaw, "linear spring-damper; d from c_r (Machado et al. 2012)"),
    "liu": (LiuLaw, "Liu, Zhang, Yang, Mech. Mach. Theory 42 (2007) 183, improved elastic foundation"),
    "bai-zhao": (BaiZhaoLaw, "Bai & Zhao, Int. J. Mech. Sci. 54 (2012) 190"),
    "hybrid": (HybridLaw, "the seed paper: LN framework, Winkler stiffness, Qin-Lu damping, Gauss points"),
}


def law_names() -> list[str]:
    """Names accepted by :func:`make_law`."""
    return sorted(LAWS)


def make_law(name: str, **kwargs):
    """Build a normal contact law by name; keyword arguments are its parameters. ``stiffness``
    is accepted by every law and goes to the law's stiffness leaf (``K`` of the Hertz family,
    ``k`` of Kelvin-Voigt, ``E*`` of Liu and Bai-Zhao, ``K_f`` of the hybrid model)."""
    if name not in LAWS:
        raise ParameterError(f"unknown contact law {name!r}; valid laws: {law_names()}")
    cls, _ = LAWS[name]
    if "stiffness" in kwargs and kwargs["stiffness"] is None:
        del kwargs["stiffness"]
    if "stiffness" in kwargs and getattr(cls, "stiffness_field", "stiffness") != "stiffness":
        kwargs[cls.stiffness_field] = kwargs.pop("stiffness")
    if cls is ContactLaw:
        return ContactLaw(model=name, **kwargs)
    try:
        return cls(**kwargs)
    except TypeError as err:
        params = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
        raise ParameterError(f"contact law {name!r}: {err}; its parameters are {params}") from None


def describe_laws() -> list[dict]:
    """One record per law: name, parameters with defaults, reference, formula line."""
    out = []
    for name, (cls, ref) in sorted(LAWS.items()):
        sig = inspect.signature(cls.__init__)
        params = {k: (None if v.default is inspect._empty else v.default) for k, v in sig.parameters.items()
                  if k not in ("self", "model")}
        doc = (cls.__doc__ or "").strip().splitlines()[0]
        if cls is ContactLaw:
            doc = f"F_N = K delta^n (1 + chi(c_r) deltadot/deltadot0), chi: {HYSTERESIS_FACTORS[name].__doc__.split(':math:')[-1].strip()}"
        out.append({"name": name, "parameters": {k: repr(v) for k, v in params.items()}, "reference": ref, "formula": doc})
    return out
