"""The ros2 CLI daemons a test process leaves (one per domain it used) end with it (tests/rosenv.py)."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rosenv import stop_ros2_daemons  # noqa: E402


def _fake_daemon(domain: int) -> subprocess.Popen:
    """A process whose command line reads like ``ros2 daemon``'s on ``domain``."""
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)", "-c",
                             "from ros2cli.daemon.daemonize import main; main()", "--name", "ros2-daemon",
                             "--ros-domain-id", str(domain), "--rmw-implementation", "rmw_fastrtps_cpp"])


def test_only_the_daemons_of_the_given_domains_are_stopped():
    # domains no ROS participant can use (ROS 2 allows 0..232): no real daemon of another test process matches
    mine, other = _fake_daemon(241), _fake_daemon(243)
    try:
        time.sleep(0.2)
        assert stop_ros2_daemons([241, 242]) == [mine.pid]
        assert mine.wait(10) != 0
        time.sleep(0.2)
        assert other.poll() is None
    finally:
        for p in (mine, other):
            p.kill()
            p.wait()
