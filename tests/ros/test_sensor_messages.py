"""Sensor samples -> /bb2/sensors/* messages (bb2_msgs_py.sensor_conversions): fields, frames, covariances,
NavSatStatus, REP-117 ranges, the mountings description; the mission's sensors:/navigation: keys."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("sensor_msgs.msg")

from bb2_msgs_py import sensor_conversions as sc  # noqa: E402
from bb2_msgs_py.contract import message_class, topic  # noqa: E402
from bb2_sim.sensors import SensorSuite, load_suite_config, truth_from_step  # noqa: E402


def _samples(z=-60.0, clearance=50.0, duration=2.0):
    truths = []
    for n in range(int(duration / 0.05) + 1):
        x = np.zeros(12)
        x[0], x[2], x[6] = -3.0 * n * 0.05, z, -3.0
        truths.append(truth_from_step(n * 0.05, x, None, clearance))
    suite = SensorSuite(load_suite_config("tactical"), seed=1)
    return suite, suite.run(truths)


def test_every_sample_becomes_its_contract_message():
    suite, samples = _samples()
    seen = set()
    for s in samples:
        for name, msg in sc.sample_messages(s, suite.config):
            assert isinstance(msg, message_class(topic(name).type)), name
            seen.add(name)
    assert seen == set(sc.SENSOR_TOPICS) - {"/bb2/sensors/mountings", sc.DVL_WATER_TOPIC}
    imu = next(s for s in samples if s.sensor == "imu")
    d = sc.imu_sample_from_message(sc.imu_sample_message(imu))
    np.testing.assert_array_equal(d["w"], imu.angular_velocity)
    np.testing.assert_array_equal(d["cov_w"], imu.angular_velocity_covariance)
    assert d["frame_id"] == "imu_link" and d["t"] == pytest.approx(imu.t)
    dvl = next(s for s in samples if s.sensor == "dvl")
    m = sc.dvl_sample_message(dvl)
    np.testing.assert_array_equal(sc.dvl_from_message(m)["v"], dvl.velocity)
    assert np.array(m.twist.covariance).reshape(6, 6)[3, 3] == -1.0
    ranges = sc.dvl_range_messages(dvl, 1.0, 200.0)
    assert [r.header.frame_id for r in ranges] == [f"dvl_beam_{i}" for i in range(4)]


def test_gps_status_and_ranges_out_of_reach():
    suite, samples = _samples(z=-60.0, clearance=400.0)
    gps = next(s for s in samples if s.sensor == "gps")
    m = sc.gps_sample_message(gps)
    assert m.status.status == m.status.STATUS_NO_FIX and m.position_covariance_type == 0
    assert math.isnan(m.latitude)
    alt = next(s for s in samples if s.sensor == "altimeter")
    assert sc.altimeter_sample_message(alt).range == math.inf
    _, up = _samples(z=-8.0, duration=6.0)
    fix = [s for s in up if s.sensor == "gps" and s.fix][0]
    m = sc.gps_sample_message(fix)
    assert m.status.status == m.status.STATUS_FIX and m.position_covariance_type == 2
    assert m.latitude == pytest.approx(32.86, abs=1e-3) and m.position_covariance[0] == pytest.approx(1.0)


def test_mountings_description():
    cfg = load_suite_config("mems")
    d = json.loads(sc.mountings_json(cfg, seed=3))
    tf = {t["child"]: t for t in d["transforms"]}
    assert tf["gps_link"]["translation_m"] == [8.763, 0.0, 11.401]
    q = np.array(tf["altimeter_link"]["rotation_xyzw"])     # pitch +90 deg: x (the beam) points down
    from scipy.spatial.transform import Rotation
    np.testing.assert_allclose(Rotation.from_quat(q).apply([1, 0, 0]), [0, 0, -1], atol=1e-12)
    b0 = Rotation.from_quat(tf["dvl_beam_0"]["rotation_xyzw"]).apply([1, 0, 0])
    np.testing.assert_allclose(b0, cfg.dvl.beams_dvl()[0], atol=1e-12)
    assert d["rates_hz"] == {"imu": 100.0, "pressure": 10.0, "dvl": 4.0, "altimeter": 2.0, "gps": 1.0}


def test_mission_sensors_and_navigation_keys(tmp_path):
    from bb2_mission.components import sensor_spec
    from bb2_mission.schema import MissionError, load_mission

    f = tmp_path / "m.yaml"
    base = f"extends: {Path(__file__).resolve().parents[2] / 'missions' / 'canyon.yaml'}\n"
    f.write_text(base + "sensors: {suite: mems, seed: 4, faults: [{sensor: gps, kind: dropout, start_s: 1}]}\n"
                 "navigation: sensors\n")
    m = load_mission(f)
    assert m.sensors.suite.name == "mems" and m.sensors.seed == 4 and m.navigation == "sensors"
    assert sensor_spec(m, "none") is None and sensor_spec(m, "tactical").suite.name == "tactical"
    assert sensor_spec(m, "tactical").seed == 4
    assert load_mission(base.split(" ", 1)[1].strip()).sensors is None
    for bad, msg in (("navigation: sensors\n", "needs a sensors: block"), ("sensors: gold\n", "neither a preset"),
                     ("navigation: gps\n", "navigation must be one of"),
                     ("sensors: {suite: tactical, seed: -1}\n", "seed must be an integer")):
        f.write_text(base + bad)
        with pytest.raises(MissionError, match=msg):
            load_mission(f)


def _round_trip(samples, config):
    """Each sample to its messages and back (the DVL beam ranges carry no sample)."""
    out = []
    for s in samples:
        for name, msg in sc.sample_messages(s, config):
            if name in sc.NAVIGATION_SENSOR_TOPICS:
                out.append(sc.sample_from_message(name, msg, config))
    return out


def test_messages_give_back_the_samples_the_navigation_filter_takes():
    """An autopilot reading /bb2/sensors/* gets the samples again (to the stamp's nanosecond), sorts them into the
    order they came out of the sensors, and its navigation filter flies the same estimate as one fed the samples
    themselves (the external HIL autopilot on sensors relies on this)."""
    from bb2_control.navigation import NavigationFilter

    suite, deep = _samples(z=-60.0, duration=3.0)
    _, up = _samples(z=-8.0, duration=8.0)  # surfaced: GPS fixes after the time to first fix
    for samples in (deep, up):
        navigable = [s for s in samples if s.sensor != "altimeter"]
        back = _round_trip(samples, suite.config)
        assert [(b.sensor, b.frame_id) for b in back] == [(s.sensor, s.frame_id) for s in navigable]
        for s, b in zip(navigable, back):
            assert abs(b.t - s.t) < 1e-9 and abs(b.t_available - s.t_available) < 1e-9, (s, b)
            if s.sensor == "imu":
                for f in ("angular_velocity", "specific_force", "orientation_xyzw", "specific_force_covariance"):
                    np.testing.assert_array_equal(getattr(b, f), getattr(s, f))
            elif s.sensor == "pressure":
                assert (b.pressure_pa, b.variance_pa2) == (s.pressure_pa, s.variance_pa2)
            elif s.sensor == "dvl":
                assert b.bottom_lock == s.bottom_lock
                np.testing.assert_array_equal(b.velocity, s.velocity)
                np.testing.assert_array_equal(b.covariance, s.covariance)
            else:
                assert b.fix == s.fix
                if s.fix:
                    np.testing.assert_allclose(b.position_enu, s.position_enu, atol=1e-6)
                    np.testing.assert_array_equal(b.covariance_enu, s.covariance_enu)
        assert [id(b) for b in sorted(back, key=sc.sample_order)] == [id(b) for b in back]  # the sensors' order
        x0 = np.zeros(12)
        x0[2], x0[6] = (-60.0 if samples is deep else -8.0), -3.0
        a, b = (NavigationFilter(suite.config, x0) for _ in range(2))
        a.update(navigable)
        b.update(sorted(reversed(back), key=sc.sample_order))
        np.testing.assert_allclose(b.state(a.t).as_vector(), a.state(a.t).as_vector(), atol=1e-6)
        assert b.stats == a.stats and sum(a.stats.used.values()) > 50, a.stats
    assert any(s.sensor == "gps" and s.fix for s in up)


def test_sample_from_message_refuses_what_carries_no_sample():
    suite, samples = _samples()
    imu = next(s for s in samples if s.sensor == "imu")
    msg = sc.imu_sample_message(imu)
    with pytest.raises(ValueError, match="no sensor sample is carried on '/bb2/sensors/altimeter'"):
        sc.sample_from_message("/bb2/sensors/altimeter", msg, suite.config)
    msg.header.frame_id = "base_link"
    with pytest.raises(ValueError, match="frame_id 'base_link', the suite's imu is mounted as 'imu_link'"):
        sc.sample_from_message("/bb2/sensors/imu", msg, suite.config)
    gps = sc.gps_sample_message(next(s for s in samples if s.sensor == "gps"))
    with pytest.raises(ValueError, match="needs the suite"):
        sc.sample_from_message("/bb2/sensors/gps", gps)


def test_a_namespaced_vehicle_s_sensor_frames_carry_its_prefix():
    """A boat in /boat1: its samples go out in boat1/imu_link ..., its mountings hang boat1/imu_link ... under
    boat1/base_link (the DVL beams under boat1/dvl_link), and its messages read back to the suite's own samples;
    another boat's message (boat2/imu_link) or an unprefixed one is refused."""
    from bb2_msgs_py.contract import frame_prefix, vehicle_frame

    prefix = frame_prefix("/boat1")
    assert prefix == "boat1/" and frame_prefix("/") == frame_prefix("") == ""
    assert vehicle_frame("base_link", prefix) == "boat1/base_link" and vehicle_frame("map", prefix) == "map"
    assert vehicle_frame("base_link", "") == "base_link"
    suite, samples = _samples()
    plain = {n: m.header.frame_id for s in samples for n, m in sc.sample_messages(s, suite.config)}
    ours = {n: m.header.frame_id for s in samples for n, m in sc.sample_messages(s, suite.config, frame_prefix=prefix)}
    assert ours == {n: "boat1/" + f for n, f in plain.items()} and ours["/bb2/sensors/imu"] == "boat1/imu_link"
    assert ours[sc.DVL_RANGES_TOPIC] == "boat1/dvl_beam_3"  # the last beam's
    d = sc.mountings_description(suite.config, frame_prefix=prefix)
    plain_tfs = sc.mountings_description(suite.config)["transforms"]
    assert [(t["parent"], t["child"]) for t in d["transforms"]] == [("boat1/" + t["parent"], "boat1/" + t["child"])
                                                                   for t in plain_tfs]
    assert ("boat1/dvl_link", "boat1/dvl_beam_0") in [(t["parent"], t["child"]) for t in d["transforms"]]
    imu = next(s for s in samples if s.sensor == "imu")
    (name, msg), = sc.sample_messages(imu, suite.config, frame_prefix=prefix)
    back = sc.sample_from_message(name, msg, suite.config, frame_prefix=prefix)
    assert back.frame_id == "imu_link" and np.array_equal(back.angular_velocity, imu.angular_velocity)
    with pytest.raises(ValueError, match="frame_id 'imu_link' is not of this vehicle"):
        sc.sample_from_message(name, sc.imu_sample_message(imu), suite.config, frame_prefix=prefix)
    msg.header.frame_id = "boat2/imu_link"
    with pytest.raises(ValueError, match="'boat2/imu_link' is not of this vehicle"):
        sc.sample_from_message(name, msg, suite.config, frame_prefix=prefix)
    with pytest.raises(ValueError, match="mounted as 'imu_link'"):  # the root namespace's reader: not its frame
        sc.sample_from_message(name, msg, suite.config)
