"""Pressure integration over the triangulated hull for a batch of boats (twin of
:meth:`bb2_sim.hydrostatics.PressureIntegrator.loads`, the regular-wave path).

It reuses the integrator's precomputed per-block data (merged points, weights and their moments), so both sum the
same terms. Per boat the loads are

* the hydrostatic part from the block moments. The fixed surfaces' block carries the buoyancy (~4e7 N terms that
  cancel against the weight), so it is summed in the scalar code's order (its 1-ulp differences, ~7e-9 N, would
  otherwise grow past 1e-12 in the states within 300 steps: the ROM amplifies ulp-level noise, see
  ``tests/sim/test_batch.py``). The five planes' blocks are small (~1e4 N) and linear in the CG depth z0 and the
  row rz of the body->earth rotation for given deflections: their loads are folded into ``z0 a + rz B`` (a (6,),
  B (3, 6) per boat) once per step by :meth:`BatchPressure.prepare`, only for the boats whose deflections changed
  (they are held over the step). [a; B] is a polynomial of degree two in each plane's (cos, sin) of its deflection
  (the hinge rotation enters the block sums and turns them back), so the fold is one product of those six terms
  per plane with coefficients made once. Each evaluation then costs a few array operations for the whole batch.
  The folding reassociates the planes' sums (1-ulp differences of ~1e5 N terms); ``exact=True`` instead follows the
  scalar code's kernels for every block (numpy's stacked matmul and batched einsum call them boat by boat): bit for
  bit the single loads, at about twice the batch's cost;
* a boat in a regular sea (either mode): bit for bit the scalar integrator's loads. Its per-point pass
  (:meth:`PressureIntegrator.point_sums`: the wave term at 11 k points per stage) runs boat by boat, the rest (block
  rows, hydrostatic sums, the planes' rotation and moving, with the scalar code's hinge rotations) for all boats at
  once. The per-point pass dominates a boat's cost and does not shrink with the batch: it bounds the speed-up of
  boats in a sea (about 100 us a boat and evaluation here);
* every boat with free-surface clipping (profile switch): the scalar integrator's own
  :meth:`PressureIntegrator.loads`, boat by boat.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import cross
from ..hydrostatics import PressureIntegrator
from .waves import BatchWaves


@dataclass
class PlaneRotations:
    """Per boat, for its held plane deflections (N, 5) deg: the planes' hydrostatic loads folded as z0 a + rz B,
    a (N, 6), B (N, 3, 6) (body axes, moments about the CG), and the scalar code's hinge rotations R_i (N, 5, 3, 3)
    (the exact mode's; else made when first needed, for boats in a sea)."""

    deflections_deg: np.ndarray
    a: np.ndarray
    B: np.ndarray
    Ri_exact: np.ndarray | None = None

    def subset(self, rows: np.ndarray) -> "PlaneRotations":
        return PlaneRotations(self.deflections_deg[rows], self.a[rows], self.B[rows],
                              None if self.Ri_exact is None else self.Ri_exact[rows])


class BatchPressure:
    """Loads [X, Y, Z, K, M, N] (N, N m; native body axes, moments about the CG) of the pressure on N hulls."""

    def __init__(self, hydro: PressureIntegrator, exact: bool = False):
        self.exact = bool(exact)
        self.rho, self.g = hydro.rho, hydro.g
        self._S0, self._S1 = hydro._S0, hydro._S1          # (B, 6), (B, 3, 6) block moments
        self._pivots = hydro._pivots                         # (B - 1, 3) plane pivots, body axes
        self._hydro = hydro
        self._RX = hydro._hinges                            # (B - 1, 3, 3) hinge frames
        self._fold = self._fold_coefficients()              # (5 * 6, 4 * 6): see prepare

    def _fold_coefficients(self) -> np.ndarray:
        """The planes' folded hydrostatic loads as polynomials in (c, s) = (cos, sin) of each deflection.

        Plane b's block sums in its own frame are G_b = -rg (z0 S0_b + rz H_b), H_b = P_b S0_b^T + R_b S1_b (3, 6)
        (cz_b = z0 + rz.P_b, vz_b = rz R_b), and its body loads F_b = -R_b G_b[:3], M_b = P_b x F_b - R_b G_b[3:].
        With R_b = c C_b + s S_b + E_b the loads are z0 a + rz B, [a; B] (4, 6) a sum over the planes of
        c^2 K0 + cs K1 + s^2 K2 + c K3 + s K4 + K5: the K's (plane, term) are made here once, from the basis
        matrices, as (30, 24) for one product per step."""
        rg = self.rho * self.g
        # R_b(delta) = RX_b Rz(delta) RX_b^T = cos(delta) C_b + sin(delta) S_b + E_b
        RX = self._RX
        Pc, Ps, Pe = np.diag([1.0, 1.0, 0.0]), np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), \
            np.diag([0.0, 0.0, 1.0])
        C, S, E = (RX @ P @ RX.transpose(0, 2, 1) for P in (Pc, Ps, Pe))
        term = {(0, 0): 0, (0, 1): 1, (1, 0): 1, (1, 1): 2, (0, 2): 3, (2, 0): 3, (1, 2): 4, (2, 1): 4, (2, 2): 5}
        K = np.zeros((len(self._pivots), 6, 4, 6))
        for b, (P, S0, S1) in enumerate(zip(self._pivots, self._S0[1:], self._S1[1:])):
            basis = (C[b], S[b], E[b])                      # R_b = c C_b + s S_b + E_b: the factors c, s, 1
            for v, Rv in enumerate(basis):                  # the rotation of the loads: factor v
                K[b, term[v, 2], 0] += _plane_load(P, Rv, -rg * S0)   # a: the z0 column, H-free
                for k in range(3):                          # row k of B: P_b[k] S0_b, then R_b[k] S1_b (factor u)
                    K[b, term[v, 2], 1 + k] += _plane_load(P, Rv, -rg * P[k] * S0)
                    for u, Ru in enumerate(basis):
                        K[b, term[u, v], 1 + k] += _plane_load(P, Rv, -rg * (Ru[k] @ S1))
        return K.reshape(len(K) * 6, 4 * 6)

    # ------------------------------------------------------------------------------------------- per step
    def prepare(self, deflections_deg: np.ndarray, previous: PlaneRotations | None = None) -> PlaneRotations:
        """The planes' folded hydrostatic loads for the actual deflections (N, 5) deg (without incidence; the
        exact mode: the scalar code's hinge rotations R_i = RX_i Rz(delta_i) RX_i^T instead); rows whose
        deflections equal ``previous``'s are copied."""
        d = np.asarray(deflections_deg, dtype=float)
        if previous is not None and previous.deflections_deg.shape == d.shape:
            changed = np.flatnonzero((previous.deflections_deg != d).any(axis=1))
            if len(changed) == 0:
                return previous
            if len(changed) < len(d):
                part = self.prepare(d[changed])
                out = PlaneRotations(d.copy(), previous.a.copy(), previous.B.copy())
                out.a[changed], out.B[changed] = part.a, part.B
                if self.exact:
                    out.Ri_exact = previous.Ri_exact.copy()
                    out.Ri_exact[changed] = part.Ri_exact
                return out
        if self.exact:
            return PlaneRotations(d.copy(), np.empty((len(d), 0)), np.empty((len(d), 0)), self._scalar_rotations(d))
        rad = np.deg2rad(d)
        c, s = np.cos(rad), np.sin(rad)
        n = len(d)
        phi = np.empty((n, d.shape[1], 6))                  # c^2, cs, s^2, c, s, 1 per plane
        np.multiply(c, c, out=phi[..., 0])
        np.multiply(c, s, out=phi[..., 1])
        np.multiply(s, s, out=phi[..., 2])
        phi[..., 3], phi[..., 4], phi[..., 5] = c, s, 1.0
        aB = (phi.reshape(n, -1) @ self._fold).reshape(n, 4, 6)
        return PlaneRotations(d.copy(), aB[:, 0], aB[:, 1:])

    def _scalar_rotations(self, d: np.ndarray) -> np.ndarray:
        """The scalar code's R_i = RX_i Rz(delta_i) RX_i^T for deflections d (N, 5) deg (numpy's stacked matmul
        calls its products boat by boat): (N, 5, 3, 3)."""
        rad = np.deg2rad(d)
        c, s = np.cos(rad), np.sin(rad)
        Rz = np.zeros(d.shape + (3, 3))
        Rz[..., 0, 0], Rz[..., 0, 1], Rz[..., 1, 0], Rz[..., 1, 1], Rz[..., 2, 2] = c, -s, s, c, 1.0
        return np.matmul(np.matmul(self._RX, Rz), self._RX.transpose(0, 2, 1))

    def exact_rotations(self, rot: PlaneRotations) -> np.ndarray:
        """``rot``'s hinge rotations as the scalar code makes them (made once per ``rot`` in the default mode)."""
        if rot.Ri_exact is None:
            rot.Ri_exact = self._scalar_rotations(rot.deflections_deg)
        return rot.Ri_exact

    # ------------------------------------------------------------------------------------------- per stage
    def loads(self, pos: np.ndarray, R: np.ndarray, t, waves: BatchWaves, rot: PlaneRotations,
              clip_emerged: bool = False) -> np.ndarray:
        """Pressure loads (N, 6) of N boats.

        pos: CG earth positions (N, 3); R: body->earth rotations (3, 3, N); t: scalar or (N,); waves: the boats'
        waves; rot: :meth:`prepare` of their actual deflections.
        """
        n = len(pos)
        out = np.empty((n, 6))
        if clip_emerged:                                # not linear in z: the scalar integrator, boat by boat
            for i in range(n):
                ti = t if np.ndim(t) == 0 else float(t[i])
                out[i] = self._hydro.loads(pos[i], np.ascontiguousarray(R[:, :, i]), ti, waves.waves[i],
                                           rot.deflections_deg[i], clip_emerged=True)
            return out
        wavy = waves.wavy
        if wavy.any():
            rows = np.flatnonzero(wavy)
            out[rows] = self._wave_loads(pos[rows], np.ascontiguousarray(R[0::2, :, rows].transpose(2, 0, 1)),
                                         t if np.ndim(t) == 0 else t[rows], [waves.waves[i] for i in rows],
                                         self.exact_rotations(rot)[rows])
        calm = ~wavy
        if calm.any():
            rows = None if calm.all() else np.flatnonzero(calm)
            sub = (lambda a: a) if rows is None else (lambda a: a[rows])
            rot_c = rot if rows is None else rot.subset(rows)
            if self.exact:
                res = self._calm_loads_exact(sub(pos), np.ascontiguousarray(sub(R[0::2].transpose(2, 0, 1))), rot_c)
            else:
                z0 = sub(pos[:, 2])
                rz = np.ascontiguousarray(R[2].T) if rows is None else np.ascontiguousarray(R[2][:, rows].T)
                res = self._calm_loads(z0, rz, rot_c)
            if rows is None:
                return res
            out[rows] = res
        return out

    def _calm_loads(self, z0: np.ndarray, rz: np.ndarray, rot: PlaneRotations) -> np.ndarray:
        """Calm-water loads (n, 6) without clipping: the fixed block in the scalar code's order, the planes folded.
        z0: CG earth z (n,); rz: row z of the body->earth rotation (n, 3)."""
        rg = self.rho * self.g
        S0, S1 = self._S0[0], self._S1[0]
        hydro0 = z0[:, None] * S0 + (rz[:, 0, None] * S1[0] + rz[:, 1, None] * S1[1] + rz[:, 2, None] * S1[2])
        B = rot.B
        planes = z0[:, None] * rot.a + (rz[:, 0, None] * B[:, 0] + rz[:, 1, None] * B[:, 1]
                                        + rz[:, 2, None] * B[:, 2])
        return -((-rg) * hydro0) + planes

    def _block_rows(self, pos: np.ndarray, rxz: np.ndarray, Ri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per boat and block, the earth rows [vx; vz] (n, B, 2, 3) and the origin's earth [x, z] (n, B, 2) of
        the block's points (the scalar code's products: numpy's stacked matmul calls them boat by boat).
        pos: CG earth positions (n, 3); rxz: rows x and z of the body->earth rotation (n, 2, 3); Ri (n, 5, 3, 3)."""
        v = np.concatenate([rxz[:, None], np.matmul(rxz[:, None], Ri)], axis=1)
        c = np.concatenate([pos[:, None, 0::2], np.matmul(self._pivots, rxz.transpose(0, 2, 1)) + pos[:, None, 0::2]],
                           axis=1)
        return v, c

    def _hydrostatic_sums(self, vz: np.ndarray, cz: np.ndarray) -> np.ndarray:
        """Per boat, the blocks' sums (n, B, 6) of z FM_j (the calm pressure is -rho g times them), as the scalar
        code's ``cz S0 + einsum('bk,bkm->bm', vz, S1)``."""
        S0, S1 = self._S0, self._S1
        return cz[..., None] * S0 + (vz[..., 0, None] * S1[:, 0] + vz[..., 1, None] * S1[:, 1]
                                     + vz[..., 2, None] * S1[:, 2])

    def _sum_blocks(self, G: np.ndarray, Ri: np.ndarray) -> np.ndarray:
        """[X, Y, Z, K, M, N] (n, 6) from the blocks' sums G (n, B, 6), as the scalar code's ``_sum_blocks``."""
        out = -G[:, 0]
        F = -np.einsum("nbij,nbj->nbi", Ri, G[:, 1:, :3])
        out[:, 0:3] += F.sum(axis=1)
        out[:, 3:6] += (cross(self._pivots, F) - np.einsum("nbij,nbj->nbi", Ri, G[:, 1:, 3:])).sum(axis=1)
        return out

    def _calm_loads_exact(self, pos: np.ndarray, rxz: np.ndarray, rot: PlaneRotations) -> np.ndarray:
        """Calm-water loads (n, 6) without clipping, every operation as the scalar code's (bit for bit).
        pos: CG earth positions (n, 3); rxz: rows x and z of the body->earth rotation (n, 2, 3)."""
        v, c = self._block_rows(pos, rxz, rot.Ri_exact)
        return self._sum_blocks((-self.rho * self.g) * self._hydrostatic_sums(v[..., 1, :], c[..., 1]), rot.Ri_exact)

    def _wave_loads(self, pos: np.ndarray, rxz: np.ndarray, t, waves: list, Ri: np.ndarray) -> np.ndarray:
        """Loads (n, 6) of boats in regular waves (not clipped), bit for bit the scalar integrator's: its per-point
        pass (:meth:`PressureIntegrator.point_sums`) boat by boat, everything around it for all boats at once.
        t: scalar or (n,); waves: one :class:`Wave` per boat."""
        hydro = self._hydro
        k = np.array([w.wavenumber for w in waves])
        omega = np.array([w.omega for w in waves])
        v, c = self._block_rows(pos, rxz, Ri)
        turns = hydro.turns
        V = np.empty(v.shape[:2] + (2, 4))
        V[..., 0, :3] = v[..., 0, :] * (k * turns)[:, None, None]
        V[..., 0, 3] = (k[:, None] * c[..., 0] - (omega * t)[:, None]) * turns
        V[..., 1, :3] = v[..., 1, :]
        V[..., 1, 3] = c[..., 1]
        G = np.empty(v.shape[:2] + (6,))
        for Vi, ki, w, Gi in zip(V, k.tolist(), waves, G):
            hydro.point_sums(Vi, ki, w.amplitude, False, Gi)
        rg = self.rho * self.g
        G = rg * G - rg * self._hydrostatic_sums(v[..., 1, :], c[..., 1])
        return self._sum_blocks(G, Ri)

    def sea_loads_and_orbital_velocity(self, pos: np.ndarray, R: np.ndarray, t, Ri: np.ndarray, seas: list,
                                       points_body: np.ndarray, q12: bool) -> tuple[np.ndarray, np.ndarray]:
        """Loads (n, 6) of n boats in component seas (not clipped) and the seas' orbital velocities (n, P, 3) earth
        axes at ``points_body`` (P, 3), bit for bit each boat's
        :meth:`PressureIntegrator.loads_and_orbital_velocity`: the grid's per-point pass boat by boat (each sea on
        its own grid), the blocks' rows, hydrostatic sums and the planes' rotation and moving for all boats at once
        (the scalar code's products: numpy's stacked matmul calls them boat by boat).
        pos (n, 3) CG earth positions; R (n, 3, 3) body->earth rotations; t scalar or (n,); Ri (n, 5, 3, 3) the
        scalar code's hinge rotations; seas: per boat (its sea, its wave-load grid of ``points_body``)."""
        n = len(pos)
        v = np.concatenate([R[:, None], np.matmul(R[:, None], Ri)], axis=1)                 # (n, B, 3, 3)
        c = np.concatenate([pos[:, None], np.matmul(self._pivots, R.transpose(0, 2, 1)) + pos[:, None]], axis=1)
        G = np.empty((n, len(self._S0), 6))
        uw = np.empty((n, len(points_body), 3))
        for j, (sea, grid) in enumerate(seas):
            tj = t if np.ndim(t) == 0 else float(t[j])
            G[j], uw[j] = grid.block_sums_and_orbital_velocity(sea.components, v[j], c[j], tj, q12=q12)
        rg = self.rho * self.g
        hydro = (-rg) * self._hydrostatic_sums(v[..., 2, :], c[..., 2])
        return self._sum_blocks(rg * G + hydro, Ri), uw


def _plane_load(P: np.ndarray, R: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Body load [F, M] (6,) of a plane with pivot P and rotation R from its block sums g (6,) in its own frame:
    F = -R g[:3], M = P x F - R g[3:]."""
    F = -(R @ g[:3])
    return np.concatenate([F, cross(P, F) - R @ g[3:]])
