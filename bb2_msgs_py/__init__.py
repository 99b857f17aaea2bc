"""bb2_msgs_py: the BB2 ROS 2 topic contract (names, standard types, QoS, frames, units) and the
numpy <-> message conversions.  Importing the package does not import rclpy."""
from .contract import (CONTRACT, FRAMES, PLANE_JOINTS, PROPELLER_JOINT, QOS, VH_JOINTS, ContractError,
                       QosDescription, TopicSpec, contract_markdown, message_class, qos_profile,
                       select_topics, topic)

__all__ = ["CONTRACT", "FRAMES", "PLANE_JOINTS", "PROPELLER_JOINT", "QOS", "VH_JOINTS", "ContractError",
           "QosDescription", "TopicSpec", "contract_markdown", "message_class", "qos_profile",
           "select_topics", "topic"]
