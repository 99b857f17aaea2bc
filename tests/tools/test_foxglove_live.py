"""Issue 13, point 7: the graph live in Foxglove.  A WebSocket client speaking the Foxglove protocol (the one
Foxglove itself speaks: ``foxglove.sdk.v1``) connects to the bridge, finds every contract topic advertised with its
``ros2msg`` schema, subscribes and decodes the CDR it receives with rclpy -- the bridge alone beside a publisher,
and ``bb2-launch --foxglove PORT`` flying a mission."""
from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
pytest.importorskip("foxglove", reason="foxglove-sdk not installed (requirements.txt)")
ws_client = pytest.importorskip("websockets.sync.client", reason="websockets not installed (requirements.txt)")

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from bb2_msgs_py import conversions as conv  # noqa: E402
from bb2_msgs_py.contract import message_class, qos_profile, select_topics  # noqa: E402
from bb2_sim.state import VehicleState  # noqa: E402

from rosenv import ros_env  # noqa: E402  (tests/rosenv.py)

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parents[2]
PY = sys.executable
SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01  # server binary opcode: op (u8), subscription id (u32 LE), log time (u64 LE ns), payload


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class FoxgloveClient:
    """The client half of the Foxglove WebSocket protocol, as much as a viewer needs: the advertised channels,
    subscriptions, the message data frames."""

    def __init__(self, url: str, timeout_s: float = 60.0):
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                self._connection = ws_client.connect(url, subprotocols=[SUBPROTOCOL], open_timeout=5)
                self.ws = self._connection.__enter__()
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        self.channels: dict[str, dict] = {}
        self.server_info: dict = {}
        self._subs: dict[int, str] = {}
        self.pending: list[tuple[str, int, bytes]] = []

    def _take(self, timeout_s: float) -> None:
        frame = self.ws.recv(timeout=timeout_s)
        if isinstance(frame, bytes):
            op, sub, log_ns = struct.unpack_from("<BIQ", frame)
            if op == MESSAGE_DATA and sub in self._subs:
                self.pending.append((self._subs[sub], log_ns, frame[13:]))
            return
        msg = json.loads(frame)
        if msg["op"] == "serverInfo":
            self.server_info = msg
        elif msg["op"] == "advertise":
            self.channels.update({c["topic"]: c for c in msg["channels"]})

    def wait_for_channels(self, topics, timeout_s: float = 20.0) -> None:
        deadline = time.monotonic() + timeout_s
        while not set(topics) <= set(self.channels):
            assert time.monotonic() < deadline, sorted(self.channels)
            self._take(max(0.1, deadline - time.monotonic()))

    def subscribe(self, topics) -> None:
        subs = []
        for i, t in enumerate(topics, start=len(self._subs) + 1):
            self._subs[i] = t
            subs.append({"id": i, "channelId": self.channels[t]["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def messages(self, topic: str, n: int, timeout_s: float = 30.0) -> list[tuple[int, bytes]]:
        deadline = time.monotonic() + timeout_s
        while sum(1 for t, _, _ in self.pending if t == topic) < n:
            assert time.monotonic() < deadline, (topic, [t for t, _, _ in self.pending][:20])
            self._take(max(0.1, deadline - time.monotonic()))
        return [(ns, data) for t, ns, data in self.pending if t == topic]

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


def _bridge(domain_id: int, port: int) -> subprocess.Popen:
    p = subprocess.Popen([PY, "-m", "bb2_tools.foxglove_live", "--ros-args", "-p", f"port:={port}"], cwd=REPO,
                         env=ros_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if "serving" not in line:
        p.kill()
        raise AssertionError(f"bridge did not start: {line!r} {p.stderr.read()}")
    return p


def test_the_bridge_serves_every_contract_topic_and_the_derived_frames(tmp_path):
    from bb2_msgs_py.sensor_conversions import mountings_json
    from bb2_sim.sensors import load_suite_config
    from bb2_tools.bagfile import message_definition
    from bb2_tools.recorder import tf_cdr_from_odometry_cdr, tf_static_cdr_from_mountings_cdr

    domain_id, port = 160 + int(time.time()) % 30, free_port()
    bridge = _bridge(domain_id, port)
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    node = rclpy.create_node("foxglove_test_publisher", context=ctx)
    odom_pub = node.create_publisher(message_class("nav_msgs/msg/Odometry"), "/bb2/odom", qos_profile("/bb2/odom"))
    mount_pub = node.create_publisher(message_class("std_msgs/msg/String"), "/bb2/sensors/mountings",
                                      qos_profile("/bb2/sensors/mountings"))
    client = FoxgloveClient(f"ws://127.0.0.1:{port}")
    try:
        contract = [t for t in select_topics()]
        client.wait_for_channels([t.name for t in contract] + ["/tf", "/tf_static"])
        for t in contract:  # every topic, with the schema our bags carry
            ch = client.channels[t.name]
            assert (ch["encoding"], ch["schemaName"], ch["schemaEncoding"]) == ("cdr", t.type, "ros2msg"), ch
            assert ch["schema"] == message_definition(t.type), t.name
        client.subscribe(["/bb2/odom", "/tf", "/tf_static"])
        mountings = mountings_json(load_suite_config("tactical"), seed=2)
        mount_pub.publish(message_class("std_msgs/msg/String")(data=mountings))  # latched: sent once
        deadline = time.monotonic() + 20
        while odom_pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.5)
        sent = []
        for k in range(5):
            odom = conv.state_to_odometry(VehicleState.from_vector(10.0 + 0.05 * k, np.linspace(-1, 1, 12) * (k + 1)))
            sent.append(serialize_message(odom))
            odom_pub.publish(odom)
            time.sleep(0.05)
        got = client.messages("/bb2/odom", 5)
        odom_type = message_class("nav_msgs/msg/Odometry")
        # the publisher's messages (CDR padding bytes are unspecified: compared decoded)
        assert [deserialize_message(data, odom_type) for _, data in got[:5]] == \
            [deserialize_message(d, odom_type) for d in sent]
        first = deserialize_message(got[0][1], odom_type)
        assert first.header.stamp.sec == 10 and first.child_frame_id == "base_link"
        tfs = client.messages("/tf", 5)
        assert [data for _, data in tfs[:5]] == [tf_cdr_from_odometry_cdr(d) for _, d in got[:5]]
        (log_ns, static), = client.messages("/tf_static", 1)
        string = message_class("std_msgs/msg/String")
        assert static == tf_static_cdr_from_mountings_cdr(serialize_message(string(data=mountings)), log_ns)
    finally:
        client.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
        bridge.send_signal(2)
        out, err = bridge.communicate(timeout=20)
    assert bridge.returncode == 0, err


def test_bb2_launch_foxglove_serves_the_flying_graph(tmp_path):
    """`bb2-launch MISSION --foxglove PORT`: a client connected while the mission flies (real time) decodes the
    vehicle's odometry, one message per step in sim-time order (the first re-sent until the controllers answer it),
    and gets the latched scene when it subscribes to it mid-run; the launcher says where to connect and ends 0."""
    mission = tmp_path / "short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: fox\nduration_s: 12.0\n")
    port = free_port()
    p = subprocess.Popen([PY, "-m", "bb2_tools.launcher", str(mission), "--mode", "realtime", "--no-record",
                          "--foxglove", str(port), "--out", str(tmp_path / "run"), "--timeout", "240"],
                         cwd=tmp_path, env=ros_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    client = None
    try:
        client = FoxgloveClient(f"ws://127.0.0.1:{port}", timeout_s=90)
        client.wait_for_channels(["/bb2/odom", "/clock"], timeout_s=30)
        client.subscribe(["/bb2/odom"])
        n = 20
        while True:  # 20 messages at least, and a second of sim time past the first state's re-sends (as many as
            got = client.messages("/bb2/odom", n, timeout_s=120)  # the controllers took to come up)
            odoms = [deserialize_message(d, message_class("nav_msgs/msg/Odometry")) for _, d in got]
            stamps = [o.header.stamp.sec + o.header.stamp.nanosec * 1e-9 for o in odoms]
            if stamps[-1] >= 1.0 or n >= 200:
                break
            n += 20
        # (the first state is re-sent until the controllers answer it, wait_for_commands; then one per step; a
        # client that subscribed once the controllers had answered, as on a fast machine, starts on a later step)
        first = next((i for i, t in enumerate(stamps) if t > 0.0), len(stamps))
        assert set(stamps[:first]) <= {0.0} and first < len(stamps), stamps
        steps = stamps[max(first - 1, 0):]
        assert all(b > a for a, b in zip(steps, steps[1:])), stamps
        assert all((o.header.frame_id, o.child_frame_id) == ("odom", "base_link") for o in odoms)
        logs = [ns for ns, _ in got]  # log times: the bridge's sim-time clock
        assert all(b >= a for a, b in zip(logs, logs[1:])) and 0 < logs[-1] <= 12.0e9 + 1, logs[:3]
        # a viewer subscribing mid-run to the latched scene still gets it (the hull, published at the start), and
        # the map -> odom frame derived from it
        client.subscribe(["/bb2/scene/markers", "/tf_static"])
        (_, scene), = client.messages("/bb2/scene/markers", 1, timeout_s=30)[:1]
        markers = deserialize_message(scene, message_class("visualization_msgs/msg/MarkerArray")).markers
        assert [m.ns for m in markers][:1] == ["bb2/hull"] and markers[0].header.frame_id == "base_link"
        client.messages("/tf_static", 1, timeout_s=30)
    finally:
        if client is not None:
            client.close()
        try:
            _, err = p.communicate(timeout=240)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
    assert p.returncode == 0, err
    assert f"[bb2-launch] foxglove: ws://127.0.0.1:{port}" in err, err
    assert "ended (" not in err, err


def test_bb2_launch_refuses_a_taken_foxglove_port(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        p = subprocess.run([PY, "-m", "bb2_tools.launcher", str(REPO / "missions" / "straight.yaml"), "--foxglove",
                            str(port), "--out", str(tmp_path / "run")], cwd=tmp_path, env=ros_env(),
                           capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and f"--foxglove {port}: the port is not free" in p.stderr, p.stderr
    assert not (tmp_path / "run").exists()
