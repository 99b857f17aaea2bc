"""bb2-launch's monitor learns the recorder's last acknowledgement even when it matches the recorder after it
was sent (real recorder, real DDS).

A lockstep run can end within a second of wall time on a fast machine; the monitor, whose participant may discover
the recorder's ack writer only after the last acknowledgement went out, then waited 30 s for a recorder that held
everything and said "stopping anyway" (a clean-clone CI run of test_composition).  The ack writer keeps its latest
acknowledgements (transient local); the monitor's reader now asks for them.
"""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")

from bb2_msgs_py import conversions as cv  # noqa: E402
from bb2_msgs_py.contract import message_class, qos_profile  # noqa: E402
from bb2_sim.state import VehicleState  # noqa: E402

from rosenv import SpinningNode, claimed_domain, ros_env  # noqa: E402  (tests/rosenv.py)

REPO = Path(__file__).resolve().parents[2]


def test_the_launch_monitor_started_after_the_last_ack_still_learns_it(tmp_path):
    from bb2_tools.graph_monitor import GraphMonitor

    domain = claimed_domain()
    rec = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--out", str(tmp_path / "bag")], cwd=REPO,
                           env=ros_env(domain), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    spinner = SpinningNode("late_ack_test", domain).start()
    node = spinner.node
    acks: list[int] = []  # what a reader matched before the run gets
    node.create_subscription(message_class("std_msgs/msg/Header"), "/bb2/recorder/ack",
                             lambda m: acks.append(cv.stamp_to_ns(m.stamp)), qos_profile("/bb2/recorder/ack",
                                                                                         reader=True))
    monitor = None
    try:
        pub = node.create_publisher(message_class("std_msgs/msg/Float64MultiArray"), "/bb2/state_native",
                                    qos_profile("/bb2/state_native"))
        end = time.monotonic() + 60
        while pub.get_subscription_count() == 0 or node.count_publishers("/bb2/recorder/ack") == 0:
            assert rec.poll() is None, rec.communicate()[0][-3000:]
            assert time.monotonic() < end, "the recorder never came up"
            time.sleep(0.05)
        time.sleep(0.5)                     # the early reader matched too
        for k in range(5):                  # a short run: five states 0.05 s apart
            pub.publish(cv.state_native_message(VehicleState.from_vector(0.05 * k, [0.0] * 12)))
            time.sleep(0.05)
        end = time.monotonic() + 10
        while (not acks or time.monotonic() < end - 9) and time.monotonic() < end:
            time.sleep(0.05)
        assert acks, "the recorder sent no acknowledgement"
        n_acks = len(acks)
        monitor = GraphMonitor(domain, node_name="late_monitor")   # after the run: nothing new will be sent
        end = time.monotonic() + 15
        while monitor.recorder_ack_s is None and time.monotonic() < end:
            time.sleep(0.05)
        assert len(acks) == n_acks          # indeed nothing new was sent meanwhile
        assert monitor.recorder_ack_s is not None, "the monitor never learnt the recorder's last acknowledgement"
        assert cv.seconds_to_ns(monitor.recorder_ack_s) == max(acks), (monitor.recorder_ack_s, acks)
    finally:
        if monitor is not None:
            monitor.close()
        spinner.close()
        rec.send_signal(signal.SIGINT)
        try:
            rec.wait(30)
        except subprocess.TimeoutExpired:
            rec.kill()
            rec.wait()


def test_the_launch_monitor_takes_the_sim_time_of_the_simulators_status_when_no_clock_came():
    """A graph that flies within the launcher's start-up may end before the monitor's /clock reader matched: the
    simulator's status (its sim time, sent with every status) still gives the closing line its sim time."""
    from bb2_tools.graph_monitor import GraphMonitor

    domain = claimed_domain()
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = rclpy.create_node("status_only_test", context=ctx)
    diag = message_class("diagnostic_msgs/msg/DiagnosticArray")
    status_t = message_class("diagnostic_msgs/msg/DiagnosticStatus")
    kv_t = message_class("diagnostic_msgs/msg/KeyValue")

    def status(state: str, t: float):
        st = status_t(name="bb2/simulator", hardware_id="/simulator",
                      values=[kv_t(key="state", value=state), kv_t(key="sim_time_s", value=f"{t:.6f}")])
        return diag(status=[st])

    monitor = GraphMonitor(domain, node_name="status_monitor", end_at="simulator")
    try:
        pub = node.create_publisher(diag, "/bb2/status", qos_profile("/bb2/status"))
        end = time.monotonic() + 30
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)
        assert pub.get_subscription_count() > 0, "the monitor's status reader never matched"
        pub.publish(status("running", 7.25))
        end = time.monotonic() + 10
        while monitor.sim_time_s is None and time.monotonic() < end:
            time.sleep(0.05)
        assert monitor.sim_time_s == 7.25 and not monitor.mission_complete
        pub.publish(status("finished", 20.0))
        end = time.monotonic() + 10
        while not monitor.mission_complete and time.monotonic() < end:
            time.sleep(0.05)
        assert monitor.mission_complete and monitor.sim_time_s == 20.0, monitor.sim_time_s
        pub.publish(status("finished", 3.0))  # an older time (a status late on its way) never takes it back
        time.sleep(0.5)
        assert monitor.sim_time_s == 20.0
        # nor does a /clock sample the monitor polls after the status but which was sent before it (its DDS source
        # timestamp older); a lower /clock sent after the status (a restarted simulator) is taken
        from rclpy.serialization import serialize_message

        def clock(t: float) -> bytes:
            return serialize_message(message_class("rosgraph_msgs/msg/Clock")(clock=cv.stamp(t)))
        monitor._on_clock(clock(19.95), time.time() - 1.0)
        assert monitor.sim_time_s == 20.0
        monitor._on_clock(clock(20.05), time.time() - 1.0)   # newer sim time: taken whenever it was sent
        assert monitor.sim_time_s == 20.05
        monitor._on_clock(clock(0.5), time.time())
        assert monitor.sim_time_s == 0.5
    finally:
        monitor.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
