"""Issue 15, point 2: the nodes composed into one process (``bb2-launch --compose`` / ``--group``).

* the composed graph (every composable node in one process, and a partial grouping) equals the graph of one process
  per node and the library runner, step by step (lockstep, 1e-9 m), every node reporting from its container;
* the container takes each node's arguments for that node alone, refuses bad command lines with one line;
* a composed process that is killed is reported like any node, and the bag is still finished.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rosenv import (last_statuses, launch_with_fault, library_trajectory, node_pid,  # noqa: E402
                    ros_env)  # (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable
DURATION_S = 20.0
H = 0.05


# ------------------------------------------------------------------------------------ without ROS
def test_compose_groups_names_and_the_container_command(tmp_path):
    from bb2_tools.launcher import COMPOSABLE, compose_groups, graph_specs, process_name, process_names
    from bb2_tools.supervisor import LaunchError

    assert compose_groups(None) == []
    assert compose_groups([]) == [COMPOSABLE]
    assert compose_groups(["mixer,path_following", " l1_autopilot "]) == [("path_following", "mixer"),
                                                                          ("l1_autopilot",)]
    for bad, why in ((["mixer,recorder"], "recorder cannot be composed"), (["mixer,nope"], "unknown node 'nope'"),
                     (["mixer", "mixer,simulator"], "'mixer' is in two groups"), ([","], "no node named")):
        with pytest.raises(LaunchError, match=why):
            compose_groups(bad)
    assert process_name(COMPOSABLE) == "container"
    assert process_name(("path_following", "mixer")) == "path_following+mixer"
    assert process_names([COMPOSABLE]) == ["recorder", "container"]

    groups = compose_groups(["path_following,l1_autopilot,mixer"])
    specs = graph_specs(tmp_path / "m.yaml", tmp_path / "run", groups=groups, runner="python")
    assert [s.name for s in specs] == ["recorder", "planner", "path_following+l1_autopilot+mixer", "simulator"]
    cmd = specs[2].command(0)
    assert "bb2_ros.container" in " ".join(cmd)
    nodes = [cmd[i + 1] for i, a in enumerate(cmd) if a == "--node"]
    assert nodes == ["path_following", "l1_autopilot", "mixer"]
    # each node's own ROS arguments, closed by '--'; a restart makes the path following rejoin the run
    first = cmd[cmd.index("--node"):cmd.index("--node", cmd.index("--node") + 1)]
    assert first[2] == "--ros-args" and first[-1] == "--" and "use_sim_time:=true" in first
    assert "rejoin_run:=true" not in cmd and "rejoin_run:=true" in specs[2].command(1)
    assert "recorder_ack_window:=10" in specs[3].command(0)
    alone = graph_specs(tmp_path / "m.yaml", tmp_path / "run", runner="python")
    assert [s.name for s in alone] == ["recorder", "planner", "path_following", "l1_autopilot", "mixer",
                                       "simulator"]


@pytest.mark.parametrize("args,why", [([], "expected --node NAME"), (["mixer"], "expected --node NAME"),
                                      (["--node"], "needs a node name"),
                                      (["--node", "recorder"], r"unknown node\(s\) \['recorder'\]"),
                                      (["--node", "mixer", "--node", "mixer"], "given twice")])
def test_the_container_refuses_a_bad_command_line_with_one_line(args, why):
    r = subprocess.run([PY, "-m", "bb2_ros.container", *args], capture_output=True, text=True, env=ros_env(),
                       timeout=60)
    assert r.returncode == 2, r
    assert re.search(why, r.stderr) and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_bb2_launch_refuses_a_restart_of_a_composed_simulator(tmp_path):
    r = subprocess.run([PY, "-m", "bb2_tools.launcher", str(REPO / "missions" / "straight.yaml"), "--compose",
                        "--restart", "container=restart:1", "--out", str(tmp_path / "x")], capture_output=True,
                       text=True, env=ros_env(), timeout=60)
    assert r.returncode == 2 and "composed in 'container', which restarts as a whole" in r.stderr, r.stderr
    r = subprocess.run([PY, "-m", "bb2_tools.launcher", str(REPO / "missions" / "straight.yaml"), "--compose",
                        "--restart", "mixer=restart", "--out", str(tmp_path / "y")], capture_output=True, text=True,
                       env=ros_env(), timeout=60)
    assert r.returncode == 2 and "mixer" in r.stderr and not (tmp_path / "y").exists(), r.stderr


# ------------------------------------------------------------------------------------ the graph, composed
def _status_names(bag: Path) -> set[str]:
    return set(last_statuses(bag))


@pytest.fixture(scope="module")
def canyon_20s(tmp_path_factory) -> tuple[Path, np.ndarray]:
    d = tmp_path_factory.mktemp("compose")
    mission = d / "canyon_short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'canyon.yaml'}\nname: canyon_short\nduration_s: {DURATION_S}\n")
    return mission, library_trajectory(mission)


LAYOUTS = {"one process per node": [], "composed": ["--compose"],
           "control loop composed": ["--group", "path_following,l1_autopilot,mixer"]}


@pytest.mark.ros
@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_the_graph_composed_or_not_equals_the_library_runner(tmp_path, canyon_20s, layout):
    """Every layout flies the same steps: the simulator's own trajectory (every step, %.17g) equals the library
    runner's within 1e-9 m, every node reports its status into the bag, the launcher saw all six nodes."""
    pytest.importorskip("rclpy")
    mission, ref = canyon_20s
    csv_file = tmp_path / "traj.csv"
    params = tmp_path / "params.yaml"
    params.write_text(f"simulator:\n  ros__parameters:\n    trajectory_csv: {csv_file}\n")
    out = tmp_path / "run"
    r = subprocess.run([PY, "-m", "bb2_tools.launcher", str(mission), "--out", str(out), "--params", str(params),
                        "--end-at", "simulator", "--timeout", "300", "--status-period", "1000", *LAYOUTS[layout]],
                       capture_output=True, text=True, env=ros_env(), timeout=400, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-4000:]
    # the status line of the end (with a status period of 1000 s, the others are the first loop's at most; a
    # composed 20-s mission may fly within the launcher's start-up): where it stopped, every node up; and the
    # closing line's sim time
    status = [ln for ln in r.stderr.splitlines() if ln.startswith("[bb2-launch] sim ")]
    assert 1 <= len(status) <= 2 and "nodes 6/6" in status[-1] and f"sim {DURATION_S:8.2f} s" in status[-1], \
        r.stderr[-3000:]
    assert f"mission complete: sim time {DURATION_S:.2f} s" in r.stderr, r.stderr[-3000:]
    assert "stopping anyway" not in r.stderr, r.stderr[-3000:]  # the launcher learnt that the recorder holds the end
    if layout == "composed":
        assert "composed: process 'container' runs planner, path_following, l1_autopilot, mixer, simulator" \
            in r.stderr
        logs = {p.name for p in (out / "logs").glob("*.log")}
        assert {"recorder.log", "container.log"} <= logs and "simulator.log" not in logs, logs
        # the four nodes on sim time (not the simulator, which publishes /clock) take it through one subscription
        assert "4 nodes of this process on sim time take /clock through one subscription" \
            in (out / "logs" / "container.log").read_text()
    elif layout == "control loop composed":
        log = out / "logs" / "path_following+l1_autopilot+mixer.log"
        assert "3 nodes of this process on sim time take /clock through one subscription" in log.read_text()
    traj = np.loadtxt(csv_file, delimiter=",", skiprows=1)
    assert traj.shape == ref.shape == (int(round(DURATION_S / H)) + 1, 13)
    np.testing.assert_array_equal(traj[:, 0], ref[:, 0])
    assert np.max(np.abs(traj[:, 1:] - ref[:, 1:])) <= 1e-9, layout
    assert np.ptp(ref[:, 1]) > 50.0  # the vehicle really travelled
    assert {"bb2/simulator", "bb2/planner", "bb2/path_following", "bb2/l1_autopilot", "bb2/mixer"} \
        <= _status_names(out), _status_names(out)
    # every node process settled its start-up heap before spinning (bb2_ros.heap): frozen, and the collections
    # since then measured (composed nodes share one collector and say the same)
    statuses = last_statuses(out)
    for name, st in statuses.items():  # (the recorder imports less than a node: neither the ROM nor the stacks)
        assert int(st["gc_frozen_objects"]) > (20_000 if name == "bb2/recorder" else 50_000) and int(st["gc_collections"]) >= 0 \
            and float(st["gc_pause_max_ms"]) >= 0.0, (name, st)
        # and what the process spent: the main thread's CPU (every callback) within the whole process's
        assert 0.0 < float(st["cpu_main_thread_s"]) <= float(st["cpu_process_s"]), (name, st)
    # one process per group: its nodes say the same process (benchmarks/graph_speed.py counts its CPU once)
    pids = {name.removeprefix("bb2/"): st["process_id"] for name, st in statuses.items()}
    groups = {"one process per node": [["simulator"], ["planner"], ["path_following"], ["l1_autopilot"], ["mixer"]],
              "composed": [["simulator", "planner", "path_following", "l1_autopilot", "mixer"]],
              "control loop composed": [["simulator"], ["planner"], ["path_following", "l1_autopilot", "mixer"]]
              }[layout] + [["recorder"]]  # the recorder always in a process of its own, saying its status too
    assert sorted(sorted(n for n in pids if pids[n] == pid) for pid in set(pids.values())) \
        == sorted(sorted(g) for g in groups), pids
    assert "recording complete: no gaps" in r.stderr, r.stderr[-3000:]


@pytest.mark.ros
def test_a_killed_container_is_reported_like_any_node_and_the_bag_is_finished(tmp_path):
    pytest.importorskip("rclpy")
    mission = tmp_path / "straight600.yaml"  # long enough to be running when the monitor's first line comes
    mission.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: straight600\nduration_s: 600\n")
    out = tmp_path / "run"
    code, err = launch_with_fault(mission, out, "--compose", min_sim_s=5.0, timeout_s=300,
                                  fault=lambda: os.kill(node_pid("container", str(mission)), signal.SIGKILL))
    assert code == 1, err[-3000:]
    assert re.search(r"node 'container' (ended|failed) \(.*SIGKILL", err), err[-3000:]
    from bb2_tools.bagfile import read_metadata

    meta = read_metadata(out)
    assert meta["message_count"] > 0, meta
