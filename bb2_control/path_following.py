"""3-D path-following law on SO(3) with virtual time (paper "Controller"; SPEC 3.1, gains of 2022).

Frames (all right-handed, inertial I is any z-up frame shared by the path and the vehicle, e.g. the
ROM native earth frame):

* B = FLU body (x forward, y port, z up); ``R_BI`` maps FLU components to I components.
* W = flow frame: w1 along the velocity, w2 = unit(z_B x w1) to port, w3 = w1 x w2 (SPEC 1).
* T = path frame at p_d(gamma): horizontal-normal frame t1 = p_d'/|p_d'|, t2 horizontal to the left.
* D = desired frame: b1 is a line of sight aimed ``d`` metres ahead along the path.

Each tick the law moves the virtual time ``gamma`` (forward Euler) and returns the rate commands
``(q_c, r_c)`` about w2 and w3 (rad/s).  :func:`flow_to_body_rates` converts them to the
sign-unambiguous body rates (q_up bow-up, r_left bow-to-port) used by the rate L1/autopilot.

Note the sign of q_c: it is a rotation about w2 (port), i.e. **bow-down positive**; q_up = -q_c for
zero flow angles.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Protocol

import numpy as np

from bb2_control.config import load_data, require
from bb2_control.errors import ControlConfigError, NonFiniteInputError, PathFollowingError
from bb2_sim.frames import cross as _cross  # a x b, the arithmetic of np.cross without its overhead

__all__ = [
    "PathLike", "PFGains", "PFOutput", "PathFollowing3D", "flow_frame", "flow_to_body_rates",
    "path_frame", "desired_frame", "attitude_error", "vee",
]

PI_R = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


class PathLike(Protocol):
    """What the laws need from a path (``bb2_planner.bernstein.BernsteinPath`` provides it)."""

    t0: float
    tf: float

    def __call__(self, t: float) -> np.ndarray: ...
    def velocity(self, t: float) -> np.ndarray: ...
    def acceleration(self, t: float) -> np.ndarray: ...


def _norm(a: np.ndarray) -> float:
    """|a| of a 1-D float array: ``np.linalg.norm``'s arithmetic (sqrt of a.dot(a)) without its overhead."""
    return math.sqrt(float(a.dot(a)))


def vee(S: np.ndarray) -> np.ndarray:
    """Inverse hat map of the skew part of ``S``: [[0,-a3,a2],[a3,0,-a1],[-a2,a1,0]] -> (a1, a2, a3)."""
    A = 0.5 * (S - S.T)
    return np.array([A[2, 1], A[0, 2], A[1, 0]])


def flow_frame(v_flu: np.ndarray) -> np.ndarray:
    """R_WB: columns w1, w2, w3 of the flow frame in FLU body components (SPEC 1)."""
    u, v, w = (float(x) for x in v_flu)
    if math.hypot(u, v) == 0.0 and w == 0.0:
        raise PathFollowingError("the flow frame is undefined at zero velocity")
    alpha = -math.atan2(w, math.hypot(u, v))
    beta = math.atan2(v, u)
    ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
    return np.array([[ca * cb, -sb, sa * cb],
                     [ca * sb, cb, sa * sb],
                     [-sa, 0.0, ca]])


def flow_to_body_rates(q_c: float, r_c: float, v_flu: np.ndarray) -> tuple[float, float]:
    """Flow-frame rate commands (about w2, w3) -> (q_up, r_left) body-rate references, rad/s.

    omega_B = R_WB (0, q_c, r_c) (zero roll command, dR_WB/dt neglected, SPEC 3.1);
    q_up = -(omega_B)_y (bow up), r_left = (omega_B)_z (bow to port) -- the ROM's native q and r.
    """
    w_b = flow_frame(v_flu) @ np.array([0.0, q_c, r_c])
    return float(-w_b[1]), float(w_b[2])


def path_frame(dp: np.ndarray) -> np.ndarray:
    """R_TI of the horizontal-normal frame for the path derivative ``dp`` (SPEC 3.1 step 2)."""
    sp = _norm(dp)
    x, y, _ = dp.tolist()
    h = math.hypot(x, y)
    if sp == 0.0:
        raise PathFollowingError("path speed |p_d'| is zero: the path frame is undefined")
    if h <= 1e-9 * sp:
        raise PathFollowingError("vertical path tangent: the horizontal-normal path frame is singular")
    t1 = dp / sp
    t2 = np.array([-y, x, 0.0]) / h
    return np.array([t1, t2, _cross(t1, t2)]).T


