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
    mine, other = _fake_daemon(231), _fake_daemon(23)
    try:
        time.sleep(0.2)
        assert stop_ros2_daemons([231, 232]) == [mine.pid]
        assert mine.wait(10) != 0
        time.sleep(0.2)
        assert other.poll() is None
    finally:
        for p in (mine, other):
            p.kill()
            p.wait()
