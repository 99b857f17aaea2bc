"""Each node alone (its own process, real DDS, its own ROS_DOMAIN_ID) starts, answers on its topics and
applies the parameters of a params file; plus the exact contract conversions the graph relies on."""
from __future__ import annotations

import math
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_msgs_py import conversions as cv  # noqa: E402
from bb2_msgs_py.contract import message_class, qos_profile, topic  # noqa: E402
from bb2_sim.state import VehicleState  # noqa: E402
from bb2_ros.node_common import REPLAY_MIN_INTERVAL_S, StampedCache, remap_rules  # noqa: E402

from rosenv import SpinningNode, claimed_domain, spawn_node  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]
MISSION = "path: circle_r400\nstack: rate_2022\nduration_s: 30\n"


# ----------------------------------------------------------------------------------------- harness
class Probe(SpinningNode):
    """A test node on its own context/domain: subscribes, publishes, waits for conditions."""

    def __init__(self, domain_id: int):
        super().__init__("probe", domain_id, spin_timeout_s=0.02)
        self.msgs: dict[str, list] = {}
        self.pubs: dict[str, Any] = {}
        self.lock = threading.Lock()
        self.start()

    def sub(self, name: str, type_name: str | None = None, qos: Any = None) -> list:
        from rclpy.qos import HistoryPolicy

        spec_type = type_name or topic(name).type
        q = qos if qos is not None else qos_profile(name if type_name is None else "command")
        q.history, q.depth = HistoryPolicy.KEEP_LAST, 1000
        box = self.msgs.setdefault(name, [])

        def cb(m):
            with self.lock:
                box.append(m)
        with self.lock:
            self.node.create_subscription(message_class(spec_type), name, cb, q)
        return box

    def pub(self, name: str, msg) -> None:
        with self.lock:
            if name not in self.pubs:
                self.pubs[name] = self.node.create_publisher(type(msg), name, qos_profile(name))
        self.pubs[name].publish(msg)

    def wait(self, cond: Callable[[], bool], timeout: float, what: str, proc=None) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return
            if proc is not None and proc.poll() is not None:
                raise AssertionError(f"node exited ({proc.returncode}) while waiting for {what}: "
                                     f"{proc.communicate()[0]}")
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting for {what}")

    def wait_subscribed(self, name: str, proc, timeout: float = 60.0) -> None:
        # (a node's start-up: its imports and its mission's pieces; over 20 s seen on two test workers beside two
        # CPU hogs)
        self.wait(lambda: self.node.count_subscribers(name) > 0, timeout, f"a subscriber of {name}", proc)


@pytest.fixture
def graph(tmp_path):
    """(probe, start(module, *ros_args) -> Popen, mission file); every process stopped with SIGINT after."""
    domain_id = claimed_domain()
    mission = tmp_path / "circle.yaml"
    mission.write_text(MISSION)
    probe = Probe(domain_id)
    procs: list[subprocess.Popen] = []

    def start(module: str, *ros_args: str) -> subprocess.Popen:
        p = spawn_node(module, domain_id, *ros_args)
        procs.append(p)
        return p

    yield probe, start, mission
    running = [p for p in procs if p.poll() is None]  # the others were checked by the test itself
    for p in running:
        p.send_signal(signal.SIGINT)
    codes = [p.wait(10) for p in running]
    probe.close()
    assert codes == [0] * len(running), [p.communicate()[0] for p in running]  # clean SIGINT exit


def _params(tmp_path: Path, node: str, **values: Any) -> str:
    import yaml

    f = tmp_path / f"{node}_params.yaml"
    f.write_text(yaml.safe_dump({node: {"ros__parameters": values}}))
    return str(f)


def _status(probe: Probe, name: str) -> dict[str, str] | None:
    with probe.lock:
        arrays = list(probe.msgs.get("/bb2/status", []))
    for arr in reversed(arrays):
        for st in arr.status:
            if st.name == name:
                return {kv.key: kv.value for kv in st.values}
    return None


