"""Unit conversions: the one place for each (SI inside, other units only at the edges)."""

from __future__ import annotations

import math

RPM_TO_RAD_S = 2.0 * math.pi / 60.0  #: 1 rev/min in rad/s


def rpm_to_rad_s(rpm):
    """Revolutions per minute to rad/s (works on floats and arrays)."""
    return rpm * RPM_TO_RAD_S


def rad_s_to_rpm(omega):
    """rad/s to revolutions per minute (works on floats and arrays)."""
    return omega / RPM_TO_RAD_S
