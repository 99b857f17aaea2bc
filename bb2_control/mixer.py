"""X-plane mixer of the BB2 (SPEC 6.1): vertical/horizontal commands -> five plane angles.

``planes_deg = M @ (dV, dH)`` with the vehicle's X-plane matrix (:mod:`bb2_sim.xplane`, rows: 1 lower
starboard, 2 upper starboard, 3 upper port, 4 lower port, 5 sail planes) and the options of
``data/mixer.yaml`` (sail sign, saturation).  dV > 0 commands a bow-up moment and
dH > 0 a bow-to-port moment from every plane (ROM per-plane angle convention, degrees).

The ROM applies the per-plane rate limit and saturation itself; the mixer clips only when
``saturation_deg`` is set.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bb2_control.config import load_data
from bb2_control.errors import ControlConfigError, NonFiniteInputError
from bb2_sim.xplane import mixing_matrix

__all__ = ["PlaneMixer", "to_rom_commands", "from_rom_commands"]


def to_rom_commands(dV_deg: float, dH_deg: float) -> tuple[float, float]:
    """Controller (dV, dH) -> the ROM manoeuvre-block convention (dV_rom, dH_rom) = (-dV, -dH).

    In the ROM's own mixer (bb2_rom SPEC 9.1) dV_rom > 0 pitches the bow down and dH_rom > 0 turns the bow to
    starboard; both conventions give the same plane angles (SPEC 4.3).
    """
    return -float(dV_deg), -float(dH_deg)


def from_rom_commands(dV_rom_deg: float, dH_rom_deg: float) -> tuple[float, float]:
    """Inverse of :func:`to_rom_commands`."""
    return -float(dV_rom_deg), -float(dH_rom_deg)


@dataclass
class PlaneMixer:
    """Stateless mixer; ``step(dV_deg, dH_deg) -> planes_deg`` (shape (5,), degrees)."""

    matrix: np.ndarray
    sail_sign: float = 1.0
    saturation_deg: float | None = None

    def __post_init__(self) -> None:
        m = np.asarray(self.matrix, dtype=float)
        if m.shape != (5, 2) or not np.all(np.isfinite(m)):
            raise ControlConfigError(f"mixer matrix must be finite 5 x 2 (planes x [dV, dH]), got shape {m.shape}")
        if self.sail_sign not in (1, -1, 1.0, -1.0):
            raise ControlConfigError(f"sail_sign must be +1 or -1, got {self.sail_sign!r}")
        if self.saturation_deg is not None and not (self.saturation_deg > 0):
            raise ControlConfigError(f"saturation_deg must be positive or null, got {self.saturation_deg!r}")
        m = m.copy()
        m[4] *= float(self.sail_sign)
        self.matrix = m
        self._rows = tuple((float(a), float(b)) for a, b in m)

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None = None) -> "PlaneMixer":
        """From a mapping like ``data/mixer.yaml`` (the default when ``cfg`` is None); the matrix is the
        vehicle's unless the mapping gives ``matrix_rows_planes_cols_dV_dH``."""
        cfg = load_data("mixer") if cfg is None else cfg
        matrix = cfg.get("matrix_rows_planes_cols_dV_dH")
        return cls(mixing_matrix() if matrix is None else np.asarray(matrix, float),
                   float(cfg.get("sail_sign", 1)), cfg.get("saturation_deg"))

    def reset(self) -> None:
        """Nothing to reset (stateless); present for a uniform piece interface."""

    def step(self, dV_deg: float, dH_deg: float) -> np.ndarray:
        """Plane angles delta_1..delta_5 (deg) for the vertical and horizontal commands (deg)."""
        dV, dH = float(dV_deg), float(dH_deg)
        if not (math.isfinite(dV) and math.isfinite(dH)):
            raise NonFiniteInputError(f"mixer input is not finite: dV={dV_deg}, dH={dH_deg}")
        planes = [a * dV + b * dH for a, b in self._rows]       # matrix @ [dV, dH] on floats
        s = self.saturation_deg
        if s is not None:
            planes = [min(max(p, -s), s) for p in planes]
        return np.array(planes)
