"""The truth the sensor models sample: the ROM state at its steps, and its values between them (no ROS).

A :class:`TruthSample` is what the ROM knows at a major step ``t_n``: the state (native frames), the body-frame
derivatives of the velocity and the angular velocity at ``t_n`` (``StepRecord.ev.xdot[6:12]``, from which the
specific force comes), and the vertical clearance of the CG above the terrain (NaN: no terrain / off the grid).

A sensor sampled at ``t`` in ``[t_n, t_n+1)`` sees :func:`interpolate`: position, Euler angles (psi unwrapped),
velocities and rates linear between the two steps; the accelerations and the specific force held at ``t_n``
(the ROM's own zero-order hold over the step: its commands and Derivative blocks are held there too); the
clearance linear.  Everything is returned in REP-103 frames (ENU world, FLU base_link), the sensors' frames.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..constants import G_M_S2

__all__ = ["TruthSample", "TruthBatch", "truth_from_step", "interpolate", "rotations_enu_flu",
           "specific_force_native"]

_D = np.array([-1.0, -1.0, 1.0])   # native body <-> FLU and native earth <-> ENU (diag(-1, -1, 1))


@dataclass(frozen=True)
class TruthSample:
    """The truth at one ROM step (native frames as the ROM: see :mod:`bb2_sim.state`)."""

    t: float
    x12: np.ndarray                   #: [x y z phi theta psi u v w p q r], native
    v_dot_body_native: np.ndarray     #: d(u, v, w)/dt in body axes, m/s^2
    w_dot_body_native: np.ndarray     #: d(p, q, r)/dt, rad/s^2
    clearance_m: float = math.nan     #: CG height above the terrain (vertical), m; NaN = unknown
    g: float = G_M_S2


def truth_from_step(t: float, x12, xdot12=None, clearance_m: float = math.nan, g: float = G_M_S2) -> TruthSample:
    """A :class:`TruthSample` from the ROM's state and its derivative (``StepRecord.ev.xdot``; None = zeros)."""
    x = np.array(x12, dtype=float)
    xd = np.zeros(12) if xdot12 is None else np.asarray(xdot12, dtype=float)
    return TruthSample(float(t), x, xd[6:9].copy(), xd[9:12].copy(), float(clearance_m), float(g))


def specific_force_native(x12, v_dot_body_native, g: float) -> np.ndarray:
    """Specific force at the CG, native body axes: ``dv/dt|_body + w x v - R^T g_earth`` (g_earth = (0, 0, -g))."""
    x = np.asarray(x12, dtype=float)
    phi, theta = x[3], x[4]
    # R^T (0, 0, -g) = -g * (third row of R)  = -g (-sin th, sin ph cos th, cos ph cos th)
    g_body = -g * np.array([-math.sin(theta), math.sin(phi) * math.cos(theta), math.cos(phi) * math.cos(theta)])
    return np.asarray(v_dot_body_native, float) + np.cross(x[9:12], x[6:9]) - g_body


def rotations_enu_flu(roll, pitch, yaw) -> np.ndarray:
    """R_enu_flu = Rz(yaw) Ry(pitch) Rx(roll) for arrays of REP-103 angles, shape (n, 3, 3)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    R = np.empty(np.shape(roll) + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


@dataclass(frozen=True)
class TruthBatch:
    """The truth at ``n`` sample times, REP-103 frames: ``p_enu`` (n, 3) of the CG, ``rpy`` (n, 3) REP-103 roll,
    pitch, yaw of base_link in ENU, ``R_enu_flu`` (n, 3, 3), ``v_flu``/``w_flu``/``w_dot_flu``/``f_flu`` (n, 3)
    (velocity over ground, rates, angular acceleration, specific force at the CG), ``clearance_m`` (n,)."""

    t: np.ndarray
    p_enu: np.ndarray
    rpy: np.ndarray
    R_enu_flu: np.ndarray
    v_flu: np.ndarray
    w_flu: np.ndarray
    w_dot_flu: np.ndarray
    f_flu: np.ndarray
    clearance_m: np.ndarray

    @property
    def n(self) -> int:
        return int(self.t.size)

    def point_enu(self, r_flu) -> np.ndarray:
        """ENU positions (n, 3) of a point fixed in base_link at ``r_flu`` (m)."""
        return self.p_enu + self.R_enu_flu @ np.asarray(r_flu, float)

    def point_velocity_flu(self, r_flu) -> np.ndarray:
        """Velocity over ground (n, 3) of the point ``r_flu``, base_link axes: v + w x r."""
        return self.v_flu + np.cross(self.w_flu, np.asarray(r_flu, float))

    def point_specific_force_flu(self, r_flu) -> np.ndarray:
        """Specific force (n, 3) at the point ``r_flu``, base_link axes: f + w_dot x r + w x (w x r)."""
        r = np.asarray(r_flu, float)
        return self.f_flu + np.cross(self.w_dot_flu, r) + np.cross(self.w_flu, np.cross(self.w_flu, r))


def interpolate(a: TruthSample, b: TruthSample | None, t) -> TruthBatch:
    """The truth at times ``t`` (array) in ``[a.t, b.t]`` (module docstring); ``b`` None holds ``a``."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    xa = a.x12
    if b is None or b.t <= a.t:
        s = np.zeros_like(t)
        dx = np.zeros(12)
        dh = 0.0
    else:
        s = (t - a.t) / (b.t - a.t)
        dx = b.x12 - xa
        dx[5] = math.remainder(dx[5], 2.0 * math.pi)   # psi unwrapped across +-pi
        dh = (b.clearance_m - a.clearance_m) if math.isfinite(a.clearance_m) and math.isfinite(b.clearance_m) \
            else 0.0
    x = xa[None, :] + s[:, None] * dx[None, :]
    roll, pitch, yaw = -x[:, 3], -x[:, 4], x[:, 5]
    R = rotations_enu_flu(roll, pitch, yaw)
    # specific force: the kinematic acceleration held at t_n, gravity turned with the interpolated attitude
    # (at t_n it equals specific_force_native in FLU)
    kin_flu = _D * (a.v_dot_body_native + np.cross(xa[9:12], xa[6:9]))
    g_enu = np.array([0.0, 0.0, -a.g])
    f_flu = kin_flu[None, :] - np.einsum("nji,j->ni", R, g_enu)
    n = t.size
    return TruthBatch(
        t=t, p_enu=x[:, 0:3] * _D, rpy=np.column_stack([roll, pitch, yaw]), R_enu_flu=R,
        v_flu=x[:, 6:9] * _D, w_flu=x[:, 9:12] * _D,
        w_dot_flu=np.broadcast_to(_D * a.w_dot_body_native, (n, 3)).copy(), f_flu=f_flu,
        clearance_m=a.clearance_m + s * dh if math.isfinite(a.clearance_m) else np.full(n, math.nan))
