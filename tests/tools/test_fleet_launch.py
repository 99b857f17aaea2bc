"""Issue 13, point 4: ``bb2-launch FLEET.yaml`` -- a fleet file flown through one ROS graph over real DDS: every
boat in its namespace with its own mission, one recorder for all, one bag that ``bb2-analyze`` reports per boat."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rosenv import library_trajectory, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90)]


def _fleet(tmp: Path, duration_s: float, duration2_s: float | None = None) -> Path:
    """boat1: the canyon as it is; boat2: the straight line from 20 m to its side (both shortened)."""
    (tmp / "c.yaml").write_text(f"extends: {REPO / 'missions' / 'canyon.yaml'}\nname: c\nduration_s: {duration_s}\n")
    (tmp / "s.yaml").write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: s\n"
                                f"duration_s: {duration2_s or duration_s}\n")
    f = tmp / "pair.yaml"
    f.write_text("name: pair\nboats:\n  boat1: c.yaml\n  boat2:\n    mission: s.yaml\n"
                 "    initial: {offset_m: [0.0, 20.0, 0.0]}\n")
    return f


def test_a_fleet_file_flies_every_boat_into_one_bag_each_boat_as_alone(tmp_path):
    pytest.importorskip("rclpy")
    from bb2_tools.bag_run import read_bag
    from bb2_tools.bagfile import BagReader

    fleet = _fleet(tmp_path, 3.0)
    p = subprocess.run([PY, "-m", "bb2_tools.launch_cli", str(fleet), "--bag-dir", str(tmp_path / "bags"),
                        "--timeout", "200"], cwd=tmp_path, env=ros_env(), capture_output=True, text=True, timeout=260)
    assert p.returncode == 0, p.stderr[-4000:]
    assert re.search(r"\[bb2-launch\] fleet pair: every boat ended, wall [0-9.]+ s, exit code 0", p.stderr), p.stderr
    assert "[boat1] [bb2-launch] mission complete: sim time 3.00 s" in p.stderr  # each boat's launcher, prefixed
    (run,) = (tmp_path / "bags").iterdir()
    assert run.name.startswith("pair_") and (run / "missions" / "boat2.yaml").is_file()
    bag = BagReader(run)
    assert bag.vehicles == ["boat1", "boat2"] and not bag.truncated and "/diagnostics" not in bag.topics
    assert {"/boat1/bb2/state_native", "/boat2/bb2/planes/cmd", "/boat1/clock", "/tf"} <= set(bag.topics)
    # each boat equals its mission flown by the library runner (lockstep: deterministic, no crosstalk)
    for boat, mission in (("boat1", tmp_path / "c.yaml"), ("boat2", run / "missions" / "boat2.yaml")):
        ref = library_trajectory(mission)
        got = read_bag(run, vehicle=boat)
        assert got.x.shape == (len(ref), 12) and not got.warnings, (boat, got.x.shape, got.warnings)
        assert np.max(np.abs(got.x - ref[:, 1:])) <= 1e-9, boat
        assert BagReader(run, boat).vehicle_base_link() == f"{boat}/base_link"
        # its simulator's statuses reached the bag, the final one too (a finished run waits for their delivery:
        # on a short run the recorder's reader may match the status writer only after the last step)
        sim = [e.values["state"] for e in got.status if e.name == "bb2/simulator"]
        assert sim and sim[-1] == "finished", (boat, sim)
    assert read_bag(run, vehicle="boat2").x[0, 1] == 20.0  # its own start: the fleet file's offset
    # each boat's nodes logged under its own run folder; the fleet's recorder and boat launchers in logs/
    assert (run / "boat1" / "logs" / "simulator.log").is_file() and (run / "logs" / "recorder.log").is_file()
    # the fleet's bag opens in rosbags (the ROS-free reader) with every boat's topics, as the mcap library reads them
    from rosbags.highlevel import AnyReader

    with AnyReader([run]) as rb:
        assert {c.topic: c.msgcount for c in rb.connections} == bag.message_counts
    a = subprocess.run([PY, "-m", "bb2_tools.analyze", str(run), "--no-report"], env=ros_env(), capture_output=True,
                       text=True, timeout=200)
    assert a.returncode == 0 and "fleet  2 vehicles: boat1, boat2" in a.stdout, a.stderr


def test_a_boat_that_fails_is_said_and_the_others_fly_on(tmp_path):
    """boat2's simulator killed mid-run: its launcher says so and exits 1; boat1 completes its mission and its part
    of the bag is whole; the fleet's exit code is 1 and names boat2."""
    pytest.importorskip("rclpy")
    from bb2_tools.bagfile import BagReader

    fleet = _fleet(tmp_path, 12.0, 120.0)  # boat2 still flying when it is killed
    p = subprocess.Popen([PY, "-m", "bb2_tools.launch_cli", str(fleet), "--bag-dir", str(tmp_path / "bags"),
                          "--timeout", "200"], cwd=tmp_path, env=ros_env(), stderr=subprocess.PIPE,
                         stdout=subprocess.DEVNULL, text=True)
    try:
        pid, t0 = None, time.monotonic()
        while pid is None and time.monotonic() - t0 < 120 and p.poll() is None:
            time.sleep(0.2)
            logs = list((tmp_path / "bags").glob("pair_*/boat2/logs/simulator.log"))
            if logs and "simulator up" in logs[0].read_text(errors="replace"):
                time.sleep(2.0)  # into its run (or still starting: killed either way)
                pid = _simulator_pid("boat2")
        assert pid is not None, "boat2's simulator never started stepping"
        import os
        import signal

        os.kill(pid, signal.SIGKILL)
        err = p.communicate(timeout=240)[1]
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 1, err[-4000:]
    assert "[boat2] [bb2-launch] stopping: node 'simulator' failed (killed by SIGKILL)" in err, err[-4000:]
    assert "[bb2-launch] /boat1: mission complete: sim time 12.00 s" in err, err[-4000:]
    assert re.search(r"fleet pair: every boat ended \(boat2 failed\), wall [0-9.]+ s, exit code 1", err), err
    (run,) = (tmp_path / "bags").iterdir()
    b1 = sorted({round(m.data[0], 6) for _n, _t, m in BagReader(run, "boat1").messages("/bb2/state_native")})
    assert len(b1) == 241 and b1[-1] == 12.0  # boat1's every state, 0 .. 12 s


