"""Sea currents: a uniform current (speed, direction) with an optional depth profile (table or power law).

Earth frame native (z up, z = 0 the calm surface); direction = where the water flows towards, degrees at the
edges (0 = +x_E, 90 = +y_E), radians inside. The profile factor f(depth) multiplies the surface speed:
``table`` = linear interpolation in (depth_m, factor) rows (held constant beyond the ends); ``power`` =
((d - depth) / d)^alpha for 0 <= depth <= d (0 below the water depth d), the usual 1/7 law for tidal
currents (DNV-RP-C205 (2010) 4.1.3). Above the surface (z > 0) the surface value applies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .sea.errors import SeaInputError, finite


@dataclass(frozen=True)
class Current:
    """speed (m/s, >= 0) towards direction_deg; profile None (uniform), ("table", depths, factors) or
    ("power", water_depth_m, alpha)."""

    speed: float
    direction_deg: float = 0.0
    profile: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "speed", finite("current speed", self.speed, nonnegative=True))
        object.__setattr__(self, "direction_deg", finite("current direction", self.direction_deg))
        p = self.profile
        if p is None:
            return
        kind = p[0]
        if kind == "table":
            d = np.asarray(p[1], dtype=float)
            f = np.asarray(p[2], dtype=float)
            if d.ndim != 1 or d.shape != f.shape or len(d) < 1 or not (np.all(np.isfinite(d))
                                                                         and np.all(np.isfinite(f))):
                raise SeaInputError("current profile table needs equal-length finite depth and factor lists")
            if np.any(np.diff(d) <= 0) or d[0] < 0:
                raise SeaInputError("current profile depths must be >= 0 and increasing")
            object.__setattr__(self, "profile", ("table", d, f))
        elif kind == "power":
            depth = finite("water depth", p[1], positive=True)
            alpha = finite("power-law exponent", p[2], positive=True)
            object.__setattr__(self, "profile", ("power", depth, alpha))
        else:
            raise SeaInputError(f"current profile must be None, ('table', depths, factors) or "
                                f"('power', water_depth, alpha), got {p!r}")

    @property
    def direction_rad(self) -> float:
        return math.radians(self.direction_deg)

    @property
    def calm(self) -> bool:
        return self.speed == 0.0

    def factor(self, z_earth) -> np.ndarray:
        """Profile factor at earth z (m, z up)."""
        depth = np.maximum(-np.asarray(z_earth, dtype=float), 0.0)
        p = self.profile
        if p is None:
            return np.ones_like(depth)
        if p[0] == "table":
            return np.interp(depth, p[1], p[2])
        d, alpha = p[1], p[2]
        return np.where(depth <= d, np.clip((d - depth) / d, 0.0, 1.0) ** alpha, 0.0)

    def velocity_earth(self, z_earth) -> np.ndarray:
        """Current velocity (m/s, earth axes, horizontal) at earth z, shape z.shape + (3,)."""
        f = self.factor(z_earth) * self.speed
        out = np.zeros(f.shape + (3,))
        out[..., 0] = f * math.cos(self.direction_rad)
        out[..., 1] = f * math.sin(self.direction_rad)
        return out
