"""Navigation filter: the vehicle state the stack flies on when a mission says ``navigation: sensors`` (no ROS).

The paper flies its stack on the ROM's exact state (``navigation: truth``, the default).  With
``navigation: sensors`` the stack flies on this filter's estimate instead, built only from the samples of a
:class:`bb2_sim.sensors.SensorSuite` in the order they come out of the sensors.  Loosely coupled, in REP-103
frames (map ENU, base_link FLU at the CG):

* attitude: the IMU's orientation output (its AHRS), turned from the imu frame to base_link by the mounting;
* angular velocity: the gyro, in base_link (its bias is left in: 1e-6 rad/s tactical, 1e-3 rad/s MEMS at most);
* position and velocity over ground, the accelerometer bias and the errors that make dead reckoning drift:
  a 12-state Kalman filter ``x = [p_enu, v_enu, b_flu, k, dpsi, dz]`` -- ``k`` the DVL's scale-factor error,
  ``dpsi`` the AHRS heading error and ``dz`` the depth error of the pressure sensor's zero offset: constant
  errors that per-sample noise cannot represent (averaging them away would make the filter overconfident).
  Predicted at every IMU sample with the previous sample's specific force turned to ENU plus gravity
  (``a = R_enu_flu (f - b) + g_enu``; ``dpsi`` grows as the AHRS's heading drift rate times the time, plus its
  random walk), corrected by

  - the DVL velocity, the lever arm removed (``v_cg = R_flu_dvl v - w x r``), turned to ENU with the AHRS
    heading: ``z = (1 + k) Rz(dpsi) v_enu`` linearised about the estimate (an extended filter), applied when
    it arrives (its latency, 0.1-0.15 s, is not compensated).  Bottom track is over ground; water track is
    through the water, taken as over ground within ``water_track.current_sigma_m_s`` (the filter does not know
    the current).  The sample's covariance less its scale-factor term (a state here) plus the AHRS's
    per-sample heading and tilt noise turning the velocity;
  - the depth of the pressure sensor, hydrostatic ``(P - P_atm) / (rho g)`` with the suite's atmospheric
    pressure, moved to the CG through the attitude: ``z_measured = z + dz`` with the white noise and resolution
    of the sensor (the offset is ``dz``); skipped while the sensor is within 3 sigma of the surface, where the
    reading only says "not deeper";
  - the GPS fix while surfaced, the antenna's lever arm removed (never gated: a first fix after a long dive
    may be far from the dead-reckoned position).  Fixes while moving make ``k`` and ``dpsi`` observable.

  The stack gets the AHRS attitude as it is (``dpsi`` corrects the velocity and position, not the heading
  the stack flies on).

  A DVL or pressure innovation outside ``gating.probability`` of its chi-square law is rejected and counted
  (a stuck value, a bias step).

Every measurement noise is the sample's own covariance (the suite's covariances); the process noise is the
accelerometer's white-noise density plus ``process.extra_accel_noise_m_s2_sqrt_hz`` and the AHRS tilt noise
turning gravity; the bias walks with the accelerometer's bias random walk from its turn-on sigma.  The filter
starts at the mission's initial state within ``initial``.  Tuning: ``data/navigation.yaml``.  The altimeter is
not used.

:meth:`NavigationFilter.state` gives the estimate at a time as a :class:`~bb2_sim.state.VehicleState` in the
ROM's native frames, the heading unwrapped continuously from the initial one::

    nav = NavigationFilter(suite.config, x0_native, rho=p.rho, g=p.g)   # p = bb2_sim.parameters.load_parameters()
    for each tick n:  state_n = nav.state(t_n);  ... ;  nav.update(suite.step(truth_n, truth_n+1))
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from bb2_control.config import DATA_DIR, load_mapping, require
from bb2_control.errors import ControlConfigError
from bb2_sim.constants import G_M_S2, RHO_KG_M3
from bb2_sim.sensors.config import rotation_rpy
from bb2_sim.state import VehicleState

__all__ = ["NavigationSettings", "NavigationFilter", "NavigationStats", "load_navigation_settings", "N_STATES"]

_D = np.array([-1.0, -1.0, 1.0])   # native body <-> FLU and native earth <-> ENU
_I3 = np.eye(3)
_I = np.arange(3)
_EZ = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])   # [e_z x]
N_STATES = 12   #: p_enu (3), v_enu (3), accel bias b_flu (3), DVL scale error k, heading error dpsi, depth offset dz


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors (numpy's cross costs ten times more on one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rotation_xyzw(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of the quaternion (x, y, z, w), normalised (as scipy's ``Rotation.from_quat``)."""
    x, y, z, w = q / math.sqrt(float(q @ q))
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@dataclass(frozen=True)
class NavigationSettings:
    """What the sensor suite cannot tell the filter (``data/navigation.yaml``; SI units)."""

    position_sigma_m: float         #: 1 sigma per axis of the initial position, m
    velocity_sigma_m_s: float       #: 1 sigma per axis of the initial velocity, m/s
    extra_accel_noise: float        #: white acceleration noise beside the accelerometer's, m/s^2/sqrt(Hz)
    current_sigma_m_s: float        #: the unknown current, 1 sigma per horizontal axis of a water track, m/s
    gate_probability: float         #: chi-square gate of the DVL and pressure innovations

    def __post_init__(self) -> None:
        for name in ("position_sigma_m", "velocity_sigma_m_s", "current_sigma_m_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ControlConfigError(f"navigation: {name} must be > 0 and finite, got {v}")
        if not (math.isfinite(self.extra_accel_noise) and self.extra_accel_noise >= 0):
            raise ControlConfigError(f"navigation: extra_accel_noise must be >= 0, got {self.extra_accel_noise}")
        if not 0.5 < self.gate_probability < 1.0:
            raise ControlConfigError(f"navigation: gating.probability must be in (0.5, 1), got "
                                     f"{self.gate_probability}")

    @classmethod
    def from_mapping(cls, doc: Mapping[str, Any], where: str = "navigation settings") -> "NavigationSettings":
        try:
            return cls(float(require(require(doc, "initial", where), "position_sigma_m", f"{where}.initial")),
                       float(require(doc["initial"], "velocity_sigma_m_s", f"{where}.initial")),
                       float(require(require(doc, "process", where), "extra_accel_noise_m_s2_sqrt_hz",
                                     f"{where}.process")),
                       float(require(require(doc, "water_track", where), "current_sigma_m_s",
                                     f"{where}.water_track")),
                       float(require(require(doc, "gating", where), "probability", f"{where}.gating")))
        except (TypeError, ValueError) as exc:
            raise ControlConfigError(f"{where}: {exc}") from None


def load_navigation_settings(path: str | Path | None = None) -> NavigationSettings:
    """The filter's tuning from ``path`` (default ``bb2_control/data/navigation.yaml``)."""
    p = Path(path) if path is not None else DATA_DIR / "navigation.yaml"
    return NavigationSettings.from_mapping(load_mapping(p), str(p))


@dataclass
class NavigationStats:
    """Measurements used and rejected (by the gate) per sensor, and those the filter does not use."""

    used: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    ignored: dict[str, int] = field(default_factory=dict)

    def count(self, kind: str, sensor: str) -> None:
        d = getattr(self, kind)
        d[sensor] = d.get(sensor, 0) + 1


class NavigationFilter:
    """The filter of the module docstring, for the sensors of ``suite`` (a ``SuiteConfig``), started at the ROM
    state ``x0_native`` (12, native frames) at time ``t0``."""

    def __init__(self, suite: Any, x0_native: np.ndarray, *, t0: float = 0.0, rho: float = RHO_KG_M3,
                 g: float = G_M_S2, settings: NavigationSettings | None = None) -> None:
        if getattr(suite, "imu", None) is None:
            raise ControlConfigError(f"navigation: sensors needs an IMU in the sensor suite (attitude and rates); "
                                     f"the suite {getattr(suite, 'name', '?')!r} has none")
        self.suite = suite
        self.settings = s = settings or load_navigation_settings()
        self.rho, self.g = float(rho), float(g)
        self.g_enu = np.array([0.0, 0.0, -self.g])
        imu = suite.imu
        self._R_flu_imu = imu.mounting.R_flu_sensor
        self._r_imu = np.asarray(imu.mounting.position_flu, float)
        acc = imu.accel
        self._q_accel = acc.noise_density ** 2 + s.extra_accel_noise ** 2          # m^2/s^3
        self._tilt_q = np.array([1.0, 1.0, 0.0]) * (self.g * imu.ahrs.roll_pitch_noise) ** 2  # (m/s^2)^2/sample
        self._q_bias = acc.bias_random_walk ** 2                                    # m^2/s^5
        from scipy.stats import chi2  # here, not at import: scipy.stats costs a process ~0.6 s

        self._gate = {n: float(chi2.ppf(s.gate_probability, n)) for n in (1, 3)}
        self.stats = NavigationStats()

        x0 = np.asarray(x0_native, dtype=float)
        if x0.shape != (12,) or not np.all(np.isfinite(x0)):
            raise ControlConfigError(f"navigation: the initial state must be 12 finite numbers, got {x0}")
        self.t = float(t0)
        self.R_enu_flu = rotation_rpy(-x0[3], -x0[4], x0[5])
        self.w_flu = x0[9:12] * _D
        self.f_flu = self.R_enu_flu.T @ -self.g_enu       # at rest until the first IMU sample
        self._yaw = float(x0[5])                           # unwrapped, continuous from the initial heading
        self.x = np.concatenate([x0[0:3] * _D, self.R_enu_flu @ (x0[6:9] * _D), np.zeros(N_STATES - 6)])
        b0 = acc.turn_on_bias ** 2 + acc.bias_instability ** 2
        k0 = suite.dvl.scale_factor ** 2 if suite.dvl is not None else 0.0
        rg = self.rho * self.g
        dz0 = (suite.pressure.offset_pa / rg) ** 2 if suite.pressure is not None else 0.0
        self.P = np.diag([s.position_sigma_m ** 2] * 3 + [s.velocity_sigma_m_s ** 2] * 3 + [b0] * 3
                         + [k0, imu.ahrs.heading_noise ** 2, dz0])
        self._t0 = self.t
        self._heading_drift_var = imu.ahrs.heading_drift ** 2      # (rad/s)^2: var(drift t) = sigma^2 t^2
        self._heading_rw_var = imu.ahrs.heading_random_walk ** 2   # rad^2/s
        self._heading_white_var = imu.ahrs.heading_noise ** 2      # rad^2 per AHRS sample
        self._tilt_white_var = imu.ahrs.roll_pitch_noise ** 2

    # ------------------------------------------------------------------ the filter
    def _propagate(self, t: float) -> None:
        dt = float(t) - self.t
        if dt <= 0.0:
            return
        R = self.R_enu_flu
        a = R @ (self.f_flu - self.x[6:9]) + self.g_enu
        self.x[0:3] += self.x[3:6] * dt + 0.5 * a * dt * dt
        self.x[3:6] += a * dt
        F = np.eye(N_STATES)
        F[0:3, 3:6] = _I3 * dt
        F[0:3, 6:9] = -0.5 * dt * dt * R
        F[3:6, 6:9] = -dt * R
        q = self._q_accel
        P = F @ self.P @ F.T                             # + Q: white acceleration, tilt noise, bias walk, heading
        P[_I, _I] += q * dt ** 3 / 3.0
        P[_I, _I + 3] += q * dt ** 2 / 2.0
        P[_I + 3, _I] += q * dt ** 2 / 2.0
        P[_I + 3, _I + 3] += q * dt + self._tilt_q * dt * dt
        P[_I + 6, _I + 6] += self._q_bias * dt
        P[10, 10] += (2.0 * self._heading_drift_var * (0.5 * (self.t + t) - self._t0) + self._heading_rw_var) * dt
        self.P = P
        self.t = float(t)

    def _correct(self, sensor: str, nu: np.ndarray, H: np.ndarray, Rm: np.ndarray, gate: bool) -> bool:
        """The update with innovation ``nu`` (measured minus predicted) and Jacobian ``H``."""
        S = H @ self.P @ H.T + Rm
        Sinv = np.linalg.inv(S)
        if gate and float(nu @ Sinv @ nu) > self._gate[nu.size]:
            self.stats.count("rejected", sensor)
            return False
        K = self.P @ H.T @ Sinv
        self.x = self.x + K @ nu
        IKH = np.eye(N_STATES) - K @ H
        self.P = IKH @ self.P @ IKH.T + K @ Rm @ K.T      # Joseph form: stays symmetric positive definite
        self.stats.count("used", sensor)
        return True

    # ------------------------------------------------------------------ the samples
    def update(self, samples: Iterable[Any]) -> None:
        """Take the sensor samples (``bb2_sim.sensors.samples``) in the order they came out of the sensors."""
        handlers = {"imu": self._imu, "dvl": self._dvl, "pressure": self._pressure, "gps": self._gps}
        for smp in samples:
            handler = handlers.get(smp.sensor)
            if handler is None:
                self.stats.count("ignored", smp.sensor)
            else:
                handler(smp)

    def _imu(self, s: Any) -> None:
        self._propagate(s.t)                             # with the previous sample's specific force
        R_imu = self._R_flu_imu
        w = R_imu @ np.asarray(s.angular_velocity, float)
        f = R_imu @ np.asarray(s.specific_force, float)
        q = np.asarray(s.orientation_xyzw, float)
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(f)) and np.all(np.isfinite(q))
                and np.linalg.norm(q) > 0.5):
            self.stats.count("rejected", "imu")
            return
        self.R_enu_flu = _rotation_xyzw(q) @ R_imu.T
        self.w_flu = w
        self.f_flu = f - _cross(w, _cross(w, self._r_imu))   # to the CG (the angular acceleration left out)
        yaw = math.atan2(self.R_enu_flu[1, 0], self.R_enu_flu[0, 0])
        self._yaw += math.remainder(yaw - self._yaw, 2.0 * math.pi)
        self.stats.count("used", "imu")

    def _dvl(self, s: Any) -> None:
        cfg = self.suite.dvl
        R_flu_dvl = cfg.mounting.R_flu_sensor
        v = np.asarray(s.velocity, float)
        C = np.asarray(s.covariance, float)
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(C))):
            self.stats.count("rejected", "dvl")
            return
        speed = float(np.linalg.norm(v))
        C = C - _I3 * (cfg.scale_factor * speed) ** 2           # the scale factor is the state k here
        v_cg = R_flu_dvl @ v - _cross(self.w_flu, np.asarray(cfg.mounting.position_flu, float))
        R = self.R_enu_flu @ R_flu_dvl
        Rm = R @ C @ R.T + np.diag([self._heading_white_var, self._heading_white_var, self._tilt_white_var]) \
            * speed ** 2                                        # the AHRS's own noise turning this velocity
        if not s.bottom_lock:
            Rm = Rm + np.diag([1.0, 1.0, 0.0]) * self.settings.current_sigma_m_s ** 2
        v_e, k, dpsi = self.x[3:6], float(self.x[9]), float(self.x[10])
        ez_v = np.array([-v_e[1], v_e[0], 0.0])                 # d(Rz(dpsi) v)/d dpsi at dpsi ~ 0
        H = np.zeros((3, N_STATES))
        H[:, 3:6] = (1.0 + k) * (_I3 + dpsi * _EZ)
        H[:, 9] = v_e + dpsi * ez_v
        H[:, 10] = (1.0 + k) * ez_v
        predicted = (1.0 + k) * (v_e + dpsi * ez_v)
        self._correct("dvl", self.R_enu_flu @ v_cg - predicted, H, Rm, gate=True)

    def _pressure(self, s: Any) -> None:
        cfg = self.suite.pressure
        rg = self.rho * self.g
        column = (float(s.pressure_pa) - cfg.atmospheric_pressure_pa) / rg
        sigma = math.sqrt(cfg.noise_pa ** 2 + cfg.resolution_pa ** 2 / 12.0) / rg   # the offset is the state dz
        total = math.sqrt(max(float(s.variance_pa2), 0.0)) / rg
        if not (math.isfinite(column) and sigma > 0) or column <= 3.0 * max(sigma, total):
            self.stats.count("ignored", "pressure")
            return
        z_cg = -column - float(self.R_enu_flu[2] @ np.asarray(cfg.mounting.position_flu, float))
        H = np.zeros((1, N_STATES))
        H[0, 2] = H[0, 11] = 1.0
        self._correct("pressure", np.array([z_cg - self.x[2] - self.x[11]]), H, np.array([[sigma * sigma]]), gate=True)

    def _gps(self, s: Any) -> None:
        if not s.fix:
            self.stats.count("ignored", "gps")
            return
        p = np.asarray(s.position_enu, float) - self.R_enu_flu @ np.asarray(self.suite.gps.mounting.position_flu,
                                                                            float)
        C = np.asarray(s.covariance_enu, float)
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(C))):
            self.stats.count("rejected", "gps")
            return
        H = np.zeros((3, N_STATES))
        H[:, 0:3] = _I3
        self._correct("gps", p - self.x[0:3], H, C, gate=False)

    # ------------------------------------------------------------------ the estimate
    def state(self, t: float) -> VehicleState:
        """The estimate at ``t`` (>= the last sample's time: predicted on from it), native frames."""
        self._propagate(t)
        R = self.R_enu_flu
        roll = math.atan2(R[2, 1], R[2, 2])
        pitch = -math.asin(max(-1.0, min(1.0, R[2, 0])))
        return VehicleState(float(t), self.x[0:3] * _D, np.array([-roll, -pitch, self._yaw]),
                            (R.T @ self.x[3:6]) * _D, self.w_flu * _D)

    @property
    def position_sigma_m(self) -> np.ndarray:
        """1 sigma of the position estimate per ENU axis, m."""
        return np.sqrt(np.diag(self.P)[0:3])

    @property
    def accel_bias_flu(self) -> np.ndarray:
        """The estimated accelerometer bias, base_link axes, m/s^2."""
        return self.x[6:9].copy()

    @property
    def dvl_scale_error(self) -> float:
        """The estimated DVL scale-factor error k (measured = (1 + k) true)."""
        return float(self.x[9])

    @property
    def heading_error_rad(self) -> float:
        """The estimated AHRS heading error dpsi (AHRS minus true), rad."""
        return float(self.x[10])
