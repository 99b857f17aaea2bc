"""Terrain grid, loaders and errors, synthetic canyon, thalweg and terrain-following path."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from bb2_planner.bernstein import BernsteinPath
from bb2_planner.paths import load_path, read_path_metadata
from bb2_planner.terrain import (PathBelowTerrainError, Terrain, TerrainError, TerrainOutOfBoundsError,
                                 canyon_path, extract_thalweg, synthetic_canyon, thalweg_path)


def plane_terrain():
    x = np.linspace(-100.0, 100.0, 21)
    y = np.linspace(0.0, 300.0, 31)
    X, Y = np.meshgrid(x, y, indexing="ij")
    return Terrain(x, y, -200.0 + 0.1 * X - 0.05 * Y + 0.001 * X * Y)   # bilinear: interpolation is exact


@pytest.fixture(scope="module")
def canyon():
    return synthetic_canyon()


def test_bilinear_interpolation_is_exact_on_bilinear_field():
    T = plane_terrain()
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-100, 100, 50), rng.uniform(0, 300, 50)
    np.testing.assert_allclose(T.elevation(x, y), -200.0 + 0.1 * x - 0.05 * y + 0.001 * x * y, atol=1e-9)
    p = np.c_[x, y, np.full(50, -120.0)]
    np.testing.assert_allclose(T.clearance(p), -120.0 - T.elevation(x, y))
    np.testing.assert_allclose(T.gradient(10.0, 100.0), [0.1 + 0.1, -0.05 + 0.01], atol=1e-9)


def test_decreasing_axes_are_accepted_and_flipped():
    T = plane_terrain()
    U = Terrain(T.x[::-1], T.y, T.z[::-1, :])
    assert U.elevation(13.0, 77.0) == pytest.approx(float(T.elevation(13.0, 77.0)))


def test_terrain_errors():
    T = plane_terrain()
    z = T.z.copy()
    z[3, 4] = np.nan
    with pytest.raises(TerrainError, match="1 hole"):
        Terrain(T.x, T.y, z)
    x = T.x.copy()
    x[5] = x[4]
    with pytest.raises(TerrainError, match="x axis is not strictly monotonic"):
        Terrain(x, T.y, T.z)
    with pytest.raises(TerrainError, match="shape"):
        Terrain(T.x, T.y, T.z.T)
    with pytest.raises(TerrainError, match="1-D"):
        Terrain(T.x[:1], T.y, T.z[:1])
    with pytest.raises(TerrainOutOfBoundsError, match="outside the terrain grid"):
        T.elevation(500.0, 10.0)
    with pytest.raises(TerrainError, match="3 coordinates"):
        T.clearance(np.zeros((4, 2)))
    assert issubclass(TerrainOutOfBoundsError, ValueError) and issubclass(PathBelowTerrainError, ValueError)


def test_npz_and_csv_loaders(tmp_path):
    T = plane_terrain()
    U = Terrain.load_npz(T.save_npz(tmp_path / "t.npz"))
    np.testing.assert_array_equal(U.z, T.z)
    X, Y = np.meshgrid(T.x, T.y, indexing="ij")
    rows = np.c_[X.ravel(), Y.ravel(), T.z.ravel()]
    rows = rows[np.random.default_rng(1).permutation(len(rows))]          # scattered order
    f = tmp_path / "t.csv"
    np.savetxt(f, rows, delimiter=",", header="x,y,z", comments="")
    V = Terrain.load_csv(f)
    np.testing.assert_allclose(V.z, T.z)
    np.savetxt(f, rows[:-1], delimiter=",")                                # one node missing -> hole
    with pytest.raises(TerrainError, match="hole"):
        Terrain.load_csv(f)
    np.savetxt(f, np.vstack([rows, rows[:1]]), delimiter=",")
    with pytest.raises(TerrainError, match="appears 2 times"):
        Terrain.load_csv(f)
    np.savez(tmp_path / "bad.npz", x=T.x, y=T.y)
    with pytest.raises(TerrainError, match="missing array"):
        Terrain.load_npz(tmp_path / "bad.npz")
    np.savez(tmp_path / "bad2.npz", x=T.x, y=T.y, z=T.z[:, :-1])
    with pytest.raises(TerrainError, match="shape"):
        Terrain.load_npz(tmp_path / "bad2.npz")


def test_synthetic_canyon_is_seeded_and_shaped(canyon):
    again = synthetic_canyon()
    np.testing.assert_array_equal(again.terrain.z, canyon.terrain.z)
    p = canyon.params
    other = synthetic_canyon({**p, "noise": {**p["noise"], "seed": p["noise"]["seed"] + 1}})
    assert not np.allclose(other.terrain.z, canyon.terrain.z)
    assert canyon.core_length_m == pytest.approx(1609.0, abs=1.0)          # one statute mile
    T = canyon.terrain
    axis_z = T.elevation(canyon.centreline_xy[::50, 0], canyon.centreline_xy[::50, 1])
    assert axis_z.max() < p["floor"]["elevation_start_m"] + 10 and axis_z.min() > p["floor"]["elevation_end_m"] - 10
    assert T.z.max() < p["walls"]["shelf_elevation_m"] + 10                 # shelf plus noise


def test_thalweg_follows_valley_axis(canyon):
    th = extract_thalweg(canyon.terrain, canyon.start_xy, canyon.end_xy)
    d, _ = cKDTree(canyon.centreline_xy).query(th.xy)
    assert d.max() < 25.0                                  # inside the 120 m wide floor, near the axis
    assert th.s[-1] == pytest.approx(canyon.core_length_m, rel=0.03)
    np.testing.assert_allclose(th.xy[[0, -1]], [canyon.start_xy, canyon.end_xy])


def test_canyon_path_clearance_and_geometry(canyon):
    P = canyon_path(canyon)
    pp = canyon.params["path"]
    c, _ = canyon.terrain.min_clearance(P)
    assert pp["min_clearance_m"] <= c <= pp["clearance_m"]
    t = np.linspace(P.t0, P.tf, 1001)
    clear = canyon.terrain.clearance(P(t))
    assert abs(np.median(clear) - pp["clearance_m"]) < 5.0
    assert P(t)[:, 2].max() < pp["max_elevation_m"]
    assert P.arc_length() == pytest.approx(1609.0, rel=0.03)
    assert 1.0 / P.curvature(t).max() > 300.0              # turnable by a 70 m boat
    # the shipped file is this path
    shipped = load_path("synthetic_canyon")
    np.testing.assert_allclose(shipped.control_points, P.control_points, atol=1e-6)
    assert read_path_metadata("synthetic_canyon")["facts"]["min_clearance_m"] == pytest.approx(c, abs=0.01)


def test_path_below_terrain_is_refused(canyon):
    with pytest.raises(PathBelowTerrainError, match="required >= 40") as e:
        thalweg_path(canyon.terrain, canyon.start_xy, canyon.end_xy, clearance_m=20.0, min_clearance_m=40.0,
                     degree=12, tf_s=500.0)
    assert e.value.clearance < 40.0
    T = plane_terrain()
    low = BernsteinPath([[-50, 10, -250.0], [50, 290, -150.0]], 0, 100)
    with pytest.raises(PathBelowTerrainError):
        T.check_path(low, 5.0)
    with pytest.raises(TerrainError, match="above the limit"):
        thalweg_path(canyon.terrain, canyon.start_xy, canyon.end_xy, clearance_m=50.0, min_clearance_m=40.0,
                     degree=12, tf_s=500.0, max_elevation_m=-160.0)
