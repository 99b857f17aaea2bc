"""Issue 13 (2): parameters mean what they say.  Every parameter is either live (a set at run time takes
effect; its description says so) or read-only (the set is refused); a set of the wrong type or of an invalid
value is refused with a reason; a float parameter accepts an integer (it stays a float) and nothing else.

In-process on a real simulator node (real time, never started: no executor), then through the upstream
``ros2 param set/get/describe/dump`` on a running simulator, whose step rate follows ``rate_hz``."""
from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from rclpy.parameter import Parameter  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ros2_tooling import tooling_env, tooling_venv  # noqa: E402  (tests/ros2_tooling.py)
from rosenv import claimed_domain, ros_env  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
MISSION = REPO / "missions" / "straight.yaml"


@pytest.fixture
def simulator(tmp_path):
    from bb2_ros.simulator import Simulator

    params = tmp_path / "p.yaml"
    params.write_text("/**:\n  ros__parameters:\n    command_timeout_s: 2\n")  # an integer for a float
    argv = ["simulator", "--ros-args", "--params-file", str(params), "-p", f"mission_file:={MISSION}",
            "-p", "time_mode:=realtime", "-p", "realtime_priority:=0", "-p", "hold_cpu_dma_latency:=false"]
    ctx = rclpy.Context()
    rclpy.init(args=argv, context=ctx, domain_id=claimed_domain())
    import bb2_ros.node_common as nc

    nc._node_argv = argv
    try:
        from unittest import mock

        with mock.patch("rclpy.node.get_default_context", return_value=ctx):
            node = Simulator(argv)
        yield node
    finally:
        nc._node_argv = None
        try:
            node.close()
            node.destroy_node()
        except Exception:
            pass
        rclpy.shutdown(context=ctx)


def _set(node, name, value):
    return node.set_parameters([Parameter(name, value=value)])[0]


def test_live_parameters_take_effect_and_bad_sets_are_refused_with_a_reason(simulator):
    sim = simulator
    assert sim.get_parameter("command_timeout_s").type_ == Parameter.Type.DOUBLE  # the file's 2 became 2.0
    assert sim.gate.timings.command_timeout_s == 2.0
    r = _set(sim, "rate_hz", 10)  # an integer for a float: accepted, stays a float
    assert r.successful, r.reason
    assert sim.rate_hz == 10.0 and sim.get_parameter("rate_hz").type_ == Parameter.Type.DOUBLE
    for bad, why in (("abc", "Wrong parameter type"), (True, "Wrong parameter type"), (-5.0, "must be > 0"),
                     (math.nan, "finite"), (math.inf, "finite")):
        r = _set(sim, "rate_hz", bad)
        assert not r.successful and why in r.reason, (bad, r.reason)
    assert sim.rate_hz == 10.0 and sim.get_parameter("rate_hz").value == 10.0
    r = _set(sim, "time_mode", "lockstep")  # read-only: refused, the node keeps its mode
    assert not r.successful and "read-only" in r.reason
    assert sim.time_mode.value == "realtime"
    for name in ("mission_file", "realtime_priority", "trajectory_csv", "sea_file", "strict_remaps"):
        assert sim.describe_parameter(name).read_only, name
    # the gate's frozen timings are replaced, the validator's stale-command age follows
    for name, value in (("lockstep_timeout_s", 2.5), ("lockstep_retry_s", 0.2), ("startup_timeout_s", 9.0),
                        ("startup_settle_s", 0.0), ("command_timeout_s", 0.7)):
        assert _set(sim, name, value).successful, name
        assert getattr(sim.gate.timings, name) == value and getattr(sim, name) == value
    assert not _set(sim, "startup_settle_s", -0.1).successful
    assert _set(sim, "max_command_age_s", 0.3).successful and sim.gate.validator.max_age_ns == 300_000_000
    assert _set(sim, "warn_throttle_s", 7).successful and sim.warn.period_s == 7.0
    assert _set(sim, "duration_s", 12.5).successful and sim.duration_s == 12.5
    assert _set(sim, "duration_s", -1.0).successful and sim.duration_s == float(sim.mission.duration)
    sim.finished = True
    assert _set(sim, "exit_at_end", True).successful and sim.done  # a finished run exits now
    # every parameter says which it is
    ours = set(sim._parameters) - {"use_sim_time", "start_type_description_service"}  # rclpy's own
    assert len(ours) >= 20
    for name in ours:
        d = sim.describe_parameter(name)
        assert ("[read-only" in d.description) == d.read_only and ("[live" in d.description) != d.read_only, name


