#!/usr/bin/env python3
"""Soak: one hour of simulated time through the whole lockstep graph (all nodes + recorder); memory must stay flat.

    python benchmarks/soak_memory.py [--sim-hours 1.0] [--mission missions/circle.yaml] [--every 10]

Runs ``bb2-launch MISSION --mode lockstep --end-at simulator`` with the mission's duration set to the soak length
(the circle path is flown for its 500 s, then the stack holds its last commands and the boat keeps going), samples
the resident memory (VmRSS) of every node process every ``--every`` wall seconds, and prints per node the RSS after
warm-up, at the end, and the linear trend over the run (kB per simulated hour). Not a CI test (it takes minutes).
"""
from __future__ import annotations

import argparse
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
NODES = ("simulator", "planner", "path_following", "l1_autopilot", "mixer", "recorder")


def node_processes(domain: int) -> dict[str, int]:
    """pid of each BB2 node process running on ROS_DOMAIN_ID = domain (by its command line and environment)."""
    out = {}
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            env = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if f"ROS_DOMAIN_ID={domain}".encode() not in env or "launcher" in cmd:
            continue
        for n in NODES:
            if n in cmd and ("python" in cmd or "/lib/" in cmd):
                out[n] = int(pid)
    return out


def rss_kb(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim-hours", type=float, default=1.0)
    ap.add_argument("--mission", default=str(REPO / "missions" / "circle.yaml"))
    ap.add_argument("--every", type=float, default=10.0, help="sampling period, wall s")
    a = ap.parse_args()
    duration = a.sim_hours * 3600.0
    tmp = Path(tempfile.mkdtemp(prefix="bb2_soak_"))
    mission = tmp / "soak.yaml"
    mission.write_text(f"extends: {Path(a.mission).resolve()}\nname: soak\nduration_s: {duration}\n")
    domain = random.randint(60, 99)
    env = dict(os.environ, AMENT_PREFIX_PATH=os.environ.get("AMENT_PREFIX_PATH", sys.prefix),
               RMW_IMPLEMENTATION=os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"))
    cmd = [sys.executable, "-m", "bb2_tools.launcher", str(mission), "--mode", "lockstep", "--end-at", "simulator",
           "--domain-id", str(domain), "--out", str(tmp / "bag"), "--timeout", str(max(600.0, duration))]
    print(f"soak: {duration:.0f} s simulated on domain {domain}; bag and logs in {tmp}", flush=True)
    t0 = time.time()
    proc = subprocess.Popen(cmd, env=env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    samples: dict[str, list[tuple[float, int]]] = {n: [] for n in NODES}
    while proc.poll() is None:
        time.sleep(a.every)
        for n, pid in node_processes(domain).items():
            kb = rss_kb(pid)
            if kb is not None:
                samples[n].append((time.time() - t0, kb))
    wall = time.time() - t0
    print(f"launcher exit {proc.returncode} after {wall:.0f} s wall ({duration / wall:.1f}x real time)")
    print(f"{'node':<16s}{'RSS after warm-up':>20s}{'RSS at end':>14s}{'trend':>22s}")
    for n, s in samples.items():
        if len(s) < 4:
            print(f"{n:<16s}  (not enough samples)")
            continue
        warm = [x for x in s if x[0] >= 0.2 * wall] or s
        import numpy as np

        t = np.array([x[0] for x in warm]) * duration / wall / 3600.0  # simulated hours
        kb = np.array([x[1] for x in warm], float)
        slope = np.polyfit(t, kb, 1)[0] if np.ptp(t) > 0 else 0.0
        print(f"{n:<16s}{kb[0] / 1024:>17.1f} MB{kb[-1] / 1024:>11.1f} MB{slope / 1024:>15.2f} MB/sim-h")
    return proc.returncode or 0


if __name__ == "__main__":
    sys.exit(main())
