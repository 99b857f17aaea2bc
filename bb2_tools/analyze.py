"""bb2-analyze: the figures and numbers of a recorded BB2 run (one bag, or two bags compared), or of a fleet.

Usage::

    bb2-analyze BAG [BAG2] [--out DIR] [--mission FILE.yaml] [--maneuver NAME] [--label A --label B]
    bb2-analyze FLEET_BAG | FLEET_DIR | BAG BAG BAG ...          # a fleet: every vehicle, side by side

``BAG`` is a rosbag2 bag directory (metadata.yaml + .mcap, ours or any rosbag2 MCAP with the contract's
topics) or a bare ``.mcap``.  A bag whose recorder was killed (no summary) is read up to its last complete
chunk and the report says so.  Output (``--out``, default ``<BAG>/analysis/``): PNG figures
(:mod:`bb2_tools.analysis_plots`), ``report.html`` (one self-contained file, :mod:`bb2_tools.report`) and
``figures.json``; the figures are also printed.  With two bags the plots overlay both runs and every
figure is printed as ``A``, ``B`` and ``B - A``.

A fleet (``FLEET_BAG``: the one bag of a fleet's recorder, every boat under its namespace, as ``fleet.launch.py``
writes ``<bag_dir>/fleet_<date>/``; ``FLEET_DIR``: a folder of boat bags; or three bags or more, e.g. the runs of
``bb2-launch --namespace``): every vehicle is analysed alone (its label: its namespace, or its folder's name), its
figures printed and its report written into ``<out>/<label>/``, then one table of every figure with a column per
vehicle; ``<out>/figures.json`` holds them all (default ``<out>``: ``<FLEET_BAG or FLEET_DIR>/analysis/``).

This module is the command line, its printout and its files: what is read from a bag is
:mod:`bb2_tools.bag_run` (:func:`~bb2_tools.bag_run.read_bag`), the figures and their definitions are
:mod:`bb2_tools.analysis` (:func:`~bb2_tools.analysis.analyze`; printed and written by their names,
:meth:`~bb2_tools.analysis.RunFigures.named`).

Figures are SI (m, s, rad); names ending in ``_rad``/``_rad_s`` are printed in degrees.
Exit codes: 0 done; 2 bad input (no bag, not a bag, no usable topics, bad mission file).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Sequence

from bb2_sim.outputs import check_output_file, os_error_line, run_cli

from bb2_tools.analysis import Analysis, analyze, compare, format_figure
from bb2_tools.bag_run import AnalysisError, read_bag
from bb2_tools.bagfile import BagError

__all__ = ["figure_lines", "comparison_lines", "write_outputs", "main"]

# ------------------------------------------------------------------------------------------ printing
def figure_lines(a: Analysis) -> list[str]:
    """The printout of one run: its source, warnings and every named figure in display units."""
    out = [f"{a.label}: {a.run.source}"]
    for w in a.warnings:
        out.append(f"  warning: {w}")
    if a.figures.end.reason:
        out.append(f"  end: {a.figures.end.line()}")
    for k, v in a.named_figures.items():
        label, text, unit = format_figure(k, v)
        out.append(f"  {label:<44s} {text:>12s} {unit}")
    return out


def comparison_lines(a: Analysis, b: Analysis) -> list[str]:
    """The printout of two runs: every named figure of either as A, B and B - A."""
    out = [f"comparison  A = {a.label}  B = {b.label}",
           f"  {'figure':<44s} {'A':>12s} {'B':>12s} {'B - A':>12s}"]
    for k, va, vb, d in compare(a, b):
        label, ta, unit = format_figure(k, va)
        _, tb, _ = format_figure(k, vb)
        _, td, _ = format_figure(k, d)
        out.append(f"  {label:<44s} {ta:>12s} {tb:>12s} {td:>12s} {unit}")
    return out


def fleet_lines(analyses: Sequence[Analysis]) -> list[str]:
    """The printout of a fleet: every named figure of any vehicle, one column per vehicle (blank where a vehicle
    has no such figure)."""
    labels = [a.label for a in analyses]
    names = list(dict.fromkeys(k for a in analyses for k in a.named_figures))
    out = [f"fleet  {len(analyses)} vehicles: {', '.join(labels)}",
           f"  {'figure':<44s} " + " ".join(f"{lb[:12]:>12s}" for lb in labels)]
    for k in names:
        shown = {a.label: format_figure(k, a.named_figures[k]) for a in analyses if k in a.named_figures}
        label, _, unit = next(iter(shown.values()))
        out.append(f"  {label:<44s} " + " ".join(f"{shown[lb][1] if lb in shown else '':>12s}" for lb in labels)
                   + f" {unit}")
    return out


def fleet_bags(path: Path) -> list[Path] | None:
    """The boat bags of a fleet folder (its subfolders that hold a bag: metadata.yaml or an .mcap), sorted; None when
    ``path`` is itself a bag or holds no bag folders."""
    def holds_bag(d: Path) -> bool:
        return (d / "metadata.yaml").is_file() or any(d.glob("*.mcap"))

    if not path.is_dir() or holds_bag(path):
        return None
    return sorted(d for d in path.iterdir() if d.is_dir() and holds_bag(d)) or None


def fleet_vehicles(path: Path) -> list[str] | None:
    """The boats of a fleet's bag (one recorder for all, every boat's topics under its namespace), sorted; None for
    any other bag (or no readable bag: read_bag says why)."""
    from bb2_tools.bagfile import BagReader

    try:
        reader = BagReader(path)
    except BagError:
        return None
    own = "/bb2/state_native" in reader.topics or "/bb2/odom" in reader.topics
    return reader.vehicles if len(reader.vehicles) > 1 and not own else None


# ------------------------------------------------------------------------------------------ outputs
def _figures_doc(analyses: Sequence[Analysis]) -> dict:
    """figures.json's per-run part: label -> source, figures, warnings, end."""
    return {a.label: {"source": str(a.run.source), "figures": a.named_figures, "warnings": a.warnings,
                      "end": a.figures.end.as_dict()} for a in analyses}


