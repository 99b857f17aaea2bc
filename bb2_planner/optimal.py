"""Constrained optimal Bernstein trajectories (after Cichella et al. 2019; SPEC of bb2_control, section 2.7).

The decision variables are the free control points of a degree-``N`` path on ``[t0, tf]`` (native frame,
metres).  End points are fixed; end velocities are fixed when given (they fix ``c_1`` and ``c_{N-1}``
through ``p'(t0) = N (c_1 - c_0) / (tf - t0)``).  Objectives:

* ``"energy"``: ``int |p''|^2 dt`` in closed form (derivative, Gram matrix of the Bernstein basis);
* ``"length"``: arc length by Gauss-Legendre quadrature of ``|p'|``.

Constraints (all inequalities, solved with scipy's SLSQP and analytic Jacobians):

* speed ``v_min <= |p'| <= v_max`` on the control points of ``|p'|^2`` (``p'.p'`` by the product rule):
  by the convex-hull property this bounds the **whole** curve (conservative);
* turn rate ``|p' x p''| / |p'|^2 <= turn_rate_max`` on ``n_samples`` uniform samples;
* terrain clearance ``z - z_terrain(x, y) >= min_clearance + clearance_margin`` on the samples;
* ``z <= z_max`` (e.g. the ROM's validity depth) on the samples (on the control points it would be
  infeasible whenever a fixed end velocity points upwards).

Sampled constraints hold at the samples only; :func:`constraint_margins` re-checks every bound on a
dense grid and is what the tests use.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy import optimize, special

from bb2_planner.bernstein import (BernsteinPath, basis_matrix, fit_control_points, gram_matrix)
from bb2_planner.terrain import Terrain

__all__ = ["TrajectoryProblem", "TrajectoryResult", "optimal_trajectory", "constraint_margins",
           "OptimisationError"]


class OptimisationError(ValueError):
    """The trajectory problem is malformed (the solver's own failures are reported in the result)."""


@dataclass
class TrajectoryProblem:
    """A trajectory to plan (native frame: x, y horizontal, z up; SI units).

    ``p_start``/``p_end`` [m]; ``tf``/``t0`` [s]; ``v_start``/``v_end`` [m/s] or None (free);
    ``v_max``/``v_min`` [m/s]; ``turn_rate_max`` [rad/s] (|p' x p''|/|p'|^2, 3-D);
    ``terrain`` + ``min_clearance`` [m]; ``z_max`` [m] highest allowed elevation.
    ``clearance_margin`` [m], ``turn_rate_margin`` [rad/s] and ``z_margin`` [m] tighten the sampled constraints so that
    the bound also holds between samples; ``n_samples`` is the number of uniform constraint samples.
    """

    p_start: np.ndarray
    p_end: np.ndarray
    tf: float
    degree: int = 8
    t0: float = 0.0
    objective: Literal["energy", "length"] = "energy"
    v_start: np.ndarray | None = None
    v_end: np.ndarray | None = None
    v_max: float | None = None
    v_min: float | None = None
    turn_rate_max: float | None = None
    terrain: Terrain | None = None
    min_clearance: float | None = None
    clearance_margin: float = 0.0
    turn_rate_margin: float = 0.0
    z_margin: float = 0.0
    z_max: float | None = None
    n_samples: int = 60
    name: str = "optimal"

    def __post_init__(self) -> None:
        self.p_start = np.asarray(self.p_start, dtype=float)
        self.p_end = np.asarray(self.p_end, dtype=float)
        for label, v in (("p_start", self.p_start), ("p_end", self.p_end)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise OptimisationError(f"{label} must be 3 finite coordinates, got {v!r}")
        for label in ("v_start", "v_end"):
            v = getattr(self, label)
            if v is not None:
                v = np.asarray(v, dtype=float)
                if v.shape != (3,) or not np.all(np.isfinite(v)):
                    raise OptimisationError(f"{label} must be 3 finite components, got {v!r}")
                setattr(self, label, v)
        if not self.tf > self.t0:
            raise OptimisationError(f"need tf > t0, got t0={self.t0}, tf={self.tf}")
        fixed = 2 + (self.v_start is not None) + (self.v_end is not None)
        if self.degree + 1 <= fixed:
            raise OptimisationError(f"degree {self.degree} leaves no free control point with {fixed} fixed")
        if self.objective not in ("energy", "length"):
            raise OptimisationError(f"objective must be 'energy' or 'length', got {self.objective!r}")
        if (self.terrain is None) != (self.min_clearance is None):
            raise OptimisationError("terrain and min_clearance go together")
        for label in ("v_max", "v_min", "turn_rate_max"):
            v = getattr(self, label)
            if v is not None and not v > 0:
                raise OptimisationError(f"{label} must be > 0, got {v}")
        if self.turn_rate_max is not None and not 0 <= self.turn_rate_margin < self.turn_rate_max:
            raise OptimisationError(f"turn_rate_margin must be in [0, turn_rate_max), got {self.turn_rate_margin}")
        if self.clearance_margin < 0:
            raise OptimisationError(f"clearance_margin must be >= 0, got {self.clearance_margin}")
        if self.v_min is not None and self.v_max is not None and self.v_min >= self.v_max:
            raise OptimisationError(f"v_min {self.v_min} must be below v_max {self.v_max}")

    @property
    def span(self) -> float:
        return self.tf - self.t0


@dataclass
class TrajectoryResult:
    """Solver outcome: the path, whether SLSQP converged, and the dense-sample margins of every bound."""

    path: BernsteinPath
    success: bool
    message: str
    objective: float
    iterations: int
    margins: dict[str, float] = field(default_factory=dict)


def _diff_matrix(n: int, span: float) -> np.ndarray:
    """(n, n+1) matrix mapping control points to derivative control points."""
    return n / span * np.diff(np.eye(n + 1), axis=0)


def _square_product_tensor(m: int) -> np.ndarray:
    """W[k, i, j] with (a.a)_k = sum_ij W[k,i,j] a_i.a_j for degree-m a (product rule)."""
    W = np.zeros((2 * m + 1, m + 1, m + 1))
    c = special.comb(m, np.arange(m + 1))
    for i in range(m + 1):
        for j in range(m + 1):
            W[i + j, i, j] = c[i] * c[j] / special.comb(2 * m, i + j)
    return W


class _Model:
    """Precomputed linear maps from the full control-point array X (N+1, 3) to what constraints need."""

    def __init__(self, pb: TrajectoryProblem):
        N, span = pb.degree, pb.span
        self.pb, self.N = pb, N
        fixed = {0: pb.p_start, N: pb.p_end}
        if pb.v_start is not None:
            fixed[1] = pb.p_start + pb.v_start * span / N
        if pb.v_end is not None:
            fixed[N - 1] = pb.p_end - pb.v_end * span / N
        self.fixed = fixed
        self.free = np.array([i for i in range(N + 1) if i not in fixed])
        D1 = _diff_matrix(N, span)
        D2 = _diff_matrix(N - 1, span) @ D1
        self.D1 = D1
        tau = np.linspace(0.0, 1.0, pb.n_samples)
        self.B0 = basis_matrix(N, tau)
        self.B1 = basis_matrix(N - 1, tau) @ D1
        self.B2 = basis_matrix(N - 2, tau) @ D2 if N >= 2 else np.zeros((tau.size, N + 1))
        self.Q = D2.T @ gram_matrix(N - 2, span) @ D2 if N >= 2 else np.zeros((N + 1, N + 1))
        x, w = special.roots_legendre(16)
        panels = 8
        edges = np.linspace(0.0, 1.0, panels + 1)
        tq = (0.5 * (edges[:-1] + edges[1:])[:, None] + 0.5 / panels * x[None, :]).ravel()
        self.Bl = basis_matrix(N - 1, tq) @ D1
        self.wl = np.tile(w, panels) * 0.5 / panels * span
        self.W = _square_product_tensor(N - 1)

    # x (free points, flattened) <-> X (all points)
    def full(self, x: np.ndarray) -> np.ndarray:
        X = np.empty((self.N + 1, 3))
        for i, p in self.fixed.items():
            X[i] = p
        X[self.free] = x.reshape(-1, 3)
        return X

    def reduce(self, G: np.ndarray) -> np.ndarray:
        """Gradient w.r.t. X (..., N+1, 3) -> gradient w.r.t. x (..., n_free*3)."""
        return G[..., self.free, :].reshape(G.shape[:-2] + (-1,))

    # objective
    def objective(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        X = self.full(x)
        if self.pb.objective == "energy":
            QX = self.Q @ X
            return float(np.sum(X * QX)), self.reduce(2.0 * QX)
        V = self.Bl @ X
        s = np.linalg.norm(V, axis=1)
        s_safe = np.maximum(s, 1e-12)
        G = self.Bl.T @ (self.wl[:, None] * V / s_safe[:, None])
        return float(self.wl @ s), self.reduce(G)

    # constraints, each (values, jacobian wrt x); feasible when values >= 0
    def speed_sq_points(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = self.D1 @ X                                            # (N, 3) derivative control points
        e = np.einsum("kij,id,jd->k", self.W, d, d)
        de_dd = 2.0 * np.einsum("kij,jd->kid", self.W, d)          # (K, N, 3)
        de_dX = np.einsum("kid,ia->kad", de_dd, self.D1)           # (K, N+1, 3)
        return e, de_dX

    def constraints(self) -> list[dict]:
        pb, cons = self.pb, []
        v_ref = max(np.linalg.norm(pb.p_end - pb.p_start) / pb.span, pb.v_max or 0.0, 1e-3)
        if pb.v_max is not None or pb.v_min is not None:
            def speed(x, sign, bound):
                e, J = self.speed_sq_points(self.full(x))
                return sign * (bound ** 2 - e) / v_ref ** 2, sign * self.reduce(-J) / v_ref ** 2
            if pb.v_max is not None:
                cons.append(dict(type="ineq", fun=lambda x: speed(x, 1.0, pb.v_max)[0],
                                 jac=lambda x: speed(x, 1.0, pb.v_max)[1]))
            if pb.v_min is not None:
                cons.append(dict(type="ineq", fun=lambda x: speed(x, -1.0, pb.v_min)[0],
                                 jac=lambda x: speed(x, -1.0, pb.v_min)[1]))
        if pb.turn_rate_max is not None:
            w_max = pb.turn_rate_max - pb.turn_rate_margin
            scale = 1.0 / (w_max ** 2 * v_ref ** 4)

            def turn(x):
                X = self.full(x)
                v, a = self.B1 @ X, self.B2 @ X
                c = np.cross(v, a)
                vv = np.sum(v * v, axis=1)
                g = w_max ** 2 * vv ** 2 - np.sum(c * c, axis=1)
                gv = 4.0 * w_max ** 2 * vv[:, None] * v - 2.0 * np.cross(a, c)
                ga = -2.0 * np.cross(c, v)
                J = self.B1[:, :, None] * gv[:, None, :] + self.B2[:, :, None] * ga[:, None, :]
                return g * scale, self.reduce(J) * scale
            cons.append(dict(type="ineq", fun=lambda x: turn(x)[0], jac=lambda x: turn(x)[1]))
        if pb.terrain is not None:
            need = pb.min_clearance + pb.clearance_margin

            def clear(x):
                P = self.B0 @ self.full(x)
                x0, x1, y0, y1 = pb.terrain.bounds     # trial points off the grid see the edge value
                P[:, 0], P[:, 1] = np.clip(P[:, 0], x0, x1), np.clip(P[:, 1], y0, y1)
                g = pb.terrain.clearance(P) - need
                grad = pb.terrain.gradient(P[:, 0], P[:, 1])
                dg = np.c_[-grad, np.ones(len(P))]
                return g / need, self.reduce(self.B0[:, :, None] * dg[:, None, :]) / need
            cons.append(dict(type="ineq", fun=lambda x: clear(x)[0], jac=lambda x: clear(x)[1]))
        if pb.z_max is not None:
            sel = np.zeros((self.B0.shape[0], self.N + 1, 3))
            sel[:, :, 2] = -self.B0
            Jz = self.reduce(sel)
            cons.append(dict(type="ineq", fun=lambda x: pb.z_max - pb.z_margin - (self.B0 @ self.full(x))[:, 2],
                             jac=lambda x: Jz))
        return cons


def _initial_points(pb: TrajectoryProblem, initial: BernsteinPath | None) -> np.ndarray:
    if initial is None:
        tau = np.linspace(0.0, 1.0, pb.degree + 1)
        return pb.p_start + tau[:, None] * (pb.p_end - pb.p_start)
    ini = initial.to_frame("native")
    tau = np.linspace(0.0, 1.0, 8 * (pb.degree + 1))
    pts = ini(ini.t0 + tau * ini.span)
    pts[0], pts[-1] = pb.p_start, pb.p_end
    return fit_control_points(tau, pts, pb.degree)


def constraint_margins(path: BernsteinPath, pb: TrajectoryProblem, samples: int = 4001) -> dict[str, float]:
    """Smallest margin of every bound of ``pb`` on ``samples`` uniform samples (negative = violated).

    Units: speed m/s, turn rate rad/s, clearance and z in m; end conditions as the largest error.
    """
    t = np.linspace(path.t0, path.tf, samples)
    p, v, a = path(t), path.velocity(t), path.acceleration(t)
    speed = np.linalg.norm(v, axis=1)
    out = {"end_position_error_m": float(max(np.linalg.norm(p[0] - pb.p_start), np.linalg.norm(p[-1] - pb.p_end)))}
    if pb.v_start is not None:
        out["start_velocity_error_mps"] = float(np.linalg.norm(v[0] - pb.v_start))
    if pb.v_end is not None:
        out["end_velocity_error_mps"] = float(np.linalg.norm(v[-1] - pb.v_end))
    if pb.v_max is not None:
        out["v_max"] = float(pb.v_max - speed.max())
    if pb.v_min is not None:
        out["v_min"] = float(speed.min() - pb.v_min)
    if pb.turn_rate_max is not None:
        rate = np.linalg.norm(np.cross(v, a), axis=1) / np.maximum(speed, 1e-12) ** 2
        out["turn_rate_max"] = float(pb.turn_rate_max - rate.max())
    if pb.terrain is not None:
        out["min_clearance"] = float(pb.terrain.clearance(p).min() - pb.min_clearance)
    if pb.z_max is not None:
        out["z_max"] = float(pb.z_max - p[:, 2].max())
    return out


def optimal_trajectory(pb: TrajectoryProblem, initial: BernsteinPath | None = None, *,
                       maxiter: int = 300, ftol: float = 1e-10) -> TrajectoryResult:
    """Solve ``pb`` with SLSQP from ``initial`` (default: the straight line between the end points).

    Returns a :class:`TrajectoryResult` whose ``margins`` come from :func:`constraint_margins`.
    """
    model = _Model(pb)
    X0 = _initial_points(pb, initial)
    for i, p in model.fixed.items():
        X0[i] = p
    # scaled variables y = (x - x_ref) / L (order one) and objective f / f0
    x_ref = np.tile(0.5 * (pb.p_start + pb.p_end), model.free.size)
    L = max(float(np.linalg.norm(pb.p_end - pb.p_start)), 1.0)
    y0 = (X0[model.free].ravel() - x_ref) / L
    f_ref = L ** 2 / pb.span ** 3 if pb.objective == "energy" else L     # (L/T^2)^2 T, or L
    f0 = max(abs(model.objective(X0[model.free].ravel())[0]), f_ref)

    def fun(y):
        f, g = model.objective(x_ref + L * y)
        return f / f0, g * (L / f0)

    def scaled(c):
        return dict(type=c["type"], fun=lambda y: c["fun"](x_ref + L * y),
                    jac=lambda y: c["jac"](x_ref + L * y) * L)

    res = optimize.minimize(fun, y0, jac=True, method="SLSQP",
                            constraints=[scaled(c) for c in model.constraints()],
                            options={"maxiter": maxiter, "ftol": ftol})
    x = x_ref + L * res.x
    path = BernsteinPath(model.full(x), pb.t0, pb.tf, "native", pb.name)
    return TrajectoryResult(path=path, success=bool(res.success), message=str(res.message),
                            objective=float(model.objective(x)[0]), iterations=int(res.nit),
                            margins=constraint_margins(path, pb))
