"""The wave part of the hull pressure integral for many components, interpolated from body-fixed grids.

The pressure integrator needs, per block b of points d_j (block coordinates, m) with weights FM_j (6),

    G_b = sum_j w_j FM_j,   w_j = sum_i a_i exp(k_i z_j) cos(th_ij) = Re sum_i c_i exp(kappa_i . d_j),

where the block's earth coordinates are x = c + V d (V = the earth rows of the block's rotation), so
kappa_i = k_i (v_z + i (cos mu_i v_x + sin mu_i v_y)) and c_i = a_i exp(k_i c_z + i (k_i (c_x cos mu_i +
c_y sin mu_i) - omega_i t + eps_i)). A direct sum costs (points x components) exp/cos evaluations. Here
exp(kappa . d) is replaced by its tensor-product Lagrange interpolant on a regular grid d = g0 + h n that
spans the block's bounding box (degree ``order`` per axis; per axis n = max(order, ceil(extent / h) + 1) cells,
so the spacing is below h and the point sits in the middle cell of its stencil except next to the ends):

    G_b ~= Re sum_i c_i sum_n exp(kappa_i . (g0 + h n)) Q_b[n],   Q_b[n] = sum_j L_n(d_j) FM_j,

independent of the number of points. The interpolation error per axis is about 0.023 (|kappa_a| h)^4 of a
component's local pressure (order 3; up to 0.042 (|kappa_a| h)^4 next to the ends), so the spacing follows
the wavelength: every component i uses the coarsest spacing h of ``spacings_m`` with k_i h <= ``max_kh`` (the
finest if none), and the components sharing a spacing share its grids (``sea_spectra.yaml`` ->
``wave_load_grid``). Long waves, most of a sea's energy, need few nodes: a 64-component JONSWAP sea puts about
50 of them on the 6 m grid, where the hull's block is 14 x 20 nodes used; the orbital velocities at the model's
flow points are a few more columns of the same exponentials. An axis shorter than the spacing (a control
plane's chord, span and thickness) takes the lowest degree whose error bound for the level's wavenumbers stays
within degree ``order``'s at spacing h (:func:`axis_plan`): on the 6 m grid an X plane's block is 3 x 3 x 3
nodes (quadratic), the rudder's thickness linear.

Every block's grid is factorised, exp(kappa . d_n) = X1[i, n1] Y[i, (n2, n3)] with X1 the x grid line (carrying
c_i) and Y the (y, z) nodes that any point's stencil touches; the node sums are one real matrix product
Re(X1^T Y) (n1 x 2I times 2I x n23) and G_b = Q_b . node. The hull is contracted alone, the control planes
padded to one shape and contracted together in batched products.

The exponents of all grid lines and nodes of a spacing are one matrix product of per-component, per-block
parameters with a fixed coefficient matrix, and everything from that product to the node sums runs in single
precision (numpy's vectorised float32 kernels: cos/sin about 15 times, exp about 4 times faster than float64
here, the products half the cost): the parameters are formed in double precision and the phase offsets (which
grow with time and distance) reduced modulo 2 pi there (fmod, without rounding), so that a float32 exponent only
adds a grid node's
kappa . d, at most k times the hull's length (about 15 rad): an error of about 1e-6 of a component's pressure,
far below the interpolation error. A node's value is the product of two factors (x line, (y, z) node) summed
over 2 I terms, so each factor's exponent is capped at 40 (twice 40 plus ln(2 I) stays below float32's
overflow at 88.7); no point of a hull in a sea comes near k z = 40 (100 m above the surface for a 15 m wave).
The node sums are contracted with the weights Q in single precision too, each block's six sums added up in double:
the hull's sums cancel little (the sum of |Q node| is 2 to 600 times the result; measured here, 3e-6 of the roll
moment on the 6 m grid, 2e-7 of the loads on the 1.5 m grid). The hydrostatic part stays exact (pressure
integrator moments); this is only the dynamic part.
"""
from __future__ import annotations

import math

import numpy as np

from .components import WaveComponents

TWO_PI = 2.0 * np.pi
LEVELS_KEPT = 8
"""Spacing levels a :class:`WavePressureGrid` keeps (the most recently used): levels are planned per sea."""
EXP_CAP = 40.0
"""Largest exponent of a factor (two factors and a sum of 2 I products must stay below float32's 3.4e38)."""


def _lagrange_weights(u: np.ndarray, order: int) -> np.ndarray:
    """(n, order+1) weights of the nodes 0..order at local coordinates u (node units)."""
    W = np.ones((len(u), order + 1))
    for j in range(order + 1):
        for r in range(order + 1):
            if r != j:
                W[:, j] *= (u - r) / (j - r)
    return W


