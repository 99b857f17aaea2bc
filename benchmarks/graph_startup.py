"""What starting the graph costs: the CPU of one short ``bb2-launch`` run, whole and per process.

A graph launch is seven Python processes (the launcher, five nodes, the recorder), each importing what it needs
and building its piece of the mission before the first step: on a 2-core machine that start-up, not the stepping,
is most of a short run's CPU (every graph test pays it, and a campaign with ``--graph`` once per run).  This
prints, over ``--repeat`` launches of the 4-s straight mission (lockstep, recorded):

* the launch's wall time and its CPU (user + system of every process it started, from ``getrusage`` of the
  children), min / median / max;
* each process's CPU (``/proc/<pid>/stat``, sampled every 50 ms until it exits: a lower bound by at most one
  sample), median over the launches.

Usage: ``python benchmarks/graph_startup.py [--repeat N] [--duration S]`` (about 10 s per launch on 2 cores).
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HZ = os.sysconf("SC_CLK_TCK")
NAME = re.compile(r"(bb2-launch|bb2_tools\.launcher|bb2_(?:ros|tools)[./](\w+))")


def _children(pid: int) -> list[int]:
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return out


def _process_name(pid: int) -> str | None:
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return None
    m = NAME.search(cmd)
    if m is None:
        return None
    return m.group(2) or "launcher"


def _cpu_s(pid: int) -> float | None:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / HZ


def one_launch(mission: Path, out: Path) -> tuple[float, float, dict[str, float]]:
    """(wall s, CPU s of every process of the launch, CPU s per named process) of one ``bb2-launch`` run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--out", str(out)],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=REPO)
    names: dict[int, str] = {}
    cpu: dict[int, float] = {}
    while p.poll() is None:
        stack = [p.pid]
        while stack:
            pid = stack.pop()
            if pid not in names:
                name = _process_name(pid)
                if name is not None:
                    names[pid] = name
            c = _cpu_s(pid)
            if c is not None and pid in names:
                cpu[pid] = max(cpu.get(pid, 0.0), c)
            stack += _children(pid)
        time.sleep(0.05)
    wall = time.perf_counter() - t0
    err = p.stderr.read() if p.stderr else ""
    if p.returncode != 0:
        raise SystemExit(f"bb2-launch exited {p.returncode}:\n{err}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    per: dict[str, float] = {}
    for pid, c in cpu.items():
        per[names[pid]] = per.get(names[pid], 0.0) + c
    return wall, total, per


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5, help="launches (default 5)")
    ap.add_argument("--duration", type=float, default=4.0, help="sim seconds of the straight mission (default 4)")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bb2_startup_") as tmp:
        mission = Path(tmp) / "straight_short.yaml"
        mission.write_text(f"extends: {REPO / 'missions' / 'straight.yaml'}\nduration_s: {a.duration}\n")
        walls, totals, per = [], [], {}
        for i in range(a.repeat):
            wall, total, procs = one_launch(mission, Path(tmp) / f"run{i}")
            walls.append(wall)
            totals.append(total)
            for name, c in procs.items():
                per.setdefault(name, []).append(c)
            print(f"launch {i + 1}/{a.repeat}: wall {wall:.2f} s, CPU {total:.2f} s", flush=True)

    def mmm(v: list[float]) -> str:
        return f"{min(v):.2f} / {statistics.median(v):.2f} / {max(v):.2f}"

    print(f"\nbb2-launch of the {a.duration:g}-s straight mission (lockstep, recorded), {a.repeat} launches, "
          f"on {os.cpu_count()} cores")
    print(f"  wall s (min / median / max):              {mmm(walls)}")
    print(f"  CPU s of the launch (min / median / max): {mmm(totals)}")
    print("  CPU s per process (median):")
    for name, v in sorted(per.items(), key=lambda kv: -statistics.median(kv[1])):
        print(f"    {name:16s} {statistics.median(v):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
