"""A ROS domain's discovery multicast port, and whether the machine's participants can hear each other on it.

DDS participants announce themselves (SPDP) to UDP multicast port ``7400 + 250 * domain_id`` (the DDSI-RTPS
well-known port mapping, its defaults PB = 7400, DG = 250, d0 = 0).  Fast DDS binds that port with
``SO_REUSEADDR``, so every participant of the machine shares it.  Another socket bound to the same port *without*
``SO_REUSEADDR`` keeps Fast DDS's bind from succeeding, and Fast DDS says nothing.  Such a socket is often an
ephemeral port the kernel gave some unrelated UDP client: for domains 102..214 the port lies in Linux's ephemeral
range (32768..60999), which is why the ROS 2 documentation advises domains 0..101.

Every participant of the machine on that domain then misses the others' announcements, shared memory or not
(measured with Fast DDS 2.14: two processes with its default transports never matched), unless it has unicast peers
(``ROS_STATIC_PEERS``).  A graph there starts and hears nothing.  :func:`discovery_port_blocked` finds that case, so
the nodes (``node_common.run_nodes``), the recorder and bb2-launch can say it and stop.  :func:`hold_discovery_port`
keeps the kernel from handing the port out at all while it is held.  The tests hold it for each domain they claim.
"""
from __future__ import annotations

import errno
import os
import socket
from collections.abc import Mapping
from pathlib import Path

RTPS_PORT_BASE = 7400  # PB: DDSI-RTPS 2.2 section 9.6.1.1, the default port base
RTPS_DOMAIN_GAIN = 250  # DG: the default domain id gain
RTPS_SPDP_MULTICAST_OFFSET = 0  # d0: the offset of the discovery multicast port
TRANSPORTS_ENV = "FASTDDS_BUILTIN_TRANSPORTS"  # Fast DDS's builtin transports of a process (unset: DEFAULT)
IP_MULTICAST_ALL = getattr(socket, "IP_MULTICAST_ALL", 49)  # linux/in.h; Python names it from 3.12 on


def discovery_multicast_port(domain_id: int) -> int:
    """The UDP port that participants of ``domain_id`` announce themselves to (multicast)."""
    if not 0 <= int(domain_id) <= 232:
        raise ValueError(f"a ROS domain id is 0..232, got {domain_id}")
    return RTPS_PORT_BASE + RTPS_DOMAIN_GAIN * int(domain_id) + RTPS_SPDP_MULTICAST_OFFSET


def _shared_socket() -> socket.socket:
    """A UDP socket bound as Fast DDS binds its multicast input (``SO_REUSEADDR``). It receives no multicast:
    ``IP_MULTICAST_ALL`` off, and it joins no group."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.setsockopt(socket.IPPROTO_IP, IP_MULTICAST_ALL, 0)
    except OSError:  # not Linux: multicast it never joined may reach it; it is never read
        pass
    return s


def hold_discovery_port(domain_id: int) -> socket.socket | None:
    """A socket holding ``domain_id``'s discovery port as Fast DDS shares it: while it is open the kernel gives
    the port to no ephemeral socket, and Fast DDS's participants still bind it.  None when another socket holds the
    port unshared already (:func:`discovery_port_blocked`).  Close it to release the port."""
    s = _shared_socket()
    try:
        s.bind(("0.0.0.0", discovery_multicast_port(domain_id)))
    except OSError as exc:
        s.close()
        if exc.errno == errno.EADDRINUSE:
            return None
        raise
    return s


def discovery_port_blocked(domain_id: int) -> str | None:
    """None when Fast DDS can bind ``domain_id``'s discovery port (or has: a running participant shares it);
    otherwise what holds it unshared (``UDP port 44900 is held by pid 123 (python3)``)."""
    s = hold_discovery_port(domain_id)
    if s is not None:
        s.close()
        return None
    port = discovery_multicast_port(domain_id)
    owner = _udp_port_owner(port)
    return f"UDP port {port} is held by " + (f"pid {owner[0]} ({owner[1]})" if owner else "another socket")


def _udp_port_owner(port: int) -> tuple[int, str] | None:
    """The pid and command name of a process with a UDP socket on ``port`` (from /proc; None if none is visible)."""
    try:
        links = {f"socket:[{f[9]}]" for f in (line.split() for line in
                                              Path("/proc/net/udp").read_text().splitlines()[1:])
                 if int(f[1].rsplit(":", 1)[1], 16) == port}
    except (OSError, IndexError, ValueError):
        return None
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            for fd in (proc / "fd").iterdir():
                if os.readlink(fd) in links:
                    return int(proc.name), (proc / "comm").read_text().strip()
        except OSError:
            continue
    return None


DISCOVERY_CONFIGURED = ("ROS_DISCOVERY_SERVER", "ROS_STATIC_PEERS")
"""Environment variables that give a participant unicast peers to discover: with one set, it does not depend on
hearing its domain's multicast discovery port."""
UDP_DISCOVERY_TRANSPORTS = ("DEFAULT", "UDPv4", "LARGE_DATA")
"""Fast DDS builtin transports that discover over UDPv4 multicast (checked: ``UDPv4`` and ``DEFAULT``)."""


def discovery_blocked(environ: Mapping[str, str], domain_id: int) -> str | None:
    """Why this process would hear no node of ``domain_id`` (its discovery multicast port held by a socket that does
    not share it, :func:`bb2_ros.discovery_port.discovery_port_blocked`), or None: unicast peers configured, no
    UDPv4 discovery (``SHM``, the v6 transports: not checked), or the port is Fast DDS's to share.  Checked once the
    participant exists, so a port it bound itself counts as shared, not blocked."""
    transports = environ.get(TRANSPORTS_ENV, "").strip() or "DEFAULT"
    if transports.split("?", 1)[0] not in UDP_DISCOVERY_TRANSPORTS \
            or any(environ.get(k, "").strip() for k in DISCOVERY_CONFIGURED) \
            or environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() == "OFF":
        return None
    held = discovery_port_blocked(domain_id)
    if held is None:
        return None
    return (f"ROS domain {domain_id}'s discovery port: {held}, which does not share it, so no participant of this "
            f"machine there would discover another; use a ROS_DOMAIN_ID in 0..101 (below Linux's ephemeral ports), "
            f"free the port, or name the graph's peers in ROS_STATIC_PEERS")
