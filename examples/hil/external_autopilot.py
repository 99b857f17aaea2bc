#!/usr/bin/env python3
"""An "external" autopilot for the BB2 simulator node, speaking only the documented topic contract.

This is the template a hardware-in-the-loop user replaces with their own autopilot.  It knows nothing of
the simulator's internals: it subscribes to the vehicle state the simulator publishes and answers with
plane and propeller commands, stamped with the time of the state they answer.  Inside it runs the BB2
project's own guidance and control (the mission's stack: 3-D path following -> rate L1 -> rate autopilot ->
X-plane mixer, built by :func:`bb2_mission.mission_components`), so the example flies the mission.

Topics (see examples/README.md for the whole contract):

in   ``/bb2/odom``          nav_msgs/Odometry, best effort (sensor QoS)   (``--state-source odometry``, default)
in   ``/bb2/state_native``  std_msgs/Float64MultiArray, reliable          (``--state-source native``: lockstep)
out  ``/bb2/planes/cmd``    sensor_msgs/JointState delta1..delta5, position rad, frame base_link, reliable
out  ``/bb2/propeller/cmd`` sensor_msgs/JointState propeller, velocity rad/s, frame base_link, reliable

One controller tick per new state stamp (a repeated stamp -- the lockstep simulator re-sends an unanswered
state -- is answered again with the same commands, the controllers are not stepped twice).

Usage::

    python examples/hil/external_autopilot.py --mission missions/canyon.yaml [--state-source odometry|native]
        [--domain-id N]

It prints ``external autopilot ready`` once its subscriptions exist, and a line per 10 s of sim time.
"""
from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(REPO))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mission", required=True, type=Path, help="mission YAML (path, stack, adaptation)")
    p.add_argument("--state-source", choices=("odometry", "native"), default="odometry",
                   help="odometry: /bb2/odom (REP-103, real time); native: /bb2/state_native (exact, lockstep)")
    p.add_argument("--domain-id", type=int, default=None, help="ROS domain id (default: ROS_DOMAIN_ID)")
    args = p.parse_args(argv)

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from bb2_control.errors import NonFiniteInputError, PathFollowingError
    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_mission import load_mission, mission_components

    stack = mission_components(load_mission(args.mission)).stack

    kw = {"signal_handler_options": SignalHandlerOptions.NO}
    if args.domain_id is not None:
        kw["domain_id"] = args.domain_id
    rclpy.init(**kw)
    node = rclpy.create_node("external_autopilot")
    log = node.get_logger()
    joint_state = message_class("sensor_msgs/msg/JointState")
    pub_planes = node.create_publisher(joint_state, "/bb2/planes/cmd", qos_profile("/bb2/planes/cmd"))
    pub_prop = node.create_publisher(joint_state, "/bb2/propeller/cmd", qos_profile("/bb2/propeller/cmd"))
    last = {"stamp": None, "msgs": None, "ticks": 0, "t_print": 0.0}

    def on_state(state, stamp) -> None:
        """One tick: state (native frames) -> stack -> commands stamped like the state."""
        ns = cv.stamp_to_ns(stamp)
        if last["stamp"] is not None and ns <= last["stamp"]:
            if ns == last["stamp"]:  # re-sent state: answer again, do not step twice
                for pub, msg in zip((pub_planes, pub_prop), last["msgs"]):
                    pub.publish(msg)
            return
        try:
            out = stack.step(state)
        except (NonFiniteInputError, PathFollowingError, ValueError) as exc:
            log.error(f"controller failed at t = {state.t:.3f} s: {exc}", throttle_duration_sec=2.0)
            return
        planes = cv.planes_message(0.0, [math.radians(float(d)) for d in out.planes_deg])
        prop = cv.propeller_message(0.0, out.rps * 2.0 * math.pi)
        planes.header.stamp = prop.header.stamp = stamp  # the time of the state answered
        pub_planes.publish(planes)
        pub_prop.publish(prop)
        last.update(stamp=ns, msgs=(planes, prop), ticks=last["ticks"] + 1)
        if state.t >= last["t_print"] + 10.0:
            last["t_print"] = state.t
            log.info(f"t = {state.t:6.1f} s: {last['ticks']} ticks, path error horizontal "
                     f"{out.e_horizontal_m:+.2f} m, vertical {out.e_vertical_m:+.2f} m")

    if args.state_source == "odometry":
        def on_odom(msg) -> None:
            try:
                on_state(cv.odometry_to_state(msg), msg.header.stamp)
            except cv.ConversionError as exc:
                log.warning(f"ignored /bb2/odom: {exc}", throttle_duration_sec=2.0)
        node.create_subscription(message_class("nav_msgs/msg/Odometry"), "/bb2/odom", on_odom,
                                 qos_profile("/bb2/odom", reader=True))
    else:
        def on_native(msg) -> None:
            try:
                s = cv.state_native_from_message(msg)
            except cv.ConversionError as exc:
                log.warning(f"ignored /bb2/state_native: {exc}", throttle_duration_sec=2.0)
                return
            from bb2_ros.node_common import time_msg
            on_state(s, time_msg(cv.seconds_to_ns(s.t)))
        node.create_subscription(message_class("std_msgs/msg/Float64MultiArray"), "/bb2/state_native", on_native,
                                 qos_profile("/bb2/state_native", reader=True))

    stop = threading.Event()
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *_: stop.set())
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    print(f"external autopilot ready: stack {stack.name}, state from "
          f"{'/bb2/odom' if args.state_source == 'odometry' else '/bb2/state_native'}", flush=True)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
    finally:
        print(f"external autopilot: {last['ticks']} controller ticks", flush=True)
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
