"""ROS 2 node shells of bb2_sim (rclpy only here, never in the library modules)."""
