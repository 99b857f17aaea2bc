"""The sensor topics on real nodes over DDS (issue 12): the simulator in lockstep with the controllers publishes
/bb2/sensors/* at each sensor's rate with the frames of the suite, a dropout window gives no DVL message inside
it, the mountings are latched, and two runs with the same seed give byte-identical messages."""
from __future__ import annotations

import json
import signal
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_msgs_py.contract import message_class, qos_profile, topic  # noqa: E402
from bb2_msgs_py.sensor_conversions import SENSOR_TOPICS  # noqa: E402

from rosenv import SpinningNode, claimed_domain, spawn_node  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
PARAMS = REPO / "config" / "bb2_graph.yaml"
CONTROLLERS = ("bb2_ros.planner", "bb2_ros.path_following", "bb2_ros.l1_autopilot", "bb2_ros.mixer")
DURATION_S = 6.0
MISSION = f"""extends: {REPO / 'missions' / 'canyon.yaml'}
duration_s: {DURATION_S}
sensors:
  suite: tactical
  seed: 7
  faults:
    - {{sensor: dvl, kind: dropout, start_s: 2.0, end_s: 3.5}}
"""


class Listener(SpinningNode):
    """Every /bb2/sensors/* message, serialized (raw), in arrival order per topic; also reads /bb2/state_native so
    the simulator (min_state_subscribers) waits for it before the first step."""

    def __init__(self, domain_id: int):
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        super().__init__("sensors_test", domain_id)
        self.raw: dict[str, list[bytes]] = {n: [] for n in SENSOR_TOPICS}
        for name in SENSOR_TOPICS:
            latched = name == "/bb2/sensors/mountings"
            q = qos_profile(name) if latched else QoSProfile(
                history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.VOLATILE)
            self.node.create_subscription(message_class(topic(name).type), name,
                                          lambda m, n=name: self.raw[n].append(bytes(m)), q, raw=True)
        self.node.create_subscription(message_class("std_msgs/msg/Float64MultiArray"), "/bb2/state_native",
                                      lambda m: None, qos_profile("/bb2/state_native"))
        self.start()


def _run(tmp_path: Path, mission: Path, domain_id: int) -> dict[str, list[bytes]]:
    common = ["--params-file", str(PARAMS), "-p", f"mission_file:={mission}"]
    procs = {m: spawn_node(m, domain_id, *common) for m in CONTROLLERS}
    listener = Listener(domain_id)
    sim = None
    try:
        over = tmp_path / "sim.yaml"
        over.write_text("simulator:\n  ros__parameters:\n    exit_at_end: true\n    min_state_subscribers: 3\n"
                        "    lockstep_timeout_s: 20.0\n    startup_settle_s: 1.0\n")
        sim = spawn_node("bb2_ros.simulator", domain_id, *common, "--params-file", str(over))
        out, _ = sim.communicate(timeout=120)
        assert sim.returncode == 0, out
        assert "no answer to step" not in out, out
        import time
        time.sleep(0.5)   # the last messages in flight
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs.values():
            p.wait(10)
        if sim is not None and sim.poll() is None:
            sim.kill()
        listener.close()
    return listener.raw


def _decode(raw: dict[str, list[bytes]]):
    from rclpy.serialization import deserialize_message

    return {n: [deserialize_message(b, message_class(topic(n).type)) for b in v] for n, v in raw.items()}


def _t(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_sensor_topics_at_their_rates_and_identical_for_a_seed(tmp_path):
    mission = tmp_path / "canyon_sensors.yaml"
    mission.write_text(MISSION)
    first = _run(tmp_path, mission, claimed_domain())
    msgs = _decode(first)

    # the last step integrated is [DURATION - h, DURATION): samples up to just before DURATION_S
    def stamps(name):
        return np.array([_t(m) for m in msgs[name]])

    for name, rate in (("/bb2/sensors/imu", 200.0), ("/bb2/sensors/pressure", 10.0), ("/bb2/sensors/gps", 5.0)):
        t = stamps(name)
        want = np.arange(round(DURATION_S * rate)) / rate
        np.testing.assert_allclose(t, want, atol=1e-9, err_msg=name)
    t_alt = stamps("/bb2/sensors/altimeter")
    k = np.round(t_alt * 5.0)
    np.testing.assert_allclose(t_alt, k / 5.0, atol=1e-9)
    assert 0.9 * DURATION_S * 5 <= t_alt.size <= DURATION_S * 5          # 1 % of the pings lost at most a few
    t_dvl = stamps("/bb2/sensors/dvl")                                   # 50 m above the floor: bottom lock
    want = [k / 5.0 for k in range(round(DURATION_S * 5)) if not 2.0 <= k / 5.0 < 3.5 and k / 5.0 + 0.1 < DURATION_S]
    np.testing.assert_allclose(t_dvl, want, atol=1e-9)
    assert not msgs["/bb2/sensors/dvl/water_track"]
    assert len(msgs["/bb2/sensors/dvl/ranges"]) == 4 * len(want)
    assert all(m.status.status == -1 for m in msgs["/bb2/sensors/gps"])      # 200 m deep: no fix

    frames = {n: {m.header.frame_id for m in v} for n, v in msgs.items() if n != "/bb2/sensors/mountings"}
    assert frames["/bb2/sensors/imu"] == {"imu_link"} and frames["/bb2/sensors/dvl"] == {"dvl_link"}
    assert frames["/bb2/sensors/dvl/ranges"] == {f"dvl_beam_{i}" for i in range(4)}
    assert frames["/bb2/sensors/gps"] == {"gps_link"} and frames["/bb2/sensors/altimeter"] == {"altimeter_link"}
    imu = msgs["/bb2/sensors/imu"]
    assert np.mean([m.linear_acceleration.z for m in imu]) == pytest.approx(9.81, abs=0.05)
    assert all(m.angular_velocity_covariance[0] > 0 for m in imu)
    mount = json.loads(msgs["/bb2/sensors/mountings"][-1].data)
    assert mount["suite"] == "tactical" and mount["seed"] == 7
    assert {tf["child"] for tf in mount["transforms"]} >= {"imu_link", "pressure_link", "dvl_link", "altimeter_link",
                                                           "gps_link", "dvl_beam_0"}
    assert mount["rates_hz"]["imu"] == 200.0

    second = _run(tmp_path, mission, claimed_domain())
    for name in SENSOR_TOPICS:
        assert second[name] == first[name], name
