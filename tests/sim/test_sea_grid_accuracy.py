"""Issue 11, point 6: the fast (grid) wave loads of an irregular sea stay within 0.5 % of each load's range
of a direct full-resolution pressure integration (every point, every component) along a flown run."""
import math

import numpy as np
import pytest

from bb2_sim.frames import rotation_native
from bb2_sim.integrator import Simulator
from bb2_sim.maneuvers import ManeuverCommander, maneuver_settings
from bb2_sim.model import BB2Model
from bb2_sim.sea import ComponentSea, Cos2sSpreading, JonswapSpectrum, discretise
from bb2_sim.waves import Wave


def _fly(model: BB2Model, s, every: int):
    """(t, x, actual plane deflections) every ``every`` major steps of maneuver ``s`` (grid wave loads)."""
    sim, cmd = Simulator(model, s.initial_state()), ManeuverCommander(s)
    out = []
    for k in range(int(round(s.duration / sim.h))):
        planes, rps = cmd.step(sim.t, sim.x)
        rec = sim.step(planes, rps)
        if k % every == 0:
            out.append((rec.t, rec.x.copy(), rec.act.planes_deg.copy()))
    return out


def _errors(model: BB2Model, samples):
    """Max |grid - direct| per load over the samples, as a fraction of the range of the direct wave loads."""
    H, sea = model.hydro, model.sea
    direct, grid, calm = [], [], []
    for t, x, defl in samples:
        R, pos = rotation_native(*x[3:6]), x[0:3]
        direct.append(H.loads(pos, R, t, None, defl, sea=sea, wave_load_method="direct"))
        grid.append(H.loads(pos, R, t, None, defl, sea=sea, wave_load_method="grid"))
        calm.append(H.loads(pos, R, t, Wave(), defl))
    direct, grid, calm = np.array(direct), np.array(grid), np.array(calm)
    return np.abs(grid - direct).max(axis=0) / np.ptp(direct - calm, axis=0)


@pytest.mark.parametrize("case", ["self-propulsion, head seas", "turning in oblique seas", "turning in a short sea"])
def test_grid_wave_loads_within_half_a_percent_of_direct_integration_over_a_run(case):
    if case.startswith("self"):   # the benchmark's sea (benchmarks/rom_speed.py) and run, 60 s of it
        sea = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7, 3.3), 64, seed=1, spreading=Cos2sSpreading(0.0, 4.0)))
        s = maneuver_settings("self-propulsion", duration=60.0, sea_state=0)
    elif case.endswith("oblique seas"):  # a 20 deg rudder turn at periscope-ish depth through a sea from 30 deg
        sea = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7), 64, seed=11,
                                      spreading=Cos2sSpreading(math.radians(30.0), 4.0), mean_direction_deg=30.0))
        s = maneuver_settings("turning-circle", duration=60.0, depth=15.3724, sea_state=0)
    else:                         # Tp 6 s (k up to ~1 rad/m) at 11 m, the sail's top near the surface: the short
        # waves need the fine grid (on 2 m grids the roll moment was off by 0.56 % of its range)
        sea = ComponentSea(discretise(JonswapSpectrum(1.5, 6.0), 64, seed=4,
                                      spreading=Cos2sSpreading(math.radians(60.0), 4.0), mean_direction_deg=60.0))
        s = maneuver_settings("turning-circle", duration=40.0, depth=11.0, sea_state=0)
    model = BB2Model(profile=s.profile, sea=sea)
    err = _errors(model, _fly(model, s, every=10))          # every 0.5 s
    assert np.all(err < 0.005), err


def test_grid_wave_loads_stay_finite_where_k_z_passes_float32s_exp_range():
    """The grid evaluates exp(k z) in float32 (overflow at k z = 88.7, and a node multiplies two such factors):
    a hull lifted 40 m out of a short sea (k z up to ~150 at its top) still gets finite loads, capped rather
    than inf * 0 = NaN."""
    sea = ComponentSea(discretise(JonswapSpectrum(1.0, 3.0), 16, seed=3))   # k up to ~3.7 rad/m
    model = BB2Model(sea=sea)
    assert sea.components.wavenumber.max() * 40.0 > 88.7
    loads = model.hydro.loads(np.array([0.0, 0.0, 40.0]), rotation_native(0.0, 0.0, 0.0), 1.0, None, np.zeros(5),
                              sea=sea, wave_load_method="grid")
    assert np.all(np.isfinite(loads)), loads


