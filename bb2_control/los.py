"""2-D line-of-sight heading plus depth guidance of the 2023 stack (LOS23; SPEC 3.3).

Per tick, with p_d, p_d' at the virtual time gamma (inertial z-up frame I shared with the path):

* t1 = horizontal unit tangent, t2 = (-t1_y, t1_x) its left normal; y_T = t2 . (p - p_d)_h (m, > 0 left);
* psi_d = atan2(t1_y, t1_x) - atan2(y_T, d)  (heading of the bow counter-clockwise from x_I);
* z_d = p_d,z (m, z up);
* gamma_dot = (u d1 + k_gamma (p - p_d)_h) . t1 / |p_d,h'| with u the body surge and d1 = (cos psi_d, sin psi_d);
  no floor; gamma += Ts gamma_dot.

``psi_d`` is returned **unwrapped** next to the vehicle heading passed in (which must itself be
continuous), so that depth/heading L1 and PD see no 2 pi jumps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bb2_control.config import load_data, require
from bb2_control.errors import ControlConfigError, NonFiniteInputError, PathFollowingError
from bb2_control.path_following import PathFollowingLaw, PathLike

__all__ = ["LOSGains", "LOSOutput", "LineOfSightDepth", "wrap_to_pi"]


def wrap_to_pi(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


@dataclass(frozen=True)
class LOSGains:
    """k_gamma (1/s), look-ahead d (m), gamma0 (s), Ts (s)."""

    k_gamma: float = 1.0
    d: float = 50.0
    gamma0: float = 0.0
    Ts: float = 0.05

    def __post_init__(self) -> None:
        for name in ("k_gamma", "d", "Ts"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ControlConfigError(f"LOS guidance: {name} must be positive, got {v}")

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None = None) -> "LOSGains":
        cfg = load_data("guidance")["los_2d_depth_2023"] if cfg is None else cfg
        w = "LOS guidance"
        return cls(float(require(cfg, "k_gamma_per_s", w)), float(require(cfg, "d_m", w)),
                   float(cfg.get("gamma0_s", 0.0)), float(require(cfg, "Ts_s", w)))


@dataclass(frozen=True)
class LOSOutput:
    z_d: float             #: depth reference (z up), m
    psi_d: float           #: heading reference, rad, unwrapped next to the input heading
    gamma: float           #: virtual time used this tick, s
    gamma_dot: float
    p_d: np.ndarray        #: desired position, m (frame I)
    y_T: float             #: horizontal cross-track error, m (> 0: vehicle left of the path)
    z_err: float           #: z - z_d, m (> 0: vehicle above the path)
    finished: bool


class LineOfSightDepth(PathFollowingLaw):
    """LOS heading + depth law.  ``step(p_I, heading, surge)`` once per Ts; ``reset()`` restarts gamma."""

    def __init__(self, path: PathLike, gains: LOSGains | None = None) -> None:
        self.gains = gains or LOSGains.from_config()
        super().__init__(path, self.gains.gamma0, self.gains.Ts)

    def reset(self) -> None:
        self.gamma = self._gamma0

    def step(self, p_I: np.ndarray, heading: float, surge: float) -> LOSOutput:
        """Position (m, I), continuous bow heading (rad, CCW from x_I), surge (m/s, forward > 0)."""
        p = np.asarray(p_I, dtype=float)
        if not (np.all(np.isfinite(p)) and math.isfinite(heading) and math.isfinite(surge)):
            raise NonFiniteInputError(f"LOS guidance: non-finite input p={p}, heading={heading}, surge={surge}")
        g = self.gains
        gam = float(np.clip(self.gamma, self.path.t0, self.path.tf))
        p_d = np.asarray(self.path(gam), dtype=float)
        dp = np.asarray(self.path.velocity(gam), dtype=float)
        h = math.hypot(dp[0], dp[1])
        if h == 0.0:
            raise PathFollowingError("LOS guidance: the path has no horizontal tangent here")
        t1 = dp[:2] / h
        t2 = np.array([-t1[1], t1[0]])
        e_h = p[:2] - p_d[:2]
        y_T = float(t2 @ e_h)
        psi_d = math.atan2(t1[1], t1[0]) - math.atan2(y_T, g.d)
        psi_d = heading + wrap_to_pi(psi_d - heading)
        d1 = np.array([math.cos(psi_d), math.sin(psi_d)])
        gamma_dot = float((surge * d1 + g.k_gamma * e_h) @ t1) / h
        out = LOSOutput(float(p_d[2]), psi_d, gam, gamma_dot, p_d, y_T, float(p[2] - p_d[2]),
                        gam >= self.path.tf)
        self.gamma = self.gamma + g.Ts * gamma_dot
        return out
