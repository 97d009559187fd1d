"""Force elements between two bodies, each with its own slice of the state: the revolute
clearance joint and the impact-memory rule it shares with future elements."""

from .base import AbstractForceElement, ContactOutput, start_states
from .memory import ContactMemory, contact_switches, ongoing_contact, onset_update
from .lubricated import FILMS, LubricatedJoint, film_force, film_integrals, gauss_film_force
from .pin_slot import IDEALS, PinSlotJoint
from .translational_clearance import CornerMemory, TranslationalClearanceJoint
from .revolute_clearance import AbstractJournalJoint, ClearanceJoint, contact_forces, joint_forces, journal_state, kinematics
