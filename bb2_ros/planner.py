"""``planner`` node: publishes the mission's Bernstein path, latched (transient local).

* ``/bb2/path`` (``nav_msgs/Path``, ENU ``map``): ``path_samples`` samples, orientation along the tangent;
* ``/bb2/path/bernstein`` (``std_msgs/Float64MultiArray``): the exact control points and time span in the
  path's own frame (layout in :func:`bb2_msgs_py.conversions.bernstein_message`), which the path-following
  node flies, so the graph follows exactly the path the library runner follows.

Parameters: ``mission_file``, ``path_samples`` (>= 2), ``status_period_s``, ``strict_remaps``.
"""
from __future__ import annotations

import sys
from typing import Sequence

from rclpy.node import Node

from bb2_msgs_py import conversions as cv
from bb2_ros.node_common import (NodeConfigError, NodeStatus, check_remaps, contract_publisher, declare, mission_only,
                                 node_options, require_positive, run_node)

TOPICS = ("/bb2/path", "/bb2/path/bernstein", "/bb2/status")


class Planner(Node):
    def __init__(self, argv: Sequence[str]):
        super().__init__("planner", **node_options())
        node = self
        mission_file = declare(node, "mission_file", "", "mission YAML (same file as `bb2-sim mission`)")
        n = int(declare(node, "path_samples", 1001, "number of samples published on /bb2/path (>= 2)"))
        if n < 2:
            raise NodeConfigError(f"parameter 'path_samples' must be >= 2, got {n}")
        period = require_positive("status_period_s", declare(node, "status_period_s", 1.0,
                                                             "wall period of this node's /bb2/status"))
        strict = bool(declare(node, "strict_remaps", False, "a remap rule naming no topic of this node is an error"))
        check_remaps(node, argv, TOPICS, strict=strict)
        mission = mission_only(mission_file)
        self.path = mission.path
        path_native = self.path.to_frame("native")
        _, p_native = path_native.sample(n)
        pubs = {name: contract_publisher(node, name) for name in TOPICS[:2]}
        pubs["/bb2/path"].publish(cv.path_message(0.0, p_native))
        pubs["/bb2/path/bernstein"].publish(cv.bernstein_message(self.path))
        self.pubs = pubs
        self.status = NodeStatus(node, "bb2/planner", period, lambda: {
            "mission": mission.name, "path": mission.path_source, "degree": str(self.path.degree),
            "frame": self.path.frame, "t0_s": repr(self.path.t0), "tf_s": repr(self.path.tf),
            "samples": str(n)})
        node.get_logger().info(f"planner: path {mission.path_source} ({self.path!r}) published")


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_ros planner``)."""
    return run_node("planner", Planner, args)


if __name__ == "__main__":
    sys.exit(main())
