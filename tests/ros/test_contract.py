"""The topic contract: tables, QoS, and exact numpy <-> message round trips."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from bb2_msgs_py import CONTRACT, QOS, ContractError, contract_markdown, select_topics, topic
from bb2_sim import frames
from bb2_sim.state import VehicleState

rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
from bb2_msgs_py import conversions as conv  # noqa: E402
from bb2_msgs_py.contract import message_class, qos_profile  # noqa: E402

RNG = np.random.default_rng(20240611)


def random_state() -> VehicleState:
    return VehicleState(
        t=float(RNG.uniform(0.0, 1000.0)),
        p_native=RNG.uniform(-500.0, 500.0, 3),
        euler_native=np.array([RNG.uniform(-1.0, 1.0), RNG.uniform(-1.2, 1.2), RNG.uniform(-3.1, 3.1)]),
        v_body_native=RNG.uniform(-8.0, 8.0, 3),
        w_body_native=RNG.uniform(-0.3, 0.3, 3),
    )


def test_import_does_not_pull_rclpy():
    code = "import sys, bb2_msgs_py, bb2_msgs_py.conversions; print('rclpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_every_contract_type_is_a_real_message_or_embedded():
    for t in CONTRACT:
        if t.type == "tf2_msgs/msg/TFMessage":
            assert t.bag_only  # tf2_msgs is not in the wheels: /tf is written into bags only
            continue
        cls = message_class(t.type)
        assert cls.__name__ == t.type.split("/")[-1]
    assert len({t.name for t in CONTRACT}) == len(CONTRACT)


def test_qos_choices():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy, qos_profile_sensor_data

    for name in ("/bb2/odom", "/bb2/imu"):  # written reliable (reliable and best-effort readers both receive),
        q = qos_profile(name)                # read best effort (as sensor data; matches any writer)
        assert q.reliability == ReliabilityPolicy.RELIABLE
        assert qos_profile(name, reader=True).reliability == qos_profile_sensor_data.reliability \
            == ReliabilityPolicy.BEST_EFFORT
        assert q.history == HistoryPolicy.KEEP_LAST and q.depth == 100  # >> the recorder's lockstep window of 10
    for name in ("/bb2/planes/cmd", "/bb2/propeller/cmd", "/bb2/guidance/rate_cmd", "/bb2/autopilot/vh_cmd"):
        assert qos_profile(name).reliability == ReliabilityPolicy.RELIABLE
    path = qos_profile("/bb2/path")
    assert path.reliability == ReliabilityPolicy.RELIABLE
    assert path.durability == DurabilityPolicy.TRANSIENT_LOCAL
    clock = qos_profile("/clock")  # written reliable: serves rclcpp::ClockQoS readers (best effort) and the recorder
    assert clock.reliability == ReliabilityPolicy.RELIABLE and clock.depth == 100
    assert qos_profile("/clock", reader=True).reliability == ReliabilityPolicy.BEST_EFFORT
    assert set(QOS) >= {t.qos for t in CONTRACT}


def test_unknown_topics_and_patterns_are_rejected():
    with pytest.raises(ContractError, match="unknown topic"):
        topic("/bb2/odometry")
    with pytest.raises(ContractError, match="matches no contract topic"):
        select_topics(["/bb2/nothing.*"])
    assert [t.name for t in select_topics(["/bb2/planes/.*"])] == ["/bb2/planes/state", "/bb2/planes/cmd"]
    assert "/tf" not in [t.name for t in select_topics()]
    assert "/tf" in [t.name for t in select_topics(include_bag_only=True)]


def test_markdown_table_lists_every_topic():
    md = contract_markdown()
    lines = md.strip().splitlines()
    assert lines[0].startswith("| topic | type | QoS | frame | units | publisher | subscribers |")
    assert len(lines) == 2 + len(CONTRACT)
    for t in CONTRACT:
        row = next(line for line in lines if f"`{t.name}`" in line)
        assert f"`{t.type}`" in row and t.publisher in row
        assert row.count("|") == 8


def test_odometry_round_trip_is_exact():
    for _ in range(200):
        s = random_state()
        msg = conv.state_to_odometry(s)
        assert msg.header.frame_id == "odom" and msg.child_frame_id == "base_link"
        back = conv.odometry_to_state(msg)
        np.testing.assert_allclose(back.as_vector(), s.as_vector(), rtol=0, atol=1e-12)
        assert abs(back.t - s.t) <= 0.5e-9  # stamps are whole nanoseconds


def test_a_namespaced_vehicle_s_readers_take_its_frames_and_refuse_another_s():
    """boat1's odometry (boat1/odom -> boat1/base_link) and rate command (boat1/base_link) read back where the
    reader names boat1's base_link; boat2's, or the root namespace's, are refused."""
    s = random_state()
    msg = conv.state_to_odometry(s, frame_id="boat1/odom", child_frame_id="boat1/base_link")
    np.testing.assert_allclose(conv.odometry_to_state(msg, child_frame_id="boat1/base_link").as_vector(),
                               s.as_vector(), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="'boat2/base_link', got 'boat1/base_link'"):
        conv.odometry_to_state(msg, child_frame_id="boat2/base_link")
    with pytest.raises(ValueError, match="'base_link', got 'boat1/base_link'"):
        conv.odometry_to_state(msg)
    rate = conv.rate_command_message(1.0, 0.02, -0.03, frame_id="boat1/base_link")
    assert conv.rate_command_from_message(rate, frame_id="boat1/base_link") == (0.02, -0.03)
    with pytest.raises(ValueError, match="must be in 'base_link', got 'boat1/base_link'"):
        conv.rate_command_from_message(rate)
    assert conv.path_error_message(0.0, [1, 2, 3], frame_id="boat1/path_frenet").header.frame_id == "boat1/path_frenet"


