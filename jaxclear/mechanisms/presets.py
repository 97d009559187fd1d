"""Reference mechanisms, each with its source. Values are presets to start from, not truths
to tune to (the values commonly reported in the papers named in each docstring). Every preset
takes keyword overrides; :func:`preset` builds one by name."""

from __future__ import annotations

import inspect

import math
from pathlib import Path

import numpy as np

from ..elements import ClearanceJoint, LubricatedJoint, PinSlotJoint, TranslationalClearanceJoint
from ..contact import Friction
from ..contact import make_law
from .._errors import ParameterError, check_range
from .._units import rpm_to_rad_s
from .files import save_mechanism
from ..model import GROUND, AngleDriver, Body, Mechanism, Revolute, Translational


#: the lubricated joint's options of a preset, with their defaults (those of :class:`LubricatedJoint`)
FILM_OPTIONS = {"film": "half", "blend_start": 0.95, "blend_end": 0.99}


def _film_options(viscosity, film, blend_start, blend_end) -> dict:
    """The film options given to a preset, checked: they need ``viscosity`` (a lubricated joint)."""
    given = {k: v for k, v in (("film", film), ("blend_start", blend_start), ("blend_end", blend_end)) if v is not None}
    if given and viscosity is None:
        raise ParameterError(f"{sorted(given)} set the oil film of a lubricated joint: give viscosity [Pa s] "
                             "too (without it the joint is dry)")
    return {**FILM_OPTIONS, **given}


def _clearance_joint(name, bearing, bearing_point, journal, journal_point, *, bearing_radius, clearance,
                     law, restitution, stiffness, friction, length, law_options, viscosity=None, film_options=None):
    check_range("clearance", clearance, low=0.0, low_open=True, unit="m")
    check_range("bearing_radius", bearing_radius, low=0.0, low_open=True, unit="m")
    if clearance >= bearing_radius:
        raise ParameterError(
            f"clearance = {clearance:g} m must be smaller than bearing_radius = {bearing_radius:g} m "
            "(the journal radius R_B - c must stay positive)"
        )
    if viscosity is not None:
        return LubricatedJoint(
            bearing, bearing_point, journal, journal_point, bearing_radius=bearing_radius,
            journal_radius=bearing_radius - clearance, length=length, viscosity=viscosity,
            law=make_law(law, restitution=restitution, stiffness=stiffness, **(law_options or {})),
            friction=Friction(friction), name=name, **(film_options or FILM_OPTIONS),
        )
    return ClearanceJoint(
        bearing,
        bearing_point,
        journal,
        journal_point,
        bearing_radius=bearing_radius,
        journal_radius=bearing_radius - clearance,
        length=length,
        law=make_law(law, restitution=restitution, stiffness=stiffness, **(law_options or {})),
        friction=Friction(friction),
        name=name,
    )


def _slider_crank(*, name, crank_length, crank_mass, crank_inertia, rod_length, rod_mass, rod_inertia,
                  slider_mass, slider_inertia, speed_rpm, clearance, bearing_radius, length, law,
                  restitution, stiffness, friction, ideal, gravity, law_options, viscosity=None, film_options=None):
    r, l = crank_length, rod_length
    check_range("crank_length", r, low=0.0, low_open=True, unit="m")
    check_range("rod_length", l, low=r, low_open=True, unit="m")
    crank = Body("crank", crank_mass, crank_inertia, {"O": (-r / 2, 0.0), "A": (r / 2, 0.0)}, (r / 2, 0.0, 0.0))
    rod = Body("rod", rod_mass, rod_inertia, {"A": (-l / 2, 0.0), "B": (l / 2, 0.0)}, (r + l / 2, 0.0, 0.0))
    slider = Body("slider", slider_mass, slider_inertia, {"B": (0.0, 0.0)}, (r + l, 0.0, 0.0))
    joints = [
        Revolute(GROUND, "O", "crank", "O"),
        Revolute("crank", "A", "rod", "A"),
        Translational(GROUND, "rail", "slider", "B", axis=(1.0, 0.0)),
    ]
    clearance_joints = []
    if ideal:
        joints.append(Revolute("rod", "B", "slider", "B"))
    else:
        clearance_joints.append(
            _clearance_joint("rod-slider", "slider", "B", "rod", "B", bearing_radius=bearing_radius,
                             clearance=clearance, law=law, restitution=restitution, stiffness=stiffness,
                             friction=friction, length=length, law_options=law_options, viscosity=viscosity,
                             film_options=film_options)
        )
    return Mechanism(
        bodies=[crank, rod, slider],
        joints=joints,
        drivers=[AngleDriver("crank", rpm_to_rad_s(speed_rpm))],
        clearance_joints=clearance_joints,
        gravity=gravity,
        ground_points={"O": (0.0, 0.0), "rail": (0.0, 0.0)},
        name=name + ("-ideal" if ideal else ""),
        roles={"crank": "crank", "rod": "rod", "slider": "slider"},
    )


