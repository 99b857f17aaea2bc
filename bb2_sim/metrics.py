"""Key figures of the BB2 maneuvers (ITTC-style turning circle, zig-zags, self-propulsion, open loop).

Input is a *trajectory*: a mapping from the column names of the maneuver CSV files (REFERENCE.md,
"CSV columns": ``t_s, x_m, y_m, z_m, phi_deg, ..., torque_Nm``) to 1-D numpy arrays of equal length, as
returned by :func:`load_csv`.  Everything is in the ROM's native frames:

* earth: ``x_E, y_E`` horizontal, z up (z < 0 submerged); at psi = 0 the bow points to -x_E and +y_E is
  the initial starboard side;
* body: x aft, y starboard, z up (u < 0 moving ahead);
* Euler angles ZYX: theta > 0 bow up, phi > 0 starboard up, psi > 0 bow to port (unwrapped).

The figures are frozen dataclasses whose fields are in SI units and radians (the field name carries the
unit); :meth:`Figures.as_rows` converts to the units a naval architect reads (deg, deg/s, kN, kt, x/L) for
printing, and :meth:`Figures.to_dict` gives the raw SI values.  Figures that a run does not reach (e.g. a
turn that never gets to 180 degrees) are ``nan``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from bb2_sim.names import did_you_mean
from bb2_sim.parameters import RomParameters, load_parameters

Trajectory = Mapping[str, np.ndarray]

PLANE_COLUMNS = tuple(f"dX{i}_deg" for i in range(1, 6))
CMD_COLUMNS = tuple(f"cmd_dX{i}_deg" for i in range(1, 6))
KNOT_M_S = 1852.0 / 3600.0

__all__ = [
    "TrajectoryError", "Figures", "TurningCircleFigures", "ZigzagFigures", "SelfPropulsionFigures",
    "DepthHeadingFigures", "OpenLoopFigures", "load_csv", "turning_circle_figures", "zigzag_figures",
    "self_propulsion_figures", "depth_heading_figures", "open_loop_figures", "figures_for",
    "imposed_channels_deg", "MANEUVER_NAMES", "format_value",
]


class TrajectoryError(ValueError):
    """A trajectory is missing columns, has inconsistent lengths, or is too short for the figure asked."""


# ------------------------------------------------------------------------------------------ base type
_DISPLAY = {  # SI unit -> (display unit, factor)
    "rad": ("deg", 180.0 / math.pi),
    "rad/s": ("deg/s", 180.0 / math.pi),
    "N": ("kN", 1e-3),
    "N·m": ("kN·m", 1e-3),
}


def _fig(label: str, unit: str = "", *, per_length: bool = False, knots: bool = False) -> Any:
    """A dataclass field with its printed label, SI unit, and optional extra rows (x/L, knots)."""
    return field(metadata={"label": label, "unit": unit, "per_length": per_length, "knots": knots})


def _convert(value: Any, factor: float) -> Any:
    if isinstance(value, tuple):
        return tuple(_convert(v, factor) for v in value)
    if isinstance(value, (float, int, np.floating)) and not isinstance(value, bool):
        return float(value) * factor
    return value


@dataclass(frozen=True)
class Figures:
    """Base of the figure dataclasses: printing helpers."""

    def to_dict(self) -> dict[str, Any]:
        """Field name -> value, in SI units and radians."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def as_rows(self) -> list[tuple[str, Any, str]]:
        """(label, value, unit) rows in display units (deg, deg/s, kN, kt); tuples stay tuples."""
        rows: list[tuple[str, Any, str]] = []
        length = getattr(self, "length_m", float("nan"))
        for f in fields(self):
            md = f.metadata
            if not md:
                continue
            value = getattr(self, f.name)
            rows.append(self.row(f.name))
            if md["per_length"] and np.isfinite(length):
                rows.append((md["label"] + " / L", _convert(value, 1.0 / length), "-"))
            if md["knots"]:
                rows.append((md["label"], _convert(value, 1.0 / KNOT_M_S), "kt"))
        return rows

    def unreached(self) -> list[str]:
        """Labels of the figures that are NaN (a tuple: every item NaN): what the run did not reach, as a run too
        short for a crossing or a steady phase (a turning circle of less than 360 deg has no steady turn)."""
        names = set(self.unreached_fields())
        return [f.metadata["label"] for f in fields(self) if f.name in names]

    def unreached_fields(self) -> list[str]:
        """Field names of :meth:`unreached`, in order."""
        def missing(value: Any) -> bool:
            if isinstance(value, tuple):
                return bool(value) and all(missing(v) for v in value)
            return isinstance(value, (float, np.floating)) and math.isnan(value)

        undefined = self._undefined()
        return [f.name for f in fields(self)
                if f.metadata and f.name not in undefined and missing(getattr(self, f.name))]

    def _undefined(self) -> set[str]:
        """Names of the fields that are NaN by definition in this run (no order given), not for want of time."""
        return set()

    def row(self, name: str) -> tuple[str, Any, str]:
        """(label, value, unit) of one field in display units (deg, deg/s, kN)."""
        f = {f.name: f for f in fields(self)}.get(name)
        if f is None or not f.metadata:
            raise KeyError(f"{type(self).__name__} has no figure {name!r}")
        unit = f.metadata["unit"]
        shown_unit, factor = _DISPLAY.get(unit, (unit, 1.0))
        return f.metadata["label"], _convert(getattr(self, name), factor), shown_unit

    def format(self, title: str | None = None) -> str:
        """A plain-text table of :meth:`as_rows`."""
        lines = [title] if title else []
        for label, value, unit in self.as_rows():
            lines.append(f"  {label:<38s} {_fmt(value):>28s} {unit}")
        return "\n".join(lines)


