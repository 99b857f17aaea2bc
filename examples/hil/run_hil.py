#!/usr/bin/env python3
"""The worked HIL example: the simulator node alone, in real time, flown by an external autopilot process.

Three processes on one ROS domain:

* ``bb2_ros.simulator`` -- the "vehicle on the bench", ``time_mode: realtime`` at ``--rate-hz``;
* ``examples/hil/external_autopilot.py`` -- the "external" autopilot (our stack, contract topics only);
* ``examples/hil/monitor.py`` -- watches ``/bb2/odom`` and ``/bb2/status`` and judges the flight.

``--netns``: the autopilot runs on *another network host*: two network namespaces (``bb2bench<pid>`` with the
simulator and the monitor, ``bb2ap<pid>`` with the autopilot) joined by a veth pair (10.200.0.1/24 and
10.200.0.2/24, multicast on, a 224.0.0.0/4 route for DDS discovery), Fast DDS restricted to UDPv4
(``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``: no shared-memory shortcut between the "hosts").  Needs root
(``ip netns add``); the namespaces are deleted at the end.

Usage::

    python examples/hil/run_hil.py [--mission missions/canyon.yaml] [--duration 60] [--rate-hz 20]
        [--mode realtime|lockstep] [--sensors tactical|mems|FILE] [--command-timeout 0.5] [--netns]
        [--domain-id N] [--summary hil.json] [--trajectory states.csv]

``--mode lockstep`` shows the software-in-the-loop handshake instead: the simulator waits for the commands of
each step (the autopilot then answers the reliable ``/bb2/state_native``) and runs as fast as both allow.

``--sensors SUITE``: the boat carries the sensor suite SUITE (``tactical``, ``mems`` or a suite file) and the
autopilot flies on its sensors alone (``--state-source sensors``: ``/bb2/sensors/*`` into its own navigation
filter), not on the simulator's state.  The mission the processes get is the given one with ``sensors: SUITE`` and
``navigation: sensors`` (written beside the summary).

In real time the autopilot runs at SCHED_FIFO priority 40 (``--autopilot-priority``), below the simulator's
stepping thread: a real autopilot has a computer of its own, and on a shared, busy machine a starved one would
miss the simulator's command timeout (seen beside two CPU hogs: 0.5 s without a command, the failsafe).  The
simulator receives the commands at SCHED_FIFO 40 too (``callback_priority`` in ``simulator_hil.yaml``): normally
scheduled, its reception waited past the command timeout beside two CPU hogs and two real-time busy loops (and, by
every sign, in the test suite's runs beside two hogs: a command answered at 27.2 s arrived at 28.35 s).

Exit status: 0 the flight finished with finite states and no failsafe after the autopilot took over;
1 otherwise (the monitor's summary says why).
"""
from __future__ import annotations

import argparse
import math
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
PARAMS = HERE / "simulator_hil.yaml"
BENCH_IP, AUTOPILOT_IP = "10.200.0.1", "10.200.0.2"


class Proc:
    """A child process whose output lines are echoed with a prefix and kept."""

    def __init__(self, name: str, cmd: list[str], env: dict[str, str], netns: str | None = None):
        self.name, self.lines = name, []
        full = (["ip", "netns", "exec", netns] if netns else []) + cmd
        self.p = subprocess.Popen(full, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True, bufsize=1)
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.p.stdout:
            self.lines.append(line.rstrip())
            print(f"[{self.name}] {line.rstrip()}", flush=True)

    def wait_for(self, text: str, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.p.poll() is None:
            if any(text in ln for ln in self.lines):
                return True
            time.sleep(0.05)
        return any(text in ln for ln in self.lines)

    def stop(self, timeout: float = 10.0) -> int:
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGINT)
            try:
                self.p.wait(timeout)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        self.reader.join(2)
        return self.p.returncode


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


