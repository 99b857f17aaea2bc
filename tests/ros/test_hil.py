"""The HIL example (examples/hil): the simulator node alone, in real time, flown by an external autopilot process.

The test listens on the example's domain itself (odometry and the simulator's status) and judges the flight
independently of the example's own monitor: finite states, bounded path error from the mission path, real
time pacing, and no failsafe once the autopilot has taken over.  A second test runs the autopilot on
another network host (two network namespaces and a veth pair; needs root) and checks the monitor's summary.
"""
from __future__ import annotations

import json
import math
import os
import resource
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=110)]  # slow: started first (tests/conftest.py)
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_msgs_py import conversions as cv  # noqa: E402
from bb2_msgs_py.contract import message_class, qos_profile  # noqa: E402

from rosenv import SpinningNode, claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
RUN_HIL = REPO / "examples" / "hil" / "run_hil.py"
MISSION = REPO / "missions" / "canyon.yaml"
DURATION_S = 30.0
MAX_PATH_ERROR_M = 1.5  # the library runner stays within ~0.2 m over this stretch
# the simulator's failsafe timeout in the real-time flights here, wall s (the example's default, a bench's, is 0.5):
# what these tests check is that the autopilot keeps the boat out of the failsafe for the whole flight, not how
# late a shared 2-vCPU test machine can deliver one command.  At 0.5 s the first test failed in three of about a
# dozen clean-clone suites: twice beside two CPU hogs while the simulator's command reception was normally scheduled
# (a command answered at 27.2 s arrived at 28.35 s), then once idle with every thread of the loop at SCHED_FIFO 40
# (1.0-2.0 s without a command, 1 s after the takeover; not reproduced here: 0.054 s worst gap idle, 0.065 s beside
# two hogs).  The worst gap of each flight is in the simulator's status (command_gap_max_s) and asserted below.
COMMAND_TIMEOUT_S = 3.0


