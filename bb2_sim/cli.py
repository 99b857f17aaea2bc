"""``bb2-sim``: command-line runner of the BB2 ROM.

    bb2-sim maneuver NAME [options]     one of: self-propulsion, depth-heading, turning-circle, hzz, vzz, open-loop
    bb2-sim mission FILE.yaml [options] closed-loop mission (ROM + planner + guidance + autopilot), no ROS

Exit status: 0 done, 1 the simulation diverged (the CSV keeps every row up to it), 2 bad input.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import asdict


class InputError(ValueError):
    """Bad command-line input (exit status 2)."""


def finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def plane_list(text: str) -> tuple[float, ...]:
    parts = [p for p in text.replace(" ", "").split(",") if p != ""]
    vals = tuple(finite_float(p) for p in parts)
    if len(vals) != 5:
        raise argparse.ArgumentTypeError(f"needs exactly 5 comma-separated angles d1,d2,d3,d4,d5, got {len(vals)}")
    return vals


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one clear line and status 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """``bb2-sim`` with the ROM's own sub-command (``maneuver``); the tools layer adds ``mission``
    (:mod:`bb2_tools.sim_cli`)."""
    p = _Parser(prog="bb2-sim", description="BB2 reduced-order model: maneuvers and missions.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    add_maneuver_parser(sub)
    return p


def add_maneuver_parser(sub) -> argparse.ArgumentParser:
    """The ``maneuver`` sub-command on a sub-parsers object."""
    from .maneuvers import maneuver_names

    m = sub.add_parser("maneuver", help="run a standard maneuver and print its ITTC figures",
                       description="Run a standard maneuver of the BB2 ROM. Angles in the authors' native "
                                   "convention (psi > 0 bow to port); depths positive down.")
    m.add_argument("name", choices=maneuver_names(), metavar="NAME",
                   help="one of: " + ", ".join(maneuver_names()))
    m.add_argument("--depth", type=finite_float, metavar="M", help="initial CG depth (m, positive down)")
    m.add_argument("--depth-ref", type=finite_float, metavar="M",
                   help="depth held by the autopilot (m); default: --depth")
    m.add_argument("--heading-ref-deg", type=finite_float, metavar="D",
                   help="heading held by the autopilot (deg, native psi: positive = bow to port)")
    m.add_argument("--speed-mps", type=finite_float, metavar="U", help="initial forward speed (m/s, positive ahead)")
    m.add_argument("--rps", type=finite_float, metavar="N", help="propeller command (rps); default U/4 as the authors")
    m.add_argument("--sea-state", type=finite_float, metavar="S", help="sea state 0..7 (0, 1 calm; regular head waves)")
    m.add_argument("--rudder-deg", type=finite_float, metavar="D",
                   help="turning circle rudder (deg); positive = starboard turn (dh = -D)")
    m.add_argument("--amplitude-deg", type=finite_float, metavar="A", help="zig-zag deflection (deg)")
    m.add_argument("--check-deg", type=finite_float, metavar="C", help="zig-zag check angle (deg)")
    m.add_argument("--sail-planes", choices=["pid", "zero"], help="vzz: sail planes at zero or flown by the depth PID")
    m.add_argument("--planes-deg", type=plane_list, metavar="d1,d2,d3,d4,d5",
                   help="open loop: the five plane angles (deg, the authors' plane signs)")
    m.add_argument("--duration", type=finite_float, metavar="T", help="simulated time (s)")
    m.add_argument("--profile", default="iowa", choices=["iowa", "corrected"], help="physics profile")
    m.add_argument("--hull-mesh", metavar="DIR", help="directory of hull surface files (STL/OBJ); default: "
                                                      "the BB2 hull generated from the table of offsets")
    m.add_argument("--out", metavar="FILE.csv", help="write the trajectory (reference CSV columns, every 0.1 s)")
    m.add_argument("--plot", metavar="FILE.png", help="draw the maneuver plot")
    m.add_argument("--quiet", action="store_true", help="no progress line")
    return m


def _fmt(value) -> str:
    """A figure for printing: numbers to 4 significant digits, tuples element-wise."""
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(_fmt(v) for v in value) + ")"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _progress(enabled: bool, total: float):
    if not enabled:
        return None

    def cb(t: float) -> None:
        sys.stderr.write(f"\r  t = {t:7.1f} / {total:.0f} s")
        sys.stderr.flush()
    return cb


def run_maneuver_cli(a: argparse.Namespace) -> int:
    from .geometry import HullMeshError
    from .maneuvers import CsvWriter, ManeuverError, build_model, maneuver_settings, run_maneuver
    from .waves import SeaStateError

    try:
        s = maneuver_settings(a.name, depth=a.depth, depth_ref=a.depth_ref, heading_ref_deg=a.heading_ref_deg,
                              speed_mps=a.speed_mps, rps=a.rps, sea_state=a.sea_state, rudder_deg=a.rudder_deg,
                              amplitude_deg=a.amplitude_deg, check_deg=a.check_deg, sail_planes=a.sail_planes,
                              planes_deg=a.planes_deg, duration=a.duration, profile=a.profile)
        model = build_model(s, a.hull_mesh)
    except (ManeuverError, SeaStateError, HullMeshError, ValueError) as e:
        print(f"bb2-sim: error: {e}", file=sys.stderr)
        return 2
    writer = None
    if a.out:
        try:
            writer = CsvWriter(a.out)
        except OSError as e:
            print(f"bb2-sim: error: cannot write {a.out}: {e}", file=sys.stderr)
            return 2
    print(f"maneuver {s.name}: {s.doc}")
    print(f"  hull: {model.surfaces.source} ({model.surfaces.n_triangles()} triangles, V = {model.volume:.3f} m^3"
          f"{', weight trimmed to buoyancy' if model.trimmed else ''}); profile {model.profile.name}; "
          f"sea state {model.wave.sea_state}")
    try:
        res = run_maneuver(s, model, on_row=writer.write if writer else None,
                           progress=_progress(not a.quiet and sys.stderr.isatty(), s.duration))
    finally:
        if writer:
            writer.close()
    if not a.quiet and sys.stderr.isatty():
        sys.stderr.write("\n")
    sim_t = res.traj["t_s"][-1] if len(res.traj["t_s"]) else 0.0
    print(f"  simulated {sim_t:.1f} s in {res.wall_time_s:.2f} s wall "
          f"({sim_t / max(res.wall_time_s, 1e-9):.0f}x real time)")
    if res.error is not None:
        print(f"bb2-sim: {res.error}; the CSV keeps every row up to t = {sim_t:.2f} s"
              + (f" ({a.out})" if a.out else ""), file=sys.stderr)
    try:
        from .metrics import figures_for
        fig = figures_for(s.name, res.traj, **asdict(s))
    except Exception as e:  # figures of a truncated run may not exist
        fig = None
        print(f"  (no maneuver figures: {e})")
    if fig is not None:
        print("  figures:")
        for name, value, unit in fig.as_rows():
            print(f"    {name:<40s} {_fmt(value):>14} {unit}")
    if a.out:
        print(f"  trajectory: {a.out}")
    if a.plot and len(res.traj["t_s"]) > 1:
        from .plots import plot_maneuver
        plot_maneuver(s.name, res.traj, a.plot, figures=fig, settings=asdict(s))
        print(f"  plot: {a.plot}")
    return 1 if res.error is not None else 0


def main(argv: list[str] | None = None) -> int:
    """``python -m bb2_sim maneuver ...`` (the ROM alone); ``bb2-sim`` is :func:`bb2_tools.sim_cli.main`."""
    args = build_parser().parse_args(argv)
    return run_maneuver_cli(args)


if __name__ == "__main__":
    sys.exit(main())