def test_odometry_is_rep103():
    # heading psi = 0, level, moving ahead at 5 m/s (u = -5 native): ENU +x, forward speed +5 FLU
    s = VehicleState(1.0, np.array([10.0, 20.0, -30.0]), np.zeros(3), np.array([-5.0, 0.0, 0.0]),
                     np.array([0.0, 0.1, 0.2]))
    msg = conv.state_to_odometry(s)
    p = msg.pose.pose.position
    assert (p.x, p.y, p.z) == (-10.0, -20.0, -30.0)
    assert msg.twist.twist.linear.x == 5.0
    # native q > 0 is bow up; REP-103 pitch about +y (left) positive is bow down
    assert msg.twist.twist.angular.y == -0.1 and msg.twist.twist.angular.z == 0.2
    q = msg.pose.pose.orientation
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], [0, 0, 0, 1], atol=1e-15)
    # bow up 10 deg: the nose (FLU +x) points up in ENU
    s2 = VehicleState(0.0, np.zeros(3), np.array([0.0, np.radians(10.0), 0.0]), np.zeros(3), np.zeros(3))
    q2 = conv.state_to_odometry(s2).pose.pose.orientation
    nose_enu = frames.rotation_from_quaternion([q2.x, q2.y, q2.z, q2.w]) @ [1.0, 0.0, 0.0]
    assert nose_enu[2] == pytest.approx(np.sin(np.radians(10.0)), abs=1e-12)


