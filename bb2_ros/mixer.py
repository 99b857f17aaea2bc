"""``mixer`` node: virtual plane commands (δV, δH) -> the five plane commands δ1..δ5.

A thin shell around the mission stack's X-plane mixer (only the mixer, built by
:func:`bb2_mission.components.build_mixer`): each ``/bb2/autopilot/vh_cmd`` (rad) becomes one
``/bb2/planes/cmd`` (``JointState`` delta1..delta5, rad) with the same stamp.  A stamp already answered is
answered again from the cache.

Parameters: ``mission_file``, ``status_period_s``, ``strict_remaps``.
"""
from __future__ import annotations

import math
import sys
from typing import Sequence

from rclpy.node import Node

from bb2_control.errors import NonFiniteInputError
from bb2_msgs_py import conversions as cv
from bb2_msgs_py.contract import FRAME_BASE_LINK, message_class, node_topic_name, qos_profile

from bb2_mission.components import build_mixer
from bb2_ros.node_common import (NodeStatus, StampedCache, build_piece, check_remaps, contract_publisher, declare,
                                 declare_callback_priority,
                                 mission_only, node_frame, node_options, require_positive, run_node)

TOPICS = ("/bb2/autopilot/vh_cmd", "/bb2/planes/cmd", "/bb2/status")


class Mixer(Node):
    def __init__(self, argv: Sequence[str]):
        super().__init__("mixer", **node_options())
        node = self
        self.base_link = node_frame(node, FRAME_BASE_LINK)  # boat1/base_link in /boat1
        mission_file = declare(node, "mission_file", "", "mission YAML (same file as `bb2-sim mission`)")
        period = require_positive("status_period_s", declare(node, "status_period_s", 1.0,
                                                             "wall period of this node's /bb2/status"))
        strict = bool(declare(node, "strict_remaps", False, "a remap rule naming no topic of this node is an error"))
        check_remaps(node, argv, TOPICS, strict=strict)
        declare_callback_priority(self)
        self.mission = mission_only(mission_file)
        self.mixer = build_piece(self.mission, build_mixer)  # only the mixer: no hull, no path, no guidance
        self.cache = StampedCache()
        self.counts = {"answered": 0, "rejected": 0}
        self.pub = contract_publisher(node, "/bb2/planes/cmd")
        self.sub = node.create_subscription(message_class("sensor_msgs/msg/JointState"),
                                            node_topic_name("/bb2/autopilot/vh_cmd"), self._on_vh,
                                            qos_profile("/bb2/autopilot/vh_cmd", reader=True))
        self.status = NodeStatus(node, "bb2/mixer", period, lambda: {
            "mission": self.mission.name,
            "callback_scheduling": self.callback_scheduling,
            **{k: str(v) for k, v in (self.counts | self.cache.counts()).items()}})

    def _on_vh(self, msg) -> None:
        ns = cv.stamp_to_ns(msg.header.stamp)
        if self.cache.replay(ns):
            return
        try:
            dV, dH = cv.vh_from_message(msg)
            planes_deg = self.mixer.step(math.degrees(dV), math.degrees(dH))
        except (cv.ConversionError, NonFiniteInputError) as exc:
            self.counts["rejected"] += 1
            self.get_logger().warning(f"rejected vh command: {exc}", throttle_duration_sec=2.0)
            return
        out = cv.planes_message(0.0, [math.radians(float(d)) for d in planes_deg], frame_id=self.base_link)
        out.header.stamp = msg.header.stamp
        self.cache.store(ns, [(self.pub, out)])
        self.counts["answered"] += 1


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_ros mixer``)."""
    return run_node("mixer", Mixer, args)


if __name__ == "__main__":
    sys.exit(main())