def flores_slider_crank(
    clearance=0.5e-3,
    restitution=0.9,
    friction=0.0,
    speed_rpm=5000.0,
    law="lankarani-nikravesh",
    stiffness=None,
    ideal=False,
    crank_inertia=1e-4,
    bearing_radius=0.010,
    length=0.010,
    gravity=(0.0, -9.81),
    law_options=None,
    viscosity=None,
    film=None,
    blend_start=None,
    blend_end=None,
):
    """The Flores benchmark slider-crank with a clearance in the rod-slider joint.

    Source: P. Flores, J. Ambrósio, J.C.P. Claro, H.M. Lankarani, "Kinematics and Dynamics of
    Multibody Systems with Imperfect Joints", Springer 2008, sec. 4.7; P. Flores, Nonlinear Dyn.
    61 (2010) 633-653. Crank 0.05 m, 0.30 kg, J = 1e-4 kg m^2 (some papers print 1e-5; pass
    ``crank_inertia``); rod 0.12 m, 0.21 kg, 2.5e-4 kg m^2; slider 0.14 kg, 1e-4 kg m^2;
    centroids at mid-length; crank at 5000 rpm; bearing (on the slider) radius 10 mm, journal
    (on the rod) radius 9.5 mm (c = 0.5 mm); steel E = 207 GPa, nu = 0.3; c_r = 0.9;
    Baumgarte alpha = beta = 5 (the default Settings). Joint length 10 mm (used only by the
    cylindrical laws). Starts at crank angle 0 with the journal centred.

    ``viscosity`` [Pa s] (default None: dry) makes the rod-slider joint a
    :class:`~jaxclear.LubricatedJoint`, the lubricated benchmark of Flores, Ambrósio, Claro,
    Lankarani, Koshy, Nonlinear Dyn. 56 (2009) 277-295 (their oil: 400 cP = 0.4 Pa s): a
    short-bearing film whose width is the joint's ``length`` (10 mm unless given: pass
    ``length`` for another film width), the dry law taking over at contact. ``film`` (default
    ``"half"``; ``"pi"`` for the classical fixed film of the literature) and ``blend_start``,
    ``blend_end`` (default 0.95, 0.99) set the film as :class:`~jaxclear.LubricatedJoint` does;
    they need ``viscosity``.
    """
    return _slider_crank(
        name="flores-slider-crank", crank_length=0.05, crank_mass=0.30, crank_inertia=crank_inertia,
        rod_length=0.12, rod_mass=0.21, rod_inertia=2.5e-4, slider_mass=0.14, slider_inertia=1e-4,
        speed_rpm=speed_rpm, clearance=clearance, bearing_radius=bearing_radius, length=length, law=law,
        restitution=restitution, stiffness=stiffness, friction=friction, ideal=ideal, gravity=gravity,
        law_options=law_options, viscosity=viscosity,
        film_options=_film_options(viscosity, film, blend_start, blend_end),
    )


