"""Wall time of the full canyon mission (ROM + planner path + full rate stack), with and without adaptation.

    .venv/bin/python benchmarks/mission_speed.py [--mission missions/canyon.yaml] [--out DIR] [--no-compare]

Prints the real-time factor (goal >= 40x on one core), where the time goes (ROM step, stack step, the
mission's own bookkeeping), the mission figures, and writes the figures (with the run without adaptation
overlaid on the path errors) into ``--out`` (default ``out/mission_speed``, ignored by git).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bb2_mission import MISSIONS_DIR, MissionRunner, load_mission  # noqa: E402


class _Timed:
    """Wraps a callable and accumulates its wall time."""

    def __init__(self, f):
        self.f, self.total = f, 0.0

    def __call__(self, *a, **k):
        t = time.perf_counter()
        try:
            return self.f(*a, **k)
        finally:
            self.total += time.perf_counter() - t


def run(mission, profile_parts: bool):
    runner = MissionRunner(mission)
    parts = {}
    if profile_parts:
        parts["ROM step (ode3, 3 evaluations)"] = runner.sim.step = _Timed(runner.sim.step)
        parts["stack step (guidance + L1 + autopilot + mixer)"] = runner.stack.step = _Timed(runner.stack.step)
        parts["terrain clearance (hull probes)"] = runner._clearances = _Timed(runner._clearances)
    res = runner.run()
    return res, {k: v.total for k, v in parts.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mission", default=str(MISSIONS_DIR / "canyon.yaml"))
    ap.add_argument("--out", default=str(REPO / "out" / "mission_speed"))
    ap.add_argument("--no-compare", action="store_true", help="skip the run without adaptation")
    a = ap.parse_args(argv)
    m = load_mission(a.mission)

    res, _ = run(m, profile_parts=False)          # clean timing, no wrappers
    s = res.summary
    rtf = s.mission_time_s / s.wall_time_s
    print("\n".join(s.lines()))
    print(f"\nREAL-TIME FACTOR: {rtf:.1f}x  ({s.mission_time_s:.1f} s simulated in {s.wall_time_s:.2f} s wall; "
          f"goal >= 40x) -> {'MET' if rtf >= 40 else 'NOT MET'}")

    res_p, parts = run(m, profile_parts=True)
    wall = res_p.summary.wall_time_s
    print(f"\nwhere the time goes (separate instrumented run, {wall:.2f} s wall):")
    rest = wall - sum(parts.values())
    for k, v in list(parts.items()) + [("mission bookkeeping (rows, checks)", rest)]:
        per_tick_ms = 1e3 * v / max(len(res_p.traj['t_s']), 1)
        print(f"  {k:<50s} {v:7.2f} s  {100 * v / wall:5.1f} %  {per_tick_ms:6.3f} ms/tick")

    compare = None
    if not a.no_compare:
        off = run(m.with_adaptation(False), profile_parts=False)[0]
        compare = off.traj
        print()
        print("\n".join(off.summary.lines()))
    from bb2_tools.mission_plots import plot_mission

    figs = plot_mission(res.traj, res.path_native, a.out, terrain=m.terrain, title=m.name, compare=compare,
                        compare_label="adaptation off",
                        label="adaptation on" if m.adaptation else "adaptation off")
    print(f"\nfigures: {', '.join(str(f) for f in figs.values())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