def _simulator_pid(boat: str) -> int | None:
    for stat in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            cmd = stat.read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if re.search(r"(bb2_ros\.simulator:main|lib/bb2_ros/simulator\b|bb2_ros simulator\b)", cmd) \
                and f"__ns:=/{boat} " in cmd + " ":
            return int(stat.parent.name)
    return None


def test_a_fleet_launch_refuses_bad_input_with_one_line_before_anything_starts(tmp_path, capsys):
    from bb2_tools import launch_cli as L

    fleet = _fleet(tmp_path, 3.0)
    bad = tmp_path / "bad.yaml"
    bad.write_text("boats:\n  boat1: c.yaml\n  boat2: nowhere.yaml\n")
    for argv, why in (([str(fleet), "--namespace", "x"], "--namespace: a fleet file's boats are the namespaces"),
                      ([str(fleet), "--foxglove"], "--foxglove is not available for a fleet file"),
                      ([str(fleet), "--external-recorder"], "starts the fleet's recorder itself"),
                      ([str(fleet), "--timeout", "-1"], "--timeout must be > 0"),
                      ([str(bad)], "boat 'boat2': no mission 'nowhere.yaml'")):
        assert L.main([*argv, "--bag-dir", str(tmp_path / "bags")]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("bb2-launch: error: ") and why in err[0], (argv, err)
    assert not (tmp_path / "bags").exists()  # nothing claimed, nothing started
    from bb2_tools import launcher  # the mission launcher alone says where a fleet file goes

    assert launcher.main([str(fleet), "--bag-dir", str(tmp_path / "bags")]) == 2
    assert "is a fleet file: run it with bb2-launch" in capsys.readouterr().err
