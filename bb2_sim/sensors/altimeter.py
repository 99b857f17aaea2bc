"""Altimeter: range to the terrain along its boresight (the x axis of its frame, REP-117), no ROS.

``range = h_alt / cos(incidence)`` with ``h_alt`` the clearance of the mounting point (the bottom taken locally flat)
and ``incidence`` the boresight's angle from the vertical; noise ``noise_m + noise_fraction * range`` (1 sigma).
Beyond ``max_range`` (or no bottom / boresight not downward) the range is +inf, below ``min_range`` -inf (REP-117);
each ping is lost with ``dropout_probability`` (no echo detected: no message).
"""
from __future__ import annotations

import numpy as np

from .config import AltimeterConfig
from .noise import stream, uniform_from_normal
from .samples import AltimeterSample
from .truth import TruthBatch

__all__ = ["AltimeterModel"]


class AltimeterModel:
    name = "altimeter"

    def __init__(self, cfg: AltimeterConfig, seed: int, index: int = 3, t0: float = 0.0) -> None:
        self.cfg = cfg
        self.period = 1.0 / cfg.rate_hz
        self.rng = stream(seed, index, 1)
        self.axis_flu = cfg.mounting.R_flu_sensor[:, 0]

    def true_range(self, truth: TruthBatch) -> np.ndarray:
        r = self.cfg.mounting.position_flu
        h = truth.clearance_m + (truth.R_enu_flu @ r)[:, 2]
        cos_inc = -(truth.R_enu_flu @ self.axis_flu)[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where((cos_inc > 1e-6) & np.isfinite(h), h / np.maximum(cos_inc, 1e-6), np.inf)

    def sample(self, truth: TruthBatch, env=None) -> list[AltimeterSample]:
        c = self.cfg
        W = self.rng.standard_normal((truth.n, 2))
        rng = self.true_range(truth)
        sig = c.noise_m + c.noise_fraction * np.where(np.isfinite(rng), rng, 0.0)
        meas = rng + sig * W[:, 0]
        lost = uniform_from_normal(W[:, 1]) < c.dropout_probability
        out = []
        for k in range(truth.n):
            if lost[k]:
                continue
            r = float(meas[k])
            if not np.isfinite(rng[k]) or r > c.max_range_m:
                r = float("inf")
            elif r < c.min_range_m:
                r = float("-inf")
            t = float(truth.t[k])
            out.append(AltimeterSample("altimeter", t, t, c.frame_id, r, float(sig[k]) ** 2, c.min_range_m,
                                       c.max_range_m, c.field_of_view_rad))
        return out