def _error_constant(p: int) -> float:
    """max over a stencil's end cell of |prod_{r=0..p} (u - r)| / (p + 1)!: the interpolation error of degree p at
    node spacing s is about this times (k s)^(p+1) of a component's local pressure (p = 3: 0.042)."""
    u = np.linspace(0.0, 1.0, 2001)
    return float(np.abs(np.prod([u - r for r in range(p + 1)], axis=0)).max() / math.factorial(p + 1))


_C_END = {p: _error_constant(p) for p in range(1, 8)}


def axis_plan(extent: float, h: float, order: int, k_design: float | None = None) -> tuple[int, int]:
    """(degree, cells) of one grid axis of the given extent (m): degree ``order`` on n = max(order, ceil(extent /
    h) + 1) cells (spacing below h) -- unless, for the wavenumbers up to ``k_design`` (rad/m), a lower degree on
    fewer nodes interpolates as well as degree ``order`` at spacing h does (error C_p (k s)^(p+1) <=
    C_order (k h)^(order+1)): the thin and short axes of the control planes, where a few metres of a long wave
    are nearly linear."""
    n_default = max(order, math.ceil(extent / h - 1e-9) + 1)
    best = (order, n_default)
    if not k_design or not k_design > 0:
        return best
    tol = _C_END[order] * (k_design * h) ** (order + 1)
    for p in range(order - 1, 0, -1):
        for n in range(p, best[1]):                                   # fewer nodes than the best so far
            s = extent / n if extent > 0 else h
            if _C_END[p] * (k_design * s) ** (p + 1) <= tol:
                best = (p, n)
                break
    return best


