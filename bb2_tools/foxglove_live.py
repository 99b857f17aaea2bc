"""The graph live in Foxglove: a node serving every contract topic over the Foxglove WebSocket protocol.

``bb2-launch MISSION --foxglove [PORT]`` starts it beside the graph (``foxglove:=true`` in the launch file); alone:
``ros2 run bb2_tools foxglove_bridge --ros-args -p port:=8765`` or ``python -m bb2_tools.foxglove_live``.  In
Foxglove: *Open connection* -> *Foxglove WebSocket* -> ``ws://127.0.0.1:8765``.

It reads every topic of the contract (:func:`bb2_msgs_py.contract.select_topics`) with the QoS a reader of it asks
for, as raw CDR, and logs each message unchanged on a Foxglove channel of the same name (message encoding ``cdr``,
schema ``ros2msg``: the type's definition with its dependencies, as in our bags), with the log time the recorder
gives it (the node's clock: the simulation time with ``use_sim_time``).  The latched topics (the scene, the path, the
sea, the mountings) and the ``/tf_static`` derived from them are sent again to a client when it subscribes, as a
DDS transient-local reader would get them: a viewer connecting mid-run still sees the hull, the path and the frames.
tf2_msgs is not in the wheels, so, as the
recorder does for bags, it derives ``/tf`` (``odom -> base_link``) from ``/bb2/odom`` and ``/tf_static`` (the
sensor mountings) from ``/bb2/sensors/mountings``: the 3-D panel shows the vehicle and its sensor frames.  The
server is made by foxglove-sdk (:func:`foxglove.start_server`), which advertises every channel at start, so a client
may subscribe before the first message.

Parameters: ``port`` (default 8765; 0 = any free port, printed), ``host`` (default 127.0.0.1; 0.0.0.0 serves other
machines), ``tf_from_odom`` (default true), ``topics`` (regular expressions of contract topics; default all).
"""
from __future__ import annotations

import sys
import threading
from typing import Any, Sequence

from rclpy.node import Node

from bb2_msgs_py.contract import TopicSpec, message_class, node_topic_name, qos_profile, select_topics
from bb2_ros.node_common import NodeConfigError, declare, node_frame, node_options, run_node

NODE_NAME = "foxglove_bridge"
DEFAULT_PORT = 8765


def foxglove_schema(type_name: str) -> Any:
    """The ``ros2msg`` schema of a ROS type for a Foxglove channel (the definition our bags embed)."""
    import foxglove

    from bb2_tools.bagfile import message_definition

    return foxglove.Schema(name=type_name, encoding="ros2msg", data=message_definition(type_name).encode())


