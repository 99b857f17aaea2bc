#!/usr/bin/env python3
"""An "external" autopilot for the BB2 simulator node, speaking only the documented topic contract.

This is the template a hardware-in-the-loop user replaces with their own autopilot.  It knows nothing of
the simulator's internals: it reads the vehicle's state (or its sensors) from the topics the simulator publishes
and answers with plane and propeller commands, stamped with the time they answer.  Inside it runs the BB2
project's own guidance and control (the mission's stack: 3-D path following -> rate L1 -> rate autopilot ->
X-plane mixer, built by :func:`bb2_mission.mission_components`), so the example flies the mission.

Where the state comes from (``--state-source``):

``odometry`` (default)  ``/bb2/odom``  nav_msgs/Odometry, best effort (sensor QoS): the ground truth, real time
``native``              ``/bb2/state_native``  std_msgs/Float64MultiArray, reliable: the exact truth, lockstep
``sensors``             the sensors only, as an autopilot on a real boat: ``/bb2/sensors/imu``, ``pressure``,
                        ``dvl``, ``dvl/water_track`` and ``gps`` (reliable, keep last 100) into a navigation filter
                        of its own (:class:`bb2_control.navigation.NavigationFilter`, for the suite of the mission's
                        ``sensors:`` block -- the boat's sensor datasheet -- started at the mission's initial
                        state), which gives the state the stack flies on.  It ticks once per step of the bench's
                        clock (``--tick clock``: ``/clock``, real time) or on the lockstep handshake (``--tick
                        handshake``: the stamp of ``/bb2/state_native``, of which only the time is read); at each
                        tick the filter takes the samples received so far, in the order they came out of the
                        sensors, and is predicted on to the tick.

out  ``/bb2/planes/cmd``    sensor_msgs/JointState delta1..delta5, position rad, frame base_link, reliable
out  ``/bb2/propeller/cmd`` sensor_msgs/JointState propeller, velocity rad/s, frame base_link, reliable

One controller tick per new state stamp (a repeated stamp -- the lockstep simulator re-sends an unanswered
state -- is answered again with the same commands, the controllers are not stepped twice).

In lockstep with ``--state-source sensors`` the simulator's mission must say ``navigation: sensors``: the simulator
then publishes a step's samples before the state of the next step, so the tick finds them all, and the flight is
the library runner's (``bb2-sim mission``) with that mission.

Usage::

    python examples/hil/external_autopilot.py --mission missions/canyon.yaml
        [--state-source odometry|native|sensors] [--tick clock|handshake] [--domain-id N]

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
    p.add_argument("--state-source", choices=("odometry", "native", "sensors"), default="odometry",
                   help="odometry: /bb2/odom (REP-103, real time); native: /bb2/state_native (exact, lockstep); "
                        "sensors: /bb2/sensors/* into a navigation filter of its own")
    p.add_argument("--tick", choices=("clock", "handshake"), default="clock",
                   help="with --state-source sensors: tick on /clock (real time, default) or on the lockstep "
                        "handshake (the stamp of /bb2/state_native)")
    p.add_argument("--domain-id", type=int, default=None, help="ROS domain id (default: ROS_DOMAIN_ID)")
    p.add_argument("--realtime-priority", type=int, default=0, metavar="N",
                   help="SCHED_FIFO priority 1-99 of the thread that runs the callbacks and of the middleware's "
                        "threads, once everything is built "
                        "(0: normal scheduling): a real autopilot has a computer of its own; one sharing the "
                        "bench's CPU with other work must not be starved past the simulator's command timeout")
    args = p.parse_args(argv)
    if not 0 <= args.realtime_priority <= 99:
        p.error(f"--realtime-priority must be in 0..99, got {args.realtime_priority}")

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from bb2_control.errors import NonFiniteInputError, PathFollowingError
    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import FRAME_BASE_LINK, frame_prefix, message_class, qos_profile, vehicle_frame
    from bb2_mission import MissionError, load_mission, mission_components

    try:
        mission = load_mission(args.mission)
    except MissionError as exc:   # bad input: one line, exit 2 (not a traceback)
        p.exit(2, f"{p.prog}: error: {exc}\n")
    parts = mission_components(mission)
    stack = parts.stack
    nav = None
    if args.state_source == "sensors":
        from bb2_mission.components import build_navigation_filter, build_sensor_suite

        suite = build_sensor_suite(mission, parts.model)
        if suite is None:
            p.error(f"--state-source sensors needs the boat's sensors: the mission {args.mission} has no "
                    f"sensors: block (e.g. 'sensors: tactical')")
        nav = build_navigation_filter(suite, parts.simulator)

    kw = {"signal_handler_options": SignalHandlerOptions.NO}
    if args.domain_id is not None:
        kw["domain_id"] = args.domain_id
    rclpy.init(**kw)
    node = rclpy.create_node("external_autopilot")
    # the vehicle's frames (base_link; boat1/base_link when run in /boat1 with --ros-args -r __ns:=/boat1)
    prefix = frame_prefix(node.get_namespace())
    base_link = vehicle_frame(FRAME_BASE_LINK, prefix)
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
        planes = cv.planes_message(0.0, [math.radians(float(d)) for d in out.planes_deg], frame_id=base_link)
        prop = cv.propeller_message(0.0, out.rps * 2.0 * math.pi, frame_id=base_link)
        planes.header.stamp = prop.header.stamp = stamp  # the time of the state answered
        pub_planes.publish(planes)
        pub_prop.publish(prop)
        last.update(stamp=ns, msgs=(planes, prop), ticks=last["ticks"] + 1)
        if state.t >= last["t_print"] + 10.0:
            last["t_print"] = state.t
            log.info(f"t = {state.t:6.1f} s: {last['ticks']} ticks, path error horizontal "
                     f"{out.e_horizontal_m:+.2f} m, vertical {out.e_vertical_m:+.2f} m")

    pending = {"samples": [], "ticks": []}   # --state-source sensors: what arrived since the last tick

    def native_state(msg):
        """The state of a /bb2/state_native message, or None (said, throttled) when it is malformed."""
        try:
            return cv.state_native_from_message(msg)
        except cv.ConversionError as exc:
            log.warning(f"ignored /bb2/state_native: {exc}", throttle_duration_sec=2.0)
            return None

    if args.state_source == "odometry":
        def on_odom(msg) -> None:
            try:
                on_state(cv.odometry_to_state(msg, child_frame_id=base_link), msg.header.stamp)
            except cv.ConversionError as exc:
                log.warning(f"ignored /bb2/odom: {exc}", throttle_duration_sec=2.0)
        node.create_subscription(message_class("nav_msgs/msg/Odometry"), "/bb2/odom", on_odom,
                                 qos_profile("/bb2/odom", reader=True))
    elif args.state_source == "native":
        def on_native(msg) -> None:
            s = native_state(msg)
            if s is not None:
                on_state(s, cv.stamp(s.t))
        node.create_subscription(message_class("std_msgs/msg/Float64MultiArray"), "/bb2/state_native", on_native,
                                 qos_profile("/bb2/state_native", reader=True))
    else:
        from bb2_msgs_py.contract import topic as contract_topic
        from bb2_msgs_py.sensor_conversions import NAVIGATION_SENSOR_TOPICS, sample_from_message, sample_order

        def on_sample(name: str):
            def cb(msg) -> None:
                try:
                    pending["samples"].append(sample_from_message(name, msg, suite.config, frame_prefix=prefix))
                except ValueError as exc:
                    log.warning(f"ignored {name}: {exc}", throttle_duration_sec=2.0)
            return cb
        for name in NAVIGATION_SENSOR_TOPICS:
            node.create_subscription(message_class(contract_topic(name).type), name, on_sample(name),
                                     qos_profile(name, reader=True))
        if args.tick == "clock":
            node.create_subscription(message_class("rosgraph_msgs/msg/Clock"), "/clock",
                                     lambda msg: pending["ticks"].append(msg.clock), qos_profile("/clock", reader=True))
        else:  # the handshake: only the time of the state is read, never the state
            def on_handshake(msg) -> None:
                s = native_state(msg)
                if s is not None:
                    pending["ticks"].append(cv.stamp(s.t))
            node.create_subscription(message_class("std_msgs/msg/Float64MultiArray"), "/bb2/state_native",
                                     on_handshake, qos_profile("/bb2/state_native", reader=True))

    def drain() -> None:
        """Take in every message already received (a tick must see the samples published before it)."""
        quiet = 0
        for _ in range(1000):
            before = (len(pending["samples"]), len(pending["ticks"]))
            executor.spin_once(timeout_sec=0.0)
            quiet = quiet + 1 if (len(pending["samples"]), len(pending["ticks"])) == before else 0
            if quiet >= 2:
                return

    def on_ticks() -> None:
        """--state-source sensors: the filter takes the samples, then the stack flies the newest tick."""
        drain()
        samples, ticks = sorted(pending["samples"], key=sample_order), pending["ticks"]
        pending["samples"], pending["ticks"] = [], []
        nav.update(samples)
        stamp = max(ticks, key=cv.stamp_to_ns)  # in real time a late tick is superseded by the newer one
        on_state(nav.state(cv.stamp_to_seconds(stamp)), stamp)

    stop = threading.Event()
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *_: stop.set())
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    source = {"odometry": "/bb2/odom", "native": "/bb2/state_native",
              "sensors": f"/bb2/sensors/* (suite {nav.suite.name if nav else ''}, tick {args.tick})"}
    if args.realtime_priority:  # now that the imports and builds are done: this thread (the callbacks) and the
        # middleware's (Fast DDS's reception threads, which hand it the messages); a refusal changes none of them
        from bb2_ros.node_common import set_callback_priority

        print(f"external autopilot: callbacks at {set_callback_priority(args.realtime_priority)}", flush=True)
    print(f"external autopilot ready: stack {stack.name}, state from {source[args.state_source]}", flush=True)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
            if pending["ticks"]:
                on_ticks()
    finally:
        print(f"external autopilot: {last['ticks']} controller ticks", flush=True)
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
