"""Issue 12, point 3, through the ROS graph: with ``navigation: sensors`` the simulator's navigation filter
publishes its estimate on ``/bb2/nav/state_native`` with every state, the controllers fly on it, and the lockstep
run equals the library runner's (the truth and the estimate, every step)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rosenv import ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
DURATION_S = 10.0


def _library(mission: Path):
    """The runner's truth ``t -> x12``, the estimate it flew on ``t -> x12``, every step, and its summary."""
    from bb2_mission import MissionRunner, load_mission

    r = MissionRunner(load_mission(mission))
    truth, est, rows = {}, {}, []
    while not r.done:
        est[r.sim.t] = r.nav.state(r.sim.t).as_vector()   # what the stack gets this tick (idempotent)
        truth[r.sim.t] = r.sim.x.copy()
        rows.append(r.step().row)
    truth[r.sim.t] = r.sim.x.copy()
    est[r.sim.t] = r.nav.state(r.sim.t).as_vector()
    return truth, est, rows


def _bag_states(bag: Path, topic: str) -> dict[float, np.ndarray]:
    from bb2_tools.bagfile import BagReader

    out: dict[float, np.ndarray] = {}
    for _name, _t, msg in BagReader(bag).messages(topic):
        d = np.array(msg.data, dtype=float)
        if d[0] in out:
            assert np.array_equal(out[d[0]], d[1:]), "a re-sent state differs"
        out[float(d[0])] = d[1:]
    return out


@pytest.mark.ros
def test_the_lockstep_graph_flies_on_the_navigation_estimate_as_the_runner_does(tmp_path):
    pytest.importorskip("rclpy")
    mission = tmp_path / "canyon_nav.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon.yaml'}\nname: canyon_nav\nduration_s: {DURATION_S}\n"
                       "sensors: {suite: mems, seed: 5}\nnavigation: sensors\n")
    truth, est, rows = _library(mission)
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out),
                        "--end-at", "simulator", "--timeout", "300"], capture_output=True, text=True,
                       env=ros_env(), timeout=400, cwd=tmp_path)
    assert r.returncode == 0 and "mission complete" in r.stderr, r.stderr[-4000:]
    bag_truth = _bag_states(out, "/bb2/state_native")
    bag_est = _bag_states(out, "/bb2/nav/state_native")
    assert sorted(bag_truth) == sorted(truth) and sorted(bag_est) == sorted(truth)   # every step, both
    assert len(truth) == int(round(DURATION_S / 0.05)) + 1
    for t in truth:
        assert np.max(np.abs(bag_truth[t] - truth[t])) <= 1e-9, t
        assert np.max(np.abs(bag_est[t] - est[t])) <= 1e-9, t
    # the estimate is not the truth: the graph's controllers flew on something else than /bb2/state_native
    last = max(truth)
    assert np.linalg.norm(bag_est[last][0:3] - bag_truth[last][0:3]) > 0.01
    # bb2-analyze says the estimate's errors, as the runner's summary does
    from bb2_mission.summary import rms_max
    from bb2_tools.analysis import analyze
    from bb2_tools.bag_run import read_bag

    f = analyze(read_bag(out)).figures.named()
    rms, mx = rms_max(np.array([row.nav_position_error_m for row in rows]))
    assert f["rms_nav_error_m"] == pytest.approx(rms, abs=1e-9) and f["max_nav_error_m"] == pytest.approx(mx, abs=1e-9)
    psi = rms_max(np.array([row.nav_heading_error_deg for row in rows]))[1]
    assert f["max_nav_heading_error_deg"] == pytest.approx(psi, abs=1e-9)
