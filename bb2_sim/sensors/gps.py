"""GPS: a fix only while the antenna is above the instantaneous free surface, after a time to first fix (no ROS).

The antenna (the sail top) is out of the water when its height above the sea's elevation at its horizontal
position (``Sea.elevation``: waves included) is at least ``min_antenna_height_m``.  It must stay out for
``time_to_first_fix_s`` before the first fix; a wave over it or a dive loses the fix and restarts that wait.
While there is no fix the receiver still reports, status NO_FIX (NaN position).  A fix is the antenna's position
plus white noise (horizontal / vertical sigmas, ENU), as latitude / longitude / ellipsoidal height about the
configured origin of ``map`` (local tangent plane on WGS-84: meridian and prime-vertical radii at the origin;
the error of the flat approximation is below 1 cm in position within 10 km).
"""
from __future__ import annotations

import math

import numpy as np

from .config import GpsConfig
from .geodesy import enu_to_geodetic, geodetic_to_enu
from .noise import stream
from .samples import GpsSample
from .truth import TruthBatch

__all__ = ["GpsModel", "enu_to_geodetic", "geodetic_to_enu"]

class GpsModel:
    name = "gps"

    def __init__(self, cfg: GpsConfig, seed: int, index: int = 4, t0: float = 0.0) -> None:
        self.cfg = cfg
        self.period = 1.0 / cfg.rate_hz
        self.rng = stream(seed, index, 1)
        self.out_since: float | None = None     # the time the antenna last came out of the water
        self.origin = (cfg.origin_lat_deg, cfg.origin_lon_deg, cfg.origin_alt_m)
        self.cov = np.diag([cfg.horizontal_noise_m ** 2, cfg.horizontal_noise_m ** 2, cfg.vertical_noise_m ** 2])

    def antenna_height(self, truth: TruthBatch, env) -> np.ndarray:
        """Height (m) of the antenna above the instantaneous free surface."""
        p = truth.point_enu(self.cfg.mounting.position_flu)
        eta = np.zeros(truth.n)
        if env is not None and env.sea is not None:
            for k in range(truth.n):
                x, y = -p[k, 0], -p[k, 1]            # native earth x, y
                eta[k] = float(np.asarray(env.sea.elevation(np.array([x]), np.array([y]), float(truth.t[k])))[0])
        return p[:, 2] - eta

    def sample(self, truth: TruthBatch, env) -> list[GpsSample]:
        c = self.cfg
        W = self.rng.standard_normal((truth.n, 3))
        p = truth.point_enu(c.mounting.position_flu)
        h = self.antenna_height(truth, env)
        out = []
        nan3 = np.full(3, math.nan)
        for k in range(truth.n):
            t = float(truth.t[k])
            if h[k] >= c.min_antenna_height_m:
                if self.out_since is None:
                    self.out_since = t
            else:
                self.out_since = None
            fix = self.out_since is not None and t - self.out_since >= c.time_to_first_fix_s - 1e-9
            if fix:
                pe = p[k] + W[k] * np.array([c.horizontal_noise_m, c.horizontal_noise_m, c.vertical_noise_m])
                lat, lon, alt = enu_to_geodetic(pe, *self.origin)
                out.append(GpsSample("gps", t, t, c.frame_id, True, float(lat), float(lon), float(alt), pe,
                                     self.cov, self.origin))
            else:
                out.append(GpsSample("gps", t, t, c.frame_id, False, math.nan, math.nan, math.nan, nan3,
                                     np.full((3, 3), math.nan), self.origin))
        return out
