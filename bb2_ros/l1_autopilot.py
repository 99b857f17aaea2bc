"""``l1_autopilot`` node: rate command + vehicle state -> virtual plane commands (δV, δH) and the propeller.

A thin shell around the mission stack's inner loop (``stack.inner``: rate L1 + proportional rate autopilot)
and speed command (``stack.speed``), built by the mission runner's factory.  For each state stamp it waits
for the rate command with the same stamp (``/bb2/guidance/rate_cmd``), converts the flow-frame commands to
body-rate references (:func:`bb2_control.path_following.flow_to_body_rates`, as ``Stack.step`` does), steps
the inner loop once and publishes, stamped like the state:

* ``/bb2/autopilot/vh_cmd`` (``JointState`` delta_V, delta_H, rad);
* ``/bb2/propeller/cmd`` (``JointState`` propeller, velocity rad/s).

A stamp already answered is answered again from the cache (lockstep re-sends); the loop never steps twice.

Parameters: ``mission_file``, ``state_source`` (native | odometry), ``status_period_s``, ``strict_remaps``.
"""
from __future__ import annotations

import math
import sys
from typing import Sequence

from rclpy.node import Node

from bb2_control.errors import NonFiniteInputError
from bb2_control.path_following import flow_to_body_rates
from bb2_msgs_py import conversions as cv
from bb2_msgs_py.contract import FRAME_BASE_LINK, message_class, node_topic_name, qos_profile

from bb2_mission.components import build_mission_stack
from bb2_ros.node_common import (NodeStatus, StampedCache, build_piece, check_remaps, contract_publisher, declare,
                                 declare_callback_priority,
                                 mission_only, node_frame, node_options, require_choice, require_positive,
                                 require_rate_stack, run_node, state_topic, subscribe_state, time_msg)

TOPICS = ("/bb2/state_native", "/bb2/odom", "/bb2/guidance/rate_cmd", "/bb2/autopilot/vh_cmd",
          "/bb2/propeller/cmd", "/bb2/status", "/bb2/nav/state_native")
KEEP = 20  # pending inputs kept per kind (stamps not yet paired)


class L1Autopilot(Node):
    def __init__(self, argv: Sequence[str]):
        super().__init__("l1_autopilot", **node_options())
        node = self
        self.base_link = node_frame(node, FRAME_BASE_LINK)  # boat1/base_link in /boat1
        mission_file = declare(node, "mission_file", "", "mission YAML (same file as `bb2-sim mission`)")
        source = require_choice("state_source", declare(
            node, "state_source", "native", "native (/bb2/state_native, exact) | odometry (/bb2/odom)"),
            ("native", "odometry"))
        period = require_positive("status_period_s", declare(node, "status_period_s", 1.0,
                                                             "wall period of this node's /bb2/status"))
        strict = bool(declare(node, "strict_remaps", False, "a remap rule naming no topic of this node is an error"))
        check_remaps(node, argv, TOPICS, strict=strict)
        declare_callback_priority(self)
        self.mission = mission_only(mission_file)
        self.stack = build_piece(self.mission, build_mission_stack)  # its inner loop and speed command run here
        require_rate_stack(self.stack)
        self.cache = StampedCache()
        self.states: dict[int, object] = {}
        self.rates: dict[int, tuple[float, float]] = {}
        self.counts = {"answered": 0, "rejected": 0, "errors": 0}
        self.pub = {n: contract_publisher(node, n) for n in TOPICS[3:5]}
        self.sub_rate = node.create_subscription(message_class("geometry_msgs/msg/Vector3Stamped"),
                                                 node_topic_name("/bb2/guidance/rate_cmd"), self._on_rate,
                                                 qos_profile("/bb2/guidance/rate_cmd", reader=True))
        self.sub_state = subscribe_state(node, source, self._on_state, state_topic(self.mission))
        self.status = NodeStatus(node, "bb2/l1_autopilot", period, lambda: {
            "mission": self.mission.name,
            "callback_scheduling": self.callback_scheduling, "stack": self.stack.name,
            "state_source": source,
            "adaptation": str(self.stack.adaptation).lower(),
            **{k: str(v) for k, v in (self.counts | self.cache.counts()).items()}})

    def _on_rate(self, msg) -> None:
        try:
            q_c, r_c = cv.rate_command_from_message(msg, frame_id=self.base_link)
        except cv.ConversionError as exc:
            self.counts["rejected"] += 1
            self.get_logger().warning(f"rejected rate command: {exc}", throttle_duration_sec=2.0)
            return
        if not (math.isfinite(q_c) and math.isfinite(r_c)):
            self.counts["rejected"] += 1
            self.get_logger().warning(f"rejected non-finite rate command ({q_c}, {r_c})",
                                           throttle_duration_sec=2.0)
            return
        ns = cv.stamp_to_ns(msg.header.stamp)
        self._offer(ns, rate=(q_c, r_c))

    def _on_state(self, state, stamp_ns: int) -> None:
        self._offer(stamp_ns, state=state)

    def _offer(self, ns: int, *, state=None, rate=None) -> None:
        if self.cache.replay(ns):
            return
        if state is not None:
            self.states[ns] = state
        if rate is not None:
            self.rates[ns] = rate
        if ns in self.states and ns in self.rates:
            self._answer(ns, self.states.pop(ns), self.rates.pop(ns))
            for d in (self.states, self.rates):  # drop inputs older than the answered stamp
                for k in [k for k in d if k <= ns]:
                    del d[k]
        for d in (self.states, self.rates):
            while len(d) > KEEP:
                del d[min(d)]

    def _answer(self, ns: int, state, rate: tuple[float, float]) -> None:
        stack = self.stack
        try:
            x = stack.inputs(state)  # the stack's own frame conversion (shared with Stack.step)
            q_ref, r_ref = flow_to_body_rates(rate[0], rate[1], x["v_flu"])
            dV_deg, dH_deg, _ = stack.inner.step(q_ref, r_ref, x["q_up"], x["r_left"])
            rps = stack.speed.step()
        except (NonFiniteInputError, ValueError) as exc:
            self.counts["errors"] += 1
            self.get_logger().error(f"autopilot failed at t = {state.t:.3f} s: {exc}", throttle_duration_sec=2.0)
            return
        st = time_msg(ns)
        vh = cv.vh_message(0.0, math.radians(dV_deg), math.radians(dH_deg), frame_id=self.base_link)
        prop = cv.propeller_message(0.0, rps * 2.0 * math.pi, frame_id=self.base_link)
        vh.header.stamp = prop.header.stamp = st
        self.cache.store(ns, [(self.pub["/bb2/autopilot/vh_cmd"], vh), (self.pub["/bb2/propeller/cmd"], prop)])
        self.counts["answered"] += 1


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_ros l1_autopilot``)."""
    return run_node("l1_autopilot", L1Autopilot, args)


if __name__ == "__main__":
    sys.exit(main())
