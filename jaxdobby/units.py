"""Unit conversions at the boundary between the users' units and SI.

Everything inside jaxdobby is SI (m, kg, s, N, rad). The command line and the configuration files
speak the users' units: millimetres, revolutions per minute, newtons, degrees. Convert only here.
"""

from __future__ import annotations

import math

MM = 1e-3
"""One millimetre [m]."""

RPM = 2.0 * math.pi / 60.0
"""One revolution per minute [rad/s]."""

DEG = math.pi / 180.0
"""One degree [rad]."""


def mm_to_m(x):
    """Millimetres to metres."""
    return x * MM


def m_to_mm(x):
    """Metres to millimetres."""
    return x / MM


def rpm_to_rad_s(x):
    """Revolutions per minute to radians per second."""
    return x * RPM


def rad_s_to_rpm(x):
    """Radians per second to revolutions per minute."""
    return x / RPM


def deg_to_rad(x):
    """Degrees to radians."""
    return x * DEG


def rad_to_deg(x):
    """Radians to degrees."""
    return x / DEG