def format_value(value: Any) -> str:
    """Compact text of a figure value (float, tuple of floats, or string)."""
    return _fmt(value)


def _fmt(value: Any) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(_fmt(v) for v in value) + ")" if value else "none"
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.6g}"
    return str(value)


# ----------------------------------------------------------------------------------------- input
def load_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read a maneuver CSV (one header line of column names) into {column: float array}."""
    path = Path(path)
    if not path.is_file():
        raise TrajectoryError(f"no trajectory file {path}")
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=float, encoding="utf-8")
    if data.dtype.names is None or data.ndim != 1 or data.size < 2:
        raise TrajectoryError(f"{path}: expected a header line and at least two rows of numbers")
    return {name: np.asarray(data[name], dtype=float) for name in data.dtype.names}


def _columns(traj: Trajectory, *names: str, min_rows: int = 2) -> list[np.ndarray]:
    missing = [n for n in names if n not in traj]
    if missing:
        raise TrajectoryError(f"trajectory lacks column(s) {', '.join(missing)}")
    out = [np.asarray(traj[n], dtype=float).ravel() for n in names]
    t = np.asarray(traj["t_s"], dtype=float).ravel() if "t_s" in traj else out[0]
    for n, a in zip(names, out):
        if a.shape != t.shape:
            raise TrajectoryError(f"column {n} has {a.size} rows, t_s has {t.size}")
    if t.size < min_rows:
        raise TrajectoryError(f"trajectory has {t.size} rows, need at least {min_rows}")
    return out


def _time(traj: Trajectory, min_rows: int = 2) -> np.ndarray:
    (t,) = _columns(traj, "t_s", min_rows=min_rows)
    if not np.all(np.diff(t) > 0):
        raise TrajectoryError("t_s must be strictly increasing")
    return t


def _rad(traj: Trajectory, name: str) -> np.ndarray:
    return np.radians(_columns(traj, name)[0])


def _crossing(t: np.ndarray, s: np.ndarray, level: float) -> tuple[float, int, float]:
    """First time where s reaches level from below: (t, index i with s[i] >= level, fraction in [i-1, i])."""
    idx = np.flatnonzero(s >= level)
    if idx.size == 0:
        return float("nan"), -1, float("nan")
    i = int(idx[0])
    if i == 0:
        return float(t[0]), 0, 1.0
    f = (level - s[i - 1]) / (s[i] - s[i - 1])
    return float(t[i - 1] + f * (t[i] - t[i - 1])), i, float(f)


def _at(a: np.ndarray, i: int, f: float) -> float:
    if i < 0:
        return float("nan")
    if i == 0:
        return float(a[0])
    return float(a[i - 1] + f * (a[i] - a[i - 1]))


def _window(t: np.ndarray, seconds: float) -> np.ndarray:
    """Boolean mask of the last `seconds` of the run."""
    if not seconds > 0:
        raise TrajectoryError(f"window must be positive, got {seconds} s")
    return t >= t[-1] - seconds - 1e-9


def _mean(traj: Trajectory, name: str, mask: np.ndarray) -> float:
    if name not in traj:
        return float("nan")
    return float(np.mean(np.asarray(traj[name], dtype=float)[mask]))


def _planes_rad(traj: Trajectory, mask: np.ndarray) -> tuple[float, ...]:
    return tuple(math.radians(_mean(traj, c, mask)) for c in PLANE_COLUMNS)


def imposed_channels_deg(traj: Trajectory, commanded: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Vertical and horizontal plane commands (dv, dh) [deg] recovered from the X-plane columns.

    Inverts the authors' allocation ``[-dv+dh, -dv-dh, dv-dh, dv+dh, dv]`` (REFERENCE.md section 1) on the
    four stern planes: ``dh = (d1 - d2 - d3 + d4)/4``, ``dv = (-d1 - d2 + d3 + d4)/4``.  dv > 0 pitches the
    bow up, dh > 0 turns to port.  ``commanded`` selects the ``cmd_dX*`` columns, else the applied ``dX*``.
    """
    cols = CMD_COLUMNS if commanded else PLANE_COLUMNS
    d1, d2, d3, d4 = _columns(traj, *cols[:4])
    return (-d1 - d2 + d3 + d4) / 4.0, (d1 - d2 - d3 + d4) / 4.0


