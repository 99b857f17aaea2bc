"""``path_following`` node: vehicle state + Bernstein path -> pitch/yaw rate commands q_c, r_c.

A thin shell around the path-following law of the mission's stack (``stack.guidance``, built by the mission
runner's factory): per state it publishes

* ``/bb2/guidance/rate_cmd`` (``Vector3Stamped``, base_link FLU: (0, -q_c, r_c) rad/s), stamped with the state;
* ``/bb2/guidance/path_error`` (path frame: along, left, up; m);
* ``/bb2/mission/progress`` (fraction of the path length travelled, from the virtual time).

The path comes from the planner's ``/bb2/path/bernstein`` (``path_source: topic``, exact) or straight from
the mission file (``path_source: mission``).  A state whose stamp was already answered (the lockstep
simulator re-sends unanswered states) is answered again from the cache, the law is not stepped twice.

Restarted mid-run (parameter ``rejoin_run: true``, which ``bb2-launch --restart path_following=restart`` sets on
every restart): if the first state this node answers is not the run's first (t > 0), it rejoins the run where it
stands — the virtual time goes to the path point closest to the vehicle
(:meth:`bb2_control.path_following.PathFollowingLaw.rejoin`), as the law had been holding it — instead of chasing
the path's start; said in its log and its status (``rejoined_at_s``).

Parameters: ``mission_file``, ``state_source`` (native | odometry), ``path_source`` (topic | mission),
``status_period_s``, ``strict_remaps``.
"""
from __future__ import annotations

import dataclasses
import sys
from typing import Sequence

import numpy as np
from std_msgs.msg import Float64

from rclpy.node import Node

from bb2_control.errors import NonFiniteInputError, PathFollowingError
from bb2_msgs_py import conversions as cv
from bb2_msgs_py.contract import FRAME_BASE_LINK, FRAME_PATH, message_class, node_topic_name, qos_profile

from bb2_mission.components import build_mission_stack
from bb2_ros.node_common import (NodeStatus, StampedCache, build_piece, check_remaps, contract_publisher, declare,
                                 declare_callback_priority,
                                 mission_only, node_frame, node_options, require_choice, require_positive,
                                 require_rate_stack, run_node, state_topic, subscribe_state, time_msg)

PROGRESS_SAMPLES = 2001  # arc-length table for the progress (linear interpolation: < 1e-4 m on the shipped paths)
TOPICS = ("/bb2/state_native", "/bb2/odom", "/bb2/path/bernstein", "/bb2/guidance/rate_cmd",
          "/bb2/guidance/path_error", "/bb2/mission/progress", "/bb2/status", "/bb2/nav/state_native")


REJOIN_AFTER_S = 1e-6
"""A first state later than this (sim s; runs start at t = 0) means the node joined a run under way."""