def write_fleet_outputs(analyses: Sequence[Analysis], out_dir: str | Path) -> dict[str, Path]:
    """Every vehicle's outputs (:func:`write_outputs`) into ``out_dir/<label>/`` and the fleet's figures.json
    (label -> source, figures, warnings, end) into ``out_dir``; returns label (and ``figures_json``) -> file."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {a.label: write_outputs([a], out / a.label)["report"] for a in analyses}
    doc = _figures_doc(analyses)
    fj = out / "figures.json"
    fj.write_text(json.dumps(doc, indent=1, default=float, allow_nan=True))
    files["figures_json"] = fj
    return files


def write_outputs(analyses: Sequence[Analysis], out_dir: str | Path) -> dict[str, Path]:
    """PNG figures, figures.json and report.html into ``out_dir``; returns name -> file."""
    from bb2_tools import analysis_plots, report

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = analysis_plots.plot_analyses(analyses, out)
    doc = _figures_doc(analyses)
    if len(analyses) == 2:
        doc["comparison"] = [{"figure": k, "A": va, "B": vb, "B_minus_A": d}
                             for k, va, vb, d in compare(analyses[0], analyses[1])]
    fj = out / "figures.json"
    fj.write_text(json.dumps(doc, indent=1, default=float, allow_nan=True))
    files["figures_json"] = fj
    files["report"] = report.write_analysis_report(analyses, files, out / "report.html")
    return files


def _parse(argv: Sequence[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bb2-analyze", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bags", nargs="+", type=Path, metavar="BAG",
                   help="bag directory or .mcap; a second BAG is overlaid and compared; a folder of boat bags (or "
                        "three bags or more) is a fleet: every vehicle side by side")
    p.add_argument("--out", type=Path, default=None, help="output directory (default <BAG>/analysis/)")
    p.add_argument("--mission", default=None, help="mission YAML (or shipped name) for the terrain and path")
    p.add_argument("--maneuver", default=None,
                   help="maneuver name (self-propulsion, depth-heading, turning-circle, hzz, vzz, open-loop)")
    p.add_argument("--maneuver-settings", default=None, help="JSON object of maneuver settings")
    p.add_argument("--label", action="append", default=None, help="label of each bag (repeat)")
    p.add_argument("--no-report", action="store_true", help="print the figures only")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing report.html / figures.json in the output directory (else exit 2)")
    return p.parse_args(list(argv))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``bb2-analyze``; returns the exit code (0 ok, 2 bad input or an OS error: one line naming
    the file, 130 interrupted)."""
    return run_cli("bb2-analyze", lambda: _main(argv))


def _output_dir(args: argparse.Namespace) -> Path:
    first = args.bags[0]
    return args.out or ((first if first.is_dir() else first.parent / first.stem) / "analysis")