def test_grid_wave_loads_keep_their_accuracy_far_away_and_late():
    """The grid forms its exponents in float32 after reducing the phase offsets (k x - omega t, thousands of
    rad after an hour or 10 km) modulo 2 pi in double precision: a boat 120 km out after 100 hours gets the
    accuracy of one at the origin at t = 0, 5e-4 of a load's range here (float32 phases of ~1e6 rad would be off
    by up to 0.06 rad: 8e-3 without the reduction)."""
    sea = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7), 64, seed=5, spreading=Cos2sSpreading(0.5, 4.0),
                                  mean_direction_deg=30.0))
    H = BB2Model(sea=sea).hydro
    defl = np.array([4.0, -2.0, 3.0, -1.0, 5.0])
    for origin, t0 in [(np.zeros(3), 0.0), (np.array([90000.0, -80000.0, 0.0]), 360000.0)]:
        direct, grid, calm = [], [], []
        for t in t0 + np.linspace(0.0, 12.0, 13):
            R, pos = rotation_native(0.05, -0.1, 0.4 + 0.01 * (t - t0)), origin + (0.0, 0.0, -14.0)
            direct.append(H.loads(pos, R, t, None, defl, sea=sea, wave_load_method="direct"))
            grid.append(H.loads(pos, R, t, None, defl, sea=sea))
            calm.append(H.loads(pos, R, t, Wave(), defl))
        direct = np.array(direct)
        err = np.abs(np.array(grid) - direct).max(axis=0) / np.ptp(direct - np.array(calm), axis=0)
        assert np.all(err < 0.001), (origin, t0, err)


@pytest.mark.parametrize("h", [0.7, 2.0, 6.0, 50.0])
def test_block_grid_spans_the_block_and_is_exact_for_polynomials_of_its_order(h):
    """A block's grid covers its bounding box with a spacing below h on every axis, and its weights
    Q[n] = sum_j L_n(d_j) FM_j reproduce sum_j f(d_j) FM_j exactly for any f of degree <= order per axis
    (the interpolation is exact there), whatever the spacing: a thin block (a plane) or a long one (the hull)."""
    from bb2_sim.sea.pressure_grid import _BlockGrid
    rng = np.random.default_rng(4)
    for extent in ([3.2, 2.3, 0.35], [70.0, 9.6, 16.2]):
        d = rng.uniform(0.0, 1.0, (400, 3)) * extent + (-30.0, -4.8, -4.8)
        FM = rng.normal(size=(400, 6))
        g = _BlockGrid(d, FM, h, order=3)
        assert np.all(g.h < h) and np.allclose(g.g0, d.min(axis=0))
        assert np.allclose([g.nodes[a][-1] for a in range(3)], d.max(axis=0))
        c = rng.normal(size=(3, 4))                                   # a cubic per axis, multiplied
        X, Y, Z = np.meshgrid(*g.nodes, indexing="ij")
        on_grid = np.einsum("nm,n->m", g.Q.reshape(-1, 6), _cubics(c, X, Y, Z).reshape(-1))
        np.testing.assert_allclose(on_grid, FM.T @ _cubics(c, *d.T), rtol=1e-9, atol=1e-9 * np.abs(FM).sum())


def test_thin_and_short_axes_take_a_lower_degree_that_interpolates_as_well_and_stays_exact_for_it():
    """For the wavenumbers up to k_design, an axis shorter than the spacing takes the lowest degree (and fewest
    nodes) whose interpolation error bound C_p (k s)^(p+1) stays within degree 3's at spacing h: a control plane's
    0.35 m thickness is linear (2 nodes, not 4), its 3.2 m chord quadratic on the 6 m grid; the hull's axes keep
    degree 3. The weights reproduce products of per-axis polynomials of each axis's degree exactly."""
    from bb2_sim.sea.pressure_grid import _C_END, _BlockGrid, axis_plan

    h, k = 6.0, 0.5 / 6.0
    assert axis_plan(0.351, h, 3, k) == (1, 1) and axis_plan(3.218, h, 3, k) == (2, 2)
    assert axis_plan(69.9, h, 3, k) == axis_plan(69.9, h, 3) == (3, 13)      # the hull's length: unchanged
    assert axis_plan(0.351, 1.5, 3) == (3, 3)                                # no k_design: degree 3 everywhere
    for e in np.linspace(0.0, 40.0, 81):
        p, n = axis_plan(e, h, 3, k)
        assert p == 3 or _C_END[p] * (k * e / n) ** (p + 1) <= _C_END[3] * (k * h) ** 4, (e, p, n)
    rng = np.random.default_rng(8)
    d = rng.uniform(0.0, 1.0, (400, 3)) * [3.2, 8.4, 0.35] + (-1.0, -4.2, 0.3)
    FM = rng.normal(size=(400, 6))
    g = _BlockGrid(d, FM, h, order=3, k_design=k)
    assert g.degrees == (2, 3, 1) and g.shape == (3, 4, 2), (g.degrees, g.shape)
    c = rng.normal(size=(3, 4)) * (np.arange(4) >= 3 - np.array(g.degrees)[:, None])   # degree <= the axis's
    X, Y, Z = np.meshgrid(*g.nodes, indexing="ij")
    on_grid = np.einsum("nm,n->m", g.Q.reshape(-1, 6), _cubics(c, X, Y, Z).reshape(-1))
    np.testing.assert_allclose(on_grid, FM.T @ _cubics(c, *d.T), rtol=1e-9, atol=1e-9 * np.abs(FM).sum())
    def across(z):                                                   # a quadratic across the linear axis is not
        return ((z - 0.475) / 0.35) ** 2

    on_grid = np.einsum("nm,n->m", g.Q.reshape(-1, 6), across(Z).reshape(-1))
    assert np.abs(on_grid - FM.T @ across(d[:, 2])).max() > 1e-3 * np.abs(FM.T @ across(d[:, 2])).max()


