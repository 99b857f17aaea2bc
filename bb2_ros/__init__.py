"""bb2_ros: the ROS 2 node shells of the BB2 graph (simulator, planner, path_following, l1_autopilot, mixer).

Each node is an ``rclpy.node.Node`` subclass: parameters in, one library call (bb2_mission, bb2_control,
bb2_planner, bb2_sim), messages out through the contract (:mod:`bb2_msgs_py`).  :mod:`~bb2_ros.node_common`
holds the plumbing every shell shares.  Nothing below this package imports it.
"""
