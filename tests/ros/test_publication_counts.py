"""Each node process counts what it publishes and writes the counts as it exits (``bb2_ros.node_common``:
``contract_publisher``, ``write_publication_counts``), so the launcher can compare them with the bag and find
losses the sequence numbers cannot show.  Here: a real rclpy node in its own process, through ``run_node``."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from rosenv import claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.ros

SCRIPT = textwrap.dedent("""
    import sys
    from rclpy.node import Node
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    from bb2_ros.node_common import contract_publisher, run_node

    class Talker(Node):
        def __init__(self):
            super().__init__("talker")
            self.pub = contract_publisher(self, "/bb2/mission/progress")
            self.plain = self.create_publisher(Float64, "/not_counted", 10)  # not a contract publisher
            for k in range(3):
                self.pub.publish(Float64(data=float(k)))
            for k in range(2):
                self.pub.publish(serialize_message(Float64(data=-1.0)))   # raw bytes count too
            self.plain.publish(Float64(data=0.0))
            self.done = True
            self.exit_code = int(sys.argv[1])

    sys.exit(run_node("talker", lambda argv: Talker(), ["talker"]))
""")


@pytest.mark.parametrize("code", [0, 1])
def test_a_node_process_writes_what_it_published_as_it_exits(tmp_path, code):
    pytest.importorskip("rclpy")
    from bb2_ros.node_common import PUBLISHED_DIR_ENV

    env = ros_env(domain_id=claimed_domain())
    env[PUBLISHED_DIR_ENV] = str(tmp_path / "published")
    p = subprocess.run([sys.executable, "-c", SCRIPT, str(code)], cwd=REPO, env=env, capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == code, p.stderr
    files = list((tmp_path / "published").iterdir())
    assert [f.name.split("-")[0] for f in files] == ["talker"] and files[0].suffix == ".json", files
    doc = json.loads(files[0].read_text())
    assert doc["process"] == "talker" and f"talker-{doc['pid']}.json" == files[0].name, doc
    assert doc["published"] == {"/bb2/mission/progress": 5}, doc  # 3 messages + 2 raw; the plain one not counted
    # without the variable nothing is written
    env.pop(PUBLISHED_DIR_ENV)
    q = subprocess.run([sys.executable, "-c", SCRIPT, "0"], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=60)
    assert q.returncode == 0 and len(list((tmp_path / "published").iterdir())) == 1, q.stderr


BURST = textwrap.dedent("""
    import sys, time
    from rclpy.node import Node
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image
    from bb2_ros import node_common

    N, SIZE = int(sys.argv[1]), int(sys.argv[2])
    node_common.DELIVERY_AT_EXIT_S = float(sys.argv[3])
    QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)

    class Burst(Node):
        def __init__(self):
            super().__init__("burst")
            self.pub = self.create_publisher(Image, "/burst", QOS)
            t0 = time.monotonic()
            while self.pub.get_subscription_count() == 0 and time.monotonic() - t0 < 30:
                time.sleep(0.05)
            payload = bytes(SIZE)
            for k in range(N):  # then the process stops at once: the writer's samples are still on their way
                self.pub.publish(Image(height=1, width=SIZE, encoding="mono8", step=SIZE, data=payload))
            self.done = True

    sys.exit(node_common.run_node("burst", lambda argv: Burst(), ["burst"]))
""")

LISTEN = textwrap.dedent("""
    import sys, time
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    rclpy.init()
    node = rclpy.create_node("listen")
    got = []
    QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(Image, "/burst", lambda m: got.append(len(m.data)), QOS)
    print("ready", flush=True)
    t0 = last = time.monotonic()
    n = -1
    while time.monotonic() - t0 < 60 and (n != len(got) or time.monotonic() - last < 3.0 or not got):
        if n != len(got):
            n, last = len(got), time.monotonic()
        rclpy.spin_once(node, timeout_sec=0.05)
    print(len(got), flush=True)
""")


def test_a_node_process_delivers_what_its_reliable_writers_published_before_it_exits(tmp_path):
    """A node told to stop (here: ``done`` right after a burst) first waits, a bounded time, for its reliable readers
    to acknowledge every sample (``deliver_pending``): a writer destroyed with samples on their way takes them with
    it.  Seen: a controller's last ``/bb2/status``, published by its timer just before the launcher's SIGINT, missing
    from the bag.  The burst (many large samples) is still in flight when the publisher is done; every one of them
    reaches the reader.  (The wait is 4 s here, below the process's teardown bound ``TEARDOWN_S``, for a loaded
    machine; without it, 1 to 2 of the 40 arrived.)"""
    pytest.importorskip("rclpy")
    env = ros_env(domain_id=claimed_domain())
    listener = subprocess.Popen([sys.executable, "-c", LISTEN], cwd=REPO, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    try:
        assert listener.stdout.readline().strip() == "ready", listener.stderr.read()
        n = 40
        p = subprocess.run([sys.executable, "-c", BURST, str(n), str(1_000_000), "4"], cwd=REPO, env=env,
                           capture_output=True, text=True, timeout=90)
        assert p.returncode == 0, p.stderr
        out, err = listener.communicate(timeout=90)
        assert out.strip() == str(n), (out, err[-2000:])
    finally:
        listener.kill()
