"""What rclpy itself costs the BB2 graph per step on this machine, and the best graph / runner ratio it leaves.

Issue 15 asks the lockstep graph for >= 0.5 x the library runner's real-time factor with one process per node and
>= 0.8 x composed. ``benchmarks/graph_speed.py`` measures the ratios; this measures the floor under them, from
the graph's own messages:

1. A short composed lockstep canyon (``--sim-s``, default 60 s, the recorder in its own process, through the
   launcher's code as ``graph_speed.py`` flies it) gives, from its bag, every topic's messages per ROM step and one
   recorded message of each (the real sizes); a watcher node lists, while it flies, which graph nodes subscribe to
   each topic (the deliveries within the composed process, the time sources' ``/clock`` included).
2. The library runner on the same mission gives its wall time per step (``T_runner``).
3. In this process, on a free domain, with a reader in another process taking every topic as the recorder does:
   each topic's ``publish`` of its recorded message (``pub``: serialisation and the write to the other process),
   and the extra of a delivery to a subscription in the same process on the graph's executor (``deliver``:
   publish + ``spin_once`` to the callback, minus ``pub``).
4. A ping-pong between two processes (the state's QoS and message, each side on the graph's executor,
   back to back as lockstep is): one hop = half the round trip.

Floors per step: composed ``sum(n * pub) + sum(n * subscriptions * deliver)``; one process per node the four hops
of the step's chain (state -> path following -> autopilot -> mixer -> simulator), which follow each other. Each
floor is a lower bound (no message building, no status, no recorder acknowledgements, no competition for the
cores), so ``T_runner / (T_runner + floor)`` is an upper bound of the ratio the graph can reach here with rclpy
and the contract's messages.

Usage: ``python benchmarks/graph_floor.py [--sim-s 60] [--n 2000] [--out DIR]`` (about 1 minute on 2 cores).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from graph_speed import own_node  # noqa: E402  (benchmarks/graph_speed.py)

GRAPH_NODES = ("simulator", "planner", "path_following", "l1_autopilot", "mixer")
PING, PONG = "/bb2_floor/ping", "/bb2_floor/pong"
STATE_TYPE = "std_msgs/msg/Float64MultiArray"


class SubscriptionWatcher:
    """While a graph flies: which nodes subscribe to each topic, polled every 0.5 s; :attr:`subscribers` is the
    poll in the middle of those that saw the simulator (not the start-up, when a composed process still has its
    followers' /clock subscriptions, nor the shutdown)."""

    def __init__(self, domain_id: int):
        self.ctx, self.node = own_node(domain_id, "bb2_floor_watcher")
        self._polls: list[dict[str, set[str]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()

    def _poll(self) -> None:
        while not self._stop.wait(0.5):
            if "simulator" in self.node.get_node_names():
                self._polls.append({name: {i.node_name for i in self.node.get_subscriptions_info_by_topic(name)}
                                    for name, _types in self.node.get_topic_names_and_types()})

    @property
    def subscribers(self) -> dict[str, set[str]]:
        return self._polls[len(self._polls) // 2] if self._polls else {}

    def close(self) -> None:
        import rclpy

        self._stop.set()
        self._thread.join(timeout=5.0)
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


# ------------------------------------------------------------------------------------------- child processes
def _serve(ctx, node) -> None:
    """Spin ``node`` on the graph's executor until the parent closes our stdin, then leave at once."""
    import rclpy

    from bb2_ros.node_common import make_executor

    ex = make_executor(ctx)
    ex.add_node(node)
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    print("ready", flush=True)
    while not stop.is_set():
        ex.spin_once(timeout_sec=0.1)
    rclpy.shutdown(context=ctx)
    os._exit(0)


def role_reader(domain_id: int, topics: list[tuple[str, str]]) -> None:
    """Take every message of ``topics`` (name, type), raw, with the recorder's (reliable) reader QoS, until stdin
    closes."""
    from bb2_msgs_py.contract import message_class, qos_profile

    ctx, node = own_node(domain_id, "bb2_floor_reader")
    for name, type_name in topics:
        q = qos_profile(name)  # the writer's: reliable, as the recorder reads
        node.create_subscription(message_class(type_name), name, lambda _m: None, q, raw=True)
    _serve(ctx, node)


def role_echo(domain_id: int) -> None:
    """Answer every ping with the same message on the pong topic, from the callback (the graph's executor)."""
    from bb2_msgs_py.contract import message_class, qos_profile

    ctx, node = own_node(domain_id, "bb2_floor_echo")
    cls = message_class(STATE_TYPE)
    pub = node.create_publisher(cls, PONG, qos_profile("/bb2/state_native"))
    node.create_subscription(cls, PING, pub.publish, qos_profile("/bb2/state_native", reader=True))
    _serve(ctx, node)


def _child(role: str, domain_id: int, topics: list[tuple[str, str]] = ()) -> subprocess.Popen:
    arg = ";".join(f"{n}={t}" for n, t in topics)
    p = subprocess.Popen([sys.executable, __file__, "--role", role, "--domain", str(domain_id), "--topics", arg],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    if p.stdout.readline().strip() != "ready":
        raise RuntimeError(f"the {role} process did not start")
    return p


def _wait_matched(pub, n: int = 1, timeout_s: float = 10.0) -> None:
    t_end = time.monotonic() + timeout_s
    while pub.get_subscription_count() < n:
        if time.monotonic() > t_end:
            raise RuntimeError(f"no subscriber matched {pub.topic_name} in {timeout_s} s")
        time.sleep(0.05)


# ------------------------------------------------------------------------------------------- measurements
def graph_counts(args, tmp: Path) -> tuple[dict[str, float], dict[str, bytes], dict[str, str], dict[str, int],
                                            float]:
    """Fly the composed lockstep canyon for ``args.sim_s``: (messages per step by topic, one recorded message by
    topic, types by topic, graph-node subscriptions by topic, the graph's RTF while stepping)."""
    from bb2_msgs_py.contract import select_topics
    from bb2_tools.bagfile import BagReader
    from graph_speed import LAYOUTS, TS, run_graph_once

    watchers: list[SubscriptionWatcher] = []

    def watch(domain_id: int) -> SubscriptionWatcher:
        watchers.append(SubscriptionWatcher(domain_id))
        return watchers[-1]

    res, _stepping_wall, _ = run_graph_once(REPO / "missions" / "canyon.yaml", tmp / "graph", "lockstep",
                                           {"duration_s": float(args.sim_s)}, timeout_s=600.0,
                                           probe=watch, groups=LAYOUTS["composed"])
    if res.exit_code != 0:
        raise RuntimeError(f"the composed graph failed: {res.reason}")
    steps = float(args.sim_s) / TS
    reader = BagReader(tmp / "graph")
    published = {t.name for t in select_topics()}  # not the recorder's bag-only /tf
    counts = {t: n / steps for t, n in reader.message_counts.items() if n >= 0.9 * steps and t in published}
    samples = {}
    for topic in counts:
        for m in reader.raw_messages(topic):
            samples[topic] = bytes(m.data)
    subs = {t: len(watchers[0].subscribers.get(t, set()) & set(GRAPH_NODES)) for t in counts}
    return counts, samples, dict(reader.topics), subs, res.rtf_overall


def runner_step_s(args, tmp: Path) -> float:
    """The library runner's wall time per ROM step on the same mission."""
    from graph_speed import TS, runner_summary

    s = runner_summary(args.sim_s, tmp)
    return s.wall_time_s / (s.mission_time_s / TS)


def publish_costs(domain_id: int, topics: dict[str, str], samples: dict[str, bytes], n: int
                  ) -> dict[str, tuple[float, float]]:
    """Per topic (pub, deliver) seconds: a publish to a reader in another process, and the extra of a delivery to
    a subscription in this process on the graph's executor."""
    from rclpy.serialization import deserialize_message

    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_ros.node_common import make_executor

    reader = _child("reader", domain_id, list(topics.items()))
    ctx, node = own_node(domain_id, "bb2_floor_writer")
    ex = make_executor(ctx)
    ex.add_node(node)
    out = {}
    got = [0]

    def on(_m):
        got[0] += 1

    try:
        for topic, type_name in topics.items():
            cls = message_class(type_name)
            msg = deserialize_message(samples[topic], cls)
            pub = node.create_publisher(cls, topic, qos_profile(topic))
            _wait_matched(pub)
            for _ in range(200):
                pub.publish(msg)
            t0 = time.perf_counter()
            for _ in range(n):
                pub.publish(msg)
            t_pub = (time.perf_counter() - t0) / n
            sub = node.create_subscription(cls, topic, on, qos_profile(topic, reader=True))
            _wait_matched(pub, 2)
            for _ in range(200):
                pub.publish(msg)
                ex.spin_once(timeout_sec=1.0)
            got[0] = 0
            t0 = time.perf_counter()
            for _ in range(n):
                pub.publish(msg)
                ex.spin_once(timeout_sec=1.0)
            t_loop = (time.perf_counter() - t0) / n
            if got[0] < n:
                raise RuntimeError(f"{topic}: {got[0]} of {n} delivered in this process")
            out[topic] = (t_pub, t_loop - t_pub)
            node.destroy_subscription(sub)
            node.destroy_publisher(pub)
    finally:
        import rclpy

        reader.stdin.close()
        reader.wait(timeout=10)
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    return out


def hop_times(domain_id: int, sample: bytes, n: int) -> np.ndarray:
    """One-way hop times (s) between two processes: half of each ping-pong round trip."""
    import rclpy
    from rclpy.serialization import deserialize_message

    from bb2_msgs_py.contract import message_class, qos_profile
    from bb2_ros.node_common import make_executor

    echo = _child("echo", domain_id)
    ctx, node = own_node(domain_id, "bb2_floor_pinger")
    cls = message_class(STATE_TYPE)
    msg = deserialize_message(sample, cls)
    got = [0]

    def on(_m):
        got[0] += 1

    pub = node.create_publisher(cls, PING, qos_profile("/bb2/state_native"))
    node.create_subscription(cls, PONG, on, qos_profile("/bb2/state_native", reader=True))
    ex = make_executor(ctx)
    ex.add_node(node)
    rtt = []
    try:
        _wait_matched(pub)
        t_end = time.monotonic() + 10.0
        while not node.get_publishers_info_by_topic(PONG) or got[0] == 0:  # the pong matched and answering
            pub.publish(msg)
            ex.spin_once(timeout_sec=0.1)
            if time.monotonic() > t_end:
                raise RuntimeError("no pong in 10 s")
        for i in range(n + 100):
            want = got[0] + 1
            t0 = time.perf_counter()
            pub.publish(msg)
            while got[0] < want:
                ex.spin_once(timeout_sec=1.0)
            if i >= 100:
                rtt.append(time.perf_counter() - t0)
    finally:
        echo.stdin.close()
        echo.wait(timeout=10)
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    return np.asarray(rtt) / 2.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sim-s", type=float, default=60.0, help="simulated seconds of the composed graph and runner")
    ap.add_argument("--n", type=int, default=2000, help="publishes per topic and round trips")
    ap.add_argument("--out", type=Path, default=None, help="keep the graph's bag here (default: a temporary dir)")
    ap.add_argument("--role", choices=["reader", "echo"], help=argparse.SUPPRESS)
    ap.add_argument("--domain", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--topics", default="", help=argparse.SUPPRESS)
    args = ap.parse_args()
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    if args.role == "reader":
        role_reader(args.domain, [tuple(x.split("=", 1)) for x in args.topics.split(";") if x])
        return 0
    if args.role == "echo":
        role_echo(args.domain)
        return 0

    from bb2_tools.graph_monitor import free_domain_id

    tmp = args.out or Path(tempfile.mkdtemp(prefix="bb2_floor_"))
    tmp.mkdir(parents=True, exist_ok=True)
    counts, samples, types, subs, graph_rtf = graph_counts(args, tmp)
    t_runner = runner_step_s(args, tmp)
    monitor = free_domain_id()
    try:
        costs = publish_costs(monitor.domain_id, {t: types[t] for t in counts}, samples, args.n)
        hops = hop_times(monitor.domain_id, samples["/bb2/state_native"], args.n)
    finally:
        monitor.close()

    print(f"composed lockstep canyon, {args.sim_s:g} s: graph {graph_rtf:.1f}x while stepping; library runner "
          f"{t_runner * 1e6:.0f} us per step ({0.05 / t_runner:.1f}x): graph / runner "
          f"{graph_rtf * t_runner / 0.05:.3f}")
    print(f"\n{'topic':34s} {'per step':>8s} {'graph subs':>10s} {'bytes':>6s} {'pub us':>7s} {'deliver us':>10s}")
    pub_floor = deliver_floor = 0.0
    for t in sorted(counts):
        p, d = costs[t]
        pub_floor += counts[t] * p
        deliver_floor += counts[t] * subs[t] * d
        print(f"{t:34s} {counts[t]:8.2f} {subs[t]:10d} {len(samples[t]):6d} {p * 1e6:7.1f} {d * 1e6:10.1f}")
    composed = pub_floor + deliver_floor
    hop50, hop99 = np.percentile(hops, [50, 99])
    alone = 4 * hop50
    print(f"\nper step: publishes {pub_floor * 1e6:.0f} us, deliveries in the process {deliver_floor * 1e6:.0f} us; "
          f"one hop between processes (ping-pong / 2, {len(hops)} round trips): p50 {hop50 * 1e6:.0f} us, "
          f"p99 {hop99 * 1e6:.0f} us")
    print(f"composed floor {composed * 1e6:.0f} us per step: graph / runner at most "
          f"{t_runner / (t_runner + composed):.3f}   [goal >= 0.8]")
    print(f"one process per node floor (4 hops at p50) {alone * 1e6:.0f} us per step: graph / runner at most "
          f"{t_runner / (t_runner + alone):.3f}   [goal >= 0.5]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
