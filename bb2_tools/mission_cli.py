"""``bb2-sim mission FILE.yaml [--out DIR] [--no-adaptation] [--quiet]``: fly a closed-loop mission without ROS.

Prints what it flies (path, stack, adaptation, terrain, duration limit; the sea and current) and then the RMS/max
vertical and horizontal path errors, the minimum ground clearance and the mission time.
With ``--out DIR`` writes ``DIR/<mission>.csv`` (one row per Ts = 0.05 s, written as the run goes, so a
failed run keeps every row up to the failure) and the figures of :mod:`bb2_tools.mission_plots`.

Exit status: 0 the mission ended normally (path finished or duration reached), 1 it grounded, broached,
diverged or the stack failed (the report says what, where and when), 2 bad input.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


MISSION_ROW_BYTES = 2000
"""Memory of one tick's row (every 0.05 s) while a mission runs in process (a MissionRow of 47 floats and its
column copy): a duration whose trajectory would not fit is refused up front."""


def add_mission_parser(sub) -> argparse.ArgumentParser:
    """The ``mission`` sub-command of ``bb2-sim`` on a sub-parsers object."""
    ms = sub.add_parser("mission", help="fly a closed-loop mission without ROS",
                        description="Fly a mission file (bb2_mission.schema; missions/README.md) with the library "
                                    "runner: the ROM, the planner's path and the mission's stack, no ROS.")
    ms.add_argument("file", metavar="FILE.yaml", help="mission file, or a shipped mission's name (canyon, circle, ...)")
    ms.add_argument("--out", metavar="DIR", help="output directory for the CSV and figures")
    ms.add_argument("--no-adaptation", action="store_true", help="switch the L1 adaptation off")
    ms.add_argument("--overwrite", action="store_true", help="replace an existing DIR/<mission>.csv (else exit 2)")
    ms.add_argument("--quiet", action="store_true", help="no progress line")
    return ms


def run_mission_cli(a: argparse.Namespace) -> int:
    from bb2_sim.maneuvers import CsvWriter
    from bb2_sim.outputs import check_fits_in_memory, check_output_file, os_error_line
    from bb2_mission import MISSION_COLUMNS, MissionError, MissionRunner, load_mission

    try:
        m = load_mission(a.file)
        if a.no_adaptation:
            m = m.with_adaptation(False)
        try:
            check_fits_in_memory(m.duration / 0.05 * MISSION_ROW_BYTES, f"a {m.duration:g} s mission trajectory")
        except MemoryError as e:
            raise MissionError(f"{a.file}: duration {m.duration:g} s: {e}; fly a shorter mission") from None
        runner = MissionRunner(m)   # refuses a start above the surface or inside the sea floor
    except (MissionError, ValueError) as e:
        print(f"bb2-sim: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"bb2-sim: error: {os_error_line(e, a.file)}", file=sys.stderr)
        return 2
    writer = None
    out = Path(a.out) if a.out else None
    if out is not None:
        try:  # before the run: no silent overwrite, and a folder that does not take data fails now
            csv_file = check_output_file(out / f"{m.name}.csv", overwrite=getattr(a, "overwrite", False))
            writer = CsvWriter(csv_file, MISSION_COLUMNS)
        except OSError as e:
            print(f"bb2-sim: error: {os_error_line(e, out)}", file=sys.stderr)
            return 2
    show = not a.quiet and sys.stderr.isatty()
    if not a.quiet:
        print(f"mission {m.name}: path {m.path_source} (Tf = {m.path.span:g} s), stack {runner.stack.name}, "
              f"adaptation {'on' if m.adaptation else 'off'}, terrain {m.terrain_source or 'none'}, "
              f"duration limit {m.duration:g} s")
        print(f"  sea: {m.environment.summary()}")
    from bb2_mission import mission_warnings

    for warning in mission_warnings(m):
        print(f"bb2-sim: warning: {warning}", file=sys.stderr)

    def progress(t: float) -> None:
        sys.stderr.write(f"\r  t = {t:7.1f} / {m.duration:.0f} s")
        sys.stderr.flush()

    try:
        res = runner.run(progress=progress if show else None, on_row=writer.write if writer else None)
    finally:
        if writer:
            writer.close()
    if show:
        sys.stderr.write("\n")
    print("\n".join(res.summary.lines()))
    if out is not None:
        print(f"  trajectory: {writer.path}")
        if len(res.traj["t_s"]) > 1:
            from bb2_tools.mission_plots import plot_mission

            try:
                figs = plot_mission(res.traj, res.path_native, out, terrain=m.terrain, title=m.name)
            except OSError as e:
                print(f"bb2-sim: error: {os_error_line(e, out)}", file=sys.stderr)
                return 2
            print(f"  figures: {', '.join(str(f) for f in figs.values())}")
    if res.summary.event is not None:
        print(f"bb2-sim: mission {m.name} failed: {res.summary.event}", file=sys.stderr)
        if hint := res.divergence_hint("the mission's substeps:"):
            print(f"bb2-sim: {hint}", file=sys.stderr)
        return 1
    return 0
