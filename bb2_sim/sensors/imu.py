"""IMU: gyros, accelerometers and an AHRS-like orientation output, in the imu frame (no ROS).

Per axis (IEEE Std 952 terms, :mod:`bb2_sim.sensors.noise`)::

    gyro  = (I + S_g + M_g) w_imu + b_on + b_gm(t) + b_rw(t) + N_g / sqrt(dt) w
    accel = (I + S_a + M_a) f_imu + b_on + b_gm(t) + b_rw(t) + N_a / sqrt(dt) w

``w_imu``/``f_imu`` the true angular velocity and specific force at the mounting point in the imu frame (lever arm
included: f + w_dot x r + w x (w x r)); ``S`` diagonal scale-factor errors and ``M`` small off-diagonal
misalignments, ``b_on`` the turn-on bias -- drawn once per seed; ``b_gm`` the Gauss-Markov bias instability and
``b_rw`` the bias random walk.

Orientation (AHRS-like, not integrated from these gyros): the true attitude of base_link with roll/pitch white
noise and a heading error = white noise + a constant drift rate (drawn per seed) * t + a random walk, composed with
the mounting: the quaternion of the imu frame in ENU (REP-145).  Its covariance grows with the drift's variance
(honest: the drift is unknown to the user).
"""
from __future__ import annotations

import math

import numpy as np

from .config import ImuConfig
from .noise import GaussMarkov, RandomWalk, stream
from .samples import ImuSample
from .truth import TruthBatch, rotations_enu_flu

__all__ = ["ImuModel", "quaternions_from_rotations"]

N_COLUMNS = 22   # per sample: gyro white, gm, rw (9); accel white, gm, rw (9); roll, pitch, yaw noise (3); yaw rw (1)


def _error_matrix(rng: np.random.Generator, scale: float, misalignment: float) -> np.ndarray:
    E = np.eye(3) + np.diag(scale * rng.standard_normal(3))
    off = misalignment * rng.standard_normal(6)
    E[0, 1], E[0, 2], E[1, 0], E[1, 2], E[2, 0], E[2, 1] = off
    return E


def quaternions_from_rotations(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) as (x, y, z, w), w >= 0, of rotation matrices (n, 3, 3)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R).as_quat()
    q[q[:, 3] < 0] *= -1.0
    return q


class ImuModel:
    name = "imu"

    def __init__(self, cfg: ImuConfig, seed: int, index: int = 0, t0: float = 0.0) -> None:
        self.cfg = cfg
        self.period = 1.0 / cfg.rate_hz
        dt = self.period
        init = stream(seed, index, 0)
        self.rng = stream(seed, index, 1)
        g, a, h = cfg.gyro, cfg.accel, cfg.ahrs
        self.E_g = _error_matrix(init, g.scale_factor, g.misalignment)
        self.E_a = _error_matrix(init, a.scale_factor, a.misalignment)
        self.b_on_g = g.turn_on_bias * init.standard_normal(3)
        self.b_on_a = a.turn_on_bias * init.standard_normal(3)
        self.gm_g = GaussMarkov(g.bias_instability, g.bias_instability_tau_s, dt, g.bias_instability
                                * init.standard_normal(3))
        self.gm_a = GaussMarkov(a.bias_instability, a.bias_instability_tau_s, dt, a.bias_instability
                                * init.standard_normal(3))
        self.rw_g = RandomWalk(g.bias_random_walk, dt, np.zeros(3))
        self.rw_a = RandomWalk(a.bias_random_walk, dt, np.zeros(3))
        self.heading_drift = h.heading_drift * float(init.standard_normal())
        self.rw_h = RandomWalk(h.heading_random_walk, dt, np.zeros(1))
        self.t0 = float(t0)
        M = cfg.mounting
        self.r_flu = M.position_flu
        self.R_flu_imu = M.R_flu_sensor
        self.sd_g = g.noise_density / math.sqrt(dt)
        self.sd_a = a.noise_density / math.sqrt(dt)

    def covariances(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orientation, angular-velocity and specific-force covariances (3x3) at time ``t``: white noise plus
        the sigma of every error the model keeps (turn-on bias, bias instability, random walk so far)."""
        c, el = self.cfg, max(0.0, t - self.t0)
        g, a, h = c.gyro, c.accel, c.ahrs
        vg = self.sd_g ** 2 + g.turn_on_bias ** 2 + g.bias_instability ** 2 + g.bias_random_walk ** 2 * el
        va = self.sd_a ** 2 + a.turn_on_bias ** 2 + a.bias_instability ** 2 + a.bias_random_walk ** 2 * el
        vyaw = h.heading_noise ** 2 + (h.heading_drift * el) ** 2 + h.heading_random_walk ** 2 * el
        return (np.diag([h.roll_pitch_noise ** 2, h.roll_pitch_noise ** 2, vyaw]), np.eye(3) * vg, np.eye(3) * va)

    def raw(self, w_imu: np.ndarray, f_imu: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gyro and accelerometer outputs (n, 3) from the true values in the imu frame and the draws W."""
        gyro = w_imu @ self.E_g.T + self.b_on_g + self.gm_g.run(W[:, 3:6]) + self.rw_g.run(W[:, 6:9]) \
            + self.sd_g * W[:, 0:3]
        acc = f_imu @ self.E_a.T + self.b_on_a + self.gm_a.run(W[:, 12:15]) + self.rw_a.run(W[:, 15:18]) \
            + self.sd_a * W[:, 9:12]
        return gyro, acc

    def sample(self, truth: TruthBatch, env=None) -> list[ImuSample]:
        n = truth.n
        W = self.rng.standard_normal((n, N_COLUMNS))
        Rt = self.R_flu_imu.T
        w_imu = truth.w_flu @ Rt.T
        f_imu = truth.point_specific_force_flu(self.r_flu) @ Rt.T
        gyro, acc = self.raw(w_imu, f_imu, W)
        h = self.cfg.ahrs
        rpy = truth.rpy + W[:, 18:21] * np.array([h.roll_pitch_noise, h.roll_pitch_noise, h.heading_noise])
        rpy[:, 2] += self.heading_drift * (truth.t - self.t0) + self.rw_h.run(W[:, 21:22])[:, 0]
        R = rotations_enu_flu(rpy[:, 0], rpy[:, 1], rpy[:, 2]) @ self.R_flu_imu
        q = quaternions_from_rotations(R)
        out = []
        for k in range(n):
            t = float(truth.t[k])
            co, cw, ca = self.covariances(t)
            out.append(ImuSample("imu", t, t, self.cfg.frame_id, gyro[k], acc[k], q[k], co, cw, ca))
        return out