def flores_2011_rig(
    clearance=0.5e-3,
    restitution=0.9,
    friction=0.01,
    speed_rpm=200.0,
    law="lankarani-nikravesh",
    stiffness=None,
    ideal=False,
    bearing_radius=0.010,
    length=0.020,
    gravity=(0.0, -9.81),
    law_options=None,
):
    """The experimental slider-crank rig of Flores, Koshy, Lankarani, Ambrósio, Claro, "Numerical
    and experimental investigation on multibody systems with revolute clearance joints",
    Nonlinear Dyn. 65 (2011) 383-398 (approximate values; the rig's full data are not published): crank 0.05 m with
    flywheel (17.9 kg, 0.46 kg m^2), rod 0.30 m (1.13 kg, 0.0153 kg m^2), slider 1.01 kg;
    clearance in the rod-slider joint (0.25 to 1.0 mm studied); about 200 rpm. Bearing radius,
    joint length, slider inertia (irrelevant: the slider does not rotate) and friction are our
    assumptions.
    """
    return _slider_crank(
        name="flores-2011-rig", crank_length=0.05, crank_mass=17.9, crank_inertia=0.46, rod_length=0.30,
        rod_mass=1.13, rod_inertia=0.0153, slider_mass=1.01, slider_inertia=1e-3, speed_rpm=speed_rpm,
        clearance=clearance, bearing_radius=bearing_radius, length=length, law=law, restitution=restitution,
        stiffness=stiffness, friction=friction, ideal=ideal, gravity=gravity, law_options=law_options,
    )


def four_bar(
    clearance=0.5e-3,
    restitution=0.9,
    friction=0.0,
    speed_rpm=500.0,
    law="lankarani-nikravesh",
    stiffness=None,
    ideal=False,
    crank_angle=math.pi / 3,
    bearing_radius=0.010,
    length=0.010,
    gravity=(0.0, -9.81),
    law_options=None,
):
    """A Grashof crank-rocker four-bar with a clearance joint between coupler and rocker.

    Geometry and masses are chosen for this library (slender steel-like links, centroids at
    mid-length, J = m L^2 / 12), not taken from a paper: crank 0.10 m / 0.2 kg, coupler 0.35 m /
    0.5 kg, rocker 0.25 m / 0.4 kg, ground 0.30 m; crank at 500 rpm starting at 60 degrees. The
    clearance joint (bearing on the rocker, journal on the coupler) uses the same steel joint as
    the Flores benchmark. The start configuration is the upper assembly branch.
    """
    a, b, c, d = 0.10, 0.35, 0.25, 0.30
    masses = {"crank": 0.2, "coupler": 0.5, "rocker": 0.4}
    th = float(crank_angle)
    A = np.array([a * math.cos(th), a * math.sin(th)])
    O4 = np.array([d, 0.0])
    # B: intersection of |B - A| = b and |B - O4| = c, upper branch
    dist = np.linalg.norm(O4 - A)
    x = (dist**2 + b**2 - c**2) / (2 * dist)
    h = math.sqrt(max(b**2 - x**2, 0.0))
    u = (O4 - A) / dist
    B = A + x * u + h * np.array([-u[1], u[0]])
    ang = lambda p, q: math.atan2(q[1] - p[1], q[0] - p[0])  # noqa: E731
    crank = Body("crank", masses["crank"], masses["crank"] * a**2 / 12, {"O": (-a / 2, 0), "A": (a / 2, 0)},
                 (*(A / 2), th))
    coupler = Body("coupler", masses["coupler"], masses["coupler"] * b**2 / 12, {"A": (-b / 2, 0), "B": (b / 2, 0)},
                   (*((A + B) / 2), ang(A, B)))
    rocker = Body("rocker", masses["rocker"], masses["rocker"] * c**2 / 12, {"O": (-c / 2, 0), "B": (c / 2, 0)},
                  (*((O4 + B) / 2), ang(O4, B)))
    joints = [
        Revolute(GROUND, "O2", "crank", "O"),
        Revolute("crank", "A", "coupler", "A"),
        Revolute(GROUND, "O4", "rocker", "O"),
    ]
    clearance_joints = []
    if ideal:
        joints.append(Revolute("coupler", "B", "rocker", "B"))
    else:
        clearance_joints.append(
            _clearance_joint("coupler-rocker", "rocker", "B", "coupler", "B", bearing_radius=bearing_radius,
                             clearance=clearance, law=law, restitution=restitution, stiffness=stiffness,
                             friction=friction, length=length, law_options=law_options)
        )
    return Mechanism(
        bodies=[crank, coupler, rocker],
        joints=joints,
        drivers=[AngleDriver("crank", rpm_to_rad_s(speed_rpm), angle0=th)],
        clearance_joints=clearance_joints,
        gravity=gravity,
        ground_points={"O2": (0.0, 0.0), "O4": (d, 0.0)},
        name="four-bar" + ("-ideal" if ideal else ""),
        roles={"crank": "crank", "rocker": "rocker"},
    )


