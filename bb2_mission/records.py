"""One tick of a mission as a named record: the row of the mission CSV (no ROS).

:class:`MissionRow` names every column; :data:`MISSION_COLUMNS` is its field order, which is the CSV's
column order (a contract: analysis tools read these names).  Rows are built from named fields, never from
positional lists, so a new column is one field here and one keyword where the row is made.
"""
from __future__ import annotations

import csv
import operator
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Iterator

import numpy as np

__all__ = ["MissionRow", "MISSION_COLUMNS", "read_mission_csv", "rows_to_columns"]


@dataclass(frozen=True, slots=True)
class MissionRow:
    """One Ts = 0.05 s tick: the state at t_n (native frames; angles in deg, rates in deg/s), the stack's
    output computed from it (rates rad/s; q_c about w2 is bow-down positive; u_ad_1/2 are the L1 outputs of the
    q/r or depth/heading channels), the plane commands and the actuator angles the ROM applies over
    [t_n, t_n+1), the virtual time, the desired position p_d (native), the stack's path errors (horizontal > 0:
    vehicle left of the path; vertical > 0: above), the terrain under the CG and the CG and hull clearances
    (NaN without terrain or off the grid).  With ``navigation: sensors`` the state columns stay the truth, the
    stack's path errors are those it flew on (of its navigation estimate: the true vehicle's are the summary's
    closest-point errors), and the last two columns are the error of that estimate (position, m; heading, deg,
    estimate minus truth); NaN when the stack flies on the truth."""

    t_s: float
    x_m: float
    y_m: float
    z_m: float
    phi_deg: float
    theta_deg: float
    psi_deg: float
    u_m_s: float
    v_m_s: float
    w_m_s: float
    p_deg_s: float
    q_deg_s: float
    r_deg_s: float
    U_m_s: float
    flight_path_angle_deg: float
    q_c_rad_s: float
    r_c_rad_s: float
    q_up_ref_rad_s: float
    r_left_ref_rad_s: float
    z_ref_m: float
    psi_ref_deg: float
    u_ad_1: float
    u_ad_2: float
    dV_deg: float
    dH_deg: float
    cmd_d1_deg: float
    cmd_d2_deg: float
    cmd_d3_deg: float
    cmd_d4_deg: float
    cmd_d5_deg: float
    d1_deg: float
    d2_deg: float
    d3_deg: float
    d4_deg: float
    d5_deg: float
    rps_cmd: float
    n_rps: float
    virtual_time_s: float
    virtual_time_rate: float
    xd_m: float
    yd_m: float
    zd_m: float
    e_horizontal_m: float
    e_vertical_m: float
    terrain_z_m: float
    clearance_m: float
    hull_clearance_m: float
    nav_position_error_m: float = float("nan")
    nav_heading_error_deg: float = float("nan")

    def values(self) -> list[float]:
        """The row in :data:`MISSION_COLUMNS` order."""
        return list(_ROW_VALUES(self))

    def __iter__(self) -> Iterator[float]:
        return iter(self.values())


MISSION_COLUMNS: list[str] = [f.name for f in fields(MissionRow)]
"""The mission CSV's columns, in order (the fields of :class:`MissionRow`)."""
_ROW_VALUES = operator.attrgetter(*MISSION_COLUMNS)   # a row's fields in that order, in one C call


def rows_to_columns(rows: list[MissionRow]) -> dict[str, np.ndarray]:
    """Rows -> ``{column: array}`` (one entry per tick)."""
    arr = np.array([r.values() for r in rows], dtype=float) if rows else np.zeros((0, len(MISSION_COLUMNS)))
    return {c: arr[:, i] for i, c in enumerate(MISSION_COLUMNS)}


def read_mission_csv(file: str | Path) -> dict[str, np.ndarray]:
    """A mission CSV back into column arrays (by the names in its header)."""
    with open(file, newline="") as fh:
        r = csv.reader(fh)
        head = next(r)
        data = np.array([[float(v) for v in row] for row in r], dtype=float).reshape(-1, len(head))
    return {c: data[:, i] for i, c in enumerate(head)}
