"""Real DDS: publishers in this process, the recorder as a separate process, the bag checked after."""
from __future__ import annotations

import json

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from mcap.reader import make_reader  # noqa: E402

from bb2_msgs_py import conversions as conv  # noqa: E402
from bb2_msgs_py.contract import message_class, qos_profile  # noqa: E402
from bb2_sim.state import VehicleState  # noqa: E402
from bb2_tools.bagfile import BagReader, recover  # noqa: E402

from rosenv import claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
N_ODOM, N_CMD = 60, 20


def _mountings() -> str:
    from bb2_msgs_py.sensor_conversions import mountings_json
    from bb2_sim.sensors import load_suite_config

    return mountings_json(load_suite_config("tactical"), seed=5)


MOUNTINGS = _mountings()  # what the simulator latches on /bb2/sensors/mountings for the tactical suite
SIM_T0 = 1000.0  # /clock published before the data: log times must be sim time


@pytest.fixture(scope="module")
def domain_id() -> int:
    return claimed_domain()


def _start_recorder(out: Path, domain_id: int, *extra: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--out", str(out), *extra],
                            cwd=REPO, env=ros_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    line = proc.stdout.readline()
    if "recording" not in line:
        proc.kill()
        raise AssertionError(f"recorder did not start: {line!r} {proc.stderr.read()}")
    return proc


class Publishers:
    """Publishers of a few contract topics on an isolated context and domain."""

    TOPICS = ("/clock", "/bb2/odom", "/bb2/planes/cmd", "/bb2/path", "/bb2/sensors/mountings")

    def __init__(self, domain_id: int):
        from rclpy.context import Context

        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node("bb2_test_publishers", context=self.ctx)
        self.pubs = {t: self.node.create_publisher(message_class(_type(t)), t, qos_profile(t)) for t in self.TOPICS}

    def wait_for_subscribers(self, timeout_s: float = 10.0) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(p.get_subscription_count() > 0 for p in self.pubs.values()):
                break
            time.sleep(0.05)
        else:
            raise AssertionError({t: p.get_subscription_count() for t, p in self.pubs.items()})
        # discovery is not symmetric: the recorder may not have matched our writers yet, and
        # best-effort samples sent before it has are lost.  Give it a moment.
        time.sleep(0.5)

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


def _type(name: str) -> str:
    from bb2_msgs_py.contract import topic

    return topic(name).type


def _state(k: int) -> VehicleState:
    return VehicleState(SIM_T0 + 0.01 * k, np.array([-1.0 * k, 2.0, -25.0]), np.array([0.0, 0.02, 0.3]),
                        np.array([-5.0, 0.0, 0.1]), np.array([0.0, 0.01, 0.0]))


def test_recorder_records_real_dds_topics(tmp_path, domain_id):
    out = tmp_path / "rec"
    pubs = Publishers(domain_id)
    proc = _start_recorder(out, domain_id, "--use-sim-time", "--chunk-size", "8192")
    try:
        pubs.wait_for_subscribers()
        for _ in range(10):  # /clock is best effort, keep last 1: publish it a few times
            pubs.pubs["/clock"].publish(conv.clock_message(SIM_T0))
            time.sleep(0.05)
        time.sleep(0.3)  # the recorder's clock takes /clock before the data arrive
        path = conv.path_message(SIM_T0, np.column_stack([-np.arange(10.0), np.zeros(10), -20.0 * np.ones(10)]))
        pubs.pubs["/bb2/path"].publish(path)
        pubs.pubs["/bb2/sensors/mountings"].publish(message_class("std_msgs/msg/String")(data=MOUNTINGS))
        for k in range(N_ODOM):
            pubs.pubs["/bb2/odom"].publish(conv.state_to_odometry(_state(k)))
            if k % 3 == 0:
                pubs.pubs["/bb2/planes/cmd"].publish(conv.planes_message(SIM_T0 + 0.01 * k, [0.001 * k] * 5))
            time.sleep(0.004)
        time.sleep(0.7)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
        pubs.close()
    assert proc.returncode == 0, stderr
    assert "wrote" in stdout

    # metadata.yaml: version 9, counts
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert counts["/bb2/odom"] == N_ODOM
    assert counts["/bb2/planes/cmd"] == N_CMD
    assert counts["/tf"] == N_ODOM  # one transform per odometry message
    assert counts["/bb2/path"] == 1
    assert counts["/bb2/sensors/mountings"] == counts["/tf_static"] == 1  # the sensor frames, once
    assert counts["/clock"] == 10   # written reliable, read reliable by the recorder: none lost
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
           for t in info["topics_with_message_count"]}
    assert qos["/bb2/odom"][0]["reliability"] == "reliable"  # what the publisher offered (issue 13: state topics
    assert qos["/clock"][0]["reliability"] == "reliable"     # are written reliable; /clock too, issue 10)
    assert json.loads(info["custom_data"]["bb2_gaps"]) == []  # every sample published arrived
    assert qos["/bb2/path"][0]["durability"] == "transient_local"
    assert (qos["/tf_static"][0]["durability"], qos["/tf_static"][0]["depth"]) == ("transient_local", 1)

    # the .mcap independently
    with open(out / info["relative_file_paths"][0], "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        stats = summary.statistics
        by_topic = {summary.channels[c].topic: n for c, n in stats.channel_message_counts.items()}
        assert by_topic == counts
        assert {s.name for s in summary.schemas.values()} >= {"nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage"}
        odom_times = [m.log_time for _, _, m in reader.iter_messages(topics=["/bb2/odom"])]
    # receive time on the sim clock (use_sim_time): exactly the /clock value published
    assert set(odom_times) == {int(SIM_T0 * 1e9)}

    # decoded content equals what was published, /tf mirrors the odometry
    r = BagReader(out)
    odoms = [m for _, _, m in r.messages("/bb2/odom")]
    tfs = [m for _, _, m in r.messages("/tf")]
    got = sorted(o.header.stamp.nanosec + o.header.stamp.sec * 10**9 for o in odoms)
    assert got == [round((SIM_T0 + 0.01 * k) * 1e9) for k in range(N_ODOM)]
    for o, tf in zip(odoms, tfs):
        tr = tf.transforms[0]
        assert (tr.header.frame_id, tr.child_frame_id) == ("odom", "base_link")
        assert tr.transform.translation.x == o.pose.pose.position.x
        assert tr.header.stamp.nanosec == o.header.stamp.nanosec
    # /tf_static: every mounting of the suite (sensors, and the DVL's beams under the DVL), as described
    (_, log_ns, static), = list(r.messages("/tf_static"))
    want = json.loads(MOUNTINGS)["transforms"]
    got_tf = [(t.header.frame_id, t.child_frame_id, [t.transform.translation.x, t.transform.translation.y,
                                                     t.transform.translation.z],
               [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w])
              for t in static.transforms]
    assert got_tf == [(w["parent"], w["child"], w["translation_m"], w["rotation_xyzw"]) for w in want]
    assert {c for _, c, _, _ in got_tf} >= {"imu_link", "dvl_link", "dvl_beam_0", "gps_link"}
    assert all(t.header.stamp.sec * 10**9 + t.header.stamp.nanosec == log_ns for t in static.transforms)


def test_sigkilled_recorder_leaves_a_recoverable_bag(tmp_path, domain_id):
    out = tmp_path / "killed"
    pubs = Publishers(domain_id)
    proc = _start_recorder(out, domain_id, "--topics", "/bb2/odom", "--chunk-size", "2048",
                           "--flush-period", "0")
    try:
        pubs.pubs = {"/bb2/odom": pubs.pubs["/bb2/odom"]}
        pubs.wait_for_subscribers()
        for k in range(N_ODOM):
            pubs.pubs["/bb2/odom"].publish(conv.state_to_odometry(_state(k)))
            time.sleep(0.004)
        time.sleep(0.7)
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
        pubs.close()
    assert not (out / "metadata.yaml").exists()
    r = BagReader(out)
    assert r.truncated
    kept = r.message_counts.get("/bb2/odom", 0)
    # odometry + tf records are ~1 kB: a 2 kB chunk holds a few of them; at most the open chunk is lost
    assert N_ODOM - 5 <= kept <= N_ODOM
    rep = recover(out)
    assert rep.was_truncated and rep.message_counts["/bb2/odom"] == kept
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["message_count"] == rep.message_count and not BagReader(out).truncated


def test_a_best_effort_publisher_is_recorded_best_effort_and_its_losses_still_counted(tmp_path, domain_id):
    """The recorder reads what the contract's writers offer (reliable); an external best-effort publisher of
    /bb2/odom (a HIL bench) would not match that request, so the recorder re-subscribes best effort at its next
    flush, says so, and records it; the messages it missed before are a head gap in the bag's metadata."""
    from rclpy.qos import ReliabilityPolicy

    out = tmp_path / "be"
    pubs = Publishers(domain_id)
    q = qos_profile("/bb2/odom")
    q.reliability = ReliabilityPolicy.BEST_EFFORT
    pubs.node.destroy_publisher(pubs.pubs["/bb2/odom"])
    pubs.pubs = {"/bb2/odom": pubs.node.create_publisher(message_class("nav_msgs/msg/Odometry"), "/bb2/odom", q)}
    proc = _start_recorder(out, domain_id, "--topics", "/bb2/odom", "--flush-period", "0.2", "--no-tf")
    try:
        sent = 0
        t0 = time.monotonic()
        while time.monotonic() - t0 < 30 and pubs.pubs["/bb2/odom"].get_subscription_count() == 0:
            pubs.pubs["/bb2/odom"].publish(conv.state_to_odometry(_state(sent)))  # unmatched: never received
            sent += 1
            time.sleep(0.02)
        time.sleep(0.5)
        for _ in range(50):
            pubs.pubs["/bb2/odom"].publish(conv.state_to_odometry(_state(sent)))
            sent += 1
            time.sleep(0.004)
        time.sleep(0.7)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
        pubs.close()
    assert proc.returncode == 0, stderr
    assert "a publisher offers best effort: recording it best effort" in stderr, stderr
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    kept = info["topics_with_message_count"][0]["message_count"]
    assert kept >= 50, info
    gaps = json.loads(info["custom_data"]["bb2_gaps"])
    assert sent > 1 and kept + sum(g["missing"] for g in gaps) == sent, (sent, kept, gaps)
    assert all(g["after_sequence"] == 0 for g in gaps)   # only the ones before it matched


# The /tf bytes the recorder wrote for _fixed_odometry before it used the standard (de)serializers (with its own
# struct encoder, then tested against mcap_ros2's): CDR header, one transform, stamp 1234.56789 s | the frame
# names with their alignment padding | translation and rotation (7 float64).
TF_HEAD = "0001000001000000d20400005050d921"
TF_FRAMES = {
    ("odom", "base_link"): "050000006f646f6d000000000a000000626173655f6c696e6b000000",
    ("map", "bb2/base_link"): "040000006d6170000e0000006262322f626173655f6c696e6b000000",
    ("o", "b"): "020000006f000000020000006200000000000000",
    ("odom_ned", "base_link_frd_x"): "090000006f646f6d5f6e65640000000010000000626173655f6c696e6b5f6672645f7800",
}
TF_POSE = ("000000000000f83f00000000000002c000000000001049c0"
           "000000000000e03f000000000000e0bf000000000000e03f000000000000e03f")


def _fixed_odometry(frame_id: str, child: str):
    odom = message_class("nav_msgs/msg/Odometry")()
    odom.header.stamp.sec, odom.header.stamp.nanosec = 1234, 567_890_000
    odom.header.frame_id, odom.child_frame_id = frame_id, child
    p = odom.pose.pose
    p.position.x, p.position.y, p.position.z = 1.5, -2.25, -50.125
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = 0.5, -0.5, 0.5, 0.5
    odom.twist.twist.linear.x, odom.pose.covariance[0] = 7.0, 0.01
    return odom


@pytest.mark.parametrize("frame_id,child", list(TF_FRAMES))
def test_tf_from_odometry_cdr_equals_the_dynamic_encoder(frame_id, child):
    """The recorder's /tf (rclpy's deserializer on the odometry CDR, then mcap_ros2's encoder: tf2_msgs is not
    installed) writes the bytes mcap_ros2's dynamic encoder writes for tf_from_odometry of the message, and the
    very bytes the recorder wrote before, for frame names of every length modulo 4 and 8 (CDR alignment)."""
    from mcap_ros2._dynamic import serialize_dynamic
    from rclpy.serialization import serialize_message

    from bb2_tools.bagfile import message_definition
    from bb2_tools.recorder import TF_TYPE, tf_cdr_from_odometry_cdr, tf_from_odometry

    rng = np.random.default_rng(len(frame_id) + 7 * len(child))
    state = VehicleState.from_vector(1234.56789, rng.normal(size=12))
    odom = conv.state_to_odometry(state, frame_id=frame_id, child_frame_id=child)
    encode = serialize_dynamic(TF_TYPE, message_definition(TF_TYPE))[TF_TYPE]
    assert tf_cdr_from_odometry_cdr(serialize_message(odom)) == encode(tf_from_odometry(odom))
    want = bytes.fromhex(TF_HEAD + TF_FRAMES[frame_id, child] + TF_POSE)
    assert tf_cdr_from_odometry_cdr(serialize_message(_fixed_odometry(frame_id, child))) == want
    with pytest.raises(RuntimeError, match="deserialize"):
        tf_cdr_from_odometry_cdr(b"\x00\x00\x00\x00" + serialize_message(odom)[4:])


def test_leading_stamp_ns_reads_the_stamp_of_every_stamped_message_and_the_clock():
    """The recorder reads the per-step stamps from the CDR bytes: the same nanoseconds rclpy's deserializer gives
    for the simulator's stamped messages and /clock, little and big endian; bytes that cannot hold a stamp raise."""
    from rclpy.serialization import serialize_message

    state = VehicleState.from_vector(4321.987654321, np.arange(12) * 0.1)
    msgs = [conv.state_to_odometry(state), conv.imu_message(state, np.array([0.0, 0.0, 9.81])),
            conv.depth_message(12.345678901, 50.0), conv.planes_message(3.05, np.zeros(5)),
            conv.clock_message(2**31 - 1.5)]
    for msg in msgs:
        st = msg.clock if hasattr(msg, "clock") else msg.header.stamp
        assert conv.leading_stamp_ns(serialize_message(msg)) == conv.stamp_to_ns(st) > 0, type(msg)
    big = b"\x00\x00\x00\x00" + (7).to_bytes(4, "big") + (250_000_000).to_bytes(4, "big")
    assert conv.leading_stamp_ns(big) == 7_250_000_000
    for bad in (b"", b"\x00\x01\x00\x00\x07", b"\x00\x07\x00\x00" + bytes(8)):
        with pytest.raises(conv.ConversionError, match="not a CDR message starting with a stamp"):
            conv.leading_stamp_ns(bad)


def test_the_recorder_acknowledges_the_oldest_newest_stamp_of_the_per_step_topics():
    """The ack is the step up to which every per-step topic that has begun is held: a sensor topic lagging (its
    samples held back by the transport while the state came through) holds it back; it only goes forward."""
    from bb2_msgs_py.contract import CONTRACT
    from bb2_tools.recorder import StepAcks, step_topics

    topics = step_topics(CONTRACT)
    assert {"/bb2/state_native", "/clock", "/bb2/odom", "/bb2/imu", "/bb2/depth", "/bb2/altitude",
            "/bb2/planes/state", "/bb2/propeller/state"} == topics
    acks = StepAcks(topics)
    assert acks.next_ack() is None
    acks.received("/bb2/state_native", 100)
    assert acks.next_ack() == 100
    acks.received("/bb2/imu", 50)                     # begins behind: cannot take the ack back
    assert acks.next_ack() is None
    for k in range(2, 6):
        acks.received("/bb2/state_native", 100 * k)
    acks.received("/bb2/imu", 150)                    # stamped with its step's start: it belongs to state 250
    assert acks.next_ack() == 250 and acks.next_ack() is None   # the IMU holds it back; once said, nothing new
    acks.received("/bb2/imu", 450)
    assert acks.next_ack() == 500                     # the state holds it now
    acks.received("/bb2/imu", 400)                    # an older one (a re-send) changes nothing
    assert acks.next_ack() is None and acks.newest_ns["/bb2/imu"] == 450


def test_the_final_state_is_acknowledged_once_its_step_is_held():
    """The IMU, plane and propeller states are stamped with the start of the step they describe and come with the
    next state: the last state of a run (t_N) is acknowledged once the IMU of [t_N-1, t_N) and every state-stamped
    topic of t_N are held, not before (the simulator ends a recorded lockstep run on that acknowledgement)."""
    from bb2_msgs_py.contract import CONTRACT
    from bb2_tools.recorder import StepAcks, step_topics

    acks = StepAcks(step_topics(CONTRACT))
    h = 50_000_000
    state_stamped = ("/bb2/state_native", "/clock", "/bb2/odom", "/bb2/depth", "/bb2/altitude")
    for n in range(4):                                # states t_0..t_3; the step-start topics of t_0..t_2
        for topic in state_stamped:
            acks.received(topic, n * h)
        if n:
            for topic in ("/bb2/imu", "/bb2/planes/state", "/bb2/propeller/state"):
                acks.received(topic, (n - 1) * h)
    assert acks.step_ns == h and acks.next_ack() == 3 * h     # everything of the final step t_3 is held
    for topic in state_stamped[:-1]:                  # the state of t_4 and all but its altitude
        acks.received(topic, 4 * h)
    for topic in ("/bb2/imu", "/bb2/planes/state", "/bb2/propeller/state"):
        acks.received(topic, 3 * h)
    assert acks.next_ack() is None                    # the altitude of t_4 is not in yet
    acks.received("/bb2/altitude", 4 * h)
    assert acks.next_ack() == 4 * h
    acks.received("/bb2/state_native", 4 * h)         # a re-sent state does not change the step
    assert acks.step_ns == h and acks.next_ack() is None


def test_tf_static_from_mountings_refuses_what_is_not_a_mountings_description():
    """A mountings message the recorder cannot read gives no /tf_static (ValueError with the reason; the recorder
    logs it and keeps the message itself in the bag)."""
    from rclpy.serialization import serialize_message

    from bb2_tools.recorder import tf_static_cdr_from_mountings_cdr, tf_static_from_mountings

    string = message_class("std_msgs/msg/String")
    with pytest.raises(ValueError, match="not JSON"):
        tf_static_cdr_from_mountings_cdr(serialize_message(string(data="{oops")), 0)
    with pytest.raises(ValueError, match="bb2_sensor_mountings/1"):
        tf_static_cdr_from_mountings_cdr(serialize_message(string(data='{"format": "other"}')), 0)
    doc = json.loads(MOUNTINGS)
    doc["transforms"][0]["rotation_xyzw"] = [0.0, 0.0, 1.0]
    with pytest.raises(ValueError, match="rotation_xyzw 4"):
        tf_static_from_mountings(doc, 0)
    good = tf_static_from_mountings(json.loads(MOUNTINGS), 1_500_000_000)
    assert good["transforms"][0]["header"]["stamp"] == {"sec": 1, "nanosec": 500_000_000}
