"""What a mission run comes to: its ending event and its figures (path errors, clearance; no ROS).

The figures are the paper's: RMS and maximum of the stack's own path errors (its p_T components) and,
the same for every stack, of the errors from the closest point of the path; the minimum CG and hull
clearance over the terrain.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, Mapping

import numpy as np

from bb2_planner.bernstein import BernsteinPath

__all__ = ["EndReason", "MissionEvent", "MissionSummary", "limit_event", "path_errors_closest", "summarize",
           "rms_max", "navigation_errors"]


class EndReason(StrEnum):
    """Why a mission run ended (the first three are normal ends; the others are failures, each a
    :class:`MissionEvent`)."""

    RUNNING = ""                    #: not ended yet
    FINISHED = "finished"           #: the stack finished the path (virtual time at its end)
    DURATION = "duration"           #: the mission's time limit
    GROUNDED = "grounded"           #: the lowest hull point came closer to the terrain than the limit
    BROACHED = "broached"           #: the CG rose above the broaching limit
    DIVERGED = "diverged"           #: the ROM's state became non-finite
    CONTROL_ERROR = "control_error"  #: the stack could not compute a command


@dataclass(frozen=True)
class MissionEvent:
    """Why a mission failed: ``grounded`` / ``broached`` / ``diverged`` / ``control_error``."""

    kind: EndReason
    t: float                       #: s
    p_native: np.ndarray           #: CG position (x, y, z) native, m
    detail: str

    def __str__(self) -> str:
        x, y, z = (float(v) for v in self.p_native)
        return (f"{self.kind} at t = {self.t:.2f} s, CG at x = {x:.1f}, y = {y:.1f}, z = {z:.1f} m (native): "
                f"{self.detail}")



def limit_event(limits: Any, max_cg_z_m: float, t: float, x: np.ndarray, hull_clearance_m: float,
                cg_clearance_m: float) -> MissionEvent | None:
    """The mission's failure checks on the state ``x`` (native, 12) of the tick at ``t``: grounded when the
    lowest hull point is closer to the terrain than ``limits.min_hull_clearance_m`` (NaN: no terrain under the
    hull, no check), else broached when the CG z is above ``max_cg_z_m`` (``limits.max_cg_z_m``, or the sail top
    at the calm surface when that is None).  What the runner ends on and ``bb2-analyze`` finds in a bag."""
    if math.isfinite(hull_clearance_m) and hull_clearance_m < limits.min_hull_clearance_m:
        return MissionEvent(EndReason.GROUNDED, t, np.array(x[0:3], dtype=float),
                            f"lowest hull point {hull_clearance_m:.2f} m above the terrain (limit "
                            f"{limits.min_hull_clearance_m} m); CG clearance {cg_clearance_m:.2f} m")
    if x[2] > max_cg_z_m:
        return MissionEvent(EndReason.BROACHED, t, np.array(x[0:3], dtype=float),
                            f"CG z = {x[2]:.2f} m above the limit {max_cg_z_m:.2f} m"
                            + (" (sail top at the calm surface)" if limits.max_cg_z_m is None else ""))
    return None


@dataclass(frozen=True)
class MissionSummary:
    """Figures of a run.  Path errors are the stack's own (its p_T components); ``*_closest`` are
    measured from the closest point of the path, the same for every stack."""

    mission: str
    stack: str
    adaptation: bool
    mission_time_s: float
    completed: bool
    end_reason: EndReason
    rms_vertical_m: float
    max_vertical_m: float
    rms_horizontal_m: float
    max_horizontal_m: float
    rms_vertical_closest_m: float
    max_vertical_closest_m: float
    rms_horizontal_closest_m: float
    max_horizontal_closest_m: float
    min_clearance_m: float          #: CG vertical clearance (NaN without terrain)
    min_clearance_t_s: float
    min_hull_clearance_m: float
    virtual_time_end_s: float
    wall_time_s: float
    event: MissionEvent | None = None
    navigation: str = "truth"       #: what the stack flew on: truth | sensors (the navigation filter)
    rms_nav_error_m: float = math.nan   #: position error of the navigation estimate (NaN on truth)
    max_nav_error_m: float = math.nan
    max_nav_heading_error_deg: float = math.nan

    @property
    def failed(self) -> bool:
        return self.event is not None

    def lines(self) -> list[str]:
        """Human-readable report."""
        out = [f"mission {self.mission}: stack {self.stack}, adaptation {'on' if self.adaptation else 'off'}",
               f"  mission time {self.mission_time_s:.2f} s ({self.end_reason}; virtual time "
               f"{self.virtual_time_end_s:.1f} s){'' if self.completed else ' -- NOT completed'}",
               f"  vertical path error    RMS {self.rms_vertical_m:7.3f} m   max {self.max_vertical_m:7.3f} m"
               f"   (closest point: RMS {self.rms_vertical_closest_m:.3f}, max {self.max_vertical_closest_m:.3f})",
               f"  horizontal path error  RMS {self.rms_horizontal_m:7.3f} m   max {self.max_horizontal_m:7.3f} m"
               f"   (closest point: RMS {self.rms_horizontal_closest_m:.3f}, max {self.max_horizontal_closest_m:.3f})"]
        if self.navigation != "truth":
            out.append(f"  navigation: {self.navigation}; position estimate error RMS {self.rms_nav_error_m:.3f} m, "
                       f"max {self.max_nav_error_m:.3f} m; heading error max {self.max_nav_heading_error_deg:.3f} deg")
        if math.isfinite(self.min_clearance_m):
            out.append(f"  minimum ground clearance {self.min_clearance_m:.2f} m (CG, at t = "
                       f"{self.min_clearance_t_s:.1f} s); lowest hull point {self.min_hull_clearance_m:.2f} m")
        else:
            out.append("  minimum ground clearance: n/a (no terrain)")
        rt = self.mission_time_s / self.wall_time_s if self.wall_time_s > 0 else float("inf")
        out.append(f"  wall time {self.wall_time_s:.2f} s ({rt:.0f}x real time)")
        if self.event is not None:
            out.append(f"  FAILED: {self.event}")
        return out



def rms_max(e: np.ndarray) -> tuple[float, float]:
    """RMS and max |e| over the finite samples (NaN, NaN when there are none)."""
    e = np.asarray(e, float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return math.nan, math.nan
    return float(np.sqrt(np.mean(e ** 2))), float(np.max(np.abs(e)))


def navigation_errors(est_x12: np.ndarray, true_x12: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The errors of navigation estimates against the truth (native x12, one row each or one vector): position
    (m, norm) and heading (deg, estimate minus truth, wrapped to [-180, 180]); what the runner's rows and
    ``bb2-analyze`` report."""
    est, true = np.asarray(est_x12, float), np.asarray(true_x12, float)
    e = np.linalg.norm(est[..., 0:3] - true[..., 0:3], axis=-1)
    dpsi = np.degrees(np.remainder(est[..., 5] - true[..., 5] + math.pi, 2 * math.pi) - math.pi)
    return e, dpsi


