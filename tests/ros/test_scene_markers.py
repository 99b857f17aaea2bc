"""The scene as MarkerArray (bb2_msgs_py.scene_markers): the hull in base_link, the terrain and the sea surface in
map, each the model's own geometry turned to REP-103; and the simulator node publishing them over DDS into a bag
(the latched scene once, the sea around the boat every scene_sea_period_s)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

pytest.importorskip("visualization_msgs.msg")

from bb2_msgs_py import scene_markers as sm  # noqa: E402
from bb2_msgs_py.contract import SCENE_TOPIC, SEA_SURFACE_TOPIC  # noqa: E402

from rosenv import ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]


def _normals_up(tris: np.ndarray) -> bool:
    return bool(np.all(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])[:, 2] > 0))


def test_hull_marker_is_the_rom_hull_in_base_link():
    from bb2_sim.geometry import load_hull

    hull = load_hull(None)
    m = sm.hull_marker(hull)
    assert (m.header.frame_id, m.ns, m.type) == ("base_link", "bb2/hull", m.TRIANGLE_LIST)
    tris = sm.marker_triangles(m)
    assert tris.shape == (hull.n_triangles(), 3, 3)
    # a rotation (pi about z), not a mirror: the enclosed volume keeps its sign and size; the sail is up
    vol = trimesh.triangles.mass_properties(tris, skip_inertia=True).volume
    assert vol == pytest.approx(hull.volume(), rel=1e-6) and vol > 0
    assert tris[..., 2].max() == pytest.approx(hull.sail_top_m())
    native = np.concatenate((hull.fixed_vertices,) + tuple(hull.plane_vertices))
    np.testing.assert_allclose(tris[..., 0], -native[..., 0])   # x forward = -x aft
    np.testing.assert_allclose(tris[..., 1], -native[..., 1])   # y port = -y starboard


def test_terrain_and_sea_markers_are_the_model_surfaces_in_map():
    from bb2_planner.terrain import synthetic_canyon
    from bb2_sim.sea.sea import AuthorsTableSea
    from bb2_sim.parameters import load_parameters
    from bb2_sim.waves import wave_for_sea_state

    terrain = synthetic_canyon().terrain
    m = sm.terrain_marker(terrain, max_cells=60)
    tris = sm.marker_triangles(m)
    assert m.header.frame_id == "map" and _normals_up(tris)
    assert len(tris) <= 2 * 61 * 61
    v = tris.reshape(-1, 3)
    # every vertex is a grid point of the terrain (native x, y = -ENU x, y), at its elevation
    np.testing.assert_allclose(v[:, 2], terrain.elevation(-v[:, 0], -v[:, 1]), atol=1e-9)
    # the grid's four corners are kept (the whole terrain shown)
    assert {round(float(-v[:, 0].min()), 6), round(float(-v[:, 0].max()), 6)} == \
        {round(float(terrain.x.min()), 6), round(float(terrain.x.max()), 6)}

    sea = AuthorsTableSea(wave_for_sea_state(5, load_parameters()))
    center, t = np.array([120.0, -40.0]), 33.3
    s = sm.sea_surface_marker(sea.elevation, center, t, half_size_m=80.0, cells=24)
    st = sm.marker_triangles(s)
    assert s.header.frame_id == "map" and len(st) == 2 * 24 * 24 and _normals_up(st)
    p = st.reshape(-1, 3)
    np.testing.assert_allclose(p[:, 2], sea.elevation(-p[:, 0], -p[:, 1], t), atol=1e-12)
    assert np.ptp(p[:, 2]) > 1.0  # the waves are there
    np.testing.assert_allclose([-p[:, 0].mean(), -p[:, 1].mean()], center, atol=1e-9)
    calm = sm.marker_triangles(sm.sea_surface_marker(None, center, t, cells=2))
    assert np.all(calm[..., 2] == 0.0) and len(calm) == 8


def test_the_simulator_publishes_the_scene_into_the_bag(tmp_path):
    """A short SS5 canyon run in lockstep through the graph: the bag holds the latched scene once (hull in
    base_link, terrain in map, no calm plane: the sea has waves) and the sea around the boat at each whole second
    of sim time (scene_sea_period_s 1), centred on the CG of that step."""
    pytest.importorskip("rclpy")
    from bb2_msgs_py import conversions as cv
    from bb2_sim.geometry import load_hull
    from bb2_tools.bagfile import BagReader

    mission = tmp_path / "ss5_short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon_periscope_ss5.yaml'}\nname: ss5_short\n"
                       f"duration_s: 3\n")
    params = tmp_path / "scene.yaml"
    params.write_text("simulator:\n  ros__parameters:\n    scene_sea_period_s: 1.0\n")
    out = tmp_path / "bag"
    p = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out), "--params",
                        str(params), "--end-at", "simulator", "--timeout", "300"], cwd=tmp_path, env=ros_env(),
                       capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stderr[-4000:]
    r = BagReader(out)
    scene = [m for _, _, m in r.messages(SCENE_TOPIC)]
    assert len(scene) == 1, r.message_counts
    ns = [mk.ns for mk in scene[0].markers]
    assert ns == ["bb2/hull", "bb2/terrain"], ns
    hull = scene[0].markers[0]
    assert hull.header.frame_id == "base_link" and len(hull.points) == 3 * load_hull(None).n_triangles()
    # map (path, terrain, sea) joins odom -> base_link: the recorder's /tf_static from the scene, the identity
    statics = [tr for _, _, m in r.messages("/tf_static") for tr in m.transforms]
    assert [(tr.header.frame_id, tr.child_frame_id, tr.transform.translation.x, tr.transform.rotation.w)
            for tr in statics] == [("map", "odom", 0.0, 1.0)], statics
    states = {round(s.t, 6): s for s in (cv.state_native_from_message(m) for _, _, m in
                                         r.messages("/bb2/state_native"))}
    seas = [m.markers[0] for _, _, m in r.messages(SEA_SURFACE_TOPIC)]
    times = [round(cv.stamp_to_seconds(m.header.stamp), 6) for m in seas]
    assert times == [0.0, 1.0, 2.0, 3.0], times
    for m, t in zip(seas, times):
        v = sm.marker_triangles(m).reshape(-1, 3)
        np.testing.assert_allclose([-v[:, 0].mean(), -v[:, 1].mean()], states[t].p_native[0:2], atol=1e-6)
        assert np.ptp(v[:, 2]) > 0.5
