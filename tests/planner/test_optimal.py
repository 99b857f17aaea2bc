"""Constrained optimal Bernstein trajectories: every bound holds on dense samples, and the bounds bite."""
from __future__ import annotations

import numpy as np
import pytest

from bb2_planner.bernstein import BernsteinPath
from bb2_planner.optimal import OptimisationError, TrajectoryProblem, constraint_margins, optimal_trajectory
from bb2_planner.terrain import Terrain

A, B = np.array([0.0, 0.0, -150.0]), np.array([1000.0, 600.0, -150.0])
TURN = dict(p_start=A, p_end=B, tf=300.0, degree=10, v_start=[3.5, 0.0, 0.0], v_end=[0.0, 3.5, 0.0],
            v_max=5.0)


def hill_terrain():
    x = np.linspace(-200.0, 1200.0, 141)
    y = np.linspace(-400.0, 1000.0, 141)
    X, Y = np.meshgrid(x, y, indexing="ij")
    return Terrain(x, y, -200.0 + 90.0 * np.exp(-((X - 500.0) ** 2 + (Y - 300.0) ** 2) / (2 * 150.0 ** 2)))


def assert_all_bounds_hold(result, tol=1e-9):
    m = result.margins
    assert result.success, result.message
    for key, value in m.items():
        if key.endswith("error_m") or key.endswith("error_mps"):
            assert value < 1e-9, (key, value)
        else:
            assert value >= -tol, (key, value)


def test_min_length_with_free_interior_is_a_straight_line():
    pb = TrajectoryProblem(A, B, tf=200.0, degree=6, objective="length")
    rng = np.random.default_rng(5)
    wavy = BernsteinPath(np.linspace(A, B, 7) + rng.normal(scale=200.0, size=(7, 3)) * [[0], [1], [1], [1],
                                                                                        [1], [1], [0]], 0, 200)
    r = optimal_trajectory(pb, initial=wavy)
    assert_all_bounds_hold(r)
    chord = np.linalg.norm(B - A)
    assert wavy.arc_length() > 1.05 * chord                    # the start was far from straight
    assert r.path.arc_length() == pytest.approx(chord, rel=1e-5)
    t, p = r.path.sample(501)
    u = (B - A) / chord
    off = (p - A) - np.outer((p - A) @ u, u)
    assert np.linalg.norm(off, axis=1).max() < 0.3            # metres, over a 1166 m chord


def test_turn_rate_bound_is_active_and_respected():
    free = optimal_trajectory(TrajectoryProblem(**TURN))
    assert_all_bounds_hold(free)
    w_free = constraint_margins(free.path, TrajectoryProblem(**TURN, turn_rate_max=1.0))["turn_rate_max"]
    unconstrained_peak = 1.0 - w_free
    w_max = 0.8 * unconstrained_peak                             # bound that the free optimum violates
    pb = TrajectoryProblem(**TURN, turn_rate_max=w_max, turn_rate_margin=1e-3 * w_max, v_min=2.0)
    r = optimal_trajectory(pb)
    assert_all_bounds_hold(r)
    assert r.margins["turn_rate_max"] < 0.01 * w_max               # the bound is active ...
    assert r.objective > free.objective                            # ... and costs energy
    # end conditions hold exactly
    np.testing.assert_allclose(r.path.velocity(r.path.tf), TURN["v_end"], atol=1e-9)
    # the speed bound is enforced on the control points of |p'|^2: it holds everywhere
    assert r.path.speed(np.linspace(0, 300, 20001)).max() <= 5.0


def test_terrain_clearance():
    T = hill_terrain()
    straight = BernsteinPath(np.linspace(A, B, 2), 0, 300)
    assert T.min_clearance(straight)[0] < 40.0                     # the straight line clips the hill
    pb = TrajectoryProblem(A, B, tf=300.0, degree=10, v_max=5.0, terrain=T, min_clearance=40.0,
                           clearance_margin=1.0)
    r = optimal_trajectory(pb)
    assert_all_bounds_hold(r)
    assert T.min_clearance(r.path, 4001)[0] >= 40.0
    assert r.margins["min_clearance"] < 2.0                        # it hugs the bound, not the sky


def test_z_max_holds_on_the_whole_curve():
    ends = dict(v_start=[3.0, 0.0, 1.0], v_end=[3.0, 0.0, -1.0])
    free = optimal_trajectory(TrajectoryProblem(A, B, tf=300.0, degree=8, **ends))
    z_free = free.path.sample(2001)[1][:, 2].max()
    assert z_free > -150.0 + 20.0                      # climbs well above the end points
    pb = TrajectoryProblem(A, B, tf=300.0, degree=8, z_max=-140.0, z_margin=0.05, **ends)
    r = optimal_trajectory(pb)
    assert_all_bounds_hold(r)


@pytest.mark.parametrize("kw, match", [
    (dict(tf=0.0), "tf > t0"),
    (dict(degree=3, v_start=[1, 0, 0], v_end=[1, 0, 0]), "no free control point"),
    (dict(objective="time"), "objective"),
    (dict(v_max=-1.0), "v_max"),
    (dict(v_min=6.0, v_max=5.0), "v_min"),
    (dict(min_clearance=10.0), "together"),
    (dict(p_end=[1.0, np.nan, 0.0]), "p_end"),
])
def test_bad_problems(kw, match):
    args = dict(p_start=A, p_end=B, tf=100.0)
    args.update(kw)
    with pytest.raises(OptimisationError, match=match):
        TrajectoryProblem(**args)
