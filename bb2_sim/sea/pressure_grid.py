"""The wave part of the hull pressure integral for many components, interpolated from body-fixed grids.

The pressure integrator needs, per block b of points d_j (block coordinates, m) with weights FM_j (6),

    G_b = sum_j w_j FM_j,   w_j = sum_i a_i exp(k_i z_j) cos(th_ij) = Re sum_i c_i exp(kappa_i . d_j),

where the block's earth coordinates are x = c + V d (V = the earth rows of the block's rotation), so
kappa_i = k_i (v_z + i (cos mu_i v_x + sin mu_i v_y)) and c_i = a_i exp(k_i c_z + i (k_i (c_x cos mu_i +
c_y sin mu_i) - omega_i t + eps_i)). A direct sum costs (points x components) exp/cos evaluations. Here
exp(kappa . d) is replaced by its tensor-product Lagrange interpolant on a regular grid d = g0 + h n
(degree ``order`` per axis, the point in the middle cell of its stencil):

    G_b ~= Re sum_i c_i sum_n exp(kappa_i . (g0 + h n)) Q_b[n],   Q_b[n] = sum_j L_n(d_j) FM_j,

independent of the number of points. The interpolation error per axis is about 0.023 (|kappa_a| h)^4 of a
component's local pressure (order 3), so the spacing follows the wavelength: every component i uses the
coarsest spacing h of ``spacings_m`` with k_i h <= ``max_kh`` (the finest if none), and the components
sharing a spacing share its grids (``sea_spectra.yaml`` -> ``wave_load_grid``). Long waves, most of a sea's
energy, need few nodes: a 64-component JONSWAP sea puts about 50 of them on the 6 m grid.

Per spacing, a block's grid is evaluated in one of two forms, whichever costs less (:func:`_factorise`):

* factorised (the hull): exp(kappa . d_n) = X1[i, n1] Y[i, (n2, n3)] with X1 the x grid line (carrying
  c_i) and Y the (y, z) nodes that any point's stencil touches; the node sums are one real matrix product
  Re(X1^T Y) (n1 x 2I times 2I x n23) and G_b = Q_b . node;
* node by node (the small control-plane blocks): Re sum_i c_i exp(kappa_i . d_n) at every used node.

The exponents of all grid lines and nodes of a spacing are one matrix product of per-component, per-block
parameters with a fixed coefficient matrix. The cosines, sines and the exponentials of the decay are
evaluated in single precision (numpy's vectorised float32 kernels: cos/sin about 15 times, exp about 4 times
faster than float64 here) after the phases are reduced to [-pi, pi] in double precision: an error of about
1e-7 of a component's pressure, far below the interpolation error (the exponents are capped at 80, below
float32's overflow at 88, as no point of a hull reaches k z = 80). The hydrostatic part stays exact (pressure
integrator moments); this is only the dynamic part.
"""
from __future__ import annotations

import numpy as np

from .components import WaveComponents

TWO_PI = 2.0 * np.pi
EXP_CAP = 80.0
"""Largest exponent evaluated (float32's exp overflows at 88.7)."""


def _lagrange_weights(u: np.ndarray, order: int) -> np.ndarray:
    """(n, order+1) weights of the nodes 0..order at local coordinates u (node units)."""
    W = np.ones((len(u), order + 1))
    for j in range(order + 1):
        for r in range(order + 1):
            if r != j:
                W[:, j] *= (u - r) / (j - r)
    return W


class _BlockGrid:
    """Q_b[n] = sum_j L_n(d_j) FM_j on the regular grid of one block at spacing h (only the nodes used)."""

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
        self.used = np.zeros(size, dtype=bool)
        self.used[np.unique(flat_idx)] = True
        self.used = self.used.reshape(n1, n2 * n3)
        self.nodes = [self.g0[a] + h * np.arange(self.shape[a]) for a in range(3)]