class NetnsPair:
    """Two network namespaces joined by a veth pair (the bench and the autopilot "hosts")."""

    def __init__(self, tag: str):
        self.bench, self.autopilot = f"bb2bench{tag}", f"bb2ap{tag}"
        self.veth_b, self.veth_a = f"bb2vb{tag}"[:15], f"bb2va{tag}"[:15]
        self.created: list[str] = []

    def up(self) -> None:
        if os.geteuid() != 0 or shutil.which("ip") is None:
            raise RuntimeError("--netns needs root and iproute2 (`ip netns add`)")
        for ns in (self.bench, self.autopilot):
            _ip("netns", "add", ns)
            self.created.append(ns)
        _ip("link", "add", self.veth_b, "type", "veth", "peer", "name", self.veth_a)
        for ns, dev, addr in ((self.bench, self.veth_b, BENCH_IP), (self.autopilot, self.veth_a, AUTOPILOT_IP)):
            _ip("link", "set", dev, "netns", ns)
            _ip("-n", ns, "addr", "add", f"{addr}/24", "dev", dev)
            _ip("-n", ns, "link", "set", "lo", "up")
            _ip("-n", ns, "link", "set", dev, "up", "multicast", "on")
            _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", dev)  # DDS discovery (SPDP multicast)

    def traffic(self) -> dict[str, int]:
        out = subprocess.run(["ip", "-n", self.bench, "-s", "-j", "link", "show", "dev", self.veth_b],
                             capture_output=True, text=True)
        try:
            st = json.loads(out.stdout)[0]["stats64"]
            return {"bench_rx_bytes": st["rx"]["bytes"], "bench_tx_bytes": st["tx"]["bytes"]}
        except (ValueError, KeyError, IndexError):
            return {}

    def down(self) -> None:
        for ns in self.created:  # deleting a namespace deletes its end of the veth, and so the pair
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        self.created = []


