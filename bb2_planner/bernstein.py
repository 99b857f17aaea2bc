"""Bernstein polynomials and the Bernstein path used by the BB2 planner (SPEC of bb2_control, section 2).

A degree-``n`` Bernstein polynomial on the time span ``[t0, tf]`` has control points
``c_0 .. c_n`` (array of shape ``(n + 1, d)``, one row per point) and value

    tau = (t - t0) / (tf - t0),   B_{i,n}(tau) = C(n, i) tau^i (1 - tau)^(n - i),
    p(t) = sum_i c_i B_{i,n}(tau).

Two layers:

* module functions working on control-point arrays (evaluation by de Casteljau or by the basis
  matrix, derivative, degree elevation, subdivision, antiderivative/integral, product, Gram
  matrix, least-squares fit through waypoints);
* :class:`BernsteinPath`, a curve with a time span and a named frame, with the geometric
  queries the path-following law needs.

**For the path-following law** (virtual time ``gamma`` is the path's time ``t``)::

    path = load_path("circle_r400", frame="native")     # bb2_planner.paths
    k = path.at(gamma)          # PathPoint: everything at once, all in path.frame
    k.p, k.dp, k.ddp            # p_d(gamma) [m], p_d'(gamma) [m/s], p_d''(gamma) [m/s^2]
    k.speed, k.tangent          # |p_d'| [m/s], unit tangent t1
    k.curvature, k.torsion      # [1/m], [1/m]

or individually ``path(gamma)``, ``path.velocity(gamma)``, ``path.acceleration(gamma)``,
``path.speed``, ``path.tangent``, ``path.curvature``, ``path.torsion``.  Derivatives are with
respect to time ``t`` (not the normalised ``tau``): the ``1/(tf - t0)`` factor is in the
derivative control points, as in the authors' code.  Evaluation outside ``[t0, tf]`` is
clamped to the span (the virtual time saturates at the path end).

Evaluation uses de Casteljau (stable for the degree-99 circle); never the power form.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Sequence

import numpy as np

from bb2_sim import frames as _frames

__all__ = [
    "PathError", "FRAMES", "frame_matrix_to_native",
    "basis_matrix", "de_casteljau", "de_casteljau_split", "derivative_points", "elevate_points",
    "antiderivative_points", "integral", "product_points", "dot_points", "gram_matrix",
    "fit_control_points", "BernsteinPath", "PathPoint",
]


class PathError(ValueError):
    """A path (control points, time span or frame) is malformed."""


# ------------------------------------------------------------------------------------------ frames
#: Frames a path may be expressed in, all z-up except NED, positions in metres.
#: ``controller`` is frame C of the LOS23 code: (x, y, z)_C = (-x, -y, z)_native (numerically ENU).
FRAMES: dict[str, np.ndarray] = {
    "native": np.eye(3),
    "controller": _frames.D_FLIP.copy(),
    "enu": _frames.D_FLIP.copy(),
    "ned": _frames.D_FLIP @ _frames.ENU_TO_NED.T,
}


def frame_matrix_to_native(frame: str) -> np.ndarray:
    """3x3 matrix ``M`` with ``p_native = M @ p_frame`` (all maps are rotations/reflections, no offset)."""
    try:
        return FRAMES[frame]
    except KeyError:
        raise PathError(f"unknown frame {frame!r}; expected one of {sorted(FRAMES)}") from None


# ---------------------------------------------------------------------------- control-point algebra
def _as_points(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=float)
    return c[:, None] if c.ndim == 1 else c


def basis_matrix(n: int, tau: np.ndarray) -> np.ndarray:
    """Bernstein basis ``B[k, i] = B_{i,n}(tau_k)``, shape ``(len(tau), n + 1)``.

    Computed as the binomial pmf, which is numerically safe for high degrees: scipy's own ufunc, which
    ``scipy.stats.binom.pmf`` evaluates for valid arguments and clips to [0, 1] (:func:`_binomial_pmf`).
    ``p(tau) = basis_matrix(n, tau) @ c``.
    """
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    i = np.arange(n + 1)
    return np.clip(_binomial_pmf()(i[None, :], n, np.clip(tau, 0.0, 1.0)[:, None]), 0.0, 1.0)


def _binomial_pmf():
    """The binomial pmf ufunc (k, n, p) that ``scipy.stats.binom.pmf`` calls for valid arguments (k, n integers,
    0 <= p <= 1) and clips to [0, 1]: clipped, the same values to the last digit (``tests/planner/test_bernstein.py``)
    without importing scipy.stats, which cost every process that samples a path (the planner, path following) ~0.35 s
    of CPU on this machine.  scipy.stats's own function where that private ufunc is not there."""
    try:
        from scipy.special._ufuncs import _binom_pmf
    except ImportError:  # another scipy: the public function
        from scipy import stats

        return stats.binom.pmf
    return _binom_pmf


