"""Issue 15, point 3: the nodes of one process on sim time take /clock through one subscription
(``bb2_ros.node_common.share_sim_clock``, applied by ``run_nodes`` to a composed process): every node's clock
follows the clock messages, the followers' own subscriptions are gone, and use_sim_time can no longer be switched
(refused with the reason, the clocks untouched). Real rclpy nodes over real DDS (own context and domain)."""
from __future__ import annotations

import time

import pytest

from rosenv import claimed_domain  # noqa: E402  (tests/rosenv.py)

pytestmark = pytest.mark.ros


@pytest.fixture
def ros_context():
    rclpy = pytest.importorskip("rclpy")
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=claimed_domain())
    yield ctx
    rclpy.shutdown(context=ctx)


def _node(ctx, name: str, sim_time: bool):
    import rclpy
    from rclpy.parameter import Parameter

    return rclpy.create_node(name, context=ctx, parameter_overrides=[Parameter("use_sim_time", value=sim_time)],
                             start_parameter_services=False, enable_rosout=False)


def _clock_subscribers(node) -> list[str]:
    return sorted(i.node_name for i in node.get_subscriptions_info_by_topic("/clock"))


def _wait(pred, ex, timeout_s: float = 10.0) -> bool:
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if pred():
            return True
        ex.spin_once(timeout_sec=0.05)
    return pred()


def test_nodes_on_sim_time_share_one_clock_subscription(ros_context):
    from rosgraph_msgs.msg import Clock
    from rclpy.parameter import Parameter

    from bb2_ros.node_common import USE_SIM_TIME_FIXED, make_executor, share_sim_clock
    from bb2_msgs_py.contract import qos_profile

    lead, a, b = (_node(ros_context, n, True) for n in ("lead", "follower_a", "follower_b"))
    wall = _node(ros_context, "on_wall_time", False)
    source = _node(ros_context, "clock_source", False)
    ex = make_executor(ros_context)
    for n in (lead, a, b, wall, source):
        ex.add_node(n)
    assert _wait(lambda: _clock_subscribers(source) == ["follower_a", "follower_b", "lead"], ex), \
        _clock_subscribers(source)

    assert share_sim_clock([wall, lead, a, b]) == 3  # the node on wall time is left alone
    assert _wait(lambda: _clock_subscribers(source) == ["lead"], ex), _clock_subscribers(source)

    pub = source.create_publisher(Clock, "/clock", qos_profile("/clock"))
    for t_ns in (5_000_000_000, 5_050_000_000, 7_250_000_000):
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(t_ns, 1_000_000_000)
        pub.publish(msg)
        assert _wait(lambda t_ns=t_ns: all(n.get_clock().now().nanoseconds == t_ns for n in (lead, a, b)), ex), \
            [n.get_clock().now().nanoseconds for n in (lead, a, b)]
    assert abs(wall.get_clock().now().nanoseconds - time.time_ns()) < 10_000_000_000  # still the wall clock

    for node in (lead, a):  # switching sim time off on any of them is refused and changes nothing
        res = node.set_parameters([Parameter("use_sim_time", value=False)])[0]
        assert not res.successful and res.reason == USE_SIM_TIME_FIXED
        assert node.get_parameter("use_sim_time").value is True
    assert all(n.get_clock().now().nanoseconds == 7_250_000_000 for n in (lead, a, b))
    assert lead.set_parameters([Parameter("use_sim_time", value=True)])[0].successful  # the same value is fine
    assert _clock_subscribers(source) == ["lead"]
    for n in (lead, a, b, wall, source):
        n.destroy_node()


def test_only_nodes_with_the_same_clock_topic_share(ros_context):
    """A node alone on sim time, or alone on its clock topic (remapped: another boat's clock), keeps its own."""
    import rclpy
    from rclpy.parameter import Parameter

    from bb2_ros.node_common import make_executor, share_sim_clock

    only = _node(ros_context, "only", True)
    wall = _node(ros_context, "wall", False)
    assert share_sim_clock([only, wall]) == 0
    assert only.get_subscriptions_info_by_topic("/clock")  # untouched
    boat2 = [rclpy.create_node(n, context=ros_context, cli_args=["--ros-args", "-r", "/clock:=/boat2/clock"],
                               use_global_arguments=False, start_parameter_services=False, enable_rosout=False,
                               parameter_overrides=[Parameter("use_sim_time", value=True)]) for n in ("b2a", "b2b")]
    ex = make_executor(ros_context)
    for n in (only, wall, *boat2):
        ex.add_node(n)
    assert share_sim_clock([only, *boat2]) == 2  # the two on /boat2/clock; `only` keeps /clock to itself
    assert _wait(lambda: [i.node_name for i in wall.get_subscriptions_info_by_topic("/boat2/clock")] == ["b2a"], ex)
    assert [i.node_name for i in wall.get_subscriptions_info_by_topic("/clock")] == ["only"]
    assert only.set_parameters([Parameter("use_sim_time", value=False)])[0].successful  # not sharing: still live
    for n in (only, wall, *boat2):
        n.destroy_node()