class _SpacingLevel:
    """All blocks' grids at one spacing: the coefficient matrix of the exponents and the Q contractions.

    Every block is factorised, exp(kappa . d_n) = X1[i, n1] Y[i, (n2, n3)]: X1 on the x grid line (with the
    offset c_i), Y on the (y, z) nodes that some point's stencil touches. Blocks with more than
    ``big_factor`` times the median block's nodes (the hull) are contracted alone; the others (the control
    planes) are padded to one shape and contracted together in batched products."""

    def __init__(self, blocks, h: float, order: int, big_factor: float = 3.0):
        self.h = h
        self.grids = [_BlockGrid(d, FM, h, order) for d, FM in blocks]
        nb = len(blocks)
        keep = [np.flatnonzero(g.used.any(axis=0)) for g in self.grids]
        size = [g.shape[0] * len(keep[b]) for b, g in enumerate(self.grids)]
        big = [b for b in range(nb) if size[b] > big_factor * np.median(size)]
        small = [b for b in range(nb) if b not in big]
        n1p = max((self.grids[b].shape[0] for b in small), default=0)
        n23p = max((len(keep[b]) for b in small), default=0)
        cols = []                      # (block, x or None, (y, z) or None, with offset) per exponent column

        def block_columns(b, n1, n23):
            g = self.grids[b]
            y, z = np.meshgrid(g.nodes[1], g.nodes[2], indexing="ij")
            yz = np.column_stack([y.ravel(), z.ravel()])[keep[b]]
            cols.extend((b, x, None) for x in g.nodes[0])
            cols.extend((b, None, None) for _ in range(n1 - g.shape[0]))     # padding: exponent 0, Q 0
            cols.extend((b, None, p) for p in yz)
            cols.extend((b, None, None) for _ in range(n23 - len(yz)))

        self.big = []                  # (block, x columns, (y, z) columns, Q^T (6, n1 n23))
        for b in big:
            g, x0 = self.grids[b], len(cols)
            block_columns(b, g.shape[0], len(keep[b]))
            self.big.append((b, slice(x0, x0 + g.shape[0]), slice(x0 + g.shape[0], len(cols)),
                             np.ascontiguousarray(g.Q[:, keep[b], :].reshape(-1, 6).T)))
        self.small_start, self.small, self.n1p = len(cols), np.array(small, dtype=np.int64), n1p
        QTs = np.zeros((len(small), 6, n1p, n23p))
        for s_, b in enumerate(small):
            g = self.grids[b]
            block_columns(b, n1p, n23p)
            QTs[s_, :, :g.shape[0], :len(keep[b])] = g.Q[:, keep[b], :].transpose(2, 0, 1)
        self.QTs = QTs.reshape(len(small), 6, n1p * n23p)
        C_re, C_im = np.zeros((4 * nb, len(cols))), np.zeros((4 * nb, len(cols)))
        for m, (b, x, yz) in enumerate(cols):
            if x is not None:                                     # kappa_x x + offset
                C_re[4 * b, m] = C_im[4 * b, m] = x
                C_re[4 * b + 3, m] = C_im[4 * b + 3, m] = 1.0
            elif yz is not None:                                  # kappa_y y + kappa_z z
                C_re[4 * b + 1:4 * b + 3, m] = yz
                # the (y, z) factor enters conjugated, so that Re(X1^T Y) = [Re X1; Im X1]^T [Re Y; -Im Y]
                # is one real product
                C_im[4 * b + 1:4 * b + 3, m] = -yz
        self.C_re, self.C_im = C_re, C_im
        self.n_cols = len(cols)

    def _buffers(self, ni: int):
        """Work arrays for ni components (kept: fresh temporaries of this size cost page faults each call)."""
        if getattr(self, "_buf_n", None) != ni:
            m = self.n_cols
            self._EI, self._ER, self._R = np.empty((ni, m)), np.empty((ni, m)), np.empty((ni, m))
            self._T32 = np.empty((ni, m), dtype=np.float32)
            self._E32 = np.empty((ni, m), dtype=np.float32)
            self._X = np.empty((2 * ni, m))
            self._buf_n = ni
        return self._EI, self._ER, self._R, self._T32, self._X

    def add_sums(self, P_re: np.ndarray, P_im: np.ndarray, out: np.ndarray) -> None:
        """out (B, 6) += the sums of this level's components (P_* (I, 4 B) rows of kappa and offsets)."""
        ni = len(P_re)
        EI, ER, R, T32, X = self._buffers(ni)
        E32 = self._E32
        np.matmul(P_im, self.C_im, out=EI)                                   # (I, M) phases
        np.multiply(EI, 1.0 / TWO_PI, out=R)
        np.rint(R, out=R)
        R *= TWO_PI
        EI -= R                                                              # in [-pi, pi]
        np.matmul(P_re, self.C_re, out=ER)
        np.minimum(ER, EXP_CAP, out=ER)
        np.exp(ER, out=E32, dtype=np.float32)
        np.cos(EI, out=T32, dtype=np.float32)
        np.multiply(E32, T32, out=X[:ni])
        np.sin(EI, out=T32, dtype=np.float32)
        np.multiply(E32, T32, out=X[ni:])
        for b, xs, ys, QT in self.big:
            node = X[:, xs].T @ X[:, ys]                                     # (n1, n23) = Re(X1^T Y)
            out[b] += QT @ node.ravel()
        ns = len(self.small)
        if ns:
            Xs = X[:, self.small_start:].reshape(2 * ni, ns, -1)
            node = Xs[:, :, :self.n1p].transpose(1, 2, 0) @ Xs[:, :, self.n1p:].transpose(1, 0, 2)
            out[self.small] += (self.QTs @ node.reshape(ns, -1, 1))[:, :, 0]