def desired_frame(y_T: float, z_T: float, d: float) -> np.ndarray:
    """R_DT: columns b1, b2, b3 of the line-of-sight frame in T components (SPEC 3.1 step 6)."""
    r3 = math.sqrt(d * d + y_T * y_T + z_T * z_T)
    r2 = math.hypot(d, y_T)
    b1 = np.array([d, -y_T, -z_T]) / r3
    b2 = np.array([y_T, d, 0.0]) / r2
    return np.array([b1, b2, _cross(b1, b2)]).T


def attitude_error(R_tilde: np.ndarray) -> tuple[float, np.ndarray]:
    """(Psi, e_R) of the paper for R_tilde = R_D^W: Psi = (1 - R11)/2, e_R = (R13, -R12)/2."""
    return 0.5 * (1.0 - R_tilde[0, 0]), 0.5 * np.array([R_tilde[0, 2], -R_tilde[0, 1]])


@dataclass(frozen=True)
class PFGains:
    """Gains of the 3-D law: k_gamma (1/s), k_R (1/s), d (m), gamma_dot_min, Ts (s), frame-rate method."""

    k_gamma: float = 1.0
    k_R: float = 0.1
    d: float = 250.0
    gamma0: float = 0.0
    gamma_dot_min: float = 1e-4
    Ts: float = 0.05
    frame_rates: str = "finite_difference"

    def __post_init__(self) -> None:
        for name in ("k_gamma", "k_R", "d", "Ts"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ControlConfigError(f"path following: {name} must be positive, got {v}")
        if self.frame_rates not in ("finite_difference", "analytic"):
            raise ControlConfigError(
                f"path following: frame_rates must be 'finite_difference' or 'analytic', got {self.frame_rates!r}")

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None = None) -> "PFGains":
        cfg = load_data("guidance")["pf_3d_so3_2022"] if cfg is None else cfg
        w = "path following"
        return cls(float(require(cfg, "k_gamma_per_s", w)), float(require(cfg, "k_R_per_s", w)),
                   float(require(cfg, "d_m", w)), float(cfg.get("gamma0_s", 0.0)),
                   float(cfg.get("gamma_dot_min", 0.0)), float(require(cfg, "Ts_s", w)),
                   str(cfg.get("frame_rates", "finite_difference")))


@dataclass(frozen=True)
class PFOutput:
    """One tick of the 3-D law.  Vectors in the inertial frame I unless stated."""

    q_c: float             #: rate command about w2 (port axis; bow-down positive), rad/s
    r_c: float             #: rate command about w3 (up axis; bow-to-port positive), rad/s
    gamma: float           #: virtual time used this tick, s
    gamma_dot: float       #: d gamma / dt, dimensionless
    p_d: np.ndarray        #: desired position p_d(gamma), m
    p_T: np.ndarray        #: path error (x_T, y_T, z_T) in T, m (y_T > 0: vehicle left of the path; z_T > 0 above)
    e_R: np.ndarray        #: attitude error (2,)
    Psi: float             #: attitude error function, 0..1
    finished: bool         #: gamma reached the end of the path


class PathFollowingLaw:
    """Common virtual-time bookkeeping for the guidance laws."""

    def __init__(self, path: PathLike, gamma0: float, Ts: float) -> None:
        self.path = path
        self.Ts = Ts
        self._gamma0 = float(path.t0) + gamma0
        self.gamma = self._gamma0

    @property
    def finished(self) -> bool:
        return self.gamma >= self.path.tf

    def rejoin(self, p: np.ndarray) -> tuple[float, float]:
        """Join a run under way: the virtual time goes to the path point closest to the vehicle position ``p``
        (m, the path's frame), as a law that had been running would hold it (the law then steps from there).
        Returns (gamma s, distance m).  For a controller restarted mid-run; a law that starts with the run keeps
        ``gamma0``."""
        p = np.asarray(p, dtype=float)
        if hasattr(self.path, "closest_point"):
            t, _, d = self.path.closest_point(p)
        else:
            ts = np.linspace(self.path.t0, self.path.tf, 20001)
            d2 = np.array([np.sum((np.asarray(self.path(t), float) - p) ** 2) for t in ts])
            t, d = float(ts[int(np.argmin(d2))]), float(np.sqrt(d2.min()))
        self.gamma = float(t)
        return self.gamma, float(d)


