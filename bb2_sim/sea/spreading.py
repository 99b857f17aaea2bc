"""Directional spreading D(theta) = C(s) cos^(2s)((theta - theta0)/2) and its discretisation (radians inside).

theta is the direction the waves travel towards (native earth frame, 0 = +x_E); see ``sea_spectra.yaml``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import finite


@dataclass(frozen=True)
class Cos2sSpreading:
    """cos-2s spreading about the mean direction ``mean_rad`` with spreading exponent ``s`` (> 0)."""

    mean_rad: float
    s: float

    def __post_init__(self):
        object.__setattr__(self, "mean_rad", finite("mean direction", self.mean_rad))
        object.__setattr__(self, "s", finite("spreading exponent s", self.s, positive=True))

    @property
    def norm(self) -> float:
        s = self.s
        return math.exp(math.lgamma(s + 1.0) - math.lgamma(s + 0.5)) / (2.0 * math.sqrt(math.pi))

    def __call__(self, theta) -> np.ndarray:
        """D(theta), 1/rad, integrating to 1 over one turn."""
        d = np.angle(np.exp(1j * (np.asarray(theta, dtype=float) - self.mean_rad)))   # wrapped to [-pi, pi]
        return self.norm * np.abs(np.cos(d / 2.0)) ** (2.0 * self.s)

    def moments(self) -> tuple[float, float]:
        """The exact circular moments E[cos(theta - theta0)], E[cos 2(theta - theta0)]."""
        s = self.s
        return s / (s + 1.0), s * (s - 1.0) / ((s + 1.0) * (s + 2.0))

    def strata(self, m: int, rng: np.random.Generator | None = None, jitter: float = 1.0,
               n_fine: int = 4001) -> tuple[np.ndarray, np.ndarray]:
        """``m`` directions (rad) in equal-probability strata of D and their weights (each 1/m).

        Each direction is drawn uniformly in probability within its stratum (``jitter`` = 1; 0 = the
        stratum's probability mid-point) and mapped through the inverse of the cumulative distribution.
        """
        d = np.linspace(-math.pi, math.pi, n_fine)
        dens = self.norm * np.cos(d / 2.0) ** (2.0 * self.s)
        cdf = np.concatenate([[0.0], np.cumsum((dens[1:] + dens[:-1]) * np.diff(d) / 2.0)])
        cdf /= cdf[-1]
        u = (np.arange(m) + 0.5) / m
        if rng is not None and jitter > 0:
            u = u + jitter * (rng.random(m) - 0.5) / m
        return self.mean_rad + np.interp(u, cdf, d), np.full(m, 1.0 / m)