class WavePressureGrid:
    """Grids for the blocks of a :class:`bb2_sim.hydrostatics.PressureIntegrator` (same block order).

    ``spacings_m``: one spacing or a list (coarsest used for a component with k h <= ``max_kh``)."""

    def __init__(self, blocks: list[tuple[np.ndarray, np.ndarray]], spacings_m, order: int,
                 max_kh: float = np.inf):
        spacings = sorted({float(s) for s in np.atleast_1d(spacings_m)})
        if order < 1 or not spacings or spacings[0] <= 0 or not max_kh > 0:
            raise ValueError(f"wave-load grid needs order >= 1, spacings > 0 and max_kh > 0, got {order}, "
                             f"{spacings_m}, {max_kh}")
        self.spacings_m, self.order, self.max_kh = spacings, int(order), float(max_kh)
        self._blocks = blocks
        self.n_blocks = len(blocks)
        self._levels: dict[float, _SpacingLevel] = {}
        self._comps: WaveComponents | None = None

    def level(self, h: float) -> _SpacingLevel:
        """The grids at spacing h (built on first use)."""
        if h not in self._levels:
            self._levels[h] = _SpacingLevel(self._blocks, h, self.order)
        return self._levels[h]

    def spacing_of(self, k: np.ndarray) -> np.ndarray:
        """The spacing (m) each wavenumber k (rad/m) uses: the coarsest with k h <= max_kh, else the finest."""
        sp = np.array(self.spacings_m)
        ok = k[:, None] * sp[None, :] <= self.max_kh
        idx = np.where(ok.any(axis=1), len(sp) - 1 - np.argmax(ok[:, ::-1], axis=1), 0)
        return sp[idx]

    def _prepare(self, comps: WaveComponents):
        if comps is not self._comps:
            k = comps.wavenumber
            h = self.spacing_of(k)
            order = np.argsort(-h, kind="stable")                         # coarse levels first
            hs = h[order]
            self._groups = [(self.level(float(s)), int(np.argmax(hs == s)), int(len(hs) - np.argmax(hs[::-1] == s)))
                            for s in np.unique(hs)[::-1]]
            mu = comps.direction[order]
            # per component [k, k cos mu, k sin mu, ln a, eps - omega t]: P = K @ W gives every block's
            # exponent parameters, real [k v_z, k c_z + ln a] and imaginary [k (cos mu v_x + sin mu v_y),
            # k (cos mu c_x + sin mu c_y) + eps - omega t] (see block_sums)
            k = k[order]
            self._K = np.column_stack([k, k * np.cos(mu), k * np.sin(mu),
                                       np.log(np.maximum(comps.amplitude[order], 1e-300)), comps.phase[order]])
            self._eps, self._omega = comps.phase[order].copy(), comps.omega[order]
            nb = self.n_blocks
            self._W = np.zeros((5, 2, nb, 4))
            self._W[3, 0, :, 3] = 1.0
            self._W[4, 1, :, 3] = 1.0
            self._comps = comps

    def block_sums(self, comps: WaveComponents, v: np.ndarray, c: np.ndarray, t: float) -> np.ndarray:
        """(B, 6) sums of w_j FM_j; v (B, 3, 3) the earth rows [v_x; v_y; v_z] per block, c (B, 3) origins."""
        self._prepare(comps)
        nb, W, K = self.n_blocks, self._W, self._K
        W[0, 0, :, :3], W[0, 0, :, 3] = v[:, 2], c[:, 2]                       # k (v_z, c_z)
        W[1, 1, :, :3], W[1, 1, :, 3] = v[:, 0], c[:, 0]                       # k cos mu (v_x, c_x)
        W[2, 1, :, :3], W[2, 1, :, 3] = v[:, 1], c[:, 1]                       # k sin mu (v_y, c_y)
        np.subtract(self._eps, self._omega * t, out=K[:, 4])
        P = K @ W.reshape(5, 8 * nb)                                             # (I, [re | im] x B x 4)
        out = np.zeros((nb, 6))
        for level, i0, i1 in self._groups:
            level.add_sums(P[i0:i1, :4 * nb], P[i0:i1, 4 * nb:], out)
        return out
