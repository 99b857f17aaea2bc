#!/usr/bin/env python3
"""Stress: freeze one node of a lockstep graph again and again; the bag must still hold everything published.

    python benchmarks/recording_under_freezes.py [--node simulator] [--freeze-s 4] [--every-s 4] [--sim-s 500]
        [--runs 1] [--mission missions/straight.yaml] [--fastdds-transports DEFAULT]

Runs ``bb2-launch MISSION --mode lockstep`` (the mission's duration set to ``--sim-s``) and, once the graph has run
for 15 s of wall time, stops ``--node``'s process (SIGSTOP) for ``--freeze-s`` wall seconds every ``--every-s`` until
the run ends. The launcher compares the node processes' publication counts with the bag; the script prints, per run,
its exit code, the number of freezes and the launcher's recording verdict (``recording complete: no gaps`` or the
``RECORDING GAPS`` lines). ``--fastdds-transports`` sets ``FASTDDS_BUILTIN_TRANSPORTS`` for the whole launch:
``DEFAULT`` (shared memory and UDPv4) is what the nodes use anyway and puts the recorder on shared memory too, as
before it chose UDP only for itself; unset, the recorder is on UDP only. Run it beside CPU-bound processes to starve
the recorder (nice +10). Not a CI test (minutes a run).
Exit code: 1 when a run lost messages or failed, else 0.
"""
from __future__ import annotations

import argparse
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from soak_memory import node_processes  # benchmarks/: the node processes of a domain

REPO = Path(__file__).resolve().parents[1]
WARM_UP_S = 15.0  # wall s before the first freeze: the graph is up and stepping


def one_run(a: argparse.Namespace, tmp: Path, k: int) -> tuple[int, int, list[str]]:
    """One launch with its freezes: (launcher exit code, freezes done, the launcher's recording lines)."""
    mission = tmp / f"run{k}.yaml"
    mission.write_text(f"extends: {Path(a.mission).resolve()}\nname: freezes{k}\nduration_s: {a.sim_s}\n")
    domain = random.randint(60, 99)
    env = dict(os.environ, AMENT_PREFIX_PATH=os.environ.get("AMENT_PREFIX_PATH", sys.prefix),
               RMW_IMPLEMENTATION=os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"))
    env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    cmd = [sys.executable, "-m", "bb2_tools.launcher", str(mission), "--mode", "lockstep", "--domain-id", str(domain),
           "--out", str(tmp / f"bag{k}"), "--timeout", str(max(1200.0, 10 * a.sim_s))]
    if a.fastdds_transports:  # every process of the launch; the recorder takes it instead of its UDP only
        env["FASTDDS_BUILTIN_TRANSPORTS"] = a.fastdds_transports
    proc = subprocess.Popen(cmd, env=env, cwd=tmp, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True)
    reader.start()
    time.sleep(WARM_UP_S)
    freezes = 0
    while proc.poll() is None:
        pid = node_processes(domain).get(a.node)
        if pid is not None:
            try:
                os.kill(pid, signal.SIGSTOP)
                time.sleep(a.freeze_s)
            except ProcessLookupError:
                break
            finally:
                try:
                    os.kill(pid, signal.SIGCONT)
                except ProcessLookupError:
                    pass
            freezes += 1
        time.sleep(a.every_s)
    proc.wait()
    reader.join(10)
    verdict = [ln.rstrip() for ln in lines if re.search(r"recording complete|RECORDING GAPS|never recorded", ln)]
    return proc.returncode, freezes, verdict


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--node", default="simulator", choices=("simulator", "planner", "path_following",
                                                            "l1_autopilot", "mixer"))
    ap.add_argument("--freeze-s", type=float, default=4.0, help="each freeze, wall s")
    ap.add_argument("--every-s", type=float, default=4.0, help="wall s between two freezes")
    ap.add_argument("--sim-s", type=float, default=500.0, help="the mission's duration, simulated s")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--mission", default=str(REPO / "missions" / "straight.yaml"))
    ap.add_argument("--fastdds-transports", default=None, metavar="VALUE",
                    help="FASTDDS_BUILTIN_TRANSPORTS of the whole launch (DEFAULT: the recorder on shared memory as "
                         "the nodes); default: unset (the recorder on UDP only)")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bb2_freezes_"))
    print(f"freezing {a.node} {a.freeze_s:g} s every {a.every_s:g} s; FASTDDS_BUILTIN_TRANSPORTS "
          f"{a.fastdds_transports or 'unset (the recorder on UDPv4)'}; bags and logs in {tmp}", flush=True)
    bad = 0
    for k in range(a.runs):
        code, freezes, verdict = one_run(a, tmp, k)
        lost = code != 0 or not verdict or any("complete" not in v for v in verdict)
        bad += lost
        print(f"run {k}: exit {code}, {freezes} freezes: " + (" | ".join(verdict) or "no recording verdict"),
              flush=True)
    print(f"{a.runs - bad} of {a.runs} runs recorded everything")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
