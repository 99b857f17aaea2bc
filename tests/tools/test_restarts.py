"""Issue 10, point 3: restarts that resume or refuse, on the real graph.

A path follower killed mid-run and restarted by ``bb2-launch --restart path_following=restart:1`` rejoins the run
where it stands: its virtual time goes to the path point closest to the vehicle (not the path's start), so the
mission completes with path errors as small as before the fault.  (The simulator's restart is refused up front:
tests/tools/test_exit_codes.py and test_launcher.py.)
"""
from __future__ import annotations

import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest

from rosenv import launch_with_fault, node_pid  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.ros


def test_path_following_restarted_mid_run_rejoins_where_the_vehicle_is(tmp_path):
    pytest.importorskip("rclpy")
    from bb2_tools.bag_run import read_bag

    mission = tmp_path / "canyon_short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon.yaml'}\nname: canyon_short\nduration_s: 90\n")
    out = tmp_path / "run"
    code, err = launch_with_fault(  # killed past 20 s of the 90
        mission, out, "--restart", "path_following=restart:1", min_sim_s=20.0,
        fault=lambda: os.kill(node_pid("path_following", str(mission)), signal.SIGKILL))
    assert code == 0, err[-4000:]
    assert re.search(r"path_following.*SIGKILL", err), err[-3000:]
    log = (out / "logs" / "path_following.log").read_text()
    m = re.search(r"joined a run under way at t = ([0-9.]+) s: virtual time set to the closest path point, "
                  r"gamma = ([0-9.]+) s \(([0-9.]+) m from the vehicle\)", log)
    assert m, log[-3000:]
    t_join, gamma, dist = (float(v) for v in m.groups())
    # where the vehicle is, 50 m or more along the path from its start (20 s at 2.5 m/s)
    assert 20.0 <= t_join < 90.0 and dist < 10.0 and abs(gamma - t_join) < 30.0, m.group(0)
    run = read_bag(out)
    e = run.path_error
    after = e.t > t_join
    assert after.sum() > 100, (t_join, len(e))
    # the path follower's own errors after it rejoined stay at the size of a normal run (a follower that started
    # again from the path's start would see the vehicle hundreds of metres from its desired point)
    assert np.max(np.abs(e.v[after, 1:])) < 10.0, np.max(np.abs(e.v[after]), axis=0)
    assert abs(run.progress.v[-1, 0] - run.t[-1] / 475.0) < 0.1   # progress continued from where it stood
