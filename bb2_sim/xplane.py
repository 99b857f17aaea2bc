"""X-plane mixing geometry of the BB2: virtual commands (dV, dH) -> the five plane angles delta_1..delta_5.

``planes_deg = M @ (dV, dH)`` with the matrix of ``data/xplane.yaml`` (rows: 1 lower starboard, 2 upper
starboard, 3 upper port, 4 lower port, 5 sail planes; ROM per-plane angle convention, degrees).  dV > 0
commands a bow-up moment and dH > 0 a bow-to-port moment from every plane.

It is the vehicle's geometry, so the maneuver runner uses it directly; the controllers' mixer
(:class:`bb2_control.mixer.PlaneMixer`) adds its options (sail sign, saturation) on top.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from bb2_sim.yaml_files import load as load_yaml

__all__ = ["mixing_matrix", "plane_angles_deg", "PLANE_NAMES"]

DATA_FILE = Path(__file__).resolve().parent / "data" / "xplane.yaml"


@lru_cache(maxsize=1)
def _data() -> dict:
    with open(DATA_FILE) as fh:
        return load_yaml(fh)


def mixing_matrix() -> np.ndarray:
    """The (5, 2) matrix planes x (dV, dH), deg per deg (a fresh copy)."""
    m = np.asarray(_data()["matrix_rows_planes_cols_dV_dH"], dtype=float)
    if m.shape != (5, 2) or not np.all(np.isfinite(m)):
        raise ValueError(f"{DATA_FILE}: the mixing matrix must be finite 5 x 2, got shape {m.shape}")
    return m


PLANE_NAMES: tuple[str, ...] = tuple(_data()["planes"])

_M = mixing_matrix()


def plane_angles_deg(dV_deg: float, dH_deg: float) -> np.ndarray:
    """Plane angles delta_1..delta_5 (deg) for the vertical and horizontal commands (deg)."""
    return _M @ np.array([dV_deg, dH_deg], dtype=float)