class FoxgloveBridge(Node):
    """Every contract topic (and the derived ``/tf``, ``/tf_static``) on a Foxglove WebSocket server."""

    def __init__(self, argv: Sequence[str]):
        super().__init__(NODE_NAME, **node_options())
        import foxglove

        from bb2_tools.recorder import DERIVED_TOPICS, TF_TYPE

        def port_ok(v: int) -> int:
            if not 0 <= int(v) <= 65535:
                raise NodeConfigError(f"port must be 0..65535, got {v}")
            return int(v)

        port = declare(self, "port", DEFAULT_PORT, "TCP port of the WebSocket server (0 = any free port)",
                       check=port_ok)
        host = str(declare(self, "host", "127.0.0.1", "address the server listens on (0.0.0.0: every interface)"))
        self.tf = bool(declare(self, "tf_from_odom", True, "also serve /tf from /bb2/odom and /tf_static from "
                                                           "/bb2/sensors/mountings"))
        patterns = list(declare(self, "topics", [""], "regular expressions of contract topics to serve "
                                                      "('' = all)"))
        try:
            self.specs: list[TopicSpec] = select_topics([p for p in patterns if p] or None)
        except Exception as exc:  # ContractError: a pattern that matches no topic
            raise NodeConfigError(f"topics: {exc}") from None
        self.channels: dict[str, Any] = {}
        for spec in self.specs:
            self.channels[spec.name] = foxglove.Channel(spec.name, schema=foxglove_schema(spec.type),
                                                        message_encoding="cdr")
        # source topic -> (derived tf topic, its channel), as the recorder derives them for bags
        # (one channel per derived topic: /tf_static comes from the mountings and from the scene)
        tf_channels = {d: foxglove.Channel(d, schema=foxglove_schema(TF_TYPE), message_encoding="cdr")
                       for d in sorted({DERIVED_TOPICS[s.name] for s in self.specs if s.name in DERIVED_TOPICS})}
        self.derived: dict[str, tuple[str, Any]] = {
            s.name: (DERIVED_TOPICS[s.name], tf_channels[DERIVED_TOPICS[s.name]])
            for s in self.specs if self.tf and s.name in DERIVED_TOPICS}
        # the latched topics' last messages (and the /tf_static derived from them), sent again to every client
        # that subscribes later: a viewer that connects mid-run still gets the hull, the path, the sea, the frames
        self._latched_topics = {s.name for s in self.specs if s.qos_description.durability == "transient_local"
                                and s.qos_description.depth == 1}
        self._latched: dict[tuple[str, str], tuple[Any, bytes, int]] = {}  # (source, channel topic) -> last
        self._latched_lock = threading.Lock()
        try:
            self.server = foxglove.start_server(name="bb2_sim", host=host, port=int(port),
                                                server_listener=_LatchedReplay(self))
        except Exception as exc:  # e.g. the port is taken
            raise NodeConfigError(f"cannot serve on {host}:{port}: {exc}") from None
        from bb2_msgs_py.contract import FRAME_ODOM

        self.odom_frame = node_frame(self, FRAME_ODOM)  # map -> boat1/odom for a bridge in /boat1
        self.subs = [self.create_subscription(message_class(s.type), node_topic_name(s.name), self._forwarder(s.name),
                                              qos_profile(s.name, reader=True), raw=True) for s in self.specs]
        self.url = f"ws://{host}:{self.server.port}"
        print(f"{NODE_NAME}: serving {len(self.channels) + len(tf_channels)} topics on {self.url} "
              "(Foxglove: Open connection -> Foxglove WebSocket)", flush=True)

    def _forwarder(self, topic: str):
        from bb2_tools.recorder import derived_tf_cdr

        channel = self.channels[topic]
        odom_frame = self.odom_frame
        clock = self.get_clock()
        derived = self.derived.get(topic)

        latched = topic in self._latched_topics

        def forward(data: bytes) -> None:
            t = clock.now().nanoseconds
            channel.log(data, log_time=t)
            if latched:
                with self._latched_lock:
                    self._latched[(topic, topic)] = (channel, data, t)
            if derived is not None:
                try:
                    tf = derived_tf_cdr(topic, data, t, odom_frame=odom_frame)
                except (ValueError, KeyError, TypeError) as exc:
                    self.get_logger().warning(f"{topic}: no {derived[0]} from it ({exc})")
                    return
                derived[1].log(tf, log_time=t)
                if latched:
                    with self._latched_lock:
                        self._latched[(topic, derived[0])] = (derived[1], tf, t)
        return forward

    def replay_latched(self, channel_topic: str) -> int:
        """Send the latched messages of ``channel_topic`` again (a client just subscribed to it); returns how
        many.  Every subscribed client gets them: for latched data (replaced by the same ids) that is harmless."""
        with self._latched_lock:
            todo = [v for (_src, ch), v in self._latched.items() if ch == channel_topic]
        for channel, data, t in todo:
            channel.log(data, log_time=t)
        return len(todo)

    def close(self) -> None:
        """Stop the server (clients see the connection close)."""
        self.server.stop()


class _LatchedReplay:
    """The server's listener: a subscription to a latched channel gets its last messages again."""

    def __init__(self, bridge: FoxgloveBridge):
        self.bridge = bridge

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.bridge.replay_latched(channel.topic)


def main(args: Sequence[str] | None = None) -> int:
    """Entry point (``ros2 run bb2_tools foxglove_bridge``)."""
    return run_node(NODE_NAME, FoxgloveBridge, args)


if __name__ == "__main__":
    sys.exit(main())
