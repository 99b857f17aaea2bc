"""Baseline autopilots (SPEC 4): commands in, vertical/horizontal plane commands dV, dH (deg) out.

* :class:`RateAutopilot` -- the 2022 proportional rate loop (SPEC 4.1):
  ``dV = K_q (u_q - q_up)``, ``dH = K_r (u_r - r_left)`` with q_up the bow-up and r_left the
  bow-to-port body rate (rad/s); optional I and D terms.
* :class:`DepthHeadingPD` -- the 2023 depth + pitch + heading PD ("Marin PID", SPEC 4.2).
* :class:`CommandLimiter` -- optional rate limit then saturation of dV or dH (off in the PF stacks,
  where only the ROM's per-plane limits act; the ROM's own manoeuvre PIDs use 7.11 deg/s and 30 deg).

Sign: dV > 0 commands a bow-up pitching moment, dH > 0 a bow-to-port yaw moment.  Each piece is
called once per Ts; ``reset()`` clears its memory.  Non-finite inputs raise NonFiniteInputError and
leave the state untouched.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from bb2_control.config import load_data, require
from bb2_control.errors import ControlConfigError, NonFiniteInputError

__all__ = ["CommandLimiter", "RateAutopilot", "DepthHeadingPD"]


def _finite(where: str, **values: float) -> None:
    bad = {k: v for k, v in values.items() if not math.isfinite(float(v))}
    if bad:
        raise NonFiniteInputError(f"{where}: non-finite input {bad}")


def _opt_positive(cfg: Mapping[str, Any], key: str, where: str) -> float | None:
    v = cfg.get(key)
    if v is None:
        return None
    v = float(v)
    if not v > 0:
        raise ControlConfigError(f"{where}: {key} must be positive or null, got {v}")
    return v


@dataclass
class CommandLimiter:
    """Rate limit (deg/s, over Ts) then saturation (deg) of one command; ``None`` disables either."""

    Ts: float
    rate_limit_deg_per_s: float | None = None
    saturation_deg: float | None = None
    _prev: float | None = field(default=None, init=False, repr=False)

    @property
    def active(self) -> bool:
        return self.rate_limit_deg_per_s is not None or self.saturation_deg is not None

    def reset(self) -> None:
        self._prev = None

    def step(self, x: float) -> float:
        y = float(x)
        if self.rate_limit_deg_per_s is not None and self._prev is not None:
            dmax = self.rate_limit_deg_per_s * self.Ts
            y = min(max(y, self._prev - dmax), self._prev + dmax)
        if self.saturation_deg is not None:
            y = min(max(y, -self.saturation_deg), self.saturation_deg)
        self._prev = y
        return y


def _limiters(cfg: Mapping[str, Any], Ts: float, where: str) -> tuple[CommandLimiter, CommandLimiter]:
    rl = _opt_positive(cfg, "command_rate_limit_deg_per_s", where)
    sat = _opt_positive(cfg, "command_saturation_deg", where)
    return CommandLimiter(Ts, rl, sat), CommandLimiter(Ts, rl, sat)


class RateAutopilot:
    """Proportional (optionally PID) pitch/yaw rate loop of 2022 (SPEC 4.1)."""

    def __init__(self, cfg: Mapping[str, Any] | None = None) -> None:
        cfg = load_data("autopilots")["rate_P_2022"] if cfg is None else cfg
        w = "rate autopilot"
        self.Ts = float(require(cfg, "Ts_s", w))
        if not self.Ts > 0:
            raise ControlConfigError(f"{w}: Ts_s must be positive, got {self.Ts}")
        self.K_q = float(require(cfg, "K_q_deg_per_radps", w))
        self.K_r = float(require(cfg, "K_r_deg_per_radps", w))
        self.KI_q = float(cfg.get("KI_q_deg_per_rad", 0.0))
        self.KI_r = float(cfg.get("KI_r_deg_per_rad", 0.0))
        self.KD_q = float(cfg.get("KD_q_deg_per_radps2", 0.0))
        self.KD_r = float(cfg.get("KD_r_deg_per_radps2", 0.0))
        self.limit_dV, self.limit_dH = _limiters(cfg, self.Ts, w)
        self.reset()

    def reset(self) -> None:
        self._int = (0.0, 0.0)
        self._prev: tuple[float, float] | None = None
        self.limit_dV.reset()
        self.limit_dH.reset()

    def step(self, u_q: float, u_r: float, q_up: float, r_left: float) -> tuple[float, float]:
        """Rate references u_q, u_r and measured rates q_up, r_left (rad/s) -> (dV, dH) in deg."""
        isfinite = math.isfinite
        if not (isfinite(u_q) and isfinite(u_r) and isfinite(q_up) and isfinite(r_left)):
            _finite("rate autopilot", u_q=u_q, u_r=u_r, q_up=q_up, r_left=r_left)
        Ts = self.Ts
        eq, er = float(u_q) - float(q_up), float(u_r) - float(r_left)
        iq, ir = self._int[0] + Ts * eq, self._int[1] + Ts * er
        dq, dr = (0.0, 0.0) if self._prev is None else ((eq - self._prev[0]) / Ts, (er - self._prev[1]) / Ts)
        self._int, self._prev = (iq, ir), (eq, er)
        dV = self.K_q * eq + self.KI_q * iq + self.KD_q * dq
        dH = self.K_r * er + self.KI_r * ir + self.KD_r * dr
        return self.limit_dV.step(dV), self.limit_dH.step(dH)


class DepthHeadingPD:
    """Depth + pitch + heading PD autopilot of 2023 ("Marin PID", SPEC 4.2).

    Inputs: z_ref, z (m, z up), theta (rad, bow up), psi_ref, psi (rad, continuous/unwrapped, same frame).
    Angle errors are converted to degrees; output (dV, dH) in degrees.
    """

    def __init__(self, cfg: Mapping[str, Any] | None = None) -> None:
        cfg = load_data("autopilots")["depth_pitch_yaw_PD_2023"] if cfg is None else cfg
        w = "depth/heading PD autopilot"
        g = lambda k: float(require(cfg, k, w))  # noqa: E731
        self.Ts = g("Ts_s")
        if not self.Ts > 0:
            raise ControlConfigError(f"{w}: Ts_s must be positive, got {self.Ts}")
        self.KP_z, self.KI_z, self.KD_z = g("KP_z_deg_per_m"), g("KI_z_deg_per_m_s"), g("KD_z_deg_per_mps")
        self.KP_th, self.KI_th, self.KD_th = g("KP_theta_deg_per_deg"), g("KI_theta_deg_per_deg_s"), g("KD_theta_s")
        self.KP_psi, self.KI_psi, self.KD_psi = g("KP_psi_deg_per_deg"), g("KI_psi_deg_per_deg_s"), g("KD_psi_s")
        self.theta_ref_deg = g("theta_ref_deg")
        init = cfg.get("initial_previous_error", "first")
        if init not in ("first", "zero"):
            raise ControlConfigError(f"{w}: initial_previous_error must be 'first' or 'zero', got {init!r}")
        self.initial_previous_error = init
        self.limit_dV, self.limit_dH = _limiters(cfg, self.Ts, w)
        self.reset()

    def reset(self) -> None:
        self._int = np.zeros(3)
        self._prev: np.ndarray | None = None
        self.limit_dV.reset()
        self.limit_dH.reset()

    def step(self, z_ref: float, z: float, theta: float, psi_ref: float, psi: float) -> tuple[float, float]:
        """(dV, dH) in deg from depth/heading references and the measured z, theta, psi."""
        _finite("depth/heading PD autopilot", z_ref=z_ref, z=z, theta=theta, psi_ref=psi_ref, psi=psi)
        e = np.array([z_ref - z, self.theta_ref_deg - math.degrees(theta), math.degrees(psi_ref - psi)])
        if self._prev is None:
            self._prev = e.copy() if self.initial_previous_error == "first" else np.zeros(3)
        de = (e - self._prev) / self.Ts
        self._prev = e
        self._int = self._int + self.Ts * e
        dV = (self.KP_z * e[0] + self.KI_z * self._int[0] + self.KD_z * de[0]
              + self.KP_th * e[1] + self.KI_th * self._int[1] + self.KD_th * de[1])
        dH = self.KP_psi * e[2] + self.KI_psi * self._int[2] + self.KD_psi * de[2]
        return self.limit_dV.step(dV), self.limit_dH.step(dH)