class PathFollowing3D(PathFollowingLaw):
    """The paper's 3-D SO(3) law.  ``step(p_I, R_BI, v_flu)`` once per Ts; ``reset()`` restarts gamma.

    State: gamma, previous R_TI and R_DT (initialised to the current ones: zero frame rates on the first
    tick).  Inputs are in a z-up inertial frame shared with the path.
    """

    def __init__(self, path: PathLike, gains: PFGains | None = None) -> None:
        self.gains = gains or PFGains.from_config()
        super().__init__(path, self.gains.gamma0, self.gains.Ts)
        self.reset()

    def reset(self) -> None:
        self.gamma = self._gamma0
        self._R_TI_prev: np.ndarray | None = None
        self._R_DT_prev: np.ndarray | None = None

    def step(self, p_I: np.ndarray, R_BI: np.ndarray, v_flu: np.ndarray) -> PFOutput:
        """One tick: position (m, I), FLU->I rotation, FLU velocity (m/s) -> rate commands; advances gamma."""
        p = np.asarray(p_I, dtype=float)
        R_BI = np.asarray(R_BI, dtype=float)
        v_b = np.asarray(v_flu, dtype=float)
        if not (np.isfinite(p).all() and np.isfinite(R_BI).all() and np.isfinite(v_b).all()):
            raise NonFiniteInputError(f"path following: non-finite input p={p}, v={v_b}, R_BI finite="
                                      f"{bool(np.all(np.isfinite(R_BI)))}")
        g = self.gains
        gam = float(min(max(self.gamma, self.path.t0), self.path.tf))  # np.clip's value, without its overhead
        p_d, dp = self._position_velocity(gam)
        R_TI = path_frame(dp)
        t1 = R_TI[:, 0]
        R_WB = flow_frame(v_b)
        R_WI = R_BI @ R_WB
        speed = _norm(v_b)
        gamma_dot = max(g.gamma_dot_min, float((speed * R_WI[:, 0] + g.k_gamma * (p - p_d)) @ t1) / _norm(dp))
        p_T = R_TI.T @ (p - p_d)
        R_DT = desired_frame(p_T[1], p_T[2], g.d)
        R_tilde = R_DT.T @ R_TI.T @ R_WI
        Psi, e_R = attitude_error(R_tilde)

        if g.frame_rates == "analytic":
            omega_T = self._analytic_omega_T(gam, dp, gamma_dot)
        else:
            prev = R_TI if self._R_TI_prev is None else self._R_TI_prev
            omega_T = vee(R_TI.T @ (R_TI - prev) / g.Ts)
        prev = R_DT if self._R_DT_prev is None else self._R_DT_prev
        omega_DT = vee(R_DT.T @ (R_DT - prev) / g.Ts)
        w_c = PI_R @ R_tilde.T @ (R_DT.T @ omega_T + omega_DT) - 2.0 * g.k_R * e_R

        out = PFOutput(float(w_c[0]), float(w_c[1]), gam, gamma_dot, p_d, p_T, e_R, float(Psi),
                       gam >= self.path.tf)
        self.gamma = self.gamma + g.Ts * gamma_dot
        self._R_TI_prev, self._R_DT_prev = R_TI, R_DT
        return out

    def _position_velocity(self, gam: float) -> tuple[np.ndarray, np.ndarray]:
        """(p_d, p_d') at virtual time ``gam``: one de Casteljau pass for a Bernstein path
        (``BernsteinPath.position_velocity``), else the path's two calls."""
        pv = getattr(self.path, "position_velocity", None)
        if pv is not None:
            return pv(gam)
        return np.asarray(self.path(gam), dtype=float), np.asarray(self.path.velocity(gam), dtype=float)

    def _analytic_omega_T(self, gam: float, dp: np.ndarray, gamma_dot: float) -> np.ndarray:
        """Exact angular velocity of the horizontal-normal frame in T (SPEC 3.2)."""
        ddp = np.asarray(self.path.acceleration(gam), dtype=float)
        h2 = dp[0] ** 2 + dp[1] ** 2
        h = math.sqrt(h2)
        chi_p = (dp[0] * ddp[1] - dp[1] * ddp[0]) / h2
        th_p = (ddp[2] * h2 - dp[2] * (dp[0] * ddp[0] + dp[1] * ddp[1])) / (float(dp @ dp) * h)
        th = math.atan2(dp[2], h)
        return gamma_dot * np.array([chi_p * math.sin(th), -th_p, chi_p * math.cos(th)])
