"""ROS 2 node shells of bb2_planner (rclpy only here, never in the library modules)."""