def test_imu_specific_force_includes_gravity_and_marks_unknown_orientation():
    level = VehicleState(0.0, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
    f = conv.specific_force_flu(level, np.zeros(3), 9.81)
    np.testing.assert_allclose(f, [0.0, 0.0, 9.81], atol=1e-15)  # at rest an IMU reads +g up
    # pitched bow up 30 deg at rest: gravity reaction has a forward component g sin(30)
    up = VehicleState(0.0, np.zeros(3), np.array([0.0, np.radians(30.0), 0.0]), np.zeros(3), np.zeros(3))
    f = conv.specific_force_flu(up, np.zeros(3), 9.81)
    np.testing.assert_allclose(f, [9.81 * 0.5, 0.0, 9.81 * np.cos(np.radians(30.0))], atol=1e-12)
    # steady turn: centripetal acceleration w x v shows up
    turn = VehicleState(0.0, np.zeros(3), np.zeros(3), np.array([-5.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.1]))
    f = conv.specific_force_flu(turn, np.zeros(3), 9.81)
    np.testing.assert_allclose(f, [0.0, 0.5, 9.81], atol=1e-12)  # turning to port: accel to port (+y FLU)

    s = random_state()
    msg = conv.imu_message(s, [0.1, 0.2, 9.7])
    assert msg.orientation_covariance[0] > 0 and msg.header.frame_id == "base_link"
    arr = conv.imu_to_arrays(msg)
    np.testing.assert_allclose(arr["w_flu"], frames.body_native_to_flu(s.w_body_native), atol=1e-15)
    np.testing.assert_allclose(arr["f_flu"], [0.1, 0.2, 9.7], atol=1e-15)
    back = conv.enu_arrays_to_state(s.t, [0, 0, 0], arr["q_enu_flu"], [0, 0, 0], arr["w_flu"])
    np.testing.assert_allclose(back.euler_native, s.euler_native, atol=1e-12)
    unknown = conv.imu_message(s, [0.0, 0.0, 9.81], orientation_known=False)
    assert unknown.orientation_covariance[0] == -1.0  # as sensor_msgs/Imu says
    assert conv.imu_to_arrays(unknown)["q_enu_flu"] is None


def test_refilled_odometry_and_imu_equal_fresh_messages():
    """The simulator refills one Odometry and one Imu each step (conversions.fill_*): every field is rewritten, so
    a refilled message equals a fresh one whatever it held before (another state, frame, variance, an unknown
    orientation)."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu

    odom, imu = Odometry(), Imu()
    for k in range(6):
        s = random_state()
        kw = {"frame_id": f"boat{k}/odom", "child_frame_id": f"boat{k}/base_link"}
        if k % 2:
            kw.update(pose_variance=1e-3 * k, twist_variance=2e-3 * k)
        assert conv.fill_odometry(odom, s, **kw) is odom
        assert odom == conv.state_to_odometry(s, **kw) and odom.pose.pose.position.x != 0.0
        f = RNG.uniform(-10.0, 10.0, 3)
        ikw = {"frame_id": f"boat{k}/base_link", "orientation_known": k != 2,
               "variances": {"orientation_variance_rad2": 1e-4 * (k + 1)} if k % 3 == 0 else None}
        assert conv.fill_imu(imu, s, f, **ikw) is imu
        assert imu == conv.imu_message(s, f, **ikw), k
    assert imu.orientation_covariance[0] > 0.0  # restored after the unknown orientation of k = 2


def test_depth_altitude_round_trips():
    for depth in (0.0, 12.5, 87.25, 300.0):
        msg = conv.depth_message(3.0, depth)
        assert msg.fluid_pressure > 101325.0 or depth == 0.0
        assert conv.depth_from_message(msg) == pytest.approx(depth, abs=1e-12)
    # rho g = 1025 * 9.81 Pa per metre
    assert conv.depth_message(0.0, 10.0).fluid_pressure - conv.depth_message(0.0, 0.0).fluid_pressure \
        == pytest.approx(1025.0 * 9.81 * 10.0, rel=1e-14)
    with pytest.raises(ValueError):
        conv.depth_message(0.0, float("nan"))
    r = conv.altitude_message(1.0, 23.4)
    assert conv.altitude_from_message(r) == pytest.approx(23.4, rel=1e-7)  # float32 field
    assert math.isinf(conv.altitude_from_message(conv.altitude_message(1.0, 1e6)))


def test_joint_state_round_trips():
    deg = np.array([10.0, -20.0, 5.5, 0.0, -30.0])
    msg = conv.planes_message_deg(2.0, deg)
    assert list(msg.name) == ["delta1", "delta2", "delta3", "delta4", "delta5"]
    np.testing.assert_allclose(msg.position, np.radians(deg), rtol=0, atol=1e-15)
    np.testing.assert_allclose(conv.planes_from_message_deg(msg), deg, rtol=0, atol=1e-12)
    # order independence: a reordered message decodes to the same deflections
    msg.name = list(reversed(msg.name))
    msg.position = list(reversed(msg.position))
    np.testing.assert_allclose(conv.planes_from_message_deg(msg), deg, atol=1e-12)
    msg.name = msg.name[:4]
    msg.position = msg.position[:4]
    with pytest.raises(ValueError, match="lacks joints"):
        conv.planes_from_message(msg)
    with pytest.raises(ValueError, match="5 plane deflections"):
        conv.planes_message(0.0, [0.1, 0.2])
    assert conv.propeller_from_message(conv.propeller_message(0.0, 12.345)) == 12.345
    assert conv.vh_from_message(conv.vh_message(0.0, 0.1, -0.2)) == (0.1, -0.2)


def test_guidance_round_trips():
    msg = conv.rate_command_message(1.5, 0.02, -0.03)
    assert (msg.vector.x, msg.vector.y, msg.vector.z) == (0.0, -0.02, -0.03)
    assert conv.rate_command_from_message(msg) == (0.02, -0.03)
    msg.header.frame_id = "map"
    with pytest.raises(ValueError, match="base_link"):
        conv.rate_command_from_message(msg)
    e = np.array([0.5, -1.25, 2.0])
    np.testing.assert_array_equal(conv.path_error_from_message(conv.path_error_message(0.0, e)), e)
    s = np.linspace(0.0, 1.0, 30)
    p_native = np.column_stack([-200.0 * s, 30.0 * np.sin(3 * s), -20.0 - 10.0 * s])
    path = conv.path_message(0.0, p_native)
    np.testing.assert_allclose(conv.path_from_message(path), p_native, rtol=0, atol=1e-12)
    # each pose's x axis is along the path tangent
    k = 10
    q = path.poses[k].pose.orientation
    x_axis = frames.rotation_from_quaternion([q.x, q.y, q.z, q.w]) @ [1.0, 0.0, 0.0]
    tangent = frames.earth_native_to_enu(p_native[k + 1] - p_native[k - 1])
    np.testing.assert_allclose(x_axis, tangent / np.linalg.norm(tangent), atol=1e-9)


def test_stamps_are_whole_nanoseconds():
    st = conv.stamp(12.000000001)
    assert (st.sec, st.nanosec) == (12, 1)
    assert conv.stamp_to_ns(st) == 12_000_000_001
    with pytest.raises(ValueError):
        conv.stamp(-1.0)
    assert conv.clock_message(3.25).clock.nanosec == 250_000_000


def test_nodes_name_topics_relative_to_their_namespace_but_clock_diagnostics_and_tf():
    """Issue 13, point 4: a node creates ``bb2/odom`` (the contract's ``/bb2/odom`` in the root namespace, the boat's
    ``/boat1/bb2/odom`` in /boat1); ``/clock``, ``/diagnostics`` and the tf topics stay absolute; a boat with its own
    clock resolves ``/clock`` to ``/boat1/clock``."""
    from bb2_msgs_py.contract import ABSOLUTE_TOPICS, GLOBAL_TOPICS, boat_topic, node_topic_name

    assert node_topic_name("/bb2/odom") == "bb2/odom" and node_topic_name("bb2/odom") == "bb2/odom"
    assert {node_topic_name(t) for t in ABSOLUTE_TOPICS} == set(ABSOLUTE_TOPICS) >= {"/clock", "/tf", *GLOBAL_TOPICS}
    relative = [t.name for t in CONTRACT if not node_topic_name(t.name).startswith("/")]
    assert len(relative) == len(CONTRACT) - len([t for t in CONTRACT if t.name in ABSOLUTE_TOPICS])
    assert boat_topic("/bb2/odom", "/boat1/") == "/boat1/bb2/odom" and boat_topic("/clock", "boat1") == "/boat1/clock"
    assert boat_topic("/diagnostics", "boat1") == "/diagnostics" and boat_topic("/tf", "boat1") == "/tf"
    assert all(boat_topic(t.name, "") == t.name for t in CONTRACT)  # the root namespace: the contract's names