def slider_crank_guide_clearance(
    clearance=0.1e-3,
    restitution=0.9,
    friction=0.0,
    speed_rpm=1000.0,
    law="lankarani-nikravesh",
    stiffness=4.8e9,
    ideal=False,
    slider_length=0.05,
    slider_height=0.03,
    gravity=(0.0, -9.81),
):
    r"""The benchmark slider-crank (links, masses and inertias of :func:`flores_slider_crank`,
    every revolute joint ideal) with a clearance in the slider's guide: a
    :class:`~jaxclear.TranslationalClearanceJoint`, the system studied by Flores, Ambrósio,
    Claro, Lankarani, "Translational joints with clearance in rigid multibody systems",
    J. Comput. Nonlinear Dyn. 3 (2008) 011007.

    Stated values (ours, not the paper's): block 50 mm long and 30 mm high centred on the rod-slider
    pin, clearance 0.1 mm per side, corners with the Lankarani-Nikravesh law, c_r = 0.9 and
    K = 4.8e9 N/m^1.5 (Hertz sphere on plane, :math:`K = (4/3)E^*\sqrt{r}` with a 1 mm corner
    radius and steel, :math:`E^* = E/(2(1-\nu^2))`), no friction, crank at 1000 rpm; the slider
    starts centred in its guide.
    """
    check_range("clearance", clearance, low=0.0, low_open=True, unit="m")
    base = flores_slider_crank(speed_rpm=speed_rpm, ideal=True, gravity=gravity)
    name = "slider-crank-guide-clearance"
    if ideal:
        return Mechanism(base.bodies, base.joints, base.drivers, gravity=base.gravity, ground_points=base.ground_points,
                         name=name + "-ideal", roles=dict(base.roles))
    guide = TranslationalClearanceJoint(
        GROUND, "rail", "slider", "B", slider_length=slider_length, slider_height=slider_height,
        guide_width=slider_height + 2 * clearance, law=make_law(law, restitution=restitution, stiffness=stiffness),
        friction=Friction(friction), name="guide",
    )
    joints = [j for j in base.joints if not isinstance(j, Translational)]
    return Mechanism(base.bodies, joints, base.drivers, [guide], gravity=base.gravity, ground_points=base.ground_points,
                     name=name, roles=dict(base.roles))