def simulator_params(out: Path, **overrides: float | str) -> Path:
    """``simulator_hil.yaml`` with ``overrides`` applied, written to ``out`` (a node-specific params-file
    entry would win over ``-p``, so the options go into the file)."""
    import yaml
    from bb2_sim.yaml_files import load as load_yaml

    doc = load_yaml(PARAMS.read_text())
    doc["simulator"]["ros__parameters"].update(
        {k: v if isinstance(v, str) else float(v) for k, v in overrides.items()})
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mission", type=Path, default=REPO / "missions" / "canyon.yaml")
    p.add_argument("--duration", type=float, default=60.0, help="sim seconds to fly (default 60)")
    p.add_argument("--rate-hz", type=float, default=20.0, help="simulator steps per wall second (20 = real time)")
    p.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime",
                   help="simulator time mode; lockstep: the autopilot answers /bb2/state_native (default realtime)")
    p.add_argument("--sensors", default=None, metavar="SUITE",
                   help="fly on the sensors of this suite (tactical, mems or a suite file) instead of the state")
    p.add_argument("--command-timeout", type=float, default=0.5, help="simulator failsafe timeout, wall s")
    p.add_argument("--netns", action="store_true", help="autopilot on another network host (namespaces, root)")
    p.add_argument("--autopilot-priority", type=int, default=40, metavar="N",
                   help="real time: the autopilot process's SCHED_FIFO priority, below the simulator's stepping "
                        "thread (50), as if it had a computer of its own (needs root or CAP_SYS_NICE; refused: "
                        "normal scheduling, said); 0 = normal scheduling (default 40)")
    p.add_argument("--domain-id", type=int, default=None, help="ROS domain id (default: random in 100..230)")
    p.add_argument("--summary", type=Path, default=None, help="write the monitor's JSON summary here")
    p.add_argument("--trajectory", type=Path, default=None,
                   help="the simulator writes every state (t and the native state, CSV) here")
    args = p.parse_args(argv)
    for flag, v in (("--duration", args.duration), ("--rate-hz", args.rate_hz),
                    ("--command-timeout", args.command_timeout)):
        if not (v > 0 and math.isfinite(v)):  # a negative duration would fly the whole mission (issue 10)
            p.exit(2, f"{p.prog}: error: {flag} must be > 0 and finite, got {v:g}\n")
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        p.exit(2, f"{p.prog}: error: --domain-id must be in 0..232, got {args.domain_id}\n")
    if not args.mission.is_file():
        p.exit(2, f"{p.prog}: error: mission file {args.mission} does not exist\n")
    from bb2_mission import MissionError, load_mission

    try:   # before any process starts: the autopilot and the monitor would each stop on it
        load_mission(args.mission)
    except MissionError as exc:
        p.exit(2, f"{p.prog}: error: {exc}\n")
    if not 0 <= args.autopilot_priority <= 99:   # the autopilot refused it at its start: "did not come up"
        p.exit(2, f"{p.prog}: error: --autopilot-priority must be in 0..99, got {args.autopilot_priority}\n")
    if args.sensors is not None:
        from bb2_sim.sensors import PRESETS

        if args.sensors not in PRESETS and not Path(args.sensors).is_file():
            p.exit(2, f"{p.prog}: error: --sensors: no suite {args.sensors!r} (one of {', '.join(PRESETS)}, or a "
                      "suite file)\n")

    domain = args.domain_id if args.domain_id is not None else random.randint(100, 230)
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain), RMW_IMPLEMENTATION=env.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"),
               AMENT_PREFIX_PATH=env.get("AMENT_PREFIX_PATH") or sys.prefix,
               PYTHONPATH=str(REPO) + os.pathsep + env.get("PYTHONPATH", ""))
    net = None
    if args.netns:
        env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
        for k in ("ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS"):
            env.pop(k, None)
        net = NetnsPair(str(os.getpid() % 100000))
        net.up()
    summary_file = args.summary or Path(f"/tmp/bb2_hil_{os.getpid()}.json")
    procs: list[Proc] = []
    code = 1
    try:
        mission = str(args.mission.resolve())
        source = ["--state-source", "native" if args.mode == "lockstep" else "odometry"]
        if args.sensors is not None:
            import yaml

            derived = summary_file.with_suffix(".mission.yaml")
            from bb2_sim.sensors import PRESETS

            suite = args.sensors if args.sensors in PRESETS else str(Path(args.sensors).resolve())
            derived.write_text(yaml.safe_dump({"extends": mission, "sensors": suite,
                                               "navigation": "sensors"}, sort_keys=False))
            mission = str(derived)
            source = ["--state-source", "sensors", "--tick", "handshake" if args.mode == "lockstep" else "clock"]
        monitor = Proc("monitor", [sys.executable, str(HERE / "monitor.py"), "--mission", mission,
                                   "--summary", str(summary_file), "--timeout", str(args.duration / args.rate_hz * 20
                                                                                   + 120)],
                       env, net.bench if net else None)
        priority = args.autopilot_priority if args.mode == "realtime" else 0
        autopilot = Proc("autopilot", [sys.executable, str(HERE / "external_autopilot.py"), "--mission", mission,
                                       *source, "--realtime-priority", str(priority)], env,
                         net.autopilot if net else None)
        procs += [monitor, autopilot]
        for proc, ready in ((autopilot, "external autopilot ready"), (monitor, "hil monitor ready")):
            if not proc.wait_for(ready, 60):
                rc = proc.p.poll()
                said = next((ln for ln in reversed(proc.lines) if ln.strip()), "")
                print(f"run_hil: the {proc.name} did not come up ("
                      + (f"it exited with code {rc}: {said}" if rc is not None else "not ready within 60 s") + ")",
                      file=sys.stderr)
                return 1
        params = simulator_params(summary_file.with_suffix(".params.yaml"), time_mode=args.mode,
                                  rate_hz=args.rate_hz, duration_s=args.duration,
                                  command_timeout_s=args.command_timeout,
                                  **({"trajectory_csv": str(args.trajectory.resolve())} if args.trajectory else {}))
        sim = Proc("simulator", [sys.executable, "-m", "bb2_ros.simulator", "--ros-args", "--params-file",
                                 str(params), "-p", f"mission_file:={mission}"], env, net.bench if net else None)
        procs.append(sim)
        try:
            sim.p.wait(timeout=args.duration / args.rate_hz * 20 + 60)
        except subprocess.TimeoutExpired:
            print("run_hil: the simulator did not finish in time", file=sys.stderr)
        try:
            monitor.p.wait(timeout=30)  # it stops on the simulator's `finished` status (seconds on a loaded machine)
        except subprocess.TimeoutExpired:
            monitor.stop()
        if net:
            print(f"run_hil: veth traffic {net.traffic()}", flush=True)
        if not summary_file.is_file():
            print("run_hil: no monitor summary", file=sys.stderr)
            return 1
        s = json.loads(summary_file.read_text())
        ok = (sim.p.returncode == 0 and s["state_finite"] and s["failsafe_released_at_s"] is not None
              and not s["failsafe_after_release"])
        print(f"run_hil: {'OK' if ok else 'FAILED'} (domain {domain}{', two network namespaces' if net else ''}); "
              f"summary in {summary_file}", flush=True)
        code = 0 if ok else 1
    finally:
        for pr in reversed(procs):
            pr.stop()
        if net:
            net.down()
    return code


if __name__ == "__main__":
    sys.exit(main())