def de_casteljau(c: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Evaluate control points ``c`` (n+1, d) at normalised ``tau`` (any shape), vectorised.

    Returns an array of shape ``tau.shape + (d,)`` (``tau.shape`` for scalar control points of shape
    ``(n+1,)``).  Cost O(n^2) per point.
    """
    scalar = np.ndim(c) == 1
    c = _as_points(c)
    tau = np.asarray(tau, dtype=float)
    if tau.ndim == 0:  # one point (the path follower, every tick): the same arithmetic on 2-D arrays
        t = float(tau)
        b = c
        for _ in range(c.shape[0] - 1):
            b = (1.0 - t) * b[:-1] + t * b[1:]
        return b[0, 0] if scalar else b[0].copy()
    flat = tau.reshape(-1, 1, 1)
    b = np.broadcast_to(c, (flat.shape[0],) + c.shape).copy()
    for _ in range(c.shape[0] - 1):
        b = (1.0 - flat) * b[:, :-1] + flat * b[:, 1:]
    out = b[:, 0].reshape(tau.shape + (c.shape[1],))
    return out[..., 0] if scalar else out


def position_velocity_points(c: np.ndarray, s: Any, span: Any) -> tuple[np.ndarray, np.ndarray]:
    """(p, p') of control points ``c`` (n+1, d), n >= 1, at normalised ``s`` on a span of ``span`` s, from one de
    Casteljau pass: p' = n / span (b1 - b0) of its last-but-one level.  Also for N curves of one degree at once
    (``c`` (N, n+1, d), ``s`` (N, 1, 1), ``span`` (N, 1)): each curve's values bit for bit its own call's."""
    u = 1.0 - s
    n = c.shape[-2] - 1
    b = c
    for _ in range(n - 1):
        b = u * b[..., :-1, :] + s * b[..., 1:, :]
    return (u * b[..., 0:1, :] + s * b[..., 1:2, :])[..., 0, :], (b[..., 1, :] - b[..., 0, :]) * (n / span)


def de_casteljau_split(c: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Subdivide at ``tau``: control points of the left ([0, tau]) and right ([tau, 1]) pieces."""
    b = _as_points(c).copy()
    n = b.shape[0] - 1
    left, right = [b[0].copy()], [b[-1].copy()]
    for _ in range(n):
        b = (1.0 - tau) * b[:-1] + tau * b[1:]
        left.append(b[0].copy())
        right.append(b[-1].copy())
    return np.array(left), np.array(right[::-1])


def derivative_points(c: np.ndarray, span: float = 1.0) -> np.ndarray:
    """Control points of d/dt (degree n-1): ``n/span (c_{i+1} - c_i)``; ``span = tf - t0``.

    A degree-0 curve has derivative zero (returned as one zero control point).
    """
    c = _as_points(c)
    n = c.shape[0] - 1
    if n == 0:
        return np.zeros_like(c)
    return n / span * np.diff(c, axis=0)


def elevate_points(c: np.ndarray, r: int = 1) -> np.ndarray:
    """Degree elevation by ``r``: same curve, degree n+r.  Weights C(n,i) C(r,k-i) / C(n+r,k)."""
    from scipy import special  # here, not at import: scipy.special costs every process ~0.3 s

    c = _as_points(c)
    if r < 0:
        raise ValueError(f"degree elevation must be >= 0, got {r}")
    n = c.shape[0] - 1
    k = np.arange(n + r + 1)[:, None]
    i = np.arange(n + 1)[None, :]
    w = special.comb(n, i) * special.comb(r, k - i) / special.comb(n + r, k)  # comb(r, <0 or >r) = 0
    return w @ c


def antiderivative_points(c: np.ndarray, span: float = 1.0) -> np.ndarray:
    """Control points (degree n+1) of ``P(t) = int_{t0}^{t} p dt``: ``a_0 = 0, a_{k+1} = a_k + span/(n+1) c_k``."""
    c = _as_points(c)
    n = c.shape[0] - 1
    a = np.vstack([np.zeros((1, c.shape[1])), np.cumsum(c, axis=0) * span / (n + 1)])
    return a


def integral(c: np.ndarray, span: float = 1.0) -> np.ndarray:
    """Definite integral over the whole span: ``span/(n+1) sum_i c_i`` (one value per dimension)."""
    c = _as_points(c)
    return c.sum(axis=0) * span / c.shape[0]


def product_points(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Component-wise product of two Bernstein polynomials (degrees m and n) -> degree m+n.

    ``e_k = sum_{i+j=k} C(m,i) C(n,j) / C(m+n,k) a_i b_j``.  Both on the same span.
    """
    from scipy import special  # here, not at import: scipy.special costs every process ~0.3 s

    a, b = _as_points(a), _as_points(b)
    m, n = a.shape[0] - 1, b.shape[0] - 1
    wa = special.comb(m, np.arange(m + 1))[:, None] * a
    wb = special.comb(n, np.arange(n + 1))[:, None] * b
    e = np.zeros((m + n + 1, np.broadcast_shapes(a.shape[1:], b.shape[1:])[0]))
    for i in range(m + 1):
        e[i:i + n + 1] += wa[i] * wb
    return e / special.comb(m + n, np.arange(m + n + 1))[:, None]


def dot_points(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Control points (shape (m+n+1,)) of the scalar polynomial ``a(t) . b(t)``, e.g. ``|p'|^2``."""
    return product_points(a, b).sum(axis=1)


def gram_matrix(n: int, span: float = 1.0) -> np.ndarray:
    """``G[i, j] = int B_{i,n} B_{j,n} dt`` over a span: ``span C(n,i) C(n,j) / (C(2n,i+j) (2n+1))``.

    So ``int |p|^2 dt = sum_d c[:, d] @ G @ c[:, d]``.
    """
    from scipy import special  # here, not at import: scipy.special costs every process ~0.3 s

    i = np.arange(n + 1)
    ci = special.comb(n, i)
    return span * np.outer(ci, ci) / special.comb(2 * n, i[:, None] + i[None, :]) / (2 * n + 1)


def fit_control_points(tau: np.ndarray, points: np.ndarray, degree: int, *,
                       fix_ends: bool = True, smoothing: float = 0.0) -> np.ndarray:
    """Least-squares control points of a degree-``degree`` curve through ``points`` at parameters ``tau``.

    ``tau`` in [0, 1] (e.g. normalised chord length), ``points`` shape (m, d).  With ``fix_ends`` the
    curve interpolates the first and last point exactly (tau must then start at 0 and end at 1).
    ``smoothing >= 0`` adds ``smoothing * int |p''|^2 dtau`` (normalised) to damp wiggles.
    """
    tau = np.asarray(tau, dtype=float)
    pts = _as_points(points)
    if tau.ndim != 1 or tau.shape[0] != pts.shape[0]:
        raise ValueError(f"tau has {tau.shape} entries but there are {pts.shape[0]} points")
    if degree < 1:
        raise ValueError(f"degree must be >= 1, got {degree}")
    free = degree + 1 - (2 if fix_ends else 0)
    if tau.shape[0] < free:
        raise ValueError(f"{tau.shape[0]} points cannot determine a degree-{degree} fit")
    B = basis_matrix(degree, tau)
    rhs = pts.copy()
    if fix_ends:
        if not (np.isclose(tau[0], 0.0) and np.isclose(tau[-1], 1.0)):
            raise ValueError("fix_ends needs tau[0] == 0 and tau[-1] == 1")
        rhs = rhs - np.outer(B[:, 0], pts[0]) - np.outer(B[:, -1], pts[-1])
        A = B[:, 1:-1]
    else:
        A = B
    rows, b = [A], [rhs]
    if smoothing > 0.0 and degree >= 2:
        # second differences of the control points span p''; penalise them through the Gram matrix
        D2 = np.diff(np.eye(degree + 1), n=2, axis=0) * degree * (degree - 1)
        G = gram_matrix(degree - 2)
        L = np.linalg.cholesky(G + 1e-15 * np.eye(degree - 1)).T @ D2 * np.sqrt(smoothing)
        if fix_ends:
            ends = np.zeros((degree + 1, pts.shape[1]))
            ends[0], ends[-1] = pts[0], pts[-1]
            rows.append(L[:, 1:-1])
            b.append(-L @ ends)
        else:
            rows.append(L)
            b.append(np.zeros((L.shape[0], pts.shape[1])))
    sol, *_ = np.linalg.lstsq(np.vstack(rows), np.vstack(b), rcond=None)
    if fix_ends:
        sol = np.vstack([pts[:1], sol, pts[-1:]])
    return sol


# ---------------------------------------------------------------------------------------- the path
@dataclass(frozen=True)
class PathPoint:
    """Everything the path-following law needs at one time ``t`` (all vectors in the path's frame)."""

    t: float
    p: np.ndarray          #: position p_d(t) [m]
    dp: np.ndarray         #: p_d'(t) [m/s]
    ddp: np.ndarray        #: p_d''(t) [m/s^2]
    speed: float           #: |p_d'(t)| [m/s]
    tangent: np.ndarray    #: unit tangent p_d'/|p_d'|
    curvature: float       #: [1/m]
    torsion: float         #: [1/m] (0 for d < 3)


@lru_cache(maxsize=16)
def _gauss_legendre(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [-1, 1] (cached: the path follower asks every tick)."""
    from scipy import special  # here, not at import: scipy.special costs every process ~0.3 s

    return special.roots_legendre(nodes)


class BernsteinPath:
    """A Bernstein curve ``p: [t0, tf] -> R^d`` with control points in metres and time in seconds.

    Parameters
    ----------
    control_points : (n+1, d) array, metres, one row per point (n >= 1 for a path).
    t0, tf : time span in seconds (``tf > t0``); for the authors' paths ``t`` is the virtual time gamma.
    frame : one of :data:`FRAMES` (default ``"native"``: ROM native inertial frame, z up).
    name : free label.

    Derivative paths (``derivative``) keep the span and frame; their "positions" are velocities.
    """

    def __init__(self, control_points: np.ndarray | Sequence, t0: float = 0.0, tf: float = 1.0,
                 frame: str = "native", name: str = "", *, min_points: int = 2):
        c = np.array(control_points, dtype=float, copy=True)
        if c.ndim == 1:
            c = c[:, None]
        if c.ndim != 2:
            raise PathError(f"control points must be a (n+1, d) array, got shape {c.shape}")
        if c.shape[0] < min_points:
            raise PathError(f"a path needs at least {min_points} control points, got {c.shape[0]}")
        if c.shape[1] < 1:
            raise PathError("control points have zero dimensions")
        if not np.all(np.isfinite(c)):
            bad = np.argwhere(~np.isfinite(c))[0]
            raise PathError(f"control point {bad[0]} has a non-finite coordinate ({c[tuple(bad)]})")
        t0, tf = float(t0), float(tf)
        if not (np.isfinite(t0) and np.isfinite(tf)):
            raise PathError(f"time span must be finite, got [{t0}, {tf}]")
        if tf - t0 <= 0.0:
            raise PathError(f"time span must have tf > t0 (Tf = tf - t0 > 0), got t0={t0}, tf={tf}")
        if frame not in FRAMES:
            raise PathError(f"unknown frame {frame!r}; expected one of {sorted(FRAMES)}")
        c.setflags(write=False)
        self.control_points: np.ndarray = c
        self.t0: float = t0
        self.tf: float = tf
        self.frame: str = frame
        self.name: str = name
        self._deriv: dict[int, BernsteinPath] = {}

    # ------------------------------------------------------------------ basics
    @property
    def degree(self) -> int:
        return self.control_points.shape[0] - 1

    @property
    def dim(self) -> int:
        return self.control_points.shape[1]

    @property
    def span(self) -> float:
        """``tf - t0`` [s]."""
        return self.tf - self.t0

    def __repr__(self) -> str:
        return (f"BernsteinPath(name={self.name!r}, degree={self.degree}, dim={self.dim}, "
                f"t=[{self.t0}, {self.tf}] s, frame={self.frame!r})")

    def tau(self, t: np.ndarray | float) -> np.ndarray:
        """Normalised parameter in [0, 1] (clamped)."""
        return np.clip((np.asarray(t, dtype=float) - self.t0) / self.span, 0.0, 1.0)

    def __call__(self, t: np.ndarray | float) -> np.ndarray:
        """Positions at times ``t`` (de Casteljau), shape ``np.shape(t) + (d,)``."""
        return de_casteljau(self.control_points, self.tau(t))

    def position_velocity(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(p(t), p'(t)) at one time ``t`` from one de Casteljau pass (the path follower's tick).

        p is bit for bit ``self(t)``; p' is ``n / span (b1 - b0)`` of the pass's last-but-one level, the
        derivative's value computed without its own pass (it may differ from :meth:`velocity` in the last bits).
        Half the cost of ``self(t)`` and ``self.velocity(t)`` (16 against 38 us for the canyon's degree 12)."""
        s = (float(t) - self.t0) / self.span
        s = min(max(s, 0.0), 1.0)  # the clamp of tau(), without numpy's scalar overhead
        if self.degree == 0:
            return self.control_points[0].copy(), np.zeros(self.dim)
        return position_velocity_points(self.control_points, s, self.span)

    def evaluate_basis(self, t: np.ndarray | float) -> np.ndarray:
        """Same as ``__call__`` via the basis matrix (faster for many points, same result)."""
        t = np.asarray(t, dtype=float)
        return (basis_matrix(self.degree, self.tau(t).ravel()) @ self.control_points).reshape(
            t.shape + (self.dim,))

    def _new(self, c: np.ndarray, t0: float | None = None, tf: float | None = None,
             name: str | None = None) -> BernsteinPath:
        return BernsteinPath(c, self.t0 if t0 is None else t0, self.tf if tf is None else tf,
                             self.frame, self.name if name is None else name, min_points=1)

    # ------------------------------------------------------------------ derivatives
    def derivative(self, order: int = 1) -> BernsteinPath:
        """d^order p / dt^order as a Bernstein path (degree n - order, same span; cached)."""
        if order < 0:
            raise ValueError(f"derivative order must be >= 0, got {order}")
        if order == 0:
            return self
        if order not in self._deriv:
            prev = self.derivative(order - 1)
            self._deriv[order] = self._new(derivative_points(prev.control_points, self.span),
                                           name=f"{self.name}'" if self.name else "")
        return self._deriv[order]

    def velocity(self, t: np.ndarray | float) -> np.ndarray:
        """p'(t) [m/s]."""
        return self.derivative(1)(t)

    def acceleration(self, t: np.ndarray | float) -> np.ndarray:
        """p''(t) [m/s^2]."""
        return self.derivative(2)(t)

    def jerk(self, t: np.ndarray | float) -> np.ndarray:
        """p'''(t) [m/s^3]."""
        return self.derivative(3)(t)

    def speed(self, t: np.ndarray | float) -> np.ndarray:
        """Path speed |p'(t)| [m/s] (gamma is not arc length: this varies along the path)."""
        return np.linalg.norm(self.velocity(t), axis=-1)

    def tangent(self, t: np.ndarray | float) -> np.ndarray:
        """Unit tangent p'/|p'| (NaN where the speed is exactly zero)."""
        v = self.velocity(t)
        with np.errstate(invalid="ignore", divide="ignore"):
            return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def curvature(self, t: np.ndarray | float) -> np.ndarray:
        """kappa = |p' x p''| / |p'|^3 [1/m], any dimension (via |v|^2|a|^2 - (v.a)^2)."""
        v, a = self.velocity(t), self.acceleration(t)
        vv = np.sum(v * v, axis=-1)
        cross2 = np.maximum(vv * np.sum(a * a, axis=-1) - np.sum(v * a, axis=-1) ** 2, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt(cross2) / vv ** 1.5

    def torsion(self, t: np.ndarray | float) -> np.ndarray:
        """tau = (p' x p'') . p''' / |p' x p''|^2 [1/m]; 3-D paths only; 0 where the curve is straight."""
        if self.dim != 3:
            raise PathError(f"torsion needs a 3-D path, this one has d = {self.dim}")
        v, a, j = self.velocity(t), self.acceleration(t), self.jerk(t)
        c = np.cross(v, a)
        cc = np.sum(c * c, axis=-1)
        num = np.sum(c * j, axis=-1)
        scale = np.sum(v * v, axis=-1) ** 3 * 1e-20 + 1e-300   # treat |v x a| ~ 0 as straight
        return np.where(cc > scale, num / np.where(cc > scale, cc, 1.0), 0.0)

    def at(self, t: float) -> PathPoint:
        """All path quantities at one time ``t`` (the call the path-following law makes each tick)."""
        t = float(np.clip(t, self.t0, self.tf))
        tau = self.tau(t)
        v = de_casteljau(self.derivative(1).control_points, tau)
        a = de_casteljau(self.derivative(2).control_points, tau)
        s = float(np.linalg.norm(v))
        cross2 = max(float(v @ v) * float(a @ a) - float(v @ a) ** 2, 0.0)
        kappa = np.sqrt(cross2) / s ** 3 if s > 0 else np.nan
        torsion = 0.0
        if self.dim == 3:
            c = np.cross(v, a)
            cc = float(c @ c)
            if cc > s ** 6 * 1e-20 + 1e-300:
                torsion = float(c @ de_casteljau(self.derivative(3).control_points, tau)) / cc
        return PathPoint(t=t, p=de_casteljau(self.control_points, tau), dp=v, ddp=a, speed=s,
                         tangent=v / s if s > 0 else np.full_like(v, np.nan),
                         curvature=float(kappa), torsion=torsion)

    # ------------------------------------------------------------------ integrals
    def integral(self) -> np.ndarray:
        """int_{t0}^{tf} p dt (per component)."""
        return integral(self.control_points, self.span)

    def antiderivative(self) -> BernsteinPath:
        """P(t) = int_{t0}^{t} p dt as a degree n+1 path."""
        return self._new(antiderivative_points(self.control_points, self.span))

    def arc_length(self, t_a: float | None = None, t_b: float | None = None, *,
                   panels: int = 50, nodes: int = 8) -> float:
        """Length of the curve between ``t_a`` and ``t_b`` (default whole span) [m].

        Composite Gauss-Legendre quadrature of |p'| (``panels`` x ``nodes``; SPEC 2.4).
        """
        t_a = self.t0 if t_a is None else float(t_a)
        t_b = self.tf if t_b is None else float(t_b)
        if t_b < t_a:
            return -self.arc_length(t_b, t_a, panels=panels, nodes=nodes)
        x, w = _gauss_legendre(nodes)
        edges = np.linspace(t_a, t_b, panels + 1)
        half = 0.5 * np.diff(edges)
        mid = 0.5 * (edges[:-1] + edges[1:])
        tq = mid[:, None] + half[:, None] * x[None, :]
        return float(np.sum(half[:, None] * w[None, :] * self.speed(tq)))

    def cumulative_arc_length(self, samples: int = 1001, *, nodes: int = 8) -> tuple[np.ndarray, np.ndarray]:
        """(t, s): arc length ``s(t)`` from ``t0`` at ``samples`` uniform times [s, m], each interval by
        Gauss-Legendre (``nodes`` points), summed.  ``np.interp(t_q, t, s)`` then gives the length
        travelled at any ``t_q`` for a few microseconds (linear between samples: the error is of order
        dt^2/8 max|d speed/dt|, ~1e-4 m on the shipped paths at the default), e.g. the path-following
        node's progress every tick; ``s[-1]`` is :meth:`arc_length` to quadrature accuracy."""
        if samples < 2:
            raise ValueError(f"samples must be >= 2, got {samples}")
        x, w = _gauss_legendre(nodes)
        t = np.linspace(self.t0, self.tf, samples)
        half = 0.5 * np.diff(t)
        tq = 0.5 * (t[:-1] + t[1:])[:, None] + half[:, None] * x[None, :]
        ds = np.sum(half[:, None] * w[None, :] * self.speed(tq), axis=1)
        return t, np.concatenate([[0.0], np.cumsum(ds)])

    def length_bounds(self) -> tuple[float, float]:
        """(chord, control-polygon length): ``|c_n - c_0| <= L <= sum |c_{i+1} - c_i|``."""
        c = self.control_points
        return (float(np.linalg.norm(c[-1] - c[0])),
                float(np.sum(np.linalg.norm(np.diff(c, axis=0), axis=1))))

    # ------------------------------------------------------------------ geometry
    def closest_point(self, p: np.ndarray, *, samples: int | None = None,
                      candidates: int = 3) -> tuple[float, np.ndarray, float]:
        """Closest point of the curve to ``p``: returns ``(t, point, distance)``.

        Dense sampling finds the best few local minima; each is refined with a bounded scalar
        minimisation (scipy ``minimize_scalar``) on the neighbouring sample interval.
        """
        p = np.asarray(p, dtype=float)
        if p.shape != (self.dim,):
            raise PathError(f"query point must have shape ({self.dim},), got {p.shape}")
        m = samples or max(200, 10 * (self.degree + 1))
        ts = np.linspace(self.t0, self.tf, m)
        d2 = np.sum((self.evaluate_basis(ts) - p) ** 2, axis=1)
        # local minima of the sampled distance (including the ends)
        padded = np.concatenate([[np.inf], d2, [np.inf]])
        is_min = (padded[1:-1] <= padded[:-2]) & (padded[1:-1] <= padded[2:])
        idx = np.flatnonzero(is_min)
        idx = idx[np.argsort(d2[idx])][:candidates]
        best = (ts[int(np.argmin(d2))], float(np.min(d2)))
        f = lambda t: float(np.sum((self(t) - p) ** 2))  # noqa: E731
        from scipy import optimize

        for k in idx:
            lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, m - 1)]
            r = optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded",
                                         options={"xatol": 1e-10 * self.span})
            if r.fun < best[1]:
                best = (float(r.x), float(r.fun))
        t = best[0]
        point = self(t)
        return t, point, float(np.linalg.norm(point - p))

    # ------------------------------------------------------------------ transforms
    def elevate(self, r: int = 1) -> BernsteinPath:
        """Same curve with degree n + r."""
        return self._new(elevate_points(self.control_points, r))

    def split(self, t: float) -> tuple[BernsteinPath, BernsteinPath]:
        """Split at time ``t`` (t0 < t < tf) into paths on [t0, t] and [t, tf] (de Casteljau)."""
        t = float(t)
        if not self.t0 < t < self.tf:
            raise PathError(f"split time {t} is not inside ({self.t0}, {self.tf})")
        left, right = de_casteljau_split(self.control_points, float(self.tau(t)))
        return self._new(left, tf=t), self._new(right, t0=t)

    def retimed(self, t0: float, tf: float) -> BernsteinPath:
        """Same geometry on a new time span (velocities scale by old span / new span)."""
        return BernsteinPath(self.control_points, t0, tf, self.frame, self.name)

    def to_frame(self, frame: str) -> BernsteinPath:
        """The same curve expressed in another frame of :data:`FRAMES` (3-D paths).

        Frame maps are linear, so transforming the control points transforms the curve exactly.
        """
        if frame == self.frame:
            return self
        if self.dim != 3:
            raise PathError(f"frame conversion needs a 3-D path, this one has d = {self.dim}")
        M = np.linalg.inv(frame_matrix_to_native(frame)) @ frame_matrix_to_native(self.frame)
        return BernsteinPath(self.control_points @ M.T, self.t0, self.tf, frame, self.name)

    def sample(self, n: int | None = None, dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(t, positions)``: ``n`` uniform samples (default 1001, as BeBOT plots) or step ``dt``."""
        if n is not None and dt is not None:
            raise ValueError("give n or dt, not both")
        if dt is not None:
            if dt <= 0:
                raise ValueError(f"dt must be > 0, got {dt}")
            t = np.arange(self.t0, self.tf + 0.5 * dt, dt)
            t = np.minimum(t, self.tf)
        else:
            n = 1001 if n is None else int(n)
            if n < 2:
                raise ValueError(f"need at least 2 samples, got {n}")
            t = np.linspace(self.t0, self.tf, n)
        return t, self.evaluate_basis(t)
