"""A domain's discovery multicast port (``bb2_ros.discovery_port``): the RTPS mapping, a shared hold that keeps it
from ephemeral sockets, and the recorder's and the nodes' refusal to run deaf when an unshared socket holds it."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rosenv import SpinningNode, block_discovery_port, claimed_domain, ros_env  # noqa: E402


def test_the_discovery_port_is_the_rtps_well_known_port():
    from bb2_ros.discovery_port import discovery_multicast_port

    assert [discovery_multicast_port(d) for d in (0, 1, 101, 150, 232)] == [7400, 7650, 32650, 44900, 65400]
    for bad in (-1, 233):
        with pytest.raises(ValueError, match="0..232"):
            discovery_multicast_port(bad)


def test_a_shared_hold_keeps_unshared_sockets_off_the_port_and_a_plain_socket_blocks_it():
    from bb2_ros.discovery_port import (discovery_blocked, discovery_multicast_port, discovery_port_blocked,
                                        hold_discovery_port)
    from bb2_tools.recorder import RECORDER_TRANSPORTS

    d = claimed_domain()  # its port is held shared by the claim
    port = discovery_multicast_port(d)
    assert discovery_port_blocked(d) is None  # a shared hold blocks no participant
    second = hold_discovery_port(d)
    assert second is not None
    second.close()
    with pytest.raises(OSError):  # an ephemeral (unshared) socket cannot have it
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM).bind(("0.0.0.0", port))
    plain = block_discovery_port(d)
    try:
        held = discovery_port_blocked(d)
        assert held is not None and held.startswith(f"UDP port {port} is held by pid {os.getpid()} ("), held
        assert hold_discovery_port(d) is None
        udp = {"FASTDDS_BUILTIN_TRANSPORTS": RECORDER_TRANSPORTS}
        for environ in (udp, {}, {"FASTDDS_BUILTIN_TRANSPORTS": "DEFAULT"}, {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}):
            said = discovery_blocked(environ, d)  # Fast DDS's default transports too (measured: no match)
            assert said is not None and said.startswith(f"ROS domain {d}'s discovery port: {held}") \
                and "ROS_DOMAIN_ID in 0..101" in said, (environ, said)
        for environ in ({"FASTDDS_BUILTIN_TRANSPORTS": "SHM"}, {**udp, "ROS_STATIC_PEERS": "127.0.0.1"},
                        {**udp, "ROS_DISCOVERY_SERVER": "127.0.0.1:11811"},
                        {**udp, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}):
            assert discovery_blocked(environ, d) is None, environ  # no UDP multicast discovery to miss
    finally:
        plain.close()
    assert discovery_port_blocked(d) is None and discovery_blocked(udp, d) is None


def test_a_recorder_whose_discovery_port_is_taken_says_so_and_records_nothing_unless_given_peers(tmp_path):
    """Without the check it ran deaf: alive, matched by no node, its bag empty (a CI run waited 90 s for it). With
    Fast DDS's default transports (shared memory too) it is as deaf, so it stops as well.  Given unicast peers
    (``ROS_STATIC_PEERS``) it finds the graph without the port, and records."""
    from rclpy.duration import Duration

    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_tools.bagfile import BagReader
    from bb2_ros.discovery_port import discovery_multicast_port

    d = claimed_domain()
    env = ros_env(d)
    env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    env.pop("ROS_STATIC_PEERS", None)
    plain = block_discovery_port(d)
    try:
        for transports in ([], ["--transports", "DEFAULT"]):
            p = subprocess.run([sys.executable, "-m", "bb2_tools.recorder", "--out", str(tmp_path / "deaf"),
                                "--topics", "/clock", *transports], cwd=tmp_path, env=env, capture_output=True,
                               text=True, timeout=120)
            assert p.returncode == 2, (transports, p.returncode, p.stdout, p.stderr)
            assert p.stderr.startswith(f"bb2-record: error: ROS domain {d}'s discovery port: UDP port "
                                       f"{discovery_multicast_port(d)} is held by pid {os.getpid()} "), p.stderr
            assert len(p.stderr.strip().splitlines()) == 1 and not (tmp_path / "deaf").exists(), p.stderr

        bag = tmp_path / "peers"
        proc = subprocess.Popen([sys.executable, "-m", "bb2_tools.recorder", "--out", str(bag), "--topics", "/clock",
                                 "--ros-args", "-p", "status_period_s:=0.0"], cwd=tmp_path,
                                env={**env, "ROS_STATIC_PEERS": "127.0.0.1"}, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        pub = SpinningNode("deaf_probe", d).start()
        try:
            clock = pub.node.create_publisher(message_class("rosgraph_msgs/msg/Clock"), "/clock",
                                              qos_profile("/clock"))
            deadline = time.monotonic() + 90
            while not (clock.get_subscription_count() and clock.wait_for_all_acked(Duration(seconds=0.5))):
                assert proc.poll() is None and time.monotonic() < deadline, "the recorder never matched"
                clock.publish(cv.clock_message(1.0))  # until one is acknowledged
                time.sleep(0.05)
            clock.publish(cv.clock_message(2.0))
            assert clock.wait_for_all_acked(Duration(seconds=30))
        finally:
            pub.close()
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err
    finally:
        plain.close()
    assert 2.0 in [m.clock.sec + m.clock.nanosec * 1e-9 for _t, _log, m in BagReader(bag).messages("/clock")], out


def test_a_graph_node_whose_discovery_port_is_taken_says_so_and_stops():
    """Every node process (``node_common.run_nodes``) checks its domain before it builds its nodes: deaf, it would
    wait for commands or a state that never come (the simulator in lockstep at its first state); and no node says
    it is up first (the simulator logged "simulator up" before it refused)."""
    from bb2_ros.discovery_port import discovery_multicast_port
    from rosenv import spawn_node

    d = claimed_domain()
    plain = block_discovery_port(d)
    try:
        for module, process in (("bb2_ros.mixer", "mixer"), ("bb2_ros.simulator", "simulator")):
            p = spawn_node(module, d, "-p", "mission_file:=missions/straight.yaml")
            out, _ = p.communicate(timeout=120)
            assert p.returncode == 2, (module, p.returncode, out[-2000:])
            said = [ln for ln in out.splitlines() if ": error: " in ln]
            assert len(said) == 1 and said[0].startswith(
                f"{process}: error: ROS domain {d}'s discovery port: UDP port {discovery_multicast_port(d)} is held "
                f"by pid {os.getpid()} ("), out[-2000:]
            assert " up" not in out and "up:" not in out, out[-2000:]
    finally:
        plain.close()
