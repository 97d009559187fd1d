"""The mechanism file's vocabulary (format in docs/mechanism-files.md): its top-level and body
keys, every ``type`` of joint, driver, load and force element with the keys of its table (in
constructor order), and which keys hold strings, a few allowed strings, integers, arrays whose
length the class checks, or are required. :mod:`.files` reads and writes by these tables."""

from __future__ import annotations

import inspect

from ..contact import FourierProfile, Material
from ..elements import FILMS, IDEALS, ClearanceJoint, LubricatedJoint, PinSlotJoint, TranslationalClearanceJoint
from ..model import AngleDriver, Fixed, PointForce, PointOnLine, ProfileDriver, Revolute, Torque, Translational
from ..model.connectors import CONNECTORS
from ..model.discrete_beam import AXIAL

FORMAT_VERSION = 1

TOP_KEYS = ("format", "name", "gravity", "ground_points", "roles", "bodies", "joints", "drivers",
            "clearance_joints", "loads")
BODY_KEYS = ("name", "mass", "inertia", "points", "position", "velocity")
#: ``type`` -> (class, keys in constructor order)
JOINT_TYPES = {
    "revolute": (Revolute, ("body_i", "point_i", "body_j", "point_j")),
    "translational": (Translational, ("body_i", "point_i", "body_j", "point_j", "axis", "angle")),
    "fixed": (Fixed, ("body_i", "point_i", "body_j", "point_j", "angle")),
    "point-on-line": (PointOnLine, ("body_i", "point_i", "body_j", "point_j", "axis")),
}
DRIVER_TYPES = {"angle": (AngleDriver, ("body", "speed", "angle0", "relative_to")),
                "speed-profile": (ProfileDriver, ("body", "angle0", "relative_to"))}  # + the profile table
LOAD_TYPES = {
    "point-force": (PointForce, ("body", "point", "force")),
    "torque": (Torque, ("body", "torque")),  # + an optional profile table (a time factor)
    **{kind: (cls, tuple(k for k in inspect.signature(cls).parameters if k != "curve"))
       for kind, cls in CONNECTORS.items()},  # + a spring's optional curve table
}
_JOURNAL = ("name", "bearing_body", "bearing_point", "journal_body", "journal_point", "bearing_radius",
            "journal_radius")
_TAIL = ("law", "friction", "impact_velocity_floor", "initial_offset", "initial_velocity")
ELEMENT_TYPES = {
    "revolute-clearance": (ClearanceJoint, (*_JOURNAL, "length", *_TAIL)),
    "lubricated": (LubricatedJoint, (*_JOURNAL, "length", "viscosity", "film", "blend_start", "blend_end",
                                     "n_elements", "n_gauss", *_TAIL)),  # profiles: in the law's table
    "pin-slot": (PinSlotJoint, (*_JOURNAL, "slot_length", "axis", "length", "ideal", *_TAIL)),
    "translational-clearance": (TranslationalClearanceJoint, (
        "name", "guide_body", "guide_point", "slider_body", "slider_point", "slider_length", "slider_height",
        "guide_width", "axis", "angle", "corner_radius", *_TAIL)),
}
#: old file key -> the key that replaced it, per element type (read with a DeprecationWarning; the
#: lubricated joint's film width is its ``length``, as for every journal joint)
DEPRECATED_KEYS = {"lubricated": {"width": "length"}}
#: keys whose value is one of a few strings
CHOICES = {"film": FILMS, "ideal": IDEALS, "axial": AXIAL}
VECTOR_KEYS = ("start", "start_rate")  #: keys of arrays whose length the class checks (a flexible link's start)
#: keys whose value is a string (every other value is a number or an array of numbers)
STRING_KEYS = {"name", "body", "point", "body_i", "point_i", "body_j", "point_j", "bearing_body", "bearing_point",
               "journal_body", "journal_point", "guide_body", "guide_point", "slider_body", "slider_point",
               "relative_to", "body_a", "point_a", "body_b", "point_b", "drawn_at", *CHOICES}
#: law parameters that are tables, by the suffix of their key
TABLE_PARAMETERS = {"_material": (Material, ("young", "poisson")), "_profile": (FourierProfile, ("cos", "sin"))}
#: keys whose value is an integer (counts; a law's integer fields are found from its annotations)
INTEGER_KEYS = {"n_elements", "n_gauss"}
REQUIRED = {"body", "body_i", "point_i", "body_j", "point_j", "point", "bearing_body",
            "bearing_point", "journal_body", "journal_point", "bearing_radius", "guide_body", "guide_point",
            "slider_body", "slider_point", "body_a", "point_a", "body_b"}