def _cubics(c: np.ndarray, x, y, z):
    return np.polyval(c[0], x / 10) * np.polyval(c[1], y / 10) * np.polyval(c[2], z / 10)


@pytest.mark.parametrize("q12", [False, True])
def test_the_grid_gives_the_orbital_velocity_at_the_flow_points_from_the_same_evaluation(q12):
    """The model's grid path takes the orbital velocities at the CG, planes and sections from the exponentials of
    the pressure grid (a few more columns): equal to ComponentSea.orbital_velocity within single precision
    (1e-6 of the sum of the components' a omega), far and late too; the loads are loads()'s (to round-off)."""
    sea = ComponentSea(discretise(JonswapSpectrum(3.25, 9.7), 64, seed=2, spreading=Cos2sSpreading(0.4, 4.0),
                                  mean_direction_deg=20.0))
    model = BB2Model(sea=sea)
    H, pts = model.hydro, model._flow_points_body
    scale = float(np.sum(sea.components.amplitude * sea.components.omega))
    rng = np.random.default_rng(6)
    for _ in range(10):
        R = rotation_native(*rng.normal(scale=[0.1, 0.15, 2.0]))
        pos = np.array([rng.uniform(-5e4, 5e4), rng.uniform(-5e4, 5e4), rng.uniform(-25.0, -8.0)])
        t, defl = rng.uniform(0.0, 1e5), rng.normal(scale=10.0, size=5)
        loads, uw = H.loads_and_orbital_velocity(pos, R, t, defl, sea, pts, q12=q12)
        ref = sea.orbital_velocity(pos + pts @ R.T, t, q12=q12)
        assert np.abs(uw - ref).max() <= 1e-6 * scale, np.abs(uw - ref).max() / scale
        alone = H.loads(pos, R, t, None, defl, sea=sea)
        np.testing.assert_allclose(loads, alone, rtol=0, atol=1e-9 * np.abs(alone).max())


def test_a_grid_keeps_the_levels_of_its_last_seas_only():
    """Levels are planned per sea (their components' wavenumbers): a hull that meets one sea after another (a
    campaign's worker) keeps the most recently used LEVELS_KEPT levels, not one per sea it met; the current
    sea's are always there, and a sea met again gets its loads back bit for bit."""
    from bb2_sim.sea.pressure_grid import LEVELS_KEPT

    seas = [ComponentSea(discretise(JonswapSpectrum(1.0 + 0.25 * i, 5.0 + 0.5 * i), 32, seed=i)) for i in range(8)]
    H = BB2Model(sea=seas[0]).hydro
    R, pos, defl = rotation_native(0.02, -0.05, 0.3), np.array([0.0, 0.0, -14.0]), np.array([2.0, -1.0, 0, 1, 3])
    loads = []
    for sea in seas + seas[:1]:
        loads.append(H.loads(pos, R, 3.0, None, defl, sea=sea))
        grid = H.wave_grid()
        assert len(grid._levels) <= LEVELS_KEPT, len(grid._levels)
        assert all(any(level is kept for kept in grid._levels.values()) for level, _, _ in grid._groups)
    assert len(grid._levels) == LEVELS_KEPT                    # 8 seas of 2 levels each met: the last ones kept
    assert np.array_equal(loads[0], loads[-1]) and not np.allclose(loads[0], loads[1])
