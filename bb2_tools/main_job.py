"""The main job (`bash run.sh main`): fly the canyon mission through the whole ROS 2 graph in lockstep, record it to
MCAP, analyse the bag, and say where everything is.

    python -m bb2_tools.main_job [--mission missions/canyon.yaml] [--mode lockstep|realtime] [--bag-dir bags]

Steps: ``bb2-launch MISSION --mode lockstep`` (every node its own process, isolated ROS_DOMAIN_ID, the
simulator's first state once the recorder reads every topic) -> ``bb2-analyze BAG --mission MISSION`` (path
errors, clearance, command statistics, paper-style figures, one HTML report) -> summary. Exit status: the launcher's
(0 mission complete) or the analysis's.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _newest_run(bag_dir: Path, stem: str, since: float) -> Path | None:
    runs = [p for p in bag_dir.glob(f"{stem}_*") if p.is_dir() and p.stat().st_mtime >= since - 1]
    return max(runs, key=lambda p: p.stat().st_mtime) if runs else None


def _summary(figures_json: Path) -> None:
    """The path-error summary of the recorded run (from bb2-analyze's figures.json)."""
    import json

    try:
        f = next(iter(json.loads(figures_json.read_text()).values()))["figures"]
    except (OSError, ValueError, StopIteration, KeyError):
        return
    print("\n== path-error summary (from the bag)")
    print(f"  vertical path error    RMS {f['rms_vertical_m']:7.3f} m   max {f['max_vertical_m']:7.3f} m")
    print(f"  horizontal path error  RMS {f['rms_horizontal_m']:7.3f} m   max {f['max_horizontal_m']:7.3f} m")
    if f.get("min_clearance_m") is not None:
        print(f"  minimum ground clearance {f['min_clearance_m']:.2f} m (CG), "
              f"{f.get('min_hull_clearance_m', float('nan')):.2f} m (lowest hull point)")
    print(f"  mission time {f['mission_time_s']:.2f} s, "
          f"graph real-time factor {f.get('real_time_factor', float('nan')):.1f}x")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bb2_tools.main_job", description=__doc__.split("\n\n")[0])
    ap.add_argument("--mission", default=str(REPO / "missions" / "canyon.yaml"),
                    help="mission file, or a shipped mission's name (default: the canyon)")
    ap.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep", help="the graph's time mode")
    ap.add_argument("--bag-dir", type=Path, default=REPO / "bags", help="where the run's bag goes (default: bags/)")
    ap.add_argument("--timeout", type=float, default=3600.0, help="wall-clock limit of the flight (s)")
    a = ap.parse_args(argv)

    # the launcher and the analysis run from the repository: a file named from here is named absolutely
    mission = Path(a.mission).resolve() if Path(a.mission).exists() else Path(a.mission)
    a.bag_dir = a.bag_dir.resolve()
    print(f"== BB2 Sim main job: {mission.name} through the ROS 2 graph ({a.mode}), recorded to MCAP", flush=True)
    t0 = time.time()
    launch = [sys.executable, "-m", "bb2_tools.launcher", str(mission), "--mode", a.mode,
              "--bag-dir", str(a.bag_dir), "--timeout", str(a.timeout)]
    rc = subprocess.call(launch, cwd=REPO)
    run = _newest_run(a.bag_dir, mission.stem, t0)
    if run is None:
        print(f"main job: the launcher exited {rc} and left no bag under {a.bag_dir}", file=sys.stderr)
        return rc or 1
    print(f"\n== analysing the bag {run}", flush=True)
    arc = subprocess.call([sys.executable, "-m", "bb2_tools.analyze", str(run), "--mission", str(mission),
                           "--out", str(run / "analysis")], cwd=REPO)
    _summary(run / "analysis" / "figures.json")
    print("\n== where things are")
    print(f"  bag (rosbag2 / MCAP): {run}  (metadata.yaml + {', '.join(p.name for p in run.glob('*.mcap'))})")
    print(f"  node logs:            {run / 'logs'}")
    print(f"  figures and report:   {run / 'analysis'}  (report.html)")
    print(f"  launcher exit {rc}, analysis exit {arc}, wall time {time.time() - t0:.0f} s")
    return rc or arc


if __name__ == "__main__":
    sys.exit(main())
