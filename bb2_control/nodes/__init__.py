"""ROS 2 node shells of bb2_control (rclpy only here, never in the library modules)."""