class Listener(SpinningNode):
    def __init__(self, domain_id: int):
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        super().__init__("hil_test", domain_id)
        self.odom: list[tuple[float, float, np.ndarray]] = []  # (wall, t, x12 native)
        self.status: list[dict[str, str]] = []
        self.node.create_subscription(message_class("nav_msgs/msg/Odometry"), "/bb2/odom", self._on_odom,
                                      QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.node.create_subscription(message_class("diagnostic_msgs/msg/DiagnosticArray"), "/bb2/status",
                                      self._on_status, qos_profile("/bb2/status"))
        self.start()

    def _on_odom(self, msg) -> None:
        s = cv.odometry_to_state(msg)
        self.odom.append((time.monotonic(), s.t, s.as_vector()))

    def _on_status(self, msg) -> None:
        self.status += [{kv.key: kv.value for kv in s.values} for s in msg.status if s.name == "bb2/simulator"]

    def others(self) -> list[str]:
        return [n for n, _ in self.node.get_node_names_and_namespaces() if n != "hil_test"]


def _quiet_listener(attempts: int = 8) -> tuple[int, Listener]:
    """A listener on a random domain in 100..230 nobody else uses (other test runs pick random domains too)."""
    for _ in range(attempts):
        domain_id = claimed_domain()
        lst = Listener(domain_id)
        time.sleep(1.0)
        if not lst.others():
            return domain_id, lst
        lst.close()
    raise AssertionError("no free ROS domain in 100..230")




def test_external_autopilot_flies_the_mission_in_real_time(tmp_path):
    from bb2_mission import load_mission, path_errors_closest

    domain_id, lst = _quiet_listener()
    summary = tmp_path / "hil.json"
    try:
        proc = subprocess.run([sys.executable, str(RUN_HIL), "--mission", str(MISSION), "--duration", str(DURATION_S),
                               "--command-timeout", str(COMMAND_TIMEOUT_S), "--domain-id", str(domain_id),
                               "--summary", str(summary)], cwd=REPO, env=ros_env(),
                              capture_output=True, text=True, timeout=DURATION_S + 90)
        time.sleep(0.3)
    finally:
        lst.close()
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]

    # the flight, as this test received it
    assert len(lst.odom) >= 0.8 * DURATION_S / 0.05, out[-2000:]  # best effort, discovery at start
    t = np.array([o[1] for o in lst.odom])
    X = np.array([o[2] for o in lst.odom])
    assert np.all(np.isfinite(X))
    assert t[-1] == pytest.approx(DURATION_S)
    mission = load_mission(MISSION)
    path = mission.path.to_frame("native") if mission.path.frame != "native" else mission.path
    eh, ev = path_errors_closest(path, X[:, 0:3])
    assert np.max(np.abs(eh)) < MAX_PATH_ERROR_M and np.max(np.abs(ev)) < MAX_PATH_ERROR_M, \
        (np.max(np.abs(eh)), np.max(np.abs(ev)))
    # real time: sim time advanced at the wall-clock rate
    wall = np.array([o[0] for o in lst.odom])
    rate = (t[-1] - t[0]) / (wall[-1] - wall[0])
    assert rate == pytest.approx(1.0, abs=0.08)

    # the simulator's status: real-time mode; once the autopilot's commands arrived, never a failsafe again
    st = lst.status
    assert st and all(s["mode"] == "realtime" for s in st)
    # its command reception at the autopilot's priority (simulator_hil.yaml), where the OS allows it
    may_fifo = os.geteuid() == 0 or resource.getrlimit(resource.RLIMIT_RTPRIO)[0] >= 40
    # (it steps on its executor's thread, realtime_loop executor: the callbacks run at the stepping thread's priority,
    # the middleware's threads at callback_priority)
    assert ("the middleware's threads: SCHED_FIFO 40 (" if may_fifo else "normal (SCHED_FIFO 40 refused") \
        in st[-1]["callback_scheduling"], st[-1]
    # the first status that says the autopilot took over (one from before the first step says no failsafe yet, and
    # the failsafe may then engage at the first step: seen beside the fault matrix and two CPU hogs)
    first_ok = next(i for i, s in enumerate(st) if s["takeover_sim_time_s"])
    assert float(st[first_ok]["sim_time_s"]) < 3.0  # the autopilot took over within the first seconds
    last = st[-1]
    assert all(s["failsafe"] == "false" for s in st[first_ok:]) and last["failsafe_steps_after_takeover"] == "0", (
        [(s["sim_time_s"], s["failsafe_reason"], s["overruns"], s["step_rate_hz"]) for s in st[first_ok:]
         if s["failsafe"] != "false"], st[first_ok]["sim_time_s"], last, out[-3000:])
    # the simulator's own account: the takeover came at or before the first status that said so, and the longest
    # silence of the autopilot since then stayed under the timeout
    assert 0.0 <= float(last["takeover_sim_time_s"]) <= float(st[first_ok]["sim_time_s"]), (last, st[first_ok])
    assert 0.0 < float(last["command_gap_max_s"]) < COMMAND_TIMEOUT_S, last
    if float(last["command_gap_max_s"]) > 0.5:  # past the bench's own timeout: said in the suite's warnings summary
        warnings.warn(f"HIL real-time flight: the longest command gap was {last['command_gap_max_s']} s (the bench "
                      f"default command_timeout_s is 0.5 s); overruns {last['overruns']}, scheduling "
                      f"{last['scheduling']}, callbacks {last['callback_scheduling']}", stacklevel=1)
    # every failsafe step came before the takeover (start-up discovery, longer on a loaded machine), none after:
    # the status that first said "no failsafe" was sent at or after the takeover, so its step bounds them
    assert last["state"] == "finished" and int(last["failsafe_steps"]) <= int(st[first_ok]["step"])
    # nothing malformed ever; a command answered later than max_command_age_s (stale) can happen only when the
    # machine is loaded, and is rejected as it should be: a few at most
    assert all(int(last[k]) == 0 for k in ("rejected_nonfinite", "rejected_names", "rejected_frame",
                                           "rejected_future")), last
    assert int(last["rejected_stale"]) <= 20, last
    # a plane command beyond the limit can come at the takeover, after a long start-up failsafe let the vehicle
    # drift (idle: none; 1.9 s of failsafe once on a fast machine: one command clamped; the clean-clone CI once: 4,
    # how many depends on how long the loaded machine's start-up took): a few ticks at most, none once it flies
    settled = next((i for i, s in enumerate(st) if float(s["sim_time_s"]) >= float(st[first_ok]["sim_time_s"]) + 2.0),
                   len(st) - 1)
    assert int(last["clamped"]) == int(st[settled]["clamped"]) <= 10, \
        (st[settled]["clamped"], st[first_ok]["sim_time_s"], last)
    # the example's own monitor agrees
    s = json.loads(summary.read_text())
    assert s["state_finite"] and not s["failsafe_after_release"] and s["e_vertical_max_m"] < MAX_PATH_ERROR_M


