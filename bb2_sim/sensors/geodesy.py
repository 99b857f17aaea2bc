"""Map (ENU) <-> geodetic coordinates near the origin of ``map``: a local tangent plane on WGS-84 (no ROS).

Latitude from the north offset over the meridian radius, longitude from the east offset over the prime-vertical
radius times cos(lat0), both at the origin (first order in the offset: centimetres within a few km of the
origin); altitude = origin altitude + up, since the simulated world is flat (the calm surface is at the origin's
altitude everywhere).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["enu_to_geodetic", "geodetic_to_enu", "WGS84_A", "WGS84_E2"]

WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3


def _radii(lat0_deg: float) -> tuple[float, float]:
    s = math.sin(math.radians(lat0_deg))
    w = math.sqrt(1.0 - WGS84_E2 * s * s)
    return WGS84_A * (1.0 - WGS84_E2) / w ** 3, WGS84_A / w     # meridian, prime vertical


def enu_to_geodetic(p_enu, lat0_deg: float, lon0_deg: float, alt0_m: float):
    """(lat deg, lon deg, alt m) of ENU points (local tangent plane at the origin)."""
    p = np.asarray(p_enu, float)
    rm, rn = _radii(lat0_deg)
    lat = lat0_deg + np.degrees(p[..., 1] / (rm + alt0_m))
    lon = lon0_deg + np.degrees(p[..., 0] / ((rn + alt0_m) * math.cos(math.radians(lat0_deg))))
    return lat, lon, alt0_m + p[..., 2]


def geodetic_to_enu(lat_deg, lon_deg, alt_m, lat0_deg: float, lon0_deg: float, alt0_m: float) -> np.ndarray:
    """Inverse of :func:`enu_to_geodetic`."""
    rm, rn = _radii(lat0_deg)
    e = np.radians(np.asarray(lon_deg, float) - lon0_deg) * (rn + alt0_m) * math.cos(math.radians(lat0_deg))
    n = np.radians(np.asarray(lat_deg, float) - lat0_deg) * (rm + alt0_m)
    return np.stack([e, n, np.asarray(alt_m, float) - alt0_m], axis=-1)