# ----------------------------------------------------------------------------------------- contract
def test_native_state_and_bernstein_messages_are_exact():
    from bb2_planner.paths import load_path

    rng = np.random.default_rng(3)
    s = VehicleState.from_vector(123.45, rng.normal(size=12) * 100)
    back = cv.state_native_from_message(cv.state_native_message(s))
    assert back.t == s.t and np.array_equal(back.as_vector(), s.as_vector())
    p = load_path("synthetic_canyon")
    q = cv.bernstein_from_message(cv.bernstein_message(p))
    assert np.array_equal(q.control_points, p.control_points) and (q.t0, q.tf, q.frame) == (p.t0, p.tf, p.frame)
    bad = cv.state_native_message(s)
    bad.data = bad.data[:12]
    with pytest.raises(cv.ConversionError):
        cv.state_native_from_message(bad)


def test_remap_rules_are_parsed():
    argv = ["prog", "--ros-args", "-r", "/bb2/odom:=/x/odom", "--remap", "simulator:/bb2/imu:=/y", "-p", "a:=1"]
    assert remap_rules(argv) == [(None, "/bb2/odom", "/x/odom"), ("simulator", "/bb2/imu", "/y")]


# ----------------------------------------------------------------------------------------- nodes
def test_planner_publishes_exact_path_and_applies_params_file(graph, tmp_path):
    from bb2_mission import load_mission

    probe, start, mission = graph
    path_box = probe.sub("/bb2/path")
    bern_box = probe.sub("/bb2/path/bernstein")
    proc = start("bb2_ros.planner", "--params-file", _params(tmp_path, "planner", path_samples=57),
                 "-p", f"mission_file:={mission}")
    probe.wait(lambda: path_box and bern_box, 20, "the latched path topics", proc)
    assert len(path_box[0].poses) == 57  # from the params file
    assert path_box[0].header.frame_id == "map"
    ref = load_mission(mission).path
    got = cv.bernstein_from_message(bern_box[0])
    assert np.array_equal(got.control_points, ref.control_points) and (got.t0, got.tf) == (ref.t0, ref.tf)
    np.testing.assert_allclose(cv.path_from_message(path_box[0])[0], ref.to_frame("native")(ref.t0), atol=1e-9)


def test_simulator_alone_publishes_its_topics_in_realtime(graph, tmp_path):
    probe, start, mission = graph
    boxes = {n: probe.sub(n) for n in ("/clock", "/bb2/odom", "/bb2/imu", "/bb2/depth", "/bb2/planes/state",
                                       "/bb2/propeller/state", "/bb2/status", "/bb2/state_native")}
    remapped = probe.sub("/test/depth", "sensor_msgs/msg/FluidPressure", qos_profile("sensor"))
    params = _params(tmp_path, "simulator", time_mode="realtime", rate_hz=40, command_timeout_s=0.3,
                     mission_file=str(mission))
    proc = start("bb2_ros.simulator", "--params-file", params, "-r", "/bb2/depth:=/test/depth")
    probe.wait(lambda: len(boxes["/bb2/imu"]) > 20 and _status(probe, "bb2/simulator"), 20,
               "simulator output", proc)
    st = _status(probe, "bb2/simulator")
    assert st["mode"] == "realtime" and st["rate_hz"] == "40"  # from the params file
    assert st["failsafe"] == "true" and "no valid plane" in st["failsafe_reason"]  # no controller running
    assert remapped and not boxes["/bb2/depth"]  # standard -r remap applied
    imu = boxes["/bb2/imu"][-1]
    f = np.array([imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z])
    assert 8.0 < f[2] < 11.6 and np.all(np.isfinite(f))  # specific force includes the gravity reaction
    s = cv.odometry_to_state(boxes["/bb2/odom"][-1])
    assert np.all(np.isfinite(s.as_vector())) and s.t > 0
    clocks = [cv.stamp_to_seconds(c.clock) for c in boxes["/clock"]]
    assert clocks == sorted(clocks) and clocks[-1] > 0.5