# -------------------------------------------------------------------------------- turning circle
@dataclass(frozen=True)
class TurningCircleFigures(Figures):
    """ITTC turning-circle figures.  Advance/transfer are measured from the CG position at t = 0 along
    and across the initial heading; transfer is positive toward the side of the turn, so a port turn and its
    mirrored starboard turn give the same numbers."""

    turn_direction: str = _fig("Turn direction")
    length_m: float = _fig("Reference length L", "m")
    advance_90_m: float = _fig("Advance (90 deg)", "m", per_length=True)
    transfer_90_m: float = _fig("Transfer (90 deg)", "m", per_length=True)
    tactical_diameter_m: float = _fig("Tactical diameter (180 deg)", "m", per_length=True)
    advance_180_m: float = _fig("Advance at 180 deg", "m")
    time_90_s: float = _fig("Time to 90 deg", "s")
    time_180_s: float = _fig("Time to 180 deg", "s")
    time_360_s: float = _fig("Time to 360 deg", "s")
    steady_window_s: tuple[float, float] = _fig("Steady window (last 360 deg)", "s")
    steady_radius_m: float = _fig("Steady turning radius (circle fit)", "m")
    steady_diameter_m: float = _fig("Steady turning diameter", "m", per_length=True)
    circle_fit_max_residual_m: float = _fig("Circle fit max residual", "m")
    circle_centre_drift_m: float = _fig("Circle centre drift over last turn", "m")
    u_over_r_m: float = _fig("U/|r|", "m")
    steady_yaw_rate_rad_s: float = _fig("Steady yaw rate r", "rad/s")
    initial_speed_m_s: float = _fig("Approach speed U0", "m/s")
    steady_speed_m_s: float = _fig("Steady speed U", "m/s", knots=True)
    speed_ratio: float = _fig("Speed ratio U/U0", "-")
    drift_angle_rad: float = _fig("Drift angle beta = atan2(-v, -u)", "rad")
    steady_roll_rad: float = _fig("Steady roll phi", "rad")
    peak_roll_rad: float = _fig("Peak roll phi", "rad")
    steady_pitch_rad: float = _fig("Steady pitch theta", "rad")
    initial_z_m: float = _fig("z at t = 0", "m")
    final_z_m: float = _fig("z at end", "m")
    z_change_m: float = _fig("z change (+ = rose)", "m")
    steady_planes_rad: tuple[float, ...] = _fig("Steady planes dX1..dX5", "rad")
    steady_rps: float = _fig("Steady propeller n", "1/s")
    steady_thrust_N: float = _fig("Steady thrust (open water)", "N")
    steady_torque_Nm: float = _fig("Steady torque", "N·m")


