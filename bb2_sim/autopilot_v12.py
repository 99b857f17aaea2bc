"""The authors' v12.1 autopilot: discrete depth/pitch PID and heading PD (gains in ``data/autopilot_v12.yaml``).

It flew every reference run of the authors' compiled model, so the maneuver runner uses it for the channel a
maneuver does not impose. Runs once per 0.05 s major step; outputs dv (>0 bow up) and dh (>0 bow to port), deg.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from bb2_sim.yaml_files import load as load_yaml

DATA = Path(__file__).resolve().parent / "data" / "autopilot_v12.yaml"


@lru_cache(maxsize=1)
def autopilot_v12_gains() -> dict:
    return load_yaml(DATA.read_text())


@dataclass
class V12Autopilot:
    """Depth/pitch PID + heading PD of the v12.1 generated code (backward differences, rectangle integrals)."""

    z_ref: float          # m, native earth z of the CG (negative below the surface)
    psi_ref: float = 0.0  # rad, native heading (positive = bow to port)

    def __post_init__(self):
        g = autopilot_v12_gains()
        self.Ts = float(g["Ts_s"])
        self.kz, self.kth, self.kpsi = g["depth"], g["pitch"], g["heading"]
        self.reset()

    def reset(self) -> None:
        self.Iz = self.Ith = self.Ipsi = 0.0
        self.ez_prev = self.eth_prev = self.epsi_prev = 0.0

    def step(self, z: float, theta: float, psi: float) -> tuple[float, float]:
        """One tick with the native CG z (m), pitch and heading (rad): returns (dv, dh) in deg."""
        Ts = self.Ts
        ez = self.z_ref - z
        eth = -theta * 180.0 / math.pi
        epsi = (self.psi_ref - psi) * 180.0 / math.pi
        self.Iz += ez * Ts
        self.Ith += eth * Ts
        self.Ipsi += epsi * Ts
        kz, kth, kp = self.kz, self.kth, self.kpsi
        dv = (kz["D"] * (ez - self.ez_prev) / Ts + kz["P"] * ez + kz["I"] * self.Iz
              + kth["D"] * (eth - self.eth_prev) / Ts + kth["P"] * eth + kth["I"] * self.Ith)
        dh = kp["D"] * (epsi - self.epsi_prev) / Ts + kp["P"] * epsi + kp["I"] * self.Ipsi
        self.ez_prev, self.eth_prev, self.epsi_prev = ez, eth, epsi
        return dv, dh