def test_path_following_answers_a_state_with_the_library_law(graph):
    from bb2_mission import load_mission, mission_components

    probe, start, mission = graph
    rate_box, err_box, prog_box = (probe.sub(n) for n in ("/bb2/guidance/rate_cmd", "/bb2/guidance/path_error",
                                                           "/bb2/mission/progress"))
    proc = start("bb2_ros.path_following", "-p", f"mission_file:={mission}",
                 "-p", "path_source:=mission")
    comp = mission_components(load_mission(mission))
    state = VehicleState.from_vector(0.0, comp.x0)
    probe.wait_subscribed("/bb2/state_native", proc)
    msg = cv.state_native_message(state)
    probe.wait(lambda: (probe.pub("/bb2/state_native", msg) or True) and rate_box and prog_box, 20,
               "rate command", proc)
    x = comp.stack.inputs(state)
    pf = comp.stack.guidance.step(x["p"], x["R_BI"], x["v_flu"])
    q_c, r_c = cv.rate_command_from_message(rate_box[0])
    assert (q_c, r_c) == (pf.q_c, pf.r_c)
    assert cv.stamp_to_ns(rate_box[0].header.stamp) == 0
    np.testing.assert_array_equal(cv.path_error_from_message(err_box[0]), pf.p_T)
    assert 0.0 <= prog_box[0].data < 0.01
    # the same stamp again (a lockstep re-send, lockstep_retry_s apart) is answered again, identically
    time.sleep(2 * REPLAY_MIN_INTERVAL_S)
    n = len(rate_box)
    probe.wait(lambda: (probe.pub("/bb2/state_native", msg) or True) and time.sleep(0.1) is None
               and len(rate_box) > n, 10, "the replayed answer", proc)
    assert cv.rate_command_from_message(rate_box[-1]) == (q_c, r_c)
    # a backlog of copies taken at once is answered once, not once per copy (it would flood every reader)
    time.sleep(0.5)
    n = len(rate_box)
    for _ in range(30):
        probe.pub("/bb2/state_native", msg)
    time.sleep(1.0)
    assert 1 <= len(rate_box) - n <= 5, len(rate_box) - n


def test_l1_autopilot_pairs_state_and_rate_command_by_stamp(graph):
    from bb2_control.path_following import flow_to_body_rates
    from bb2_mission import load_mission, mission_components

    probe, start, mission = graph
    vh_box, prop_box = probe.sub("/bb2/autopilot/vh_cmd"), probe.sub("/bb2/propeller/cmd")
    proc = start("bb2_ros.l1_autopilot", "-p", f"mission_file:={mission}")
    comp = mission_components(load_mission(mission))
    state = VehicleState.from_vector(0.05, comp.x0)
    probe.wait_subscribed("/bb2/guidance/rate_cmd", proc)
    probe.wait_subscribed("/bb2/state_native", proc)
    time.sleep(0.3)
    probe.pub("/bb2/guidance/rate_cmd", cv.rate_command_message(0.05, 0.01, -0.02))
    time.sleep(0.3)
    assert not vh_box  # no state with that stamp yet: no answer
    probe.pub("/bb2/state_native", cv.state_native_message(state))
    probe.wait(lambda: vh_box and prop_box, 10, "autopilot answer", proc)
    x = comp.stack.inputs(state)
    dV, dH, _ = comp.stack.inner.step(*flow_to_body_rates(0.01, -0.02, x["v_flu"]), x["q_up"], x["r_left"])
    got = cv.vh_from_message(vh_box[0])
    assert got == (math.radians(dV), math.radians(dH))
    assert cv.propeller_from_message(prop_box[0]) == comp.stack.speed.step() * 2 * math.pi
    assert cv.stamp_to_ns(vh_box[0].header.stamp) == cv.stamp_to_ns(prop_box[0].header.stamp) == 50_000_000


def test_mixer_maps_vh_to_planes_and_follows_sim_time(graph):
    from bb2_mission import load_mission, mission_components

    probe, start, mission = graph
    planes_box, status_box = probe.sub("/bb2/planes/cmd"), probe.sub("/bb2/status")
    proc = start("bb2_ros.mixer", "-p", f"mission_file:={mission}", "-p", "use_sim_time:=true",
                 "-p", "status_period_s:=0.2")
    probe.wait_subscribed("/bb2/autopilot/vh_cmd", proc)
    probe.wait(lambda: (probe.pub("/clock", cv.clock_message(123.25)) or True) and _status(probe, "bb2/mixer")
               and float(_status(probe, "bb2/mixer")["node_time_s"]) == 123.25, 20, "mixer on sim time", proc)
    assert _status(probe, "bb2/mixer")["use_sim_time"] == "true"
    probe.pub("/bb2/autopilot/vh_cmd", cv.vh_message(7.5, math.radians(4.0), math.radians(-2.0)))
    probe.wait(lambda: planes_box, 10, "plane command", proc)
    expected = mission_components(load_mission(mission)).stack.mixer.step(4.0, -2.0)
    np.testing.assert_allclose(cv.planes_from_message_deg(planes_box[0]), expected, rtol=0, atol=1e-12)
    assert cv.stamp_to_ns(planes_box[0].header.stamp) == 7_500_000_000
    assert status_box  # the node reports itself