class _BlockGrid:
    """Q_b[n] = sum_j L_n(d_j) FM_j on the regular grid of one block, spacing at most h per axis (only the nodes
    used); per axis the degree and cells of :func:`axis_plan` (``degrees``)."""

    def __init__(self, d: np.ndarray, FM: np.ndarray, h: float, order: int, k_design: float | None = None):
        # the grid spans the block's bounding box: per axis n = max(order, ceil(extent / h) + 1) cells of
        # extent / n < h (or fewer of a lower degree, see axis_plan), each point's stencil centred on its cell
        # except in the cells next to the ends
        lo_m, ext = d.min(axis=0), np.ptp(d, axis=0)
        plans = [axis_plan(float(e), h, order, k_design) for e in ext]
        deg = np.array([p for p, _ in plans], dtype=np.int64)
        ncell = np.array([n for _, n in plans], dtype=np.int64)
        hs = np.where(ext > 0, ext / ncell, h)                       # (3,) m
        t = (d - lo_m) / hs
        base = np.clip(np.floor(t).astype(np.int64) - (deg - 1) // 2, 0, ncell - deg)  # first stencil node
        self.shape = tuple(int(n) + 1 for n in ncell)
        self.degrees = tuple(int(p) for p in deg)
        self.g0 = lo_m                                                # (3,) m
        self.h = hs
        rel = base
        u = t - base
        Wax = [_lagrange_weights(u[:, a], int(deg[a])) for a in range(3)]  # (n, degree+1) each
        n1, n2, n3 = self.shape
        flat_idx = np.zeros((len(d), 1), dtype=np.int64)
        weight = np.ones((len(d), 1))
        for a, stride in enumerate((n2 * n3, n3, 1)):
            idx_a = (rel[:, a][:, None] + np.arange(deg[a] + 1)) * stride
            flat_idx = (flat_idx[:, :, None] + idx_a[:, None, :]).reshape(len(d), -1)
            weight = (weight[:, :, None] * Wax[a][:, None, :]).reshape(len(d), -1)
        size = n1 * n2 * n3
        Q = np.stack([np.bincount(flat_idx.ravel(), (weight * FM[:, m][:, None]).ravel(), minlength=size)
                      for m in range(6)], axis=-1)
        self.Q = Q.reshape(n1, n2 * n3, 6)
        self.used = np.zeros(size, dtype=bool)
        self.used[np.unique(flat_idx)] = True
        self.used = self.used.reshape(n1, n2 * n3)
        self.nodes = [self.g0[a] + hs[a] * np.arange(self.shape[a]) for a in range(3)]


class _SpacingLevel:
    """All blocks' grids at one spacing: the coefficient matrix of the exponents and the Q contractions.

    Every block is factorised, exp(kappa . d_n) = X1[i, n1] Y[i, (n2, n3)]: X1 on the x grid line (with the
    offset c_i), Y on the (y, z) nodes that some point's stencil touches. Blocks with more than
    ``big_factor`` times the median block's nodes (the hull) are contracted alone; the others (the control
    planes) are padded to one shape and contracted together in batched products. ``points`` (P, 3, block 0's
    coordinates) add P whole columns c_i exp(kappa_i . d_p), for the orbital velocities there."""

    def __init__(self, blocks, h: float, order: int, points: np.ndarray | None = None, big_factor: float = 3.0,
                 k_design: float | None = None):
        self.h = h
        self.grids = [_BlockGrid(d, FM, h, order, k_design) for d, FM in blocks]
        nb = len(blocks)
        keep = [np.flatnonzero(g.used.any(axis=0)) for g in self.grids]
        size = [g.shape[0] * len(keep[b]) for b, g in enumerate(self.grids)]
        big = [b for b in range(nb) if size[b] > big_factor * np.median(size)]
        small = [b for b in range(nb) if b not in big]
        n1p = max((self.grids[b].shape[0] for b in small), default=0)
        n23p = max((len(keep[b]) for b in small), default=0)
        cols = []                      # (block, x or None, (y, z) or None) per exponent column

        def x_columns(b, n1):
            g = self.grids[b]
            cols.extend((b, x, None) for x in g.nodes[0])
            cols.extend((b, None, None) for _ in range(n1 - g.shape[0]))     # padding: exponent 0, Q 0

        def yz_columns(b, n23):
            g = self.grids[b]
            y, z = np.meshgrid(g.nodes[1], g.nodes[2], indexing="ij")
            yz = np.column_stack([y.ravel(), z.ravel()])[keep[b]]
            cols.extend((b, None, p) for p in yz)
            cols.extend((b, None, None) for _ in range(n23 - len(yz)))

        self.big = []                  # (block, x columns, (y, z) columns, Q^T (6, n1 n23))
        for b in big:
            g, x0 = self.grids[b], len(cols)
            x_columns(b, g.shape[0])
            yz_columns(b, len(keep[b]))
            self.big.append((b, slice(x0, x0 + g.shape[0]), slice(x0 + g.shape[0], len(cols)),
                             np.ascontiguousarray(g.Q[:, keep[b], :].reshape(-1, 6).T, dtype=np.float32)))
        # the small blocks' x lines side by side, then their (y, z) nodes: one product X1^T Y of all of them,
        # whose diagonal blocks are each block's node sums
        ns = len(small)
        self.n_small, self.n1p, self.n23p = ns, n1p, n23p
        x0 = len(cols)
        for b in small:
            x_columns(b, n1p)
        y0 = len(cols)
        for b in small:
            yz_columns(b, n23p)
        self.small_x, self.small_yz = slice(x0, y0), slice(y0, len(cols))
        self.small_rows = (slice(small[0], small[-1] + 1) if small and small == list(range(small[0], small[-1] + 1))
                           else np.array(small, dtype=np.int64))
        self._diag = np.arange(ns)
        QTs = np.zeros((ns, 6, n1p, n23p))
        for s_, b in enumerate(small):
            g = self.grids[b]
            QTs[s_, :, :g.shape[0], :len(keep[b])] = g.Q[:, keep[b], :].transpose(2, 0, 1)
        self.QTs = QTs.reshape(ns, 6, n1p * n23p).astype(np.float32)
        pts = np.zeros((0, 3)) if points is None else np.asarray(points, dtype=float)
        self.points = slice(len(cols), len(cols) + len(pts))      # exp(kappa . d_p + offset) of block 0, whole
        C_re, C_im = np.zeros((4 * nb, len(cols) + len(pts))), np.zeros((4 * nb, len(cols) + len(pts)))
        C_re[0:3, self.points] = C_im[0:3, self.points] = pts.T
        C_re[3, self.points] = C_im[3, self.points] = 1.0
        for m, (b, x, yz) in enumerate(cols):
            if x is not None:                                     # kappa_x x + offset
                C_re[4 * b, m] = C_im[4 * b, m] = x
                C_re[4 * b + 3, m] = C_im[4 * b + 3, m] = 1.0
            elif yz is not None:                                  # kappa_y y + kappa_z z
                C_re[4 * b + 1:4 * b + 3, m] = yz
                # the (y, z) factor enters conjugated, so that Re(X1^T Y) = [Re X1; Im X1]^T [Re Y; -Im Y]
                # is one real product
                C_im[4 * b + 1:4 * b + 3, m] = -yz
        self.C_re, self.C_im = C_re.astype(np.float32), C_im.astype(np.float32)
        self.n_cols = C_re.shape[1]

    def contract(self, X: np.ndarray, out: np.ndarray, point_weights: np.ndarray | None = None,
                 point_sums: np.ndarray | None = None) -> None:
        """out (B, 6) += the blocks' sums from X (2 I, M) = [Re; Im] of this level's exponentials (the
        components' c_i exp(kappa_i . node), float32); point_sums (P, K) += [Re X_p; Im X_p]^T point_weights
        (2 I, K), X_p the components' values at the points."""
        for b, xs, ys, QT in self.big:
            node = X[:, xs].T @ X[:, ys]                                     # (n1, n23) = Re(X1^T Y)
            out[b] += QT @ node.ravel()
        ns = self.n_small
        if ns:
            node = X[:, self.small_x].T @ X[:, self.small_yz]                # (ns n1p, ns n23p), all pairs
            d = self._diag
            node = node.reshape(ns, self.n1p, ns, self.n23p)[d, :, d, :]     # (ns, n1p, n23p): each block's
            out[self.small_rows] += (self.QTs @ node.reshape(ns, -1, 1))[:, :, 0]
        if point_sums is not None:
            point_sums += X[:, self.points].T @ point_weights


class WavePressureGrid:
    """Grids for the blocks of a :class:`bb2_sim.hydrostatics.PressureIntegrator` (same block order).

    ``spacings_m``: one spacing or a list (coarsest used for a component with k h <= ``max_kh``).
    ``points`` (P, 3): points in block 0's coordinates (the body axes about the CG) where
    :meth:`block_sums_and_orbital_velocity` also gives the sea's orbital velocity, from the same exponentials."""

    def __init__(self, blocks: list[tuple[np.ndarray, np.ndarray]], spacings_m, order: int,
                 max_kh: float = np.inf, points: np.ndarray | None = None):
        spacings = sorted({float(s) for s in np.atleast_1d(spacings_m)})
        if order < 1 or not spacings or spacings[0] <= 0 or not max_kh > 0:
            raise ValueError(f"wave-load grid needs order >= 1, spacings > 0 and max_kh > 0, got {order}, "
                             f"{spacings_m}, {max_kh}")
        self.spacings_m, self.order, self.max_kh = spacings, int(order), float(max_kh)
        self._blocks = blocks
        self.n_blocks = len(blocks)
        self.points = None if points is None else np.array(points, dtype=float).reshape(-1, 3)
        self._levels: dict[tuple[float, float | None], _SpacingLevel] = {}
        self._comps: WaveComponents | None = None

    def level(self, h: float, k_design: float | None = None) -> _SpacingLevel:
        """The grids at spacing h for wavenumbers up to k_design (rad/m; None: every axis of degree ``order``),
        built on first use."""
        key = (h, k_design)
        level = self._levels.pop(key, None)                  # re-inserted: the dict is in order of last use
        if level is None:
            level = _SpacingLevel(self._blocks, h, self.order, self.points, k_design=k_design)
        self._levels[key] = level
        return level

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
            bounds = [(float(s), int(np.argmax(hs == s)), int(len(hs) - np.argmax(hs[::-1] == s)))
                      for s in np.unique(hs)[::-1]]
            # each level's grids are planned for the largest wavenumber among its components, at most max_kh / h
            # (the finest level's shorter waves get the hull's larger error, not every block's)
            self._groups = [(self.level(s, min(float(k[order][i0:i1].max()), self.max_kh / s)), i0, i1)
                            for s, i0, i1 in bounds]
            # the levels of the last few seas are kept (a model alternating between two seas reuses them), not of
            # every sea a process met (a campaign's worker flying one sea after another: ~0.5 MB a level)
            while len(self._levels) > LEVELS_KEPT:
                del self._levels[next(iter(self._levels))]
            mu = comps.direction[order]
            # per component [k, k cos mu, k sin mu, ln a, eps - omega t]: P = K @ W gives every block's
            # exponent parameters, real [k v_z, k c_z + ln a] and imaginary [k (cos mu v_x + sin mu v_y),
            # k (cos mu c_x + sin mu c_y) + eps - omega t] (see block_sums)
            k = k[order]
            self._K = np.column_stack([k, k * np.cos(mu), k * np.sin(mu),
                                       np.log(np.maximum(comps.amplitude[order], 1e-300)), comps.phase[order]])
            self._eps, self._omega = comps.phase[order].copy(), comps.omega[order]
            # the orbital velocity a e^{kz} omega [cos th cos mu, cos th sin mu, sin th] (q12: th - pi/2, cos -> sin,
            # sin -> -cos) is [Re; Im] of the points' values times these weights, per level
            z, wc, ws = np.zeros_like(mu), self._omega * np.cos(mu), self._omega * np.sin(mu)
            horizontal, vertical = np.column_stack([wc, ws, z]), np.column_stack([z, z, self._omega])
            by_phase = {False: (horizontal, vertical), True: (-vertical, horizontal)}
            self._point_weights = {q12: [np.concatenate([a[i0:i1], b[i0:i1]]).astype(np.float32)
                                         for _, i0, i1 in self._groups] for q12, (a, b) in by_phase.items()}
            # work arrays (kept: fresh temporaries of this size cost page faults each call): each level's (I, M)
            # exponents and [Re; Im] values
            sizes = [(i1 - i0, level.n_cols) for level, i0, i1 in self._groups]
            total = sum(ni * m for ni, m in sizes)
            ER, EI, T = (np.empty(total, np.float32) for _ in range(3))
            parts, o = [], 0
            for ni, m in sizes:
                parts.append(tuple(a[o:o + ni * m].reshape(ni, m) for a in (ER, EI, T)) +
                             (np.empty((2 * ni, m), np.float32),))
                o += ni * m
            self._work = (ER, EI, T, parts)
            nb = self.n_blocks
            self._W = np.zeros((5, 2, nb, 4))
            self._W[3, 0, :, 3] = 1.0
            self._W[4, 1, :, 3] = 1.0
            self._comps = comps

    def block_sums(self, comps: WaveComponents, v: np.ndarray, c: np.ndarray, t: float) -> np.ndarray:
        """(B, 6) sums of w_j FM_j; v (B, 3, 3) the earth rows [v_x; v_y; v_z] per block, c (B, 3) origins."""
        return self._sums(comps, v, c, t, None)

    def block_sums_and_orbital_velocity(self, comps: WaveComponents, v: np.ndarray, c: np.ndarray, t: float, *,
                                        q12: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`block_sums` and the orbital velocity (P, 3) (earth axes, m/s) at the grid's ``points``, as
        :meth:`bb2_sim.sea.ComponentSea.orbital_velocity` gives it (``q12``: its phase shifted by -pi/2), from
        the same exponentials (single precision: about 1e-7 of each component's velocity)."""
        if self.points is None:
            raise ValueError("this wave-load grid was built without points for the orbital velocity")
        uw = np.zeros((len(self.points), 3))
        return self._sums(comps, v, c, t, uw, q12), uw

    def _sums(self, comps: WaveComponents, v: np.ndarray, c: np.ndarray, t: float,
              point_sums: np.ndarray | None = None, q12: bool = False) -> np.ndarray:
        self._prepare(comps)
        nb, W, K = self.n_blocks, self._W, self._K
        vc = np.concatenate([v, c[:, :, None]], axis=2)                          # (B, 3, 4): [v_a | c_a] rows
        W[0, 0], W[1, 1], W[2, 1] = vc[:, 2], vc[:, 0], vc[:, 1]                # k (v_z, c_z), k cos mu (v_x, c_x), ..
        np.subtract(self._eps, self._omega * t, out=K[:, 4])
        P = K @ W.reshape(5, 8 * nb)                                             # (I, [re | im] x B x 4)
        off = P[:, 4 * nb + 3::4]                                                # the phase offsets
        np.fmod(off, TWO_PI, out=off)                                            # to (-2 pi, 2 pi), unrounded
        P32 = P.astype(np.float32)
        # every level's exponents in one work array, so that the element-wise functions run once over all
        ER, EI, T, parts = self._work
        for (level, i0, i1), (er, ei, _, _) in zip(self._groups, parts):
            np.matmul(P32[i0:i1, :4 * nb], level.C_re, out=er)                  # (I, M) decay exponents
            np.matmul(P32[i0:i1, 4 * nb:], level.C_im, out=ei)                  # (I, M) phases
        np.minimum(ER, EXP_CAP, out=ER)
        np.exp(ER, out=ER)
        np.cos(EI, out=T)
        for er, _, t_, X in parts:
            np.multiply(er, t_, out=X[:len(er)])
        np.sin(EI, out=T)
        for er, _, t_, X in parts:
            np.multiply(er, t_, out=X[len(er):])
        out = np.zeros((nb, 6))
        weights = self._point_weights[q12]
        for j, ((level, _, _), (_, _, _, X)) in enumerate(zip(self._groups, parts)):
            level.contract(X, out, weights[j], point_sums)
        return out