_DENSE: dict[tuple, tuple[np.ndarray, np.ndarray, Any]] = {}


def _dense_samples(path: BernsteinPath, samples: int) -> tuple[np.ndarray, np.ndarray, Any]:
    """``path.sample(samples)`` and its KD-tree, kept read-only for the last few paths (the missions of a campaign
    share their path: its 20,001 samples cost ~15 ms a mission)."""
    from scipy.spatial import cKDTree

    c = np.asarray(path.control_points)
    key = (c.shape, c.tobytes(), float(path.t0), float(path.tf), str(path.frame), int(samples))
    hit = _DENSE.get(key)
    if hit is None:
        t, pts = path.sample(samples)
        t.flags.writeable = pts.flags.writeable = False
        hit = (t, pts, cKDTree(pts))
        if len(_DENSE) >= 4:
            _DENSE.pop(next(iter(_DENSE)))
        _DENSE[key] = hit
    return hit


def path_errors_closest(path_native: BernsteinPath, p_native: np.ndarray, samples: int = 20001
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(horizontal, vertical) errors of points from the closest point of the path (dense samples, KD-tree).

    Components in the path's horizontal-normal frame there: horizontal > 0 left of the path, vertical > 0
    above it (the same frame as the rate stack's p_T).
    """
    p_native = np.asarray(p_native, float).reshape(-1, 3)
    if len(p_native) == 0:
        return np.zeros(0), np.zeros(0)
    t, pts, tree = _dense_samples(path_native, samples)
    _, k = tree.query(p_native)
    d = np.asarray(path_native.velocity(t[k]), float).reshape(-1, 3)
    t1 = d / np.linalg.norm(d, axis=1, keepdims=True)
    h = np.c_[-d[:, 1], d[:, 0], np.zeros(len(d))]
    t2 = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    t3 = np.cross(t1, t2)
    e = p_native - pts[k]
    return np.einsum("ij,ij->i", e, t2), np.einsum("ij,ij->i", e, t3)


def summarize(runner: Any, traj: Mapping[str, np.ndarray], path_native: BernsteinPath,
              wall_time_s: float) -> MissionSummary:
    m = runner.mission
    rv, mv = rms_max(np.asarray(traj["e_vertical_m"]))
    rh, mh = rms_max(np.asarray(traj["e_horizontal_m"]))
    P = np.c_[traj["x_m"], traj["y_m"], traj["z_m"]]
    eh_c, ev_c = path_errors_closest(path_native, P)
    rvc, mvc = rms_max(ev_c)
    rhc, mhc = rms_max(eh_c)
    cl = np.asarray(traj["clearance_m"])
    if np.isfinite(cl).any():
        k = int(np.nanargmin(cl))
        min_cl, t_cl = float(cl[k]), float(traj["t_s"][k])
        min_hull = float(np.nanmin(traj["hull_clearance_m"]))
    else:
        min_cl = t_cl = min_hull = math.nan
    t_end = float(runner.sim.t)
    g = np.asarray(traj["virtual_time_s"])
    nav = getattr(m, "navigation", "truth")
    rn, mn = rms_max(np.asarray(traj.get("nav_position_error_m", [])))
    _, mpsi = rms_max(np.asarray(traj.get("nav_heading_error_deg", [])))
    return MissionSummary(
        mission=m.name, stack=runner.stack.name, adaptation=m.adaptation, mission_time_s=t_end,
        completed=runner.end_reason is EndReason.FINISHED, end_reason=runner.end_reason,
        rms_vertical_m=rv, max_vertical_m=mv, rms_horizontal_m=rh, max_horizontal_m=mh,
        rms_vertical_closest_m=rvc, max_vertical_closest_m=mvc, rms_horizontal_closest_m=rhc,
        max_horizontal_closest_m=mhc, min_clearance_m=min_cl, min_clearance_t_s=t_cl,
        min_hull_clearance_m=min_hull, virtual_time_end_s=float(g[-1]) if g.size else math.nan,
        wall_time_s=wall_time_s, event=runner.event, navigation=nav, rms_nav_error_m=rn, max_nav_error_m=mn,
        max_nav_heading_error_deg=mpsi)

