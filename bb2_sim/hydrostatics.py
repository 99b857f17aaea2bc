"""Hydrostatic and wave (Froude-Krylov) loads by pressure integration over the triangulated hull (SPEC 7.1-7.3).

For every triangle the pressure is sampled at its three edge mid-points and

    dF = -(p1 + p2 + p3)/3 * nA,        dM = -(1/3) (p1 m1 + p2 m2 + p3 m3) x nA     (body axes, about the CG)

summed over every triangle of every part, with the control planes rotated about their hinges by their
deflections (SPEC 7.2). This module evaluates exactly that sum, vectorised: adjacent triangles share edge
mid-points, so the pressure is computed once per distinct mid-point j and the sums become

    F = -sum_j p_j W_j,   M = -sum_j p_j (m_j x W_j),   W_j = sum over the triangles t that use j of nA_t / 3,

a single (N, 6) matrix-vector product per evaluation (about 11.7k points instead of 23.3k). For a moving
plane i with rotation R_i = RX_i Rz(delta_i) RX_i^T about the pivot P_i, the mid-points and the area vectors
rotate with it; the rotated point sets are cached per deflection.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .waves import Wave


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
        self._fixed_Wm = np.cross(self._fixed_pts, self._fixed_W)
        self._planes: list[_PlanePoints] = []
        for i, tri in enumerate(surfaces.plane_vertices):
            tri = np.asarray(tri, dtype=float)
            cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            unit = cr / np.linalg.norm(cr, axis=1)[:, None]
            area = np.asarray(surfaces.plane_areas[i], dtype=float)[:, None] * unit
            pts, W = _merge_points(tri, area)
            pivot = np.asarray(surfaces.plane_pivots[i], dtype=float)
            rel = pts - pivot
            self._planes.append(_PlanePoints(rel, W, np.cross(rel, W), pivot,
                                             np.asarray(surfaces.plane_hinge_rotations[i], dtype=float)))
        self._cache_key: tuple | None = None
        self._pts = self._Wall = self._Wmall = None
        self.n_points = len(self._fixed_pts) + sum(len(p.rel) for p in self._planes)

    # ---------------------------------------------------------------------------------------------
    def _points(self, deflections_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-frame points and weights (W, m x W) with the planes deflected; cached per deflection."""
        key = tuple(float(d) for d in deflections_deg)
        if key != self._cache_key:
            pts, W, Wm = [self._fixed_pts], [self._fixed_W], [self._fixed_Wm]
            for plane, d in zip(self._planes, key):
                R = _hinge_rotation(plane.RX, np.deg2rad(d))
                p = plane.pivot + plane.rel @ R.T
                w = plane.W @ R.T
                pts.append(p)
                W.append(w)
                Wm.append(np.cross(plane.pivot, w) + plane.WxR @ R.T)
            self._pts = np.concatenate(pts)
            self._Wall = np.concatenate(W)
            self._Wmall = np.concatenate(Wm)
            self._FM = np.hstack([self._Wall, self._Wmall])
            self._cache_key = key
        return self._pts, self._Wall, self._Wmall

    def loads(self, p_earth: np.ndarray, R: np.ndarray, t: float, wave: Wave,
              deflections_deg: np.ndarray, clip_emerged: bool = False) -> np.ndarray:
        """[X, Y, Z, K, M, N] (N, N m; body axes, moments about the CG) of the pressure on the hull.

        p_earth: CG position (native earth, z up); R: body->earth rotation; deflections_deg: the five
        actual plane deflections dX_i (deg, without the incidence). ``clip_emerged`` sets the pressure of
        points above the free surface to zero (the model itself does not: quirk Q11).
        """
        pts, _, _ = self._points(deflections_deg)
        ez = pts @ R[2] + p_earth[2]
        if wave.calm:
            p = (-self.rho * self.g) * ez
        else:
            ex = pts @ R[0] + p_earth[0]
            k = wave.wavenumber
            p = (-self.rho * self.g) * (ez - wave.amplitude * np.exp(k * ez) * np.sin(k * ex - wave.omega * t))
        if clip_emerged:
            p = np.maximum(p, 0.0)
        return -(p @ self._FM)

    def volume(self) -> float:
        """Enclosed volume of the undeflected surfaces from the same integral (calm, level, CG at z = 0).

        At z = 0 the tiny non-closure of real surface sets (sum of nA != 0) does not bias the result."""
        F = self.loads(np.zeros(3), np.eye(3), 0.0, Wave(), np.zeros(5))
        return float(F[2] / (self.rho * self.g))