def _autopilot_subscriptions(lst: Listener, proc: subprocess.Popen, expect: set[str],
                             timeout_s: float = 120.0, settle_s: float = 1.0) -> set[str]:
    """The topics the running ``external_autopilot`` node subscribes to, as the graph shows them: polled until every
    topic of ``expect`` is discovered (a node's subscriptions are discovered one by one: beside two CPU hogs the
    imu was seen with the gps and the DVL's water track still missing), then for ``settle_s`` more, so that one it
    should not have is seen too."""
    deadline = time.monotonic() + timeout_s
    topics: set[str] = set()
    settled_at = None
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            topics |= {n for n, _ in lst.node.get_subscriber_names_and_types_by_node("external_autopilot", "/")}
        except Exception:  # noqa: BLE001 - not discovered yet (rclpy raises NodeNameNonExistentError)
            pass
        if settled_at is None and expect <= topics:
            settled_at = time.monotonic() + settle_s
        if settled_at is not None and time.monotonic() >= settled_at:
            return topics
        time.sleep(0.2)
    return topics


def _sensors_mission(tmp_path: Path, duration_s: float) -> Path:
    m = tmp_path / "canyon_short.yaml"
    m.write_text(f"extends: {MISSION}\nname: canyon_short\nduration_s: {duration_s:g}\n")
    return m


