"""Hydrostatic and wave (Froude-Krylov) loads by pressure integration over the triangulated hull (SPEC 7.1-7.3).

For every triangle the pressure is sampled at its three edge mid-points and

    dF = -(p1 + p2 + p3)/3 * nA,        dM = -(1/3) (p1 m1 + p2 m2 + p3 m3) x nA     (body axes, about the CG)

summed over every triangle of every part, with the control planes rotated about their hinges by their
deflections (SPEC 7.2). This module evaluates exactly that sum, vectorised: adjacent triangles share edge
mid-points, so the pressure is computed once per distinct mid-point j and the sums become

    F = -sum_j p_j W_j,   M = -sum_j p_j (m_j x W_j),   W_j = sum over the triangles t that use j of nA_t / 3,

a single (N, 6) matrix-vector product per evaluation (about 11.7k points instead of 23.3k). For a moving
plane i with rotation R_i = RX_i Rz(delta_i) RX_i^T about the pivot P_i, the mid-points and the area vectors
rotate with it (see :meth:`PressureIntegrator.loads`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .waves import Wave
from .frames import cross


def _edge_midpoints(tri: np.ndarray) -> np.ndarray:
    """(N, 3, 3) triangles -> (N, 3, 3) mid-points m1=(v1+v2)/2, m2=(v1+v3)/2, m3=(v2+v3)/2."""
    v1, v2, v3 = tri[:, 0], tri[:, 1], tri[:, 2]
    return np.stack([(v1 + v2) / 2, (v1 + v3) / 2, (v2 + v3) / 2], axis=1)


def _merge_points(tri: np.ndarray, area_vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct edge mid-points (P, 3) and their summed weights W_j = sum nA_t / 3 (P, 3)."""
    mids = _edge_midpoints(tri).reshape(-1, 3)
    pts, inv = np.unique(mids, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    w = np.repeat(area_vectors / 3.0, 3, axis=0)
    W = np.zeros_like(pts)
    np.add.at(W, inv, w)
    return pts, W


def _hinge_rotation(RX: np.ndarray, delta_rad: float) -> np.ndarray:
    c, s = np.cos(delta_rad), np.sin(delta_rad)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return RX @ Rz @ RX.T


@dataclass
class _PlanePoints:
    rel: np.ndarray      # (P, 3) mid-points relative to the pivot, undeflected
    W: np.ndarray        # (P, 3) weights, undeflected
    WxR: np.ndarray      # (P, 3) rel x W
    pivot: np.ndarray    # (3,)
    RX: np.ndarray       # (3, 3)


class PressureIntegrator:
    """Pressure-integrated force and moment on a :class:`bb2_sim.geometry.HullSurfaces` set."""

    def __init__(self, surfaces, rho: float, g: float):
        self.rho, self.g = float(rho), float(g)
        self.surfaces = surfaces
        fixed_area = np.asarray(surfaces.fixed_area_vectors, dtype=float)
        self._fixed_pts, self._fixed_W = _merge_points(np.asarray(surfaces.fixed_vertices, dtype=float),
                                                       fixed_area)
        self._fixed_Wm = cross(self._fixed_pts, self._fixed_W)
        self._planes: list[_PlanePoints] = []
        for i, tri in enumerate(surfaces.plane_vertices):
            tri = np.asarray(tri, dtype=float)
            cr = cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            unit = cr / np.linalg.norm(cr, axis=1)[:, None]
            area = np.asarray(surfaces.plane_areas[i], dtype=float)[:, None] * unit
            pts, W = _merge_points(tri, area)
            pivot = np.asarray(surfaces.plane_pivots[i], dtype=float)
            rel = pts - pivot
            self._planes.append(_PlanePoints(rel, W, cross(rel, W), pivot,
                                             np.asarray(surfaces.plane_hinge_rotations[i], dtype=float)))
        self._fixed_FM = np.hstack([self._fixed_W, self._fixed_Wm])
        self._cache_key: tuple | None = None
        self._rot: list[np.ndarray] = []
        self.n_points = len(self._fixed_pts) + sum(len(p.rel) for p in self._planes)

    # ---------------------------------------------------------------------------------------------
    def _plane_rotations(self, deflections_deg: np.ndarray) -> list[np.ndarray]:
        """Hinge rotations R_i of the five planes (cached per deflection: they change once per step)."""
        key = tuple(float(d) for d in deflections_deg)
        if key != self._cache_key:
            self._rot = [_hinge_rotation(pl.RX, np.deg2rad(d)) for pl, d in zip(self._planes, key)]
            self._cache_key = key
        return self._rot

    def _pressure(self, pts: np.ndarray, rx: np.ndarray, rz: np.ndarray, x0: float, z0: float,
                  t: float, wave: Wave, clip: bool) -> np.ndarray:
        """Pressure at body points pts whose earth x, z are x0 + pts.rx and z0 + pts.rz."""
        ez = pts @ rz + z0
        if wave.calm:
            p = (-self.rho * self.g) * ez
        else:
            ex = pts @ rx + x0
            k = wave.wavenumber
            p = (-self.rho * self.g) * (ez - wave.amplitude * np.exp(k * ez) * np.sin(k * ex - wave.omega * t))
        return np.maximum(p, 0.0) if clip else p

    def loads(self, p_earth: np.ndarray, R: np.ndarray, t: float, wave: Wave,
              deflections_deg: np.ndarray, clip_emerged: bool = False) -> np.ndarray:
        """[X, Y, Z, K, M, N] (N, N m; body axes, moments about the CG) of the pressure on the hull.

        p_earth: CG position (native earth, z up); R: body->earth rotation; deflections_deg: the five
        actual plane deflections dX_i (deg, without the incidence). ``clip_emerged`` sets the pressure of
        points above the free surface to zero (the model itself does not: quirk Q11).

        A plane's point j sits at P + R_i d_j in the body, so its earth z is z + R[2].P + (R[2] R_i).d_j:
        the plane points are never rotated, only two row vectors per plane. Its load is
        F_i = -R_i (p . W), M_i = P x F_i - R_i (p . (d x W)).
        """
        x0, z0 = float(p_earth[0]), float(p_earth[2])
        rx, rz = R[0], R[2]
        p = self._pressure(self._fixed_pts, rx, rz, x0, z0, t, wave, clip_emerged)
        out = -(p @ self._fixed_FM)
        for pl, Ri in zip(self._planes, self._plane_rotations(deflections_deg)):
            pp = self._pressure(pl.rel, rx @ Ri, rz @ Ri, x0 + rx @ pl.pivot, z0 + rz @ pl.pivot, t, wave,
                                clip_emerged)
            F = -(Ri @ (pp @ pl.W))
            out[0:3] += F
            out[3:6] += cross(pl.pivot, F) - Ri @ (pp @ pl.WxR)
        return out

    def volume(self) -> float:
        """Enclosed volume of the undeflected surfaces from the same integral (calm, level, CG at z = 0).

        At z = 0 the tiny non-closure of real surface sets (sum of nA != 0) does not bias the result."""
        F = self.loads(np.zeros(3), np.eye(3), 0.0, Wave(), np.zeros(5))
        return float(F[2] / (self.rho * self.g))
