"""The authors' v12.1 autopilot and the root model's speed PI for a batch of boats: twins of
:class:`bb2_sim.autopilot_v12.V12Autopilot` and :class:`bb2_sim.speed_control.SpeedPI` with one state per boat
(arrays (N,)), the same gains (data) and the same operation order.
"""
from __future__ import annotations

import math

import numpy as np

from ..autopilot_v12 import autopilot_v12_gains
from ..speed_control import speed_pi_gains


class BatchV12Autopilot:
    """Depth/pitch PID + heading PD per boat: references z_ref (m, native CG z) and psi_ref (rad), (N,) each."""

    def __init__(self, z_ref, psi_ref):
        self.z_ref = np.array(z_ref, dtype=float)
        self.psi_ref = np.array(np.broadcast_to(np.asarray(psi_ref, dtype=float), self.z_ref.shape))
        g = autopilot_v12_gains()
        self.Ts = float(g["Ts_s"])
        self.kz, self.kth, self.kpsi = g["depth"], g["pitch"], g["heading"]
        self.reset()

    def reset(self) -> None:
        z = np.zeros_like(self.z_ref)
        self.Iz, self.Ith, self.Ipsi = z.copy(), z.copy(), z.copy()
        self.ez_prev, self.eth_prev, self.epsi_prev = z.copy(), z.copy(), z.copy()

    def step(self, z: np.ndarray, theta: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One tick with the native CG z (m), pitch and heading (rad), (N,) each: returns (dv, dh) in deg."""
        Ts = self.Ts
        ez = self.z_ref - z
        eth = -theta * 180.0 / math.pi
        epsi = (self.psi_ref - psi) * 180.0 / math.pi
        self.Iz = self.Iz + ez * Ts
        self.Ith = self.Ith + eth * Ts
        self.Ipsi = self.Ipsi + epsi * Ts
        kz, kth, kp = self.kz, self.kth, self.kpsi
        dv = (kz["D"] * (ez - self.ez_prev) / Ts + kz["P"] * ez + kz["I"] * self.Iz
              + kth["D"] * (eth - self.eth_prev) / Ts + kth["P"] * eth + kth["I"] * self.Ith)
        dh = kp["D"] * (epsi - self.epsi_prev) / Ts + kp["P"] * epsi + kp["I"] * self.Ipsi
        self.ez_prev, self.eth_prev, self.epsi_prev = ez, eth, epsi
        return dv, dh


class BatchSpeedPI:
    """n_cmd = ff tgt_speed + P e_u + I int(e_u) per boat, e_u = u - tgt_speed (native u, m/s, (N,))."""

    def __init__(self, tgt_speed, corrected_feedforward: bool = False):
        self.tgt_speed = np.array(tgt_speed, dtype=float)
        g = speed_pi_gains()
        self.P, self.I, self.Ts = float(g["P_rps_per_m_s"]), float(g["I_rps_per_m"]), float(g["Ts_s"])
        ff = float(g["feedforward_rps_per_m_s"])
        self.ff = -ff if corrected_feedforward else ff
        self.reset()

    def reset(self) -> None:
        self.integral = np.zeros_like(self.tgt_speed)

    def step(self, u: np.ndarray) -> np.ndarray:
        """One tick with the native body speeds u (N,): the rps commands (before the ROM's actuators)."""
        e = u - self.tgt_speed
        self.integral = self.integral + e * self.Ts
        return self.ff * self.tgt_speed + self.P * e + self.I * self.integral