def _fit_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares circle (geometric distance) through points: (xc, yc, R, max |residual|)."""
    A = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    (a, b, c), *_ = np.linalg.lstsq(A, x ** 2 + y ** 2, rcond=None)   # algebraic (Kasa) start
    r0 = math.sqrt(max(c + a * a + b * b, 0.0))

    def residual(p: np.ndarray) -> np.ndarray:
        return np.hypot(x - p[0], y - p[1]) - p[2]

    from scipy import optimize  # here, not at import (scipy.optimize costs a process ~0.4 s)

    sol = optimize.least_squares(residual, [a, b, r0], method="lm", xtol=1e-14, ftol=1e-14)
    xc, yc, R = sol.x
    return float(xc), float(yc), float(abs(R)), float(np.max(np.abs(residual(sol.x))))


def turning_circle_figures(traj: Trajectory, length_m: float | None = None,
                           params: RomParameters | None = None) -> TurningCircleFigures:
    """Turning-circle figures of a starboard or port turn started at t = 0.

    The steady phase is the last 360 degrees of heading change; its figures are means over that window and
    the radius comes from a least-squares circle fit to the CG track there.  Crossing times and positions
    are interpolated linearly between rows.  ``length_m`` defaults to the ROM's L (70.2 m).
    """
    t = _time(traj, min_rows=3)
    x, y, z, U = _columns(traj, "x_m", "y_m", "z_m", "U_m_s")
    psi, phi, theta = _rad(traj, "psi_deg"), _rad(traj, "phi_deg"), _rad(traj, "theta_deg")
    u, v = _columns(traj, "u_m_s", "v_m_s")
    r = _rad(traj, "r_deg_s")
    L = float(length_m) if length_m is not None else (params or load_parameters()).L

    dpsi = psi - psi[0]
    k_end = int(np.argmax(np.abs(dpsi)))
    if abs(dpsi[k_end]) < math.radians(1.0):
        raise TrajectoryError("heading changes by less than 1 deg: not a turning circle")
    starboard = dpsi[k_end] < 0.0          # psi > 0 is bow to port: a starboard turn makes psi decrease
    change = -dpsi if starboard else dpsi   # heading change toward the turn side, rad
    side = 1.0 if starboard else -1.0
    c0, s0 = math.cos(psi[0]), math.sin(psi[0])
    dx, dy = x - x[0], y - y[0]
    along = -c0 * dx - s0 * dy              # along the initial bow direction (-x_E rotated by psi0)
    across = side * (-s0 * dx + c0 * dy)    # toward the turn side (initial starboard for a starboard turn)

    t90, i90, f90 = _crossing(t, change, math.pi / 2)
    t180, i180, f180 = _crossing(t, change, math.pi)
    t360, _, _ = _crossing(t, change, 2 * math.pi)

    nan = float("nan")
    fit = (nan, nan, nan, nan)
    drift = nan
    window: tuple[float, float] = (nan, nan)
    if change[-1] >= 2 * math.pi:
        steady = change >= change[-1] - 2 * math.pi
        window = (float(t[steady][0]), float(t[-1]))
        fit = _fit_circle(x[steady], y[steady])
        if change[-1] >= 4 * math.pi:
            prev = (change >= change[-1] - 4 * math.pi) & (change <= change[-1] - 2 * math.pi)
            p = _fit_circle(x[prev], y[prev])
            drift = math.hypot(fit[0] - p[0], fit[1] - p[1])
    else:
        steady = np.zeros_like(t, dtype=bool)
    have_steady = bool(steady.any())

    def smean(a: np.ndarray) -> float:
        return float(np.mean(a[steady])) if have_steady else nan

    r_ss, U_ss = smean(r), smean(U)
    beta = np.arctan2(-v, -u)
    k_roll = int(np.argmax(np.abs(phi)))
    planes = _planes_rad(traj, steady) if have_steady else (nan,) * 5
    return TurningCircleFigures(
        turn_direction="starboard" if starboard else "port", length_m=L,
        advance_90_m=_at(along, i90, f90), transfer_90_m=_at(across, i90, f90),
        tactical_diameter_m=_at(across, i180, f180), advance_180_m=_at(along, i180, f180),
        time_90_s=t90, time_180_s=t180, time_360_s=t360,
        steady_window_s=window, steady_radius_m=fit[2], steady_diameter_m=2 * fit[2],
        circle_fit_max_residual_m=fit[3], circle_centre_drift_m=drift,
        u_over_r_m=U_ss / abs(r_ss) if have_steady and r_ss != 0 else nan,
        steady_yaw_rate_rad_s=r_ss, initial_speed_m_s=float(U[0]), steady_speed_m_s=U_ss,
        speed_ratio=U_ss / float(U[0]) if U[0] > 0 else nan, drift_angle_rad=smean(beta),
        steady_roll_rad=smean(phi), peak_roll_rad=float(phi[k_roll]), steady_pitch_rad=smean(theta),
        initial_z_m=float(z[0]), final_z_m=float(z[-1]), z_change_m=float(z[-1] - z[0]),
        steady_planes_rad=planes,
        steady_rps=_mean(traj, "n_rps", steady) if have_steady else nan,
        steady_thrust_N=_mean(traj, "thrust_N", steady) if have_steady else nan,
        steady_torque_Nm=_mean(traj, "torque_Nm", steady) if have_steady else nan,
    )


# ------------------------------------------------------------------------------------------ zig-zag
_ZIGZAG_ANGLES = {"psi_deg": "psi", "theta_deg": "theta", "psi": "psi", "theta": "theta"}


@dataclass(frozen=True)
class ZigzagFigures(Figures):
    """Zig-zag figures (horizontal: psi and the rudder dh; vertical: theta and the stern planes dv).

    Angles are relative to their value at t = 0.  Overshoot k is how far the angle goes beyond the check
    angle after reversal k (before reversal k+1); a last swing whose peak is not inside the run is left out.
    Periods are reversal k -> k+2.
    """

    angle: str = _fig("Zig-zag angle")
    amplitude_rad: float = _fig("Command amplitude A", "rad")
    check_rad: float = _fig("Check angle C", "rad")
    reversal_times_s: tuple[float, ...] = _fig("Reversal times", "s")
    time_to_first_check_s: float = _fig("Time to first check", "s")
    first_peak_time_s: float = _fig("Time of first peak (T1)", "s")
    overshoots_rad: tuple[float, ...] = _fig("Overshoots (all)", "rad")
    peak_times_s: tuple[float, ...] = _fig("Peak times", "s")
    peak_angles_rad: tuple[float, ...] = _fig("Peak angles", "rad")
    first_overshoot_rad: float = _fig("First overshoot", "rad")
    second_overshoot_rad: float = _fig("Second overshoot", "rad")
    later_overshoots_positive_rad: tuple[float, ...] = _fig("Later overshoots, + side", "rad")
    later_overshoots_negative_rad: tuple[float, ...] = _fig("Later overshoots, - side", "rad")
    periods_s: tuple[float, ...] = _fig("Periods (reversal k -> k+2)", "s")
    first_period_s: float = _fig("First full period", "s")
    settled_period_s: float = _fig("Settled period (last)", "s")
    initial_speed_m_s: float = _fig("Initial speed U0", "m/s")
    min_speed_m_s: float = _fig("Minimum speed U", "m/s")
    max_speed_m_s: float = _fig("Maximum speed U", "m/s")
    settled_from_s: float = _fig("Settled phase from", "s")
    settled_forward_speed_range_m_s: tuple[float, float] = _fig("Settled forward speed -u range", "m/s")
    z_range_m: tuple[float, float] = _fig("z range", "m")
    theta_range_rad: tuple[float, float] = _fig("theta range", "rad")
    phi_range_rad: tuple[float, float] = _fig("phi range", "rad")
    psi_range_rad: tuple[float, float] = _fig("psi range", "rad")
    max_abs_pitch_rate_rad_s: float = _fig("max |q|", "rad/s")
    max_abs_yaw_rate_rad_s: float = _fig("max |r|", "rad/s")
    saturated_planes: tuple[str, ...] = _fig("Planes at the deflection limit")
    plane_saturation_fraction: tuple[float, ...] = _fig("Time fraction at limit dX1..dX5", "-")


def _refine_switch(t: np.ndarray, rel: np.ndarray, k: int, sign: float, check: float, step_s: float) -> float:
    """Time of a reversal first seen in row k: the first controller step in (t[k-1], t[k]] at which the
    linearly interpolated angle has reached the check angle (rows may be coarser than the step)."""
    if k == 0:
        return float(t[0])
    t0, t1 = float(t[k - 1]), float(t[k])
    n = max(int(round((t1 - t0) / step_s)), 1)
    for j in range(1, n + 1):
        tj = t0 + j * (t1 - t0) / n
        a = rel[k - 1] + (rel[k] - rel[k - 1]) * (tj - t0) / (t1 - t0)
        if sign * a >= check - 1e-12:
            return tj
    return t1


def _reversals(t: np.ndarray, rel: np.ndarray, cmd: np.ndarray | None, check: float,
               step_s: float) -> tuple[list[float], list[float]]:
    """Reversal times and the sign of the command *before* each reversal."""
    times: list[float] = []
    signs: list[float] = []
    if cmd is not None and np.any(np.abs(cmd) > 1e-9):
        s = np.sign(np.where(np.abs(cmd) > 1e-9, cmd, 0.0))
        nz = np.flatnonzero(s)
        last = s[nz[0]]
        for k in nz[1:]:
            if s[k] != last:
                times.append(_refine_switch(t, rel, int(k), last, check, step_s))
                signs.append(float(last))
                last = s[k]
        return times, signs
    # no command columns: the angle reaching +-check alternately, starting with whichever comes first
    hit_pos, hit_neg = np.flatnonzero(rel >= check), np.flatnonzero(rel <= -check)
    if hit_pos.size == 0 and hit_neg.size == 0:
        return times, signs
    sign = 1.0 if (hit_neg.size == 0 or (hit_pos.size and hit_pos[0] < hit_neg[0])) else -1.0
    start = 0
    while True:
        idx = np.flatnonzero(sign * rel[start:] >= check)
        if idx.size == 0:
            break
        k = start + int(idx[0])
        if k == 0:
            times.append(float(t[0]))
        else:
            f = (sign * check - rel[k - 1]) / (rel[k] - rel[k - 1])
            times.append(float(t[k - 1] + f * (t[k] - t[k - 1])))
        signs.append(sign)
        sign, start = -sign, k
    return times, signs


def _peak(t: np.ndarray, a: np.ndarray, i: int) -> tuple[float, float]:
    """Peak of a sampled signal at index i refined by the parabola through its neighbours."""
    if 0 < i < a.size - 1:
        y0, y1, y2 = a[i - 1], a[i], a[i + 1]
        den = y0 - 2 * y1 + y2
        if den != 0:
            d = 0.5 * (y0 - y2) / den
            if abs(d) <= 1:
                dt = 0.5 * (t[i + 1] - t[i - 1])
                return float(t[i] + d * dt), float(y1 - 0.25 * (y0 - y2) * d)
    return float(t[i]), float(a[i])


def zigzag_figures(traj: Trajectory, angle_column: str, amplitude_deg: float, check_deg: float | None = None,
                   *, step_s: float | None = None, settled_from_s: float | None = None,
                   params: RomParameters | None = None) -> ZigzagFigures:
    """Figures of a horizontal (``angle_column='psi_deg'``) or vertical (``'theta_deg'``) zig-zag A/C.

    Reversals are taken from the sign changes of the imposed command recovered from the ``cmd_dX*``
    columns (dh for psi, dv for theta, see :func:`imposed_channels_deg`), placed on the controller step
    ``step_s`` (default the ROM's 0.05 s) where the angle reached the check angle; without command columns,
    from the angle reaching +-check alternately (linear interpolation).  The settled phase (forward speed
    range) starts at ``settled_from_s``, default the third reversal (one full cycle done).
    """
    if angle_column not in _ZIGZAG_ANGLES:
        raise TrajectoryError(f"zig-zag angle must be psi_deg or theta_deg, got {angle_column!r}")
    if not amplitude_deg > 0:
        raise TrajectoryError(f"zig-zag amplitude must be positive, got {amplitude_deg}")
    check_deg = amplitude_deg if check_deg is None else check_deg
    if not check_deg > 0:
        raise TrajectoryError(f"zig-zag check angle must be positive, got {check_deg}")
    p = params or load_parameters()
    step = p.h if step_s is None else float(step_s)
    angle = _ZIGZAG_ANGLES[angle_column]
    t = _time(traj, min_rows=3)
    a = _rad(traj, angle + "_deg")
    rel = a - a[0]
    check = math.radians(check_deg)
    cmd = None
    if all(c in traj for c in CMD_COLUMNS[:4]):
        dv, dh = imposed_channels_deg(traj)
        cmd = dh if angle == "psi" else dv
    rev, signs = _reversals(t, rel, cmd, check, step)

    overshoots: list[float] = []
    peak_t: list[float] = []
    peak_a: list[float] = []
    bounds = rev + [float(t[-1]) + 1.0]
    for k, (tr, sg) in enumerate(zip(rev, signs)):
        m = np.flatnonzero((t >= tr) & (t < bounds[k + 1]))
        if m.size < 2:
            break
        i = int(m[np.argmax(sg * rel[m])])
        if i == m[-1] or i == t.size - 1:     # still swinging at the end of the segment: no peak
            break
        tp, ap = _peak(t, sg * rel, i)
        overshoots.append(ap - check)
        peak_t.append(tp)
        peak_a.append(sg * ap)
    nan = float("nan")
    periods = tuple(rev[k + 2] - rev[k] for k in range(len(rev) - 2))
    later = list(zip(overshoots[2:], signs[2:len(overshoots)]))

    U, u, z = _columns(traj, "U_m_s", "u_m_s", "z_m")
    theta, phi, psi = _rad(traj, "theta_deg"), _rad(traj, "phi_deg"), _rad(traj, "psi_deg")
    q, r = _rad(traj, "q_deg_s"), _rad(traj, "r_deg_s")
    t_set = settled_from_s if settled_from_s is not None else (rev[2] if len(rev) > 2 else float(t[0]))
    settled = t >= t_set
    fwd = -u[settled]
    limit = p.act["plane_limit_deg"]
    frac = tuple(float(np.mean(np.abs(np.asarray(traj[c], float)) >= limit - 1e-6)) if c in traj else nan
                 for c in PLANE_COLUMNS)
    sat = tuple(c.removesuffix("_deg") for c, f in zip(PLANE_COLUMNS, frac) if f > 0)
    return ZigzagFigures(
        angle=angle, amplitude_rad=math.radians(amplitude_deg), check_rad=check,
        reversal_times_s=tuple(rev), time_to_first_check_s=rev[0] if rev else nan,
        first_peak_time_s=peak_t[0] if peak_t else nan, overshoots_rad=tuple(overshoots), peak_times_s=tuple(peak_t),
        peak_angles_rad=tuple(peak_a),
        first_overshoot_rad=overshoots[0] if overshoots else nan,
        second_overshoot_rad=overshoots[1] if len(overshoots) > 1 else nan,
        later_overshoots_positive_rad=tuple(o for o, s in later if s > 0),
        later_overshoots_negative_rad=tuple(o for o, s in later if s < 0),
        periods_s=periods, first_period_s=periods[0] if periods else nan,
        settled_period_s=periods[-1] if periods else nan,
        initial_speed_m_s=float(U[0]), min_speed_m_s=float(U.min()), max_speed_m_s=float(U.max()),
        settled_from_s=float(t_set),
        settled_forward_speed_range_m_s=(float(fwd.min()), float(fwd.max())) if fwd.size else (nan, nan),
        z_range_m=(float(z.min()), float(z.max())),
        theta_range_rad=(float(theta.min()), float(theta.max())),
        phi_range_rad=(float(phi.min()), float(phi.max())),
        psi_range_rad=(float(psi.min()), float(psi.max())),
        max_abs_pitch_rate_rad_s=float(np.abs(q).max()), max_abs_yaw_rate_rad_s=float(np.abs(r).max()),
        saturated_planes=sat, plane_saturation_fraction=frac,
    )


# ------------------------------------------------------------------------------- steady straight runs
@dataclass(frozen=True)
class SelfPropulsionFigures(Figures):
    """Self-propulsion point: means over the last ``settle_window_s`` of the run; the drifts are the change
    (last row minus first row of that window) and show whether the run has converged."""

    window_s: tuple[float, float] = _fig("Averaging window", "s")
    forward_speed_m_s: float = _fig("Forward speed -u", "m/s", knots=True)
    speed_m_s: float = _fig("Speed U", "m/s", knots=True)
    rps: float = _fig("Propeller n", "1/s")
    advance_coefficient: float = _fig("Advance coefficient J", "-")
    KT: float = _fig("KT", "-")
    KQ: float = _fig("KQ", "-")
    thrust_N: float = _fig("Thrust (open water)", "N")
    thrust_deduction: float = _fig("Thrust deduction t", "-")
    net_thrust_N: float = _fig("Net thrust (1-t)T", "N")
    torque_Nm: float = _fig("Torque", "N·m")
    z_m: float = _fig("z", "m")
    z_ref_m: float = _fig("z reference", "m")
    z_error_m: float = _fig("z - z_ref (+ = shallower)", "m")
    pitch_rad: float = _fig("Pitch theta", "rad")
    roll_rad: float = _fig("Roll phi", "rad")
    heave_velocity_m_s: float = _fig("Heave velocity w (body, up)", "m/s")
    planes_rad: tuple[float, ...] = _fig("Planes dX1..dX5", "rad")
    speed_drift_m_s: float = _fig("Drift of u over window", "m/s")
    z_drift_m: float = _fig("Drift of z over window", "m")
    pitch_drift_rad: float = _fig("Drift of theta over window", "rad")


def self_propulsion_figures(traj: Trajectory, settle_window_s: float = 50.0,
                            z_ref_m: float | None = None) -> SelfPropulsionFigures:
    """Steady straight-ahead figures over the last ``settle_window_s`` seconds (z_ref_m: the depth order,
    z up, for the depth error; optional)."""
    t = _time(traj)
    m = _window(t, settle_window_s)
    u, z = _columns(traj, "u_m_s", "z_m")
    theta = _rad(traj, "theta_deg")
    first = int(np.flatnonzero(m)[0])
    zm = _mean(traj, "z_m", m)
    zr = float("nan") if z_ref_m is None else float(z_ref_m)
    return SelfPropulsionFigures(
        window_s=(float(t[first]), float(t[-1])), forward_speed_m_s=-_mean(traj, "u_m_s", m),
        speed_m_s=_mean(traj, "U_m_s", m), rps=_mean(traj, "n_rps", m),
        advance_coefficient=_mean(traj, "J", m), KT=_mean(traj, "KT", m), KQ=_mean(traj, "KQ", m),
        thrust_N=_mean(traj, "thrust_N", m), thrust_deduction=_mean(traj, "thrust_deduction", m),
        net_thrust_N=_mean(traj, "thrust_net_N", m), torque_Nm=_mean(traj, "torque_Nm", m),
        z_m=zm, z_ref_m=zr, z_error_m=zm - zr,
        pitch_rad=float(np.mean(theta[m])), roll_rad=math.radians(_mean(traj, "phi_deg", m)),
        heave_velocity_m_s=_mean(traj, "w_m_s", m), planes_rad=_planes_rad(traj, m),
        speed_drift_m_s=float(u[-1] - u[first]), z_drift_m=float(z[-1] - z[first]),
        pitch_drift_rad=float(theta[-1] - theta[first]),
    )


@dataclass(frozen=True)
class DepthHeadingFigures(Figures):
    """Response to a depth and heading order flown by an autopilot (orders held from t = 0)."""

    initial_z_m: float = _fig("z at t = 0", "m")
    z_ref_m: float = _fig("z order", "m")
    final_z_m: float = _fig("z at end", "m")
    z_error_m: float = _fig("final z - z_ref", "m")
    z_rise_time_s: float = _fig("Time to 90 % of the depth change", "s")
    z_overshoot_m: float = _fig("Depth overshoot past the order", "m")
    initial_psi_rad: float = _fig("psi at t = 0", "rad")
    psi_ref_rad: float = _fig("psi order", "rad")
    final_psi_rad: float = _fig("psi at end", "rad")
    psi_rise_time_s: float = _fig("Time to 90 % of the heading change", "s")
    psi_overshoot_rad: float = _fig("Heading overshoot past the order", "rad")
    theta_range_rad: tuple[float, float] = _fig("theta range", "rad")
    phi_range_rad: tuple[float, float] = _fig("phi range", "rad")
    speed_range_m_s: tuple[float, float] = _fig("Speed U range", "m/s")
    max_abs_plane_rad: float = _fig("max |dX|", "rad")

    def _undefined(self) -> set[str]:
        """Without an order, its figures; with an order equal to the start, its step response (no change)."""
        out: set[str] = set()
        for ref, start, names in ((self.z_ref_m, self.initial_z_m,
                                   ("z_ref_m", "z_error_m", "z_rise_time_s", "z_overshoot_m")),
                                  (self.psi_ref_rad, self.initial_psi_rad,
                                   ("psi_ref_rad", "psi_rise_time_s", "psi_overshoot_rad"))):
            if not math.isfinite(ref):
                out.update(names)
            elif ref == start:
                out.update(names[-2:])
        return out


def _step_response(t: np.ndarray, y: np.ndarray, ref: float) -> tuple[float, float]:
    """(time to 90 % of the change y0 -> ref, overshoot past ref in the direction of the change)."""
    nan = float("nan")
    if not np.isfinite(ref) or ref == y[0]:
        return nan, nan
    s = 1.0 if ref > y[0] else -1.0
    rise = _crossing(t, s * (y - y[0]), 0.9 * s * (ref - y[0]))[0]
    return rise, max(float(np.max(s * (y - ref))), 0.0)


def depth_heading_figures(traj: Trajectory, z_ref_m: float | None = None,
                          psi_ref_rad: float | None = None) -> DepthHeadingFigures:
    """Depth/heading change figures; without orders only the end state and ranges are filled."""
    t = _time(traj)
    z, U = _columns(traj, "z_m", "U_m_s")
    psi, theta, phi = _rad(traj, "psi_deg"), _rad(traj, "theta_deg"), _rad(traj, "phi_deg")
    nan = float("nan")
    zr = nan if z_ref_m is None else float(z_ref_m)
    pr = nan if psi_ref_rad is None else float(psi_ref_rad)
    z_rise, z_os = _step_response(t, z, zr)
    p_rise, p_os = _step_response(t, psi, pr)
    planes = [np.abs(np.asarray(traj[c], float)) for c in PLANE_COLUMNS if c in traj]
    return DepthHeadingFigures(
        initial_z_m=float(z[0]), z_ref_m=zr, final_z_m=float(z[-1]), z_error_m=float(z[-1]) - zr,
        z_rise_time_s=z_rise, z_overshoot_m=z_os, initial_psi_rad=float(psi[0]), psi_ref_rad=pr,
        final_psi_rad=float(psi[-1]), psi_rise_time_s=p_rise, psi_overshoot_rad=p_os,
        theta_range_rad=(float(theta.min()), float(theta.max())),
        phi_range_rad=(float(phi.min()), float(phi.max())), speed_range_m_s=(float(U.min()), float(U.max())),
        max_abs_plane_rad=math.radians(float(max(p.max() for p in planes))) if planes else nan,
    )


@dataclass(frozen=True)
class OpenLoopFigures(Figures):
    """Open-loop run: end state, drifts from t = 0, and rates fitted over the last ``window_s``."""

    window_s: tuple[float, float] = _fig("Steady window", "s")
    final_forward_speed_m_s: float = _fig("Forward speed -u at end", "m/s")
    steady_speed_m_s: float = _fig("Speed U (window mean)", "m/s", knots=True)
    initial_z_m: float = _fig("z at t = 0", "m")
    final_z_m: float = _fig("z at end", "m")
    z_change_m: float = _fig("z change (+ = rose)", "m")
    dive_rate_m_s: float = _fig("dz/dt (fit over window, + = rising)", "m/s")
    final_pitch_rad: float = _fig("theta at end", "rad")
    final_roll_rad: float = _fig("phi at end", "rad")
    steady_pitch_rad: float = _fig("theta (window mean)", "rad")
    steady_roll_rad: float = _fig("phi (window mean)", "rad")
    final_yaw_rate_rad_s: float = _fig("r at end", "rad/s")
    steady_yaw_rate_rad_s: float = _fig("r (window mean)", "rad/s")
    heading_change_rad: float = _fig("psi change", "rad")


def open_loop_figures(traj: Trajectory, settle_window_s: float = 50.0) -> OpenLoopFigures:
    """Open-loop (imposed planes) figures: final state, drifts and steady rates."""
    t = _time(traj)
    m = _window(t, settle_window_s)
    u, z, U = _columns(traj, "u_m_s", "z_m", "U_m_s")
    theta, phi, psi, r = (_rad(traj, c) for c in ("theta_deg", "phi_deg", "psi_deg", "r_deg_s"))
    tw = t[m]
    rate = float(np.polyfit(tw - tw[0], z[m], 1)[0]) if tw.size > 1 else float("nan")
    return OpenLoopFigures(
        window_s=(float(tw[0]), float(t[-1])), final_forward_speed_m_s=float(-u[-1]),
        steady_speed_m_s=float(np.mean(U[m])), initial_z_m=float(z[0]), final_z_m=float(z[-1]),
        z_change_m=float(z[-1] - z[0]), dive_rate_m_s=rate, final_pitch_rad=float(theta[-1]),
        final_roll_rad=float(phi[-1]), steady_pitch_rad=float(np.mean(theta[m])),
        steady_roll_rad=float(np.mean(phi[m])), final_yaw_rate_rad_s=float(r[-1]),
        steady_yaw_rate_rad_s=float(np.mean(r[m])), heading_change_rad=float(psi[-1] - psi[0]),
    )


# ------------------------------------------------------------------------------------------ dispatch
MANEUVER_NAMES = ("self-propulsion", "depth-heading", "turning-circle", "hzz", "vzz", "open-loop")


def _z_ref(settings: Mapping[str, Any], *depth_keys: str) -> float | None:
    """Depth order as z (up) from settings: ``z_ref_m`` or a positive-down depth under one of depth_keys."""
    if settings.get("z_ref_m") is not None:
        return float(settings["z_ref_m"])
    for k in depth_keys:
        if settings.get(k) is not None:
            return -float(settings[k])
    return None


FIGURE_SETTINGS = ("settle_window_s", "amplitude_deg", "check_deg", "settled_from_s", "z_ref_m", "depth_ref", "depth",
                   "heading_ref_deg", "length_m")
"""The settings :func:`figures_for` reads (the others of a maneuver's entry are ignored)."""


def figures_for(maneuver_name: str, traj: Trajectory, **settings: Any) -> Figures:
    """Figures of a named maneuver (names of ``bb2_sim/data/maneuvers.yaml``).

    Settings that matter are picked from ``settings`` (the maneuver's entry; others are ignored):
    ``settle_window_s``; zig-zags ``amplitude_deg``, ``check_deg``, ``settled_from_s``; depth orders
    ``z_ref_m`` (z up) or ``depth_ref``/``depth`` (m, positive down); ``heading_ref_deg``.
    """
    name = maneuver_name.strip().lower().replace("_", "-")
    window = float(settings.get("settle_window_s", 50.0))
    if name == "self-propulsion":
        return self_propulsion_figures(traj, window, z_ref_m=_z_ref(settings, "depth_ref", "depth"))
    if name == "depth-heading":
        hd = settings.get("heading_ref_deg")
        return depth_heading_figures(traj, z_ref_m=_z_ref(settings, "depth_ref"),
                                     psi_ref_rad=None if hd is None else math.radians(float(hd)))
    if name == "turning-circle":
        return turning_circle_figures(traj, length_m=settings.get("length_m"))
    if name in ("hzz", "vzz"):
        if settings.get("amplitude_deg") is None:
            raise TrajectoryError(f"{name}: settings need amplitude_deg")
        return zigzag_figures(traj, "psi_deg" if name == "hzz" else "theta_deg",
                              float(settings["amplitude_deg"]), settings.get("check_deg"),
                              settled_from_s=settings.get("settled_from_s"))
    if name == "open-loop":
        return open_loop_figures(traj, window)
    raise TrajectoryError(f"unknown maneuver {maneuver_name!r}{did_you_mean(maneuver_name, MANEUVER_NAMES)}; known: "
                          f"{', '.join(MANEUVER_NAMES)}")
