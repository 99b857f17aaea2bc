"""The wave part of the hull pressure integral for many components, interpolated from body-fixed grids.

The pressure integrator needs, per block b of points d_j (block coordinates, m) with weights FM_j (6),

    G_b = sum_j w_j FM_j,   w_j = sum_i a_i exp(k_i z_j) cos(th_ij) = Re sum_i c_i exp(kappa_i . d_j),

where the block's earth coordinates are x = c + V d (V = the earth rows of the block's rotation), so
kappa_i = k_i (v_z + i (cos mu_i v_x + sin mu_i v_y)) and c_i = a_i exp(k_i c_z + i (k_i (c_x cos mu_i +
c_y sin mu_i) - omega_i t + eps_i)). A direct sum costs (points x components) exp/cos evaluations. Here
exp(kappa . d) is replaced by its tensor-product Lagrange interpolant on a regular grid d = g0 + h n
(degree ``order`` per axis, the point in the middle cell of its stencil):

    G_b ~= Re sum_i c_i sum_n X1[i, n1] X2[i, n2] X3[i, n3] Q_b[n],   Q_b[n] = sum_j L_n(d_j) FM_j,

with X_a[i, n] = exp(kappa_ia (g0_a + h n)): (components x grid lines) complex exponentials, two small
matrix products and one contraction per block, independent of the number of points. The interpolation
error per axis is about 0.023 (|kappa_a| h)^4 of a component's local pressure (order 3); spacing and order
are data (``sea_spectra.yaml`` -> ``wave_load_grid``). The hydrostatic part stays exact (pressure
integrator moments); this is only the dynamic part.
"""
from __future__ import annotations

import numpy as np

from .components import WaveComponents


def _lagrange_weights(u: np.ndarray, order: int) -> np.ndarray:
    """(n, order+1) weights of the nodes 0..order at local coordinates u (node units)."""
    W = np.ones((len(u), order + 1))
    for j in range(order + 1):
        for r in range(order + 1):
            if r != j:
                W[:, j] *= (u - r) / (j - r)
    return W


class _BlockGrid:
    def __init__(self, d: np.ndarray, FM: np.ndarray, h: float, order: int):
        t = d / h
        base = np.floor(t).astype(np.int64) - (order - 1) // 2      # first stencil node per point and axis
        lo = base.min(axis=0)
        self.shape = tuple(int(s) for s in base.max(axis=0) - lo + order + 1)
        self.g0 = lo * h                                              # (3,) m
        self.h = h
        rel = base - lo
        u = t - base
        Wax = [_lagrange_weights(u[:, a], order) for a in range(3)]  # (n, order+1) each
        n1, n2, n3 = self.shape
        flat_idx = np.zeros((len(d), 1), dtype=np.int64)
        weight = np.ones((len(d), 1))
        for a, stride in enumerate((n2 * n3, n3, 1)):
            idx_a = (rel[:, a][:, None] + np.arange(order + 1)) * stride
            flat_idx = (flat_idx[:, :, None] + idx_a[:, None, :]).reshape(len(d), -1)
            weight = (weight[:, :, None] * Wax[a][:, None, :]).reshape(len(d), -1)
        size = n1 * n2 * n3
        Q = np.stack([np.bincount(flat_idx.ravel(), (weight * FM[:, m][:, None]).ravel(), minlength=size)
                      for m in range(6)], axis=-1)
        self.Q = Q.reshape(n1, n2 * n3, 6)
        self.nodes = [self.g0[a] + h * np.arange(self.shape[a]) for a in range(3)]


class WavePressureGrid:
    """Grids for the blocks of a :class:`bb2_sim.hydrostatics.PressureIntegrator` (same block order)."""

    def __init__(self, blocks: list[tuple[np.ndarray, np.ndarray]], spacing_m: float, order: int):
        if order < 1 or spacing_m <= 0:
            raise ValueError(f"wave-load grid needs order >= 1 and spacing > 0, got {order}, {spacing_m}")
        self.spacing_m, self.order = float(spacing_m), int(order)
        self.grids = [_BlockGrid(d, FM, self.spacing_m, self.order) for d, FM in blocks]
        self._comps: WaveComponents | None = None
        # the grid lines of all blocks and axes side by side: node coordinate, block, axis, slices
        nodes, blk, ax, self._slices, start = [], [], [], [], 0
        for b, g in enumerate(self.grids):
            sl = []
            for a in range(3):
                n = len(g.nodes[a])
                nodes.append(g.nodes[a])
                blk += [b] * n
                ax += [a] * n
                sl.append(slice(start, start + n))
                start += n
            self._slices.append(tuple(sl))
            g.Q2 = np.ascontiguousarray(g.Q.reshape(-1, 6))
        self._line_nodes = np.concatenate(nodes)
        self._line_block = np.array(blk)
        self._line_axis = np.array(ax)
        self._first_axis = self._line_axis == 0

    def _prepare(self, comps: WaveComponents):
        if comps is not self._comps:
            k = comps.wavenumber
            self._k = k
            self._amp = comps.amplitude
            self._cos, self._sin = np.cos(comps.direction), np.sin(comps.direction)
            self._kx, self._ky = k * self._cos, k * self._sin
            self._comps = comps

    def block_sums(self, comps: WaveComponents, v: np.ndarray, c: np.ndarray, t: float) -> np.ndarray:
        """(B, 6) sums of w_j FM_j; v (B, 3, 3) the earth rows [v_x; v_y; v_z] per block, c (B, 3) origins."""
        self._prepare(comps)
        k = self._k
        om_t = comps.omega * t - comps.phase
        re_k = k[:, None, None] * v[None, :, 2, :]                                       # (I, B, 3)
        im_k = k[:, None, None] * (self._cos[:, None, None] * v[None, :, 0, :]
                                   + self._sin[:, None, None] * v[None, :, 1, :])
        re0 = k[:, None] * c[None, :, 2] + np.log(np.maximum(self._amp, 1e-300))[:, None]   # (I, B)
        im0 = self._kx[:, None] * c[None, :, 0] + self._ky[:, None] * c[None, :, 1] - om_t[:, None]
        # every grid line of every block in one (I, M) exponent: real and imaginary parts
        ER = re_k[:, self._line_block, self._line_axis] * self._line_nodes
        EI = im_k[:, self._line_block, self._line_axis] * self._line_nodes
        ER[:, self._first_axis] += re0[:, self._line_block[self._first_axis]]
        EI[:, self._first_axis] += im0[:, self._line_block[self._first_axis]]
        mag = np.exp(ER)
        Xr, Xi = mag * np.cos(EI), mag * np.sin(EI)
        out = np.empty((len(self.grids), 6))
        for b, (grid, (s1, s2, s3)) in enumerate(zip(self.grids, self._slices)):
            x2r, x2i, x3r, x3i = Xr[:, s2, None], Xi[:, s2, None], Xr[:, None, s3], Xi[:, None, s3]
            Yr = (x2r * x3r - x2i * x3i).reshape(len(k), -1)
            Yi = (x2r * x3i + x2i * x3r).reshape(len(k), -1)
            node = Xr[:, s1].T @ Yr - Xi[:, s1].T @ Yi                              # (n1, n2 n3)
            out[b] = node.ravel() @ grid.Q2
        return out
