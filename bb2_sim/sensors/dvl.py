"""DVL: a 4-beam Janus unit, bottom track within range, water track otherwise (no ROS).

Beams ``b_i`` (unit, dvl frame) point down at ``beam_angle`` from the unit's -z axis at the configured azimuths.
Per ping, with the DVL's velocity over ground ``v`` in its frame (v_base + w x r, rotated into the dvl frame)::

    beam velocity   u_i = (1 + s) b_i . v + sigma_i w_i,    sigma_i = beam_noise + beam_noise_fraction |v|
    slant range     r_i = h_dvl / cos(incidence_i),          h_dvl = CG clearance + (z_dvl - z_cg)

(the bottom taken locally flat under the vehicle).  A beam has an echo when its incidence from the vertical is at
most ``max_beam_incidence`` and ``min_range <= r_i <= max_range``.  With at least three echoes the bottom-track
velocity is the weighted least-squares solution of the echoing beams (a three-beam solution with one lost), its
covariance ``(B^T Sigma^-1 B)^-1`` plus the scale-factor sigma at this speed; with fewer the DVL has lost bottom
lock (large altitude or large roll/pitch) and reports water track: its velocity through the water (minus the
current at its depth) with ``water_track_noise`` per axis.  ``s`` is the scale error drawn per seed.  Every
sample is valid at its ping time and out ``latency_s`` later.
"""
from __future__ import annotations

import math

import numpy as np

from .config import DvlConfig
from .noise import stream
from .samples import DvlSample
from .truth import TruthBatch

__all__ = ["DvlModel"]

_D = np.array([-1.0, -1.0, 1.0])


class DvlModel:
    name = "dvl"

    def __init__(self, cfg: DvlConfig, seed: int, index: int = 2, t0: float = 0.0) -> None:
        self.cfg = cfg
        self.period = 1.0 / cfg.rate_hz
        init = stream(seed, index, 0)
        self.rng = stream(seed, index, 1)
        self.scale = cfg.scale_factor * float(init.standard_normal())
        self.B = cfg.beams_dvl()
        self.R_flu_dvl = cfg.mounting.R_flu_sensor
        self.cos_max = math.cos(cfg.max_beam_incidence_rad)

    def beam_geometry(self, truth: TruthBatch) -> tuple[np.ndarray, np.ndarray]:
        """Slant ranges (n, beams; +inf no echo) and echo flags of every ping."""
        c = self.cfg
        r = c.mounting.position_flu
        dz = (truth.R_enu_flu @ r)[:, 2]
        h = truth.clearance_m + dz
        d_enu = np.einsum("nij,bj->nbi", truth.R_enu_flu, self.B @ self.R_flu_dvl.T)
        cos_inc = -d_enu[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            rng = np.where(cos_inc > 1e-9, h[:, None] / np.maximum(cos_inc, 1e-9), np.inf)
        ok = np.isfinite(rng) & (cos_inc >= self.cos_max) & (rng >= c.min_range_m) & (rng <= c.max_range_m)
        return np.where(ok, rng, np.inf), ok

    def sample(self, truth: TruthBatch, env) -> list[DvlSample]:
        c = self.cfg
        nb = self.B.shape[0]
        W = self.rng.standard_normal((truth.n, nb + 3))
        r = c.mounting.position_flu
        Rt = self.R_flu_dvl.T
        v = truth.point_velocity_flu(r) @ Rt.T                       # over ground, dvl frame
        ranges, ok = self.beam_geometry(truth)
        out = []
        for k in range(truth.n):
            t = float(truth.t[k])
            speed = float(np.linalg.norm(v[k]))
            if ok[k].sum() >= 3:
                sig = c.beam_noise_mps + c.beam_noise_fraction * speed
                u = (1.0 + self.scale) * (self.B @ v[k]) + sig * W[k, :nb]
                Bv = self.B[ok[k]]
                info = Bv.T @ Bv / max(sig, 1e-12) ** 2
                cov = np.linalg.inv(info)
                vel = cov @ (Bv.T @ u[ok[k]]) / max(sig, 1e-12) ** 2
                cov = cov + np.eye(3) * (c.scale_factor * speed) ** 2
                lock = True
            else:
                v_w = v[k].copy()
                if env is not None and env.current is not None:
                    z = float(truth.point_enu(r)[k, 2])
                    vc_enu = np.asarray(env.current.velocity_earth(np.array(z)), float) * _D
                    v_w = v_w - Rt @ (truth.R_enu_flu[k].T @ vc_enu)
                vel = (1.0 + self.scale) * v_w + c.water_track_noise_mps * W[k, nb:]
                cov = np.eye(3) * (c.water_track_noise_mps ** 2 + (c.scale_factor * speed) ** 2)
                lock = False
            out.append(DvlSample("dvl", t, t + c.latency_s, c.frame_id, lock, vel, cov, ranges[k].copy(),
                                 ok[k].copy()))
        return out