class PathFollowing(Node):
    def __init__(self, argv: Sequence[str]):
        super().__init__("path_following", **node_options())
        node = self
        self.base_link = node_frame(node, FRAME_BASE_LINK)  # boat1/base_link in /boat1
        self.path_frame = node_frame(node, FRAME_PATH)
        mission_file = declare(node, "mission_file", "", "mission YAML (same file as `bb2-sim mission`)")
        source = require_choice("state_source", declare(
            node, "state_source", "native", "native (/bb2/state_native, exact) | odometry (/bb2/odom)"),
            ("native", "odometry"))
        self.path_source = require_choice("path_source", declare(
            node, "path_source", "topic", "topic (/bb2/path/bernstein from the planner) | mission (mission file)"),
            ("topic", "mission"))
        self.rejoin_run = bool(declare(node, "rejoin_run", False, "this node joins a run under way (bb2-launch sets "
                                       "it on a restart): the virtual time starts at the path point closest to "
                                       "the vehicle, not at the path's start"))
        period = require_positive("status_period_s", declare(node, "status_period_s", 1.0,
                                                             "wall period of this node's /bb2/status"))
        strict = bool(declare(node, "strict_remaps", False, "a remap rule naming no topic of this node is an error"))
        check_remaps(node, argv, TOPICS, strict=strict)
        declare_callback_priority(self)

        self.mission = mission_only(mission_file)
        self.stack = None
        self.length_m = float("nan")
        self.cache = StampedCache()
        self.counts = {"states": 0, "answered": 0, "waiting_for_path": 0, "errors": 0}
        self.finished = False
        self.rejoined_at_s = ""  # the sim time this node joined a run under way ('' = it started with the run)
        self._stepped = False
        self.pub = {n: contract_publisher(node, n) for n in TOPICS[3:6]}
        if self.path_source == "mission":
            self._build(self.mission.path)
        else:
            self.sub_path = node.create_subscription(message_class("std_msgs/msg/Float64MultiArray"),
                                                     node_topic_name("/bb2/path/bernstein"), self._on_path,
                                                     qos_profile("/bb2/path/bernstein", reader=True))
        self.sub_state = subscribe_state(node, source, self._on_state, state_topic(self.mission))
        self.status = NodeStatus(node, "bb2/path_following", period, lambda: {
            "mission": self.mission.name,
            "callback_scheduling": self.callback_scheduling, "path_source": self.path_source,
            "state_source": source,
            "path_received": str(self.stack is not None).lower(), "finished": str(self.finished).lower(),
            "rejoined_at_s": self.rejoined_at_s,
            **{k: str(v) for k, v in (self.counts | self.cache.counts()).items()}})

    def _build(self, path) -> None:
        if self.stack is not None:
            return
        mission = self.mission
        if self.path_source == "topic":
            if not (path.frame == mission.path.frame and path.t0 == mission.path.t0 and path.tf == mission.path.tf
                    and np.array_equal(path.control_points, mission.path.control_points)):
                self.get_logger().warning("the planner's path differs from this node's mission path: "
                                               "flying the planner's")
            mission = dataclasses.replace(mission, path=path)
        stack = build_piece(mission, build_mission_stack)  # its guidance runs here
        require_rate_stack(stack)
        self.stack = stack
        # progress = s(gamma) / L from a table of the arc length (np.interp per tick, not a quadrature)
        self._s_t, self._s = stack.path.cumulative_arc_length(PROGRESS_SAMPLES)
        self.length_m = float(self._s[-1])
        self.get_logger().info(f"path following ready: stack {stack.name}, path {path!r}, "
                                    f"length {self.length_m:.1f} m")

    def _on_path(self, msg) -> None:
        try:
            path = cv.bernstein_from_message(msg, name=self.mission.path.name)
        except cv.ConversionError as exc:
            self.get_logger().error(f"ignored /bb2/path/bernstein: {exc}")
            return
        self._build(path)

    def _on_state(self, state, stamp_ns: int) -> None:
        self.counts["states"] += 1
        if self.stack is None:
            self.counts["waiting_for_path"] += 1
            return
        if self.cache.replay(stamp_ns):
            return
        stack = self.stack
        try:
            x = stack.inputs(state)  # the stack's own frame conversion (shared with Stack.step)
            if not self._stepped:
                self._stepped = True
                if self.rejoin_run and state.t > REJOIN_AFTER_S:  # restarted mid-run: rejoin where it is
                    gamma, dist = stack.guidance.rejoin(x["p"])
                    self.rejoined_at_s = f"{state.t:.3f}"
                    self.get_logger().warning(
                        f"joined a run under way at t = {state.t:.3f} s: virtual time set to the closest path point, "
                        f"gamma = {gamma:.3f} s ({dist:.2f} m from the vehicle)")
            pf = stack.guidance.step(x["p"], x["R_BI"], x["v_flu"])
        except (NonFiniteInputError, PathFollowingError, ValueError) as exc:
            self.counts["errors"] += 1
            self.get_logger().error(f"path following failed at t = {state.t:.3f} s: {exc}",
                                         throttle_duration_sec=2.0)
            return
        st = time_msg(stamp_ns)
        rate = cv.rate_command_message(state.t, pf.q_c, pf.r_c, frame_id=self.base_link)
        rate.header.stamp = st
        path = stack.path
        progress = Float64(data=float(np.interp(min(pf.gamma, path.tf), self._s_t, self._s)) / self.length_m)
        self.finished = bool(pf.finished)
        first = []
        if progress.data >= 1.0:
            # the finishing tick's progress goes out before the rate command: it then reaches a recorder before
            # the /clock of the next step can (the simulator steps only once this answer went round), so the
            # bag logs it at this tick's time, where bb2-analyze ends the mission as the runner does
            self.pub["/bb2/mission/progress"].publish(progress)
            first = [(self.pub["/bb2/mission/progress"], progress)]
        self.pub["/bb2/guidance/rate_cmd"].publish(rate)  # first (else): the autopilot waits for it
        err = cv.path_error_message(state.t, pf.p_T, frame_id=self.path_frame)
        err.header.stamp = st
        rest = [(self.pub["/bb2/guidance/path_error"], err)] + ([] if first else
                                                                [(self.pub["/bb2/mission/progress"], progress)])
        self.cache.store(stamp_ns, rest, replay_also=first + [(self.pub["/bb2/guidance/rate_cmd"], rate)])
        self.counts["answered"] += 1


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_ros path_following``)."""
    return run_node("path_following", PathFollowing, args)


if __name__ == "__main__":
    sys.exit(main())
