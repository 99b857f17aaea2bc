"""``bb2-replay``: raw republishing of a bag (real DDS, a subscriber in this process) and the open-loop mode.

The bag is written in-process with :class:`bb2_tools.bagfile.BagWriter`: the mission factory's simulator and
stack tick as in lockstep, every message built with the contract conversions and serialized with rclpy, the
simulator stepped with the commands *decoded from those messages* (as the simulator node does), log time =
simulation time (as the recorder with use_sim_time).
"""
from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_msgs_py import conversions as cv  # noqa: E402
from bb2_msgs_py.contract import message_class, topic  # noqa: E402
from bb2_tools.bagfile import BagReader, BagWriter, qos_entry  # noqa: E402
from bb2_tools.replay import (PlaybackClock, ReplayError, main, open_loop, replay_qos,  # noqa: E402
                              select_bag_topics)

from rosenv import SpinningNode, claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
DURATION_S = 3.0
TOPICS = ("/clock", "/bb2/state_native", "/bb2/odom", "/bb2/planes/cmd", "/bb2/propeller/cmd", "/bb2/status")


def _qos(name: str) -> list[dict]:
    d = topic(name).qos_description
    return [qos_entry(reliability=d.reliability, durability=d.durability, history=d.history, depth=d.depth)]


def _write_bag(bag_dir: Path, mission_file: Path, *, tamper_step: int | None = None) -> int:
    """Fly ``mission_file`` in-process and record it; returns the number of steps."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rclpy.serialization import serialize_message

    from bb2_sim.state import VehicleState
    from bb2_mission import load_mission, mission_components

    comp = mission_components(load_mission(mission_file))
    sim, stack = comp.simulator, comp.stack
    n_steps = int(round(DURATION_S / sim.h))
    with BagWriter(bag_dir) as bag:
        for name in TOPICS:
            bag.add_topic(name, topic(name).type, offered_qos=_qos(name))

        def put(name: str, msg, t: float) -> None:
            bag.write(name, serialize_message(msg), cv.seconds_to_ns(t))

        status = DiagnosticArray(status=[DiagnosticStatus(name="bb2/simulator", values=[
            KeyValue(key="mode", value="lockstep"), KeyValue(key="mission_file", value=str(mission_file))])])
        put("/bb2/status", status, 0.0)
        for n in range(n_steps + 1):
            state = VehicleState.from_vector(sim.t, sim.x)
            t = state.t
            put("/clock", cv.clock_message(t), t)
            put("/bb2/state_native", cv.state_native_message(state), t)
            put("/bb2/odom", cv.state_to_odometry(state), t)
            if n == n_steps:
                break
            out = stack.step(state)
            planes = np.radians(out.planes_deg)
            if tamper_step is not None and n >= tamper_step:
                planes = planes + math.radians(0.5)  # what the simulator does NOT get: the open loop must notice
            p_msg = cv.planes_message(t, planes)
            r_msg = cv.propeller_message(t, out.rps * 2.0 * math.pi)
            put("/bb2/planes/cmd", p_msg, t)
            put("/bb2/propeller/cmd", r_msg, t)
            p_applied = np.radians(out.planes_deg) if tamper_step is not None else cv.planes_from_message(p_msg)
            sim.step(np.degrees(p_applied), cv.propeller_from_message(r_msg) / (2.0 * math.pi))
    return n_steps


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("replay")
    mission = d / "straight_short.yaml"
    mission.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nduration_s: {DURATION_S}\n")
    n = _write_bag(d / "bag", mission)
    return d / "bag", mission, n


# ----------------------------------------------------------------------------------------- pure pieces
def test_playback_clock_rate_and_pause():
    c = PlaybackClock(1_000_000_000, 2.0, now=10.0)
    assert c.bag_time_ns(10.5) == 2_000_000_000  # 0.5 wall s at 2x = 1 bag s
    assert c.wall_for(3_000_000_000) == pytest.approx(11.0)
    c.set_paused(True, now=11.0)
    assert c.bag_time_ns(50.0) == 3_000_000_000 and c.wall_for(3_000_000_001) == math.inf
    c.set_paused(False, now=20.0)
    assert c.bag_time_ns(20.5) == 4_000_000_000
    with pytest.raises(ReplayError):
        PlaybackClock(0, 0.0)


def test_replay_qos_and_topic_selection(recorded):
    bag, _, _ = recorded
    infos = {t.name: t for t in BagReader(bag).topic_infos()}
    assert replay_qos(infos["/bb2/odom"]).reliability == "reliable"  # as offered (state topics: issue 13)
    assert replay_qos(infos["/bb2/planes/cmd"]).reliability == "reliable"
    assert select_bag_topics(infos, None) == sorted(TOPICS)
    assert select_bag_topics(infos, ["/bb2/p.*/cmd"]) == ["/bb2/planes/cmd", "/bb2/propeller/cmd"]
    with pytest.raises(ReplayError, match="matches no topic"):
        select_bag_topics(infos, ["/bb2/imu"])


def test_bad_input_is_one_clear_error(recorded, tmp_path, capsys):
    bag, _, _ = recorded
    assert main([str(tmp_path / "nope")]) == 2
    assert "no bag" in capsys.readouterr().err
    assert main([str(bag), "--rate", "0"]) == 2
    assert main([str(bag), "--topics", "/bb2/nothing"]) == 2
    assert "matches no topic" in capsys.readouterr().err
    # a start past the end: said, not "published 0 messages" (nor open loop's "max deviation 0" over no state)
    assert main([str(bag), "--start-offset", "1e9"]) == 2
    assert f"--start-offset 1e+09 s is past the bag's end: it spans {DURATION_S:.3f} s" in capsys.readouterr().err
    assert main([str(bag), "--open-loop", "--start-offset", "1e9"]) == 2
    assert "--start-offset 1e+09 s is past the last recorded state" in capsys.readouterr().err


@pytest.mark.parametrize("args, said", [
    (["--wait-for-readers", "-1"], "--wait-for-readers must be >= 0 s and finite, got -1.0"),
    (["--open-loop", "--max-deviation", "-1"], "--max-deviation must be >= 0 m and finite, got -1.0"),
    (["--open-loop", "--max-deviation", "nan"], "--max-deviation must be >= 0 m and finite, got nan"),
    (["--open-loop", "--rate", "2"], "--rate does not apply to --open-loop (no ROS: nothing is republished)"),
    (["--open-loop", "--loop", "--pause"], "--loop, --pause do not apply to --open-loop"),
    (["--max-dev", "1"], "--max-deviation does not apply without --open-loop (the replay republishes the bag"),
    (["--mission", "canyon"], "--mission does not apply without --open-loop"),
])
def test_an_option_the_mode_does_not_read_or_a_bad_bound_is_refused(recorded, capsys, args, said):
    """Each was ignored without a word (a replay with --max-deviation checked nothing; --open-loop --rate 2 ran at
    no rate), or a negative bound failed every open-loop run ('deviation 0 exceeds -1')."""
    bag, _, _ = recorded
    assert main([str(bag), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bb2-replay: error: ") and said in err[0], err


# ----------------------------------------------------------------------------------------- open loop
def test_open_loop_reproduces_a_lockstep_recording_exactly(recorded, capsys):
    bag, mission, n = recorded
    res = open_loop(bag)  # the mission found through the recorded /bb2/status
    assert res.mission_file == str(mission)
    assert res.steps == n and res.exact_commands == n and res.held_commands == res.default_commands == 0
    assert res.compared == n + 1
    assert res.max_position_m == 0.0 and res.max_attitude_rad == 0.0 and res.max_velocity_m_s == 0.0
    assert main([str(bag), "--open-loop", "--mission", str(mission), "--max-deviation", "0"]) == 0
    assert "max deviation: position 0.000e+00 m" in capsys.readouterr().out


def test_open_loop_notices_commands_the_run_did_not_apply(tmp_path, recorded):
    _, mission, _ = recorded
    _write_bag(tmp_path / "tampered", mission, tamper_step=20)
    res = open_loop(tmp_path / "tampered", mission)
    assert res.max_position_m > 1e-6 and res.worst_time_s > 1.0
    assert main([str(tmp_path / "tampered"), "--open-loop", "--mission", str(mission),
                 "--max-deviation", "1e-9"]) == 3


# ----------------------------------------------------------------------------------------- republishing
class Listener(SpinningNode):
    def __init__(self, domain_id: int, topics: dict[str, str]):
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        super().__init__("replay_test", domain_id)
        self.got: dict[str, list[tuple[float, bytes]]] = {n: [] for n in topics}
        for name, type_name in topics.items():
            rel = ReliabilityPolicy.BEST_EFFORT if name in ("/bb2/odom", "/clock") else ReliabilityPolicy.RELIABLE
            self.node.create_subscription(message_class(type_name), name,
                                          # the publisher's send time (DDS source timestamp), so the pacing
                                          # checks do not depend on when this test's thread gets the CPU
                                          lambda data, info, name=name: self.got[name].append(
                                              (info["source_timestamp"] * 1e-9, data)),
                                          QoSProfile(depth=10000, reliability=rel), raw=True)
        self.start()


def _quiet_listener(topics: dict[str, str], attempts: int = 8) -> tuple[int, Listener]:
    """A listener on a random domain in 100..230 nobody else uses (other test runs pick random domains too)."""
    for _ in range(attempts):
        domain_id = claimed_domain()
        lst = Listener(domain_id, topics)
        time.sleep(1.0)
        if not [n for n, _ in lst.node.get_node_names_and_namespaces() if n != "replay_test"]:
            return domain_id, lst
        lst.close()
    raise AssertionError("no free ROS domain in 100..230")




def test_replay_republishes_recorded_odometry_with_pause_offset_and_filter(recorded):
    bag, _, n = recorded
    reader = BagReader(bag)
    offset_s = 0.5
    want = [m for m in reader.raw_messages("/bb2/odom") if m.log_time_ns >= cv.seconds_to_ns(offset_s)]
    domain_id, listener = _quiet_listener({"/bb2/odom": "nav_msgs/msg/Odometry", "/clock": "rosgraph_msgs/msg/Clock",
                                           "/bb2/state_native": "std_msgs/msg/Float64MultiArray"})
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.replay", str(bag), "--topics", "/bb2/odom",
                             "--rate", "0.5", "--start-offset", str(offset_s), "--domain-id", str(domain_id),
                             "--wait-for-readers", "20", "--delay", "1.0"], cwd=REPO, env=ros_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 30
        while len(listener.got["/bb2/odom"]) < 10 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.01)
        proc.send_signal(signal.SIGUSR1)  # pause
        time.sleep(0.3)
        paused_at = len(listener.got["/bb2/odom"])
        time.sleep(1.0)
        assert len(listener.got["/bb2/odom"]) == paused_at, "messages kept coming while paused"
        assert paused_at < len(want)
        proc.send_signal(signal.SIGUSR1)  # resume
        out, _ = proc.communicate(timeout=30)
        time.sleep(0.3)
    finally:
        if proc.poll() is None:
            proc.kill()
        listener.close()
    assert proc.returncode == 0, out
    got = listener.got["/bb2/odom"]
    # the recorded odometry from the offset on, byte for byte, in order. It is republished with its recorded
    # best-effort QoS, so under load DDS may drop one: what arrives is an in-order subsequence of the
    # recording with no duplicates, missing at most 2 % (usually nothing).
    datas = [m.data for m in want]
    idx = [datas.index(d) for _, d in got]  # ValueError if a received message is not a recorded one
    assert idx == sorted(set(idx)), "out of order or duplicated"
    assert idx[0] <= 1 and len(idx) >= 0.98 * len(want), (idx[:3], len(idx), len(want))
    assert not listener.got["/bb2/state_native"]  # filtered out
    # /clock: the playback time = the recorded log times, increasing
    from rclpy.serialization import deserialize_message

    clocks = [cv.stamp_to_ns(deserialize_message(d, message_class("rosgraph_msgs/msg/Clock")).clock)
              for _, d in listener.got["/clock"]]
    assert clocks and clocks == sorted(clocks) and clocks[0] >= cv.seconds_to_ns(offset_s)
    assert set(clocks) <= {m.log_time_ns for m in want}
    # the pause shows as the longest gap of the DDS send times (the rate and pause arithmetic itself is
    # checked deterministically in test_playback_clock_rate_and_pause)
    walls = np.array([w for w, _ in got])
    gaps = np.diff(walls)
    assert gaps.max() > 1.0  # the pause
    # paced at --rate 0.5 over DDS: the recorded span took twice as long in send times (less the pause). A
    # replayer can only fall behind its clock, never run ahead of it; but on a loaded machine the first message
    # itself may go out late, which shortens the measured span by as much: 0.5 s of slack below (a rate of 1 or
    # even 0.6 would still fail by far), the upper bound loose (a loaded machine may delay sends)
    log_s = np.array([want[k].log_time_ns for k in idx]) * 1e-9
    log_span_s, period_s = log_s[-1] - log_s[0], np.diff(log_s).max()
    played_s = walls[-1] - walls[0] - gaps.max()  # less the pause (and the one recorded period it spans)
    assert log_span_s > 1.0
    assert (log_span_s - period_s) / 0.5 - 0.5 <= played_s <= log_span_s / 0.5 + 3.0, (played_s, log_span_s)


def test_replay_service_pause_loop_and_clean_sigint(recorded):
    """Start paused, resume and pause again through /bb2_replay/pause (std_srvs/SetBool), loop, stop with SIGINT."""
    from std_srvs.srv import SetBool

    bag, _, _ = recorded
    offset_s = 2.5  # the last 0.5 s of commands: 10 per loop
    per_loop = sum(1 for m in BagReader(bag).raw_messages("/bb2/propeller/cmd")
                   if m.log_time_ns >= cv.seconds_to_ns(offset_s))
    domain_id, listener = _quiet_listener({"/bb2/propeller/cmd": "sensor_msgs/msg/JointState"})
    client = listener.node.create_client(SetBool, "/bb2_replay/pause")
    proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.replay", str(bag), "--topics", "/bb2/propeller/cmd",
                             "--rate", "2", "--start-offset", str(offset_s), "--pause", "--loop",
                             "--domain-id", str(domain_id), "--delay", "0"], cwd=REPO, env=ros_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def call(data: bool) -> str:
        fut = client.call_async(SetBool.Request(data=data))
        deadline = time.monotonic() + 10
        while not fut.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert fut.done() and fut.result().success
        return fut.result().message

    try:
        assert client.wait_for_service(timeout_sec=15), "no /bb2_replay/pause service"
        time.sleep(0.5)
        assert listener.got["/bb2/propeller/cmd"] == []  # started paused
        assert call(False).startswith("playing")
        deadline = time.monotonic() + 15
        while len(listener.got["/bb2/propeller/cmd"]) < 2 * per_loop + 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert call(True).startswith("paused")
        time.sleep(0.3)
        k = len(listener.got["/bb2/propeller/cmd"])
        time.sleep(0.6)
        assert len(listener.got["/bb2/propeller/cmd"]) == k
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        listener.close()
    assert proc.returncode == 0, out
    got = [d for _, d in listener.got["/bb2/propeller/cmd"]]
    first_loop = got[:per_loop]
    assert len(got) > 2 * per_loop and got[per_loop:2 * per_loop] == first_loop  # looped, same bytes
    assert "loops" in out