def test_unknown_remap_is_reported_or_refused(graph):
    probe, start, mission = graph
    ok = start("bb2_ros.mixer", "-p", f"mission_file:={mission}", "-r", "/bb2/nope:=/bb2/other")
    strict = start("bb2_ros.mixer", "-p", f"mission_file:={mission}", "-p", "strict_remaps:=true",
                   "-r", "/bb2/nope:=/bb2/other", "-r", "__node:=mixer_strict")
    out, _ = strict.communicate(timeout=30)
    assert strict.returncode == 2 and "remap /bb2/nope:=/bb2/other matches no topic" in out
    probe.wait_subscribed("/bb2/autopilot/vh_cmd", ok)
    ok.send_signal(signal.SIGINT)
    out, _ = ok.communicate(timeout=10)
    assert ok.returncode == 0 and "matches no topic of node 'mixer'" in out


def test_a_mission_on_sensors_refuses_what_would_fly_it_on_the_truth(graph, tmp_path):
    """Issue 12: with ``navigation: sensors`` the controllers fly on /bb2/nav/state_native; a controller told to
    read /bb2/odom (the truth) and a simulator without a sensor suite are refused at start with the reason."""
    _, start, mission = graph
    on_sensors = tmp_path / "on_sensors.yaml"
    on_sensors.write_text(f"extends: {mission}\nsensors: tactical\nnavigation: sensors\n")
    arg = f"mission_file:={on_sensors}"
    procs = {"bb2_ros.path_following": (start("bb2_ros.path_following", "-p", arg, "-p", "state_source:=odometry"),
                                        "state_source odometry reads the truth"),
             "bb2_ros.l1_autopilot": (start("bb2_ros.l1_autopilot", "-p", arg, "-p", "state_source:=odometry"),
                                      "state_source odometry reads the truth"),
             "bb2_ros.simulator": (start("bb2_ros.simulator", "-p", arg, "-p", "sensor_suite:=none"),
                                   "navigation: sensors needs a sensor suite")}
    for m, (p, text) in procs.items():
        out, _ = p.communicate(timeout=60)
        assert p.returncode == 2, (m, out)
        assert text in out, (m, out)


def test_the_stamped_cache_answers_a_copy_again_once_per_interval():
    """Re-sends (lockstep_retry_s apart) are answered again; copies taken within REPLAY_MIN_INTERVAL_S of the last
    answer (a backlog in the reader's queue) are handled without publishing; older inputs are ignored."""
    now = [100.0]
    sent = []

    class Pub:
        def publish(self, m):
            sent.append(m)

    cache = StampedCache(min_interval_s=0.05, clock=lambda: now[0])
    assert not cache.replay(5)  # nothing cached: the node answers
    cache.store(5, [(Pub(), "b")], replay_also=[(Pub(), "a")])
    assert sent == ["b"]  # replay_also was already published by the node
    for _ in range(50):  # a backlog: 50 copies within 10 ms
        now[0] += 0.0002
        assert cache.replay(5)
    assert sent == ["b"] and cache.copies_skipped == 50
    now[0] += 0.1  # a re-send lockstep_retry_s later
    assert cache.replay(5)
    assert sent == ["b", "a", "b"] and cache.replayed == 1
    now[0] += 0.01
    assert cache.replay(5) and sent == ["b", "a", "b"]  # a copy right behind the replay
    now[0] += 0.05
    assert cache.replay(5) and sent[-2:] == ["a", "b"] and cache.replayed == 2
    assert cache.replay(4) and cache.stale_ignored == 1 and len(sent) == 5  # an older input: ignored
    assert not cache.replay(6)  # a newer one: the node answers it
    assert cache.counts() == {"replayed": 2, "copies_skipped": 51, "stale_ignored": 1}
