"""Issue 15, point 3: the real-time loop, through ``bb2-launch --mode realtime`` over real DDS.

* ``realtime_loop`` executor (the default): the simulator steps on the thread that spins its process's executor, so
  in a composed graph the controllers answer a state on the thread that published it, within the same turn: every
  step's answer is in before the step's other samples go out (``samples_after_wait`` 0), however loaded the machine,
  as long as the controllers' callbacks fit in the wait (``answer_first_s``, at most half a period: it bounds the
  samples' delay, the turn's own work included; on a machine 5x slower than the fast ones of this kind the composed
  controllers' callbacks take ~5 ms, so that test flies at 20 Hz, real time, with a 25-ms wait);
* ``answer_first_s``: a step's IMU, plane/propeller states, depth and altitude go out after the controllers'
  plane command to its state (DDS source timestamps in the bag), or after the wait; 0 = at once, before any answer;
* ``realtime_loop`` thread (a stepping thread of its own) flies the same graph.

No wall-clock bound is asserted (the latency figures are ``benchmarks/graph_speed.py``'s): the order of the
publications and the simulator's own counts are.
"""
from __future__ import annotations

import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

from rosenv import last_statuses, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable
SIM_S = 10.0  # at 100 Hz (5x real time): 200 steps in 2 s of wall time

pytestmark = [pytest.mark.ros]


def _fly(tmp_path: Path, name: str, *launch_args: str, sim_s: float = SIM_S, rate_hz: float = 100.0,
         **sim_params) -> tuple[Path, str]:
    """A real-time straight mission of ``sim_s`` at ``rate_hz`` steps a second through bb2-launch; (bag, stderr)."""
    mission = tmp_path / f"{name}.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nname: {name}\nduration_s: {sim_s}\n")
    params = tmp_path / f"{name}_params.yaml"
    extra = "".join(f"    {k}: {v}\n" for k, v in sim_params.items())
    params.write_text(f"simulator:\n  ros__parameters:\n    rate_hz: {rate_hz}\n{extra}")
    out = tmp_path / name
    r = subprocess.run([PY, "-m", "bb2_tools.launcher", str(mission), "--out", str(out), "--mode", "realtime",
                        "--params", str(params), "--end-at", "simulator", "--timeout", "300", *launch_args],
                       capture_output=True, text=True, env=ros_env(), timeout=400, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-4000:]
    return out, r.stderr


def _sent(bag: Path, topics: tuple[str, ...]) -> dict[str, dict[int, int]]:
    """topic -> header stamp (ns) -> the DDS source timestamp (ns) of its first publication, from the bag."""
    from bb2_tools.bagfile import BagReader

    out: dict[str, dict[int, int]] = defaultdict(dict)
    for m, msg in BagReader(bag).decoded_messages(list(topics)):
        st = msg.header.stamp
        out[m.topic].setdefault(int(st.sec) * 1_000_000_000 + int(st.nanosec), m.publish_time_ns)
    return out


def _samples_after_the_answer(bag: Path) -> tuple[int, int]:
    """(steps whose IMU sample went out after the plane command answering the state of the step's end, steps
    compared).  The IMU sample of ``[t_n, t_n+1)`` is stamped t_n; the answer to the state of t_n+1 is stamped
    t_n+1."""
    sent = _sent(bag, ("/bb2/imu", "/bb2/planes/cmd"))
    imu, cmd = sent["/bb2/imu"], sent["/bb2/planes/cmd"]
    steps = sorted(imu)
    pairs = [(imu[a], cmd[b]) for a, b in zip(steps, steps[1:]) if b in cmd]
    return sum(i > c for i, c in pairs), len(pairs)


def test_composed_the_controllers_answer_on_the_stepping_thread_before_the_samples_go_out(tmp_path):
    pytest.importorskip("rclpy")
    sim_s = 5.0  # real time (20 Hz): 100 steps, a 25-ms wait for the answer
    out, err = _fly(tmp_path, "composed", "--compose", sim_s=sim_s, rate_hz=20.0, answer_first_s=0.025)
    st = last_statuses(out)
    sim = st["bb2/simulator"]
    steps = int(sim["step"])
    assert steps == round(sim_s / 0.05), sim
    after, waited = int(sim["samples_after_answer"]), int(sim["samples_after_wait"])
    # every step but the last (its samples go with the end) held its samples for the answer; on the stepping thread
    # the answer comes in the same turn: none waited out answer_first_s, even beside CPU hogs (SCHED_FIFO)
    assert after + waited == steps - 1 and waited == 0, sim
    for name in ("bb2/path_following", "bb2/l1_autopilot", "bb2/mixer"):
        assert "on the simulator's stepping thread: realtime_loop executor" in st[name]["callback_scheduling"], \
            (name, st[name])
    ordered, pairs = _samples_after_the_answer(out)
    assert pairs >= steps - 2 and ordered >= after - 1, (ordered, pairs, sim)
    assert "recording complete: no gaps" in err, err[-3000:]


@pytest.mark.parametrize("answer_first_s", [0.005, 0.0])
def test_one_process_per_node_the_samples_wait_for_the_answer_or_go_at_once(tmp_path, answer_first_s):
    pytest.importorskip("rclpy")
    out, err = _fly(tmp_path, f"alone_{answer_first_s:g}", answer_first_s=answer_first_s)
    sim = last_statuses(out)["bb2/simulator"]
    steps = int(sim["step"])
    assert steps == round(SIM_S / 0.05), sim
    after, waited = int(sim["samples_after_answer"]), int(sim["samples_after_wait"])
    ordered, pairs = _samples_after_the_answer(out)
    assert pairs >= steps - 2, (pairs, sim)
    if answer_first_s > 0:
        # each answered step's samples went out after the answer (the DDS source timestamps say so)
        assert after + waited == steps - 1 and after > 0, sim
        assert ordered >= after - 1, (ordered, after, sim)
    else:  # at once: with the state, before any controller could answer it
        assert after == waited == 0, sim
        assert ordered == 0, (ordered, pairs)
    assert "recording complete: no gaps" in err, err[-3000:]


def test_a_stepping_thread_of_its_own_flies_the_same_graph(tmp_path):
    """``realtime_loop: thread`` (as before the executor-driven loop): the run completes, the answers come and the
    statuses say where the callbacks run."""
    pytest.importorskip("rclpy")
    out, err = _fly(tmp_path, "thread", "--compose", realtime_loop="thread")
    st = last_statuses(out)
    sim = st["bb2/simulator"]
    assert int(sim["step"]) == round(SIM_S / 0.05) and sim["failsafe_steps_after_takeover"] == "0", sim
    assert int(sim["samples_after_answer"]) > 0, sim
    assert "stepping thread" not in st["bb2/mixer"]["callback_scheduling"], st["bb2/mixer"]
    assert "recording complete: no gaps" in err, err[-3000:]