def slider_crank_pin_slot(
    slot_length=1e-3,
    clearance=0.5e-3,
    restitution=0.9,
    friction=0.0,
    speed_rpm=1000.0,
    law="lankarani-nikravesh",
    stiffness=None,
    ideal=False,
    bearing_radius=0.010,
    length=0.010,
    gravity=(0.0, -9.81),
):
    """The benchmark slider-crank of :func:`flores_slider_crank` whose rod-slider joint is a pin
    in a slot (:class:`~jaxclear.PinSlotJoint`; the pin-slot clearance joint of Škrinjar, Slavič,
    Boltežar, Nonlinear Dyn. 88 (2017) 131-143).

    Stated values (ours): the slot, on the slider, runs along the stroke with a straight length
    of 1 mm and a width of 20 mm; pin radius 9.5 mm (clearance 0.5 mm), steel, Lankarani-Nikravesh
    with c_r = 0.9 and the cylindrical stiffness of the benchmark joint; crank at 1000 rpm; the
    pin starts centred. ``ideal=True`` gives the benchmark's ideal mechanism.
    """
    check_range("slot_length", slot_length, low=0.0, unit="m")
    base = flores_slider_crank(clearance=clearance, restitution=restitution, friction=friction, speed_rpm=speed_rpm,
                               law=law, stiffness=stiffness, ideal=ideal, bearing_radius=bearing_radius,
                               length=length, gravity=gravity)
    if ideal:
        return base
    dry = base.clearance_joints[0]
    slot = PinSlotJoint(dry.bearing_body, dry.bearing_point, dry.journal_body, dry.journal_point,
                        bearing_radius=dry.bearing_radius, journal_radius=dry.journal_radius, slot_length=slot_length,
                        axis=(1.0, 0.0), length=dry.length, law=dry.law, friction=dry.friction, name="rod-slider-slot")
    return Mechanism(base.bodies, base.joints, base.drivers, [slot], gravity=base.gravity,
                     ground_points=base.ground_points, name="slider-crank-pin-slot", roles=dict(base.roles))


PRESETS = {
    "flores-slider-crank": flores_slider_crank,
    "flores-2011-rig": flores_2011_rig,
    "four-bar": four_bar,
    "slider-crank-guide-clearance": slider_crank_guide_clearance,
    "slider-crank-pin-slot": slider_crank_pin_slot,
}


def preset_names() -> list[str]:
    """Names accepted by :func:`preset` (add ``ideal=True`` for the ideal-joint variant)."""
    return sorted(PRESETS)


def preset(name: str, **overrides) -> Mechanism:
    """Build a preset mechanism by name with keyword overrides (``clearance``, ``restitution``,
    ``friction``, ``speed_rpm``, ``law``, ``stiffness``, ``ideal``...)."""
    if name not in PRESETS:
        raise ParameterError(f"unknown preset {name!r}; valid presets: {preset_names()}")
    unknown = sorted(set(overrides) - set(inspect.signature(PRESETS[name]).parameters))
    if unknown and not any(p.kind is p.VAR_KEYWORD for p in inspect.signature(PRESETS[name]).parameters.values()):
        raise ParameterError(
            f"unknown option(s) {unknown} for preset {name!r}; valid: "
            f"{sorted(inspect.signature(PRESETS[name]).parameters)}"
        )
    return PRESETS[name](**overrides)


#: The presets as mechanism files, shipped inside the package (generated from the functions
#: above by :func:`write_preset_files`; a test checks that each file reads back equal).
PRESET_DIR = Path(__file__).parent


def preset_file(name: str) -> Path:
    """Path of the shipped mechanism file of preset ``name`` (default parameters)."""
    if name not in PRESETS:
        raise ParameterError(f"unknown preset {name!r}; valid presets: {preset_names()}")
    return PRESET_DIR / f"{name}.toml"


def write_preset_files(directory=PRESET_DIR) -> list[str]:
    """(Re)write the shipped preset files from the preset functions; returns the paths."""
    Path(directory).mkdir(parents=True, exist_ok=True)
    return [
        save_mechanism(PRESETS[name](), Path(directory) / f"{name}.toml",
                       comment=f"Preset {name!r}, written by jaxclear.presets.write_preset_files() from "
                               f"jaxclear.presets.{PRESETS[name].__name__} (its docstring gives the source).")
        for name in preset_names()
    ]
