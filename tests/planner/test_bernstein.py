"""Bernstein identities and the geometric queries of BernsteinPath."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import special

from bb2_planner.bernstein import (BernsteinPath, PathError, basis_matrix, de_casteljau, dot_points,
                                   elevate_points, fit_control_points, gram_matrix, integral,
                                   product_points)
from bb2_planner.paths import load_path

REPO = Path(__file__).resolve().parents[2]

RNG = np.random.default_rng(7)


def random_path(n=7, d=3, t0=2.0, tf=12.0):
    return BernsteinPath(RNG.normal(scale=50.0, size=(n + 1, d)), t0, tf)


def power_form(c, tau):
    """Reference evaluation (fine for low degree on [0, 1])."""
    n = c.shape[0] - 1
    i = np.arange(n + 1)
    B = special.comb(n, i) * tau[:, None] ** i * (1 - tau[:, None]) ** (n - i)
    return B @ c


def test_evaluation_forms_agree_with_power_form():
    P = random_path()
    t = np.linspace(P.t0, P.tf, 37)
    ref = power_form(P.control_points, (t - P.t0) / P.span)
    np.testing.assert_allclose(P(t), ref, atol=1e-9)
    np.testing.assert_allclose(P.evaluate_basis(t), ref, atol=1e-9)
    assert basis_matrix(9, np.linspace(0, 1, 11)).sum(axis=1) == pytest.approx(np.ones(11))


def test_the_basis_is_scipy_stats_binomial_pmf_to_the_last_digit():
    """basis_matrix calls scipy's binomial ufunc itself (importing scipy.stats cost every path-sampling process
    ~0.35 s of CPU): the same values, bit for bit, as scipy.stats.binom.pmf, at the ends and at high degrees."""
    from scipy import stats

    tau = np.concatenate([[0.0, 1.0, -0.5, 1.5, 1e-300, 1 - 1e-16], np.linspace(0.0, 1.0, 2001)])
    for n in (0, 1, 3, 9, 40, 200):
        want = stats.binom.pmf(np.arange(n + 1)[None, :], n, np.clip(tau, 0.0, 1.0)[:, None])
        got = basis_matrix(n, tau)
        assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want), n
    import subprocess
    import sys

    code = ("import sys, numpy as np\nfrom bb2_planner.bernstein import basis_matrix\n"
            "basis_matrix(9, np.linspace(0, 1, 5))\nprint('scipy.stats' in sys.modules)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == "False", (p.stdout, p.stderr)   # the reason it is written so


def test_shapes_and_end_point_interpolation():
    P = random_path()
    np.testing.assert_allclose(P(P.t0), P.control_points[0], atol=1e-12)
    np.testing.assert_allclose(P(P.tf), P.control_points[-1], atol=1e-12)
    assert P(np.zeros((4, 5)) + 3.0).shape == (4, 5, 3)
    assert P(3.0).shape == (3,)
    # end velocity rule p'(t0) = N (c1 - c0) / (tf - t0)
    np.testing.assert_allclose(P.velocity(P.t0),
                               P.degree * (P.control_points[1] - P.control_points[0]) / P.span)


@pytest.mark.parametrize("n", [1, 2, 12])
def test_position_velocity_in_one_pass(n):
    """The path follower's one-pass (p, p'): p bit for bit the path's own, p' the derivative path's to round-off,
    clamped to [t0, tf] outside it like both."""
    P = random_path(n=n)
    for t in list(np.linspace(P.t0, P.tf, 41)) + [P.t0 - 3.0, P.tf + 3.0]:
        p, v = P.position_velocity(t)
        assert np.array_equal(p, P(t)), t
        np.testing.assert_allclose(v, P.velocity(t), rtol=0, atol=1e-12 * np.abs(P.velocity(t)).max())
    assert np.all(np.isnan(P.position_velocity(math.nan)[0]))


@pytest.mark.parametrize("order", [1, 2, 3])
def test_derivative_matches_finite_differences(order):
    P = random_path(n=9)
    t = np.linspace(P.t0 + 1.0, P.tf - 1.0, 15)
    h = 1e-3
    lower = P.derivative(order - 1)
    fd = (lower(t + h) - lower(t - h)) / (2 * h)
    exact = P.derivative(order)(t)
    np.testing.assert_allclose(exact, fd, atol=1e-5 * np.abs(exact).max())
    assert P.derivative(order).degree == P.degree - order


def test_degree_elevation_keeps_the_curve():
    P = random_path(n=6)
    t = np.linspace(P.t0, P.tf, 50)
    for r in (1, 3, 10):
        E = P.elevate(r)
        assert E.degree == P.degree + r
        np.testing.assert_allclose(E(t), P(t), atol=1e-9)
    np.testing.assert_allclose(elevate_points(P.control_points, 2),
                               elevate_points(elevate_points(P.control_points, 1), 1), atol=1e-10)


def test_split_reproduces_the_curve():
    P = random_path(n=8)
    ts = 5.3
    L, R = P.split(ts)
    assert (L.t0, L.tf, R.t0, R.tf) == (P.t0, ts, ts, P.tf)
    tl = np.linspace(P.t0, ts, 30)
    tr = np.linspace(ts, P.tf, 30)
    np.testing.assert_allclose(L(tl), P(tl), atol=1e-9)
    np.testing.assert_allclose(R(tr), P(tr), atol=1e-9)
    np.testing.assert_allclose(L.velocity(tl), P.velocity(tl), atol=1e-8)
    with pytest.raises(PathError):
        P.split(P.tf)


def test_arc_length_matches_dense_polyline_and_bounds():
    P = random_path(n=6)
    t = np.linspace(P.t0, P.tf, 200001)
    poly = np.sum(np.linalg.norm(np.diff(P(t), axis=0), axis=1))
    L = P.arc_length()
    assert L == pytest.approx(poly, rel=1e-7)
    lo, hi = P.length_bounds()
    assert lo <= L <= hi
    tm = 7.1
    assert P.arc_length(P.t0, tm) + P.arc_length(tm, P.tf) == pytest.approx(L, rel=1e-10)


def test_cumulative_arc_length_table_interpolates_the_arc_length():
    """The path-following node's progress table: exact at the samples, within 1e-4 m between them on the
    shipped canyon path, and its end is the whole length."""
    from bb2_mission import load_mission

    for P, tol_m in ((random_path(n=6), 1e-6 * 230.5), (load_mission(REPO / "missions" / "canyon.yaml").path, 1e-4)):
        t, s = P.cumulative_arc_length(2001)
        assert t[0] == P.t0 and t[-1] == P.tf and s[0] == 0.0 and np.all(np.diff(s) > 0)
        assert s[-1] == pytest.approx(P.arc_length(), rel=1e-12)
        for k in (1, 500, 1777):
            assert s[k] == pytest.approx(P.arc_length(P.t0, t[k]), rel=1e-12, abs=1e-9)
        rng = np.random.default_rng(3)
        for tq in rng.uniform(P.t0, P.tf, 25):
            assert abs(np.interp(tq, t, s) - P.arc_length(P.t0, tq)) < tol_m
    with pytest.raises(ValueError, match="samples"):
        P.cumulative_arc_length(1)


def test_product_and_integral():
    a, b = RNG.normal(size=(5, 2)), RNG.normal(size=(4, 2))
    tau = np.linspace(0, 1, 41)
    np.testing.assert_allclose(de_casteljau(product_points(a, b), tau),
                               de_casteljau(a, tau) * de_casteljau(b, tau), atol=1e-12)
    np.testing.assert_allclose(de_casteljau(dot_points(a, b), tau),
                               np.sum(de_casteljau(a, tau) * de_casteljau(b, tau), axis=-1), atol=1e-12)
    P = random_path(n=5)
    x, w = special.roots_legendre(10)        # exact for degree 19
    tq = P.t0 + (x + 1) / 2 * P.span
    np.testing.assert_allclose(P.integral(), P.span / 2 * (w @ P(tq)), rtol=1e-10)
    A = P.antiderivative()
    np.testing.assert_allclose(A(P.tf), P.integral(), rtol=1e-12)
    np.testing.assert_allclose(A.velocity(np.linspace(P.t0, P.tf, 9)), P(np.linspace(P.t0, P.tf, 9)),
                               atol=1e-9)
    # Gram matrix: int |p''|^2 dt closed form vs quadrature
    D2 = P.derivative(2)
    G = gram_matrix(D2.degree, P.span)
    closed = sum(D2.control_points[:, k] @ G @ D2.control_points[:, k] for k in range(3))
    assert closed == pytest.approx(P.span / 2 * w @ np.sum(D2(tq) ** 2, axis=1), rel=1e-10)
    assert integral(np.ones((4, 1)), 3.0) == pytest.approx(3.0)


def test_high_degree_circle_geometry():
    P = load_path("circle_r400")
    t = np.linspace(P.t0, P.tf, 2001)
    k = P.curvature(t)
    # control points on a 400 m circle: the curve is a slightly tighter circle-like arc
    assert np.all(np.abs(k * 400.0 - 1.0) < 0.04)
    np.testing.assert_allclose(P.torsion(t), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(P.tangent(t), axis=1), 1.0, atol=1e-12)
    s = P.speed(t)
    assert s.min() == pytest.approx(4.5665, abs=1e-3) and s.max() == pytest.approx(4.7745, abs=1e-3)
    assert P.arc_length() == pytest.approx(2317.62, abs=0.01)
    # curvature formula against a circle fitted through three nearby points
    a, b, c = P(np.array([249.0, 250.0, 251.0]))
    R = np.linalg.norm(b - a) * np.linalg.norm(c - b) * np.linalg.norm(c - a) / (
        2 * np.linalg.norm(np.cross(b - a, c - a)))
    assert P.curvature(250.0) == pytest.approx(1 / R, rel=1e-4)


def test_torsion_of_a_helix_fit():
    # least-squares Bernstein fit of a helix: radius r, pitch h -> kappa = r/(r^2+c^2), tau = c/(r^2+c^2)
    r, c = 100.0, 20.0
    u = np.linspace(0, 2.0, 400)
    pts = np.c_[r * np.cos(u), r * np.sin(u), c * u]
    P = BernsteinPath(fit_control_points(u / u[-1], pts, 14), 0.0, 2.0)
    tm = np.linspace(0.3, 1.7, 20)
    np.testing.assert_allclose(P.curvature(tm), r / (r * r + c * c), rtol=1e-6)
    np.testing.assert_allclose(P.torsion(tm), c / (r * r + c * c), rtol=1e-5)
    np.testing.assert_allclose(P(0.0), pts[0], atol=1e-9)         # ends fixed


def test_closest_point():
    P = load_path("circle_r400")
    tt = np.linspace(P.t0, P.tf, 50001)      # brute force on a fine grid (10 mm spacing)
    pts = P.evaluate_basis(tt)
    for ang in (0.3, 2.0, -1.0):              # points outside the circle, and one near the gap
        q = np.array([600 * np.cos(ang), 600 * np.sin(ang), -90.0])
        t, p, d = P.closest_point(q)
        dd = np.linalg.norm(pts - q, axis=1)
        assert d == pytest.approx(dd.min(), abs=1e-4)
        assert d <= dd.min() + 1e-9
        np.testing.assert_allclose(np.linalg.norm(p - q), d)
    with pytest.raises(PathError):
        P.closest_point(np.zeros(2))


def test_path_point_bundle_is_consistent():
    P = load_path("circle_r400", frame="native")
    k = P.at(123.4)
    np.testing.assert_allclose(k.p, P(123.4))
    np.testing.assert_allclose(k.dp, P.velocity(123.4))
    np.testing.assert_allclose(k.ddp, P.acceleration(123.4))
    assert k.speed == pytest.approx(np.linalg.norm(k.dp))
    assert k.curvature == pytest.approx(float(P.curvature(123.4)))
    assert P.at(1e9).t == P.tf     # clamped


def test_frames_and_sampling():
    C = load_path("circle_r400")
    N = C.to_frame("native")
    np.testing.assert_allclose(N(0.0), [0.0, -400.0, -100.0], atol=1e-9)   # SPEC: Bx_0 = (-c0x, -c0y, c0z)
    np.testing.assert_allclose(N.to_frame("ned").to_frame("controller").control_points, C.control_points,
                               atol=1e-12)
    assert N.to_frame("ned")(0.0)[2] == pytest.approx(100.0)               # NED z is down
    t, p = C.sample(dt=0.5)
    assert t[0] == 0.0 and t[-1] == 500.0 and len(t) == 1001 and p.shape == (1001, 3)
    assert C.sample()[0].shape == (1001,)


@pytest.mark.parametrize("cp, t0, tf, frame, match", [
    ([[0, 0, 0]], 0, 1, "native", "at least 2"),
    ([[0, 0, 0], [1, np.nan, 0]], 0, 1, "native", "non-finite"),
    ([[0, 0, 0], [1, np.inf, 0]], 0, 1, "native", "non-finite"),
    ([[0, 0, 0], [1, 0, 0]], 0, 0, "native", "tf > t0"),
    ([[0, 0, 0], [1, 0, 0]], 0, -5, "native", "tf > t0"),
    ([[0, 0, 0], [1, 0, 0]], 0, 1, "body", "unknown frame"),
    (np.zeros((2, 2, 2)), 0, 1, "native", "array"),
])
def test_bad_paths_raise_path_error(cp, t0, tf, frame, match):
    with pytest.raises(PathError, match=match):
        BernsteinPath(cp, t0, tf, frame)
    assert issubclass(PathError, ValueError)
