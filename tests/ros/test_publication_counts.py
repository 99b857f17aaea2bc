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