def _main(argv: Sequence[str] | None) -> int:
    args = _parse(sys.argv[1:] if argv is None else argv)
    try:
        for b in args.bags:
            if not b.exists():
                raise AnalysisError(f"no bag at {b} (expected a bag directory or a .mcap file)")
        boats = fleet_bags(args.bags[0]) if len(args.bags) == 1 else None
        vehicles = fleet_vehicles(args.bags[0]) if len(args.bags) == 1 and boats is None else None
        if vehicles is not None:
            return _fleet(args, [(args.bags[0], v) for v in vehicles])
        if boats is not None or len(args.bags) > 2:
            return _fleet(args, [(b, None) for b in boats or args.bags])
        if not args.no_report:  # before the analysis: a folder that does not take data, or a report already there
            out = _output_dir(args)
            for name in ("report.html", "figures.json"):
                check_output_file(out / name, overwrite=args.overwrite, what="output file")
        labels = list(args.label or [])
        if len(labels) > len(args.bags):
            raise AnalysisError(f"{len(labels)} --label for {len(args.bags)} bag(s)")
        ms = _maneuver_settings(args)
        runs = []
        for i, b in enumerate(args.bags):
            label = labels[i] if i < len(labels) else None
            run = read_bag(b, label)
            if len(args.bags) == 2 and label is None:
                run.label = f"{'AB'[i]}: {run.label}"
            runs.append(run)
        analyses = [analyze(r, mission=args.mission, maneuver=args.maneuver, maneuver_settings=ms) for r in runs]
        if len(analyses) == 2 and analyses[0].label == analyses[1].label:
            analyses[1].run.label += " (2)"
    except (AnalysisError, BagError) as exc:
        print(f"bb2-analyze: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"bb2-analyze: error: {os_error_line(exc)}", file=sys.stderr)
        return 2
    if len(analyses) == 2:
        for a in analyses:
            print(f"{a.label}: {a.run.source}" + "".join(f"\n  warning: {w}" for w in a.warnings))
        print("\n".join(comparison_lines(*analyses)))
    else:
        print("\n".join(figure_lines(analyses[0])))
    if not args.no_report:
        out = _output_dir(args)
        files = write_outputs(analyses, out)
        print(f"bb2-analyze: report {files['report']} ({len(files) - 2} figures in {out})")
    return 0


def _maneuver_settings(args: argparse.Namespace) -> dict | None:
    """``--maneuver-settings`` as a dict (None when not given); :class:`AnalysisError` when it is not a JSON object."""
    if not args.maneuver_settings:
        return None
    try:
        ms = json.loads(args.maneuver_settings)
    except json.JSONDecodeError as exc:
        raise AnalysisError(f"--maneuver-settings is not JSON: {exc}") from None
    if not isinstance(ms, dict):
        raise AnalysisError("--maneuver-settings must be a JSON object")
    return ms


def _fleet(args: argparse.Namespace, sources: Sequence[tuple[Path, str | None]]) -> int:
    """A fleet: every vehicle's figures and report, then the table of all (exit codes as :func:`main`).
    ``sources``: (bag, vehicle: None for a boat's own bag, its namespace in a fleet's bag)."""
    bags = [b for b, _v in sources]
    try:
        labels = list(args.label or [])
        if len(labels) > len(bags):
            raise AnalysisError(f"{len(labels)} --label for {len(bags)} vehicle(s)")
        labels += [v or (b.name if b.is_dir() else b.stem) for b, v in sources[len(labels):]]
        if len(set(labels)) != len(labels):
            raise AnalysisError(f"the vehicles' labels must differ (give --label for each): {labels}")
        if args.out is not None:
            out = args.out
        elif len(args.bags) == 1:  # a fleet's bag or folder: its analysis in it
            out = _output_dir(args)
        else:  # bags of their own (bb2-launch --namespace runs): beside them
            out = Path(os.path.commonpath([b.resolve().parent for b in bags])) / "fleet_analysis"
        if not args.no_report:
            for name in [f"{lb}/report.html" for lb in labels] + ["figures.json"]:
                check_output_file(out / name, overwrite=args.overwrite, what="output file")
        ms = _maneuver_settings(args)
        analyses = [analyze(read_bag(b, lb, v), mission=args.mission, maneuver=args.maneuver, maneuver_settings=ms)
                    for (b, v), lb in zip(sources, labels)]
    except (AnalysisError, BagError) as exc:
        print(f"bb2-analyze: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"bb2-analyze: error: {os_error_line(exc)}", file=sys.stderr)
        return 2
    for a in analyses:
        print("\n".join(figure_lines(a)))
    print("\n".join(fleet_lines(analyses)))
    if not args.no_report:
        files = write_fleet_outputs(analyses, out)
        print(f"bb2-analyze: fleet figures {files['figures_json']}; reports "
              + ", ".join(str(files[a.label]) for a in analyses))
    return 0


if __name__ == "__main__":
    sys.exit(main())
