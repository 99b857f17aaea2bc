"""The root model's speed PI (propeller rps from the body speed error), with the feed-forward switch of quirk Q14.

Gains in ``data/speed_pi.yaml``. Used by maneuvers whose setting ``propeller`` is ``speed-pi`` (the six reference
maneuvers keep the authors' constant rps).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from bb2_sim.yaml_files import load as load_yaml

DATA = Path(__file__).resolve().parent / "data" / "speed_pi.yaml"


@lru_cache(maxsize=1)
def speed_pi_gains() -> dict:
    return load_yaml(DATA.read_text())


@dataclass
class SpeedPI:
    """n_cmd = ff tgt_speed + P e_u + I int(e_u), e_u = u - tgt_speed (native u, m/s; negative ahead).

    ``corrected_feedforward`` flips the feed-forward sign (Q14) so that it is the positive U/4 rps.
    """

    tgt_speed: float                  # m/s, native (negative ahead)
    corrected_feedforward: bool = False

    def __post_init__(self):
        g = speed_pi_gains()
        self.P, self.I, self.Ts = float(g["P_rps_per_m_s"]), float(g["I_rps_per_m"]), float(g["Ts_s"])
        ff = float(g["feedforward_rps_per_m_s"])
        self.ff = -ff if self.corrected_feedforward else ff
        self.reset()

    def reset(self) -> None:
        self.integral = 0.0

    def step(self, u: float) -> float:
        """One 0.05 s tick with the native body speed u: the rps command (before the ROM's actuator)."""
        e = u - self.tgt_speed
        self.integral += e * self.Ts
        return self.ff * self.tgt_speed + self.P * e + self.I * self.integral