def test_external_autopilot_on_sensors_alone_in_lockstep_is_the_library_runner(tmp_path):
    """The worked autopilot flying on the sensors only (``--sensors tactical``: ``/bb2/sensors/*`` into its own
    navigation filter, the lockstep handshake's stamp as its tick): the graph shows it subscribed to nothing of the
    truth, and the flight is the library runner's with the same mission (``sensors: tactical``, ``navigation:
    sensors``), step for step."""
    from bb2_msgs_py.sensor_conversions import NAVIGATION_SENSOR_TOPICS

    from rosenv import library_trajectory

    duration = 15.0
    mission = _sensors_mission(tmp_path, duration)
    states = tmp_path / "states.csv"
    domain_id, lst = _quiet_listener()
    try:
        proc = subprocess.Popen([sys.executable, str(RUN_HIL), "--mission", str(mission), "--duration",
                                 str(duration), "--mode", "lockstep", "--sensors", "tactical", "--domain-id",
                                 str(domain_id), "--summary", str(tmp_path / "hil.json"), "--trajectory", str(states)],
                                cwd=REPO, env=ros_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            subs = _autopilot_subscriptions(lst, proc, set(NAVIGATION_SENSOR_TOPICS))
            out, _ = proc.communicate(timeout=240)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    finally:
        lst.close()
    assert proc.returncode == 0, out[-4000:]
    assert "state from /bb2/sensors/* (suite tactical, tick handshake)" in out, out[-3000:]
    # what it reads: the sensors, and the handshake's stamp -- no odometry, no truth IMU/depth, no INS estimate
    assert set(NAVIGATION_SENSOR_TOPICS) <= subs, subs
    assert subs - set(NAVIGATION_SENSOR_TOPICS) <= {"/bb2/state_native", "/parameter_events"}, subs
    got = np.loadtxt(states, delimiter=",", skiprows=1)
    expected_mission = tmp_path / "expected.yaml"
    expected_mission.write_text(f"extends: {mission}\nsensors: tactical\nnavigation: sensors\n")
    want = library_trajectory(expected_mission)
    assert got.shape == want.shape == (int(duration / 0.05) + 1, 13), (got.shape, want.shape)
    np.testing.assert_array_equal(got[:, 0], want[:, 0])
    err = np.max(np.abs(got[:, 1:] - want[:, 1:]))
    assert err < 1e-9, err  # measured 5e-14 (the sample stamps carry the times to the nanosecond)
    assert np.max(np.abs(got[-1, 1:4] - got[0, 1:4])) > 20.0  # it flew


def test_external_autopilot_on_sensors_alone_in_real_time(tmp_path):
    """The same autopilot on the bench clock (``/clock`` ticks, real time): it takes over and flies the mission
    within the path error bound on its own estimate, with no failsafe after the takeover."""
    duration = 12.0
    summary = tmp_path / "hil.json"
    proc = subprocess.run([sys.executable, str(RUN_HIL), "--mission", str(MISSION), "--duration", str(duration),
                           "--sensors", "tactical", "--command-timeout", str(COMMAND_TIMEOUT_S), "--domain-id",
                           str(claimed_domain()), "--summary", str(summary)], cwd=REPO, env=ros_env(),
                          capture_output=True, text=True, timeout=duration + 120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    assert "tick clock" in out, out[-3000:]
    s = json.loads(summary.read_text())
    assert s["state_finite"] and s["t_last_s"] == pytest.approx(duration)
    assert max(s["e_horizontal_max_m"], s["e_vertical_max_m"]) < MAX_PATH_ERROR_M, s
    assert s["failsafe_released_at_s"] is not None and s["failsafe_released_at_s"] < 5.0 \
        and not s["failsafe_after_release"], s
    assert s["final_status"]["state"] == "finished" and s["final_status"]["mode"] == "realtime"


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("ip") is None, reason="network namespaces need root and iproute2")
def test_external_autopilot_on_another_network_host(tmp_path):
    probe = subprocess.run(["ip", "netns", "add", f"bb2probe{os.getpid()}"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"cannot create network namespaces here: {probe.stderr.strip()}")
    subprocess.run(["ip", "netns", "del", f"bb2probe{os.getpid()}"], capture_output=True)
    summary = tmp_path / "hil_netns.json"
    duration = 15.0
    before = set(subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout.split())
    proc = subprocess.run([sys.executable, str(RUN_HIL), "--mission", str(MISSION), "--duration", str(duration),
                           "--netns", "--command-timeout", str(COMMAND_TIMEOUT_S), "--domain-id",
                           str(claimed_domain()), "--summary", str(summary)],
                          cwd=REPO, env=ros_env(), capture_output=True, text=True, timeout=duration + 90)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    assert "two network namespaces" in out
    traffic = [ln for ln in out.splitlines() if "veth traffic" in ln]
    assert traffic and "'bench_rx_bytes': 0" not in traffic[0], traffic  # the commands came over the veth
    s = json.loads(summary.read_text())
    assert s["state_finite"] and s["t_last_s"] == pytest.approx(duration)
    assert s["odometry_messages"] >= 0.8 * duration / 0.05
    assert max(s["e_horizontal_max_m"], s["e_vertical_max_m"]) < MAX_PATH_ERROR_M
    assert s["failsafe_released_at_s"] is not None and not s["failsafe_after_release"]
    assert s["final_status"]["state"] == "finished" and s["final_status"]["mode"] == "realtime"
    # the namespaces are gone
    after = set(subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout.split())
    assert not {n for n in after - before if n.startswith(("bb2bench", "bb2ap"))}
    assert not math.isnan(s["e_horizontal_rms_m"])


def test_the_monitor_judges_the_takeover_from_the_simulators_counters_when_it_matched_late():
    """A monitor that matched the simulator's status seconds late (seen in the clean-clone CI: run_hil said OK while
    the test, listening from the start, saw the failsafe engage 1 s after the takeover) judges from the simulator's
    own account in its last status: the takeover time and the failsafe steps since then."""
    sys.path.insert(0, str(RUN_HIL.parent))
    try:
        from monitor import summarize
    finally:
        sys.path.remove(str(RUN_HIL.parent))
    ok = {"failsafe": "false", "sim_time_s": "5.000000", "state": "running"}
    seen_late = [ok, dict(ok, sim_time_s="5.5"),
                 dict(ok, sim_time_s="30.0", state="finished", takeover_sim_time_s="0.450000",
                      failsafe_steps="31", failsafe_steps_after_takeover="22")]
    s = summarize(MISSION, [], seen_late)
    assert s["failsafe_released_at_s"] == 0.45 and s["failsafe_steps_after_release"] == 22
    assert s["failsafe_after_release"]
    seen_late[-1]["failsafe_steps_after_takeover"] = "0"
    s = summarize(MISSION, [], seen_late)
    assert not s["failsafe_after_release"] and s["failsafe_released_at_s"] == 0.45
    # a monitor that matched before the first step: no failsafe yet, then the failsafe until the takeover
    early = [dict(ok, sim_time_s="0.0"), dict(ok, failsafe="true", sim_time_s="0.0"), dict(ok, sim_time_s="0.05"),
             dict(ok, sim_time_s="15.0", state="finished", takeover_sim_time_s="0.050000",
                  failsafe_steps_after_takeover="0")]
    s = summarize(MISSION, [], early)
    assert not s["failsafe_after_release"] and s["failsafe_released_at_s"] == 0.05
    early.insert(3, dict(ok, failsafe="true", sim_time_s="7.0"))  # a failsafe status after the takeover counts
    assert summarize(MISSION, [], early)["failsafe_after_release"]
    # a simulator without these keys: judged from the statuses seen, as before
    old = [dict(ok, failsafe="true", sim_time_s="0.2"), dict(ok, sim_time_s="0.5"), dict(ok, failsafe="true"), ok]
    s = summarize(MISSION, [], old)
    assert s["failsafe_released_at_s"] == 0.5 and s["failsafe_after_release"] and "failsafe_steps_after_release" not in s


def test_the_monitor_judges_against_the_path_it_loaded_before_the_flight():
    """The monitor loads the mission's path once, before the flight, and judges with it (``path=``): the same
    judgement as from the mission file, and a different path gives different errors (the one given is used)."""
    sys.path.insert(0, str(RUN_HIL.parent))
    try:
        from monitor import mission_path, summarize
    finally:
        sys.path.remove(str(RUN_HIL.parent))
    path = mission_path(MISSION)
    P = path(path.t0 + np.linspace(0.05, 0.8, 9) * (path.tf - path.t0)) + np.array([0.0, 0.0, 1.5])
    odom = [(2.0 * i, p) for i, p in enumerate(P)]  # to t = 16 s: the settled errors (from 10 s) too
    ok = [{"failsafe": "false", "sim_time_s": "1.0", "state": "finished"}]
    from_file = summarize(MISSION, odom, ok)
    given = summarize(MISSION, odom, ok, path=path)
    assert given == from_file and from_file["e_vertical_max_m"] > 1.0
    from bb2_planner.bernstein import BernsteinPath
    lifted = BernsteinPath(path.control_points + np.array([0.0, 0.0, 1.5]), path.t0, path.tf, path.frame)
    shifted = summarize(MISSION, odom, ok, path=lifted)
    assert shifted["e_vertical_max_m"] < 1e-6 < from_file["e_vertical_max_m"]