def _ros2(env, *args, timeout=60):
    if args[0] == "param":  # the verb waits 1 s for the node by default: too short for a fresh CLI's discovery on a
        args = (*args[:2], "--timeout", "20", *args[2:])  # loaded machine ("Node not found" beside two CPU hogs)
    return subprocess.run(["ros2", *args], env=env, capture_output=True, text=True, timeout=timeout)


def _sim_rate(ctx_node, seconds: float) -> float:
    """Sim seconds per wall second seen on /clock over ``seconds``."""
    from bb2_msgs_py.contract import message_class, qos_profile

    got = []
    sub = ctx_node.create_subscription(message_class("rosgraph_msgs/msg/Clock"), "/clock",
                                       lambda m: got.append((time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)),
                                       qos_profile("/clock"))
    from rclpy.executors import SingleThreadedExecutor

    ex = SingleThreadedExecutor(context=ctx_node.context)
    ex.add_node(ctx_node)
    t_match = time.monotonic() + 30.0  # a new reader needs discovery first (slow on a loaded machine)
    while not got and time.monotonic() < t_match:
        ex.spin_once(timeout_sec=0.05)
    got.clear()
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        ex.spin_once(timeout_sec=0.05)
    ex.remove_node(ctx_node)
    ctx_node.destroy_subscription(sub)
    assert len(got) > 5, "no /clock"
    return (got[-1][1] - got[0][1]) / (got[-1][0] - got[0][0])


def test_ros2_cli_on_a_running_simulator_params_qos_diagnostics(tmp_path):
    """ros2 param set/get/describe/dump; ros2 topic echo of /bb2/odom with a reliable and a best-effort
    subscription (issue 13 (6)) and of /diagnostics."""
    domain = claimed_domain()
    env = tooling_env(tooling_venv(), ROS_DOMAIN_ID=str(domain))
    proc = subprocess.Popen([sys.executable, "-m", "bb2_ros.simulator", "--ros-args",
                             "-p", f"mission_file:={MISSION}", "-p", "time_mode:=realtime", "-p", "rate_hz:=20.0",
                             "-p", "realtime_priority:=0", "-p", "hold_cpu_dma_latency:=false"],
                            cwd=REPO, env=ros_env(domain), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    probe = rclpy.create_node("param_probe", context=ctx)
    try:
        deadline = time.monotonic() + 60
        while "simulator up" not in (line := proc.stdout.readline()):
            assert proc.poll() is None and time.monotonic() < deadline, line
        assert 0.8 < _sim_rate(probe, 2.0) < 1.2  # 20 Hz = real time
        r = _ros2(env, "param", "set", "/simulator", "rate_hz", "10")
        assert r.returncode == 0 and "Set parameter successful" in r.stdout, r.stdout + r.stderr
        assert 0.4 < _sim_rate(probe, 2.0) < 0.6  # it took effect: 10 Hz = half real time
        r = _ros2(env, "param", "get", "/simulator", "rate_hz")
        assert "Double value is: 10.0" in r.stdout, r.stdout + r.stderr
        r = _ros2(env, "param", "set", "/simulator", "rate_hz", "abc")
        assert "Setting parameter failed" in r.stdout + r.stderr and "type" in r.stdout + r.stderr
        r = _ros2(env, "param", "set", "/simulator", "time_mode", "lockstep")
        assert "Setting parameter failed" in r.stdout + r.stderr and "read-only" in r.stdout + r.stderr
        r = _ros2(env, "param", "describe", "/simulator", "rate_hz", "time_mode")
        assert "[live" in r.stdout and "[read-only" in r.stdout and "Read only: true" in r.stdout, r.stdout
        r = _ros2(env, "param", "dump", "/simulator")
        assert r.returncode == 0 and "rate_hz: 10.0" in r.stdout and "time_mode: realtime" in r.stdout, r.stdout
        for reliability in ("reliable", "best_effort"):  # RViz's default and qos_profile_sensor_data
            r = _ros2(env, "topic", "echo", "--once", "--qos-reliability", reliability, "/bb2/odom",
                      "nav_msgs/msg/Odometry", timeout=60)
            assert r.returncode == 0 and "child_frame_id: base_link" in r.stdout, (reliability, r.stdout + r.stderr)
        r = _ros2(env, "topic", "echo", "--once", "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")
        assert r.returncode == 0 and "name: bb2/simulator" in r.stdout, r.stdout + r.stderr
    finally:
        probe.destroy_node()
        rclpy.shutdown(context=ctx)
        proc.terminate()
        proc.wait(timeout=20)
