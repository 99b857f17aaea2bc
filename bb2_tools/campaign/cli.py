"""``bb2-campaign``: fly a Monte Carlo / grid campaign of missions or maneuvers (see :mod:`bb2_tools.campaign`).

    bb2-campaign SPEC.yaml [--out DIR] [--engine local|ray] [--address ADDR] [--workers N] [--resume] [--graph]
                 [--batch N]
    bb2-campaign SPEC.yaml --only INDEX --out-run DIR

Exit status: 0 every run recorded (whatever their status), 2 bad input (one line naming the field), 130
interrupted (the journal keeps every finished run; ``--resume`` finishes the rest).  With ``--only``: 0 the
run ended normally, 1 it failed (grounded, broached, diverged, error).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from bb2_sim.cli import int_at_least, positive_int
from bb2_sim.outputs import plain_name
from bb2_tools.campaign.errors import SpecError

PROG = "bb2-campaign"


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one clear line and status 2
        self.exit(2, f"{self.prog}: error: {message}\n")


_index = int_at_least(0)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Fly a campaign (Monte Carlo and grids) of missions or maneuvers; "
                                       "see the SPEC format in bb2_tools/campaign/__init__.py and README.md.")
    p.add_argument("spec", metavar="SPEC.yaml", help="the campaign: its mission or maneuver, seed, samples, vary and "
                   "collect (README, \"Campaigns\"; bb2_tools/campaign/__init__.py)")
    p.add_argument("--out", metavar="DIR", help="campaign directory (default out/campaigns/<name>)")
    p.add_argument("--engine", choices=["local", "ray"], default="local",
                   help="local: a process pool on this machine (default); ray: a Ray cluster")
    p.add_argument("--address", metavar="ADDR", help="ray: 'auto' or HOST:PORT of a running cluster "
                                                      "(default: start a Ray instance for this driver)")
    p.add_argument("--workers", type=positive_int, metavar="N",
                   help="local: worker processes (default: CPUs); ray: runs in flight (default: 2 x CPUs)")
    p.add_argument("--batch", type=positive_int, metavar="N", default=None,
                   help="the most runs one worker flies together in the batch ROM (maneuvers; missions flying on "
                        "the truth), bit for bit what each gives alone (default 128; 1: every run alone; not with "
                        "--graph)")
    p.add_argument("--resume", action="store_true", help="finish exactly the runs missing from DIR")
    p.add_argument("--only", type=_index, metavar="INDEX", help="fly run INDEX alone (needs --out-run)")
    p.add_argument("--out-run", metavar="DIR", help="--only: where that run's CSV, figures and row go")
    p.add_argument("--graph", action="store_true",
                   help="each run flies the full ROS 2 graph in lockstep on its own ROS_DOMAIN_ID and records its "
                        "bag (DIR/graph/<index>/); default: the library runner")
    p.add_argument("--no-report", action="store_true", help="skip report.html")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _fail(msg: str) -> int:
    print(f"{PROG}: error: {' '.join(str(msg).split())}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    a = build_parser().parse_args(argv)
    if a.only is not None and not a.out_run:
        return _fail("--only INDEX needs --out-run DIR")
    if a.out_run and a.only is None:
        return _fail("--out-run DIR goes with --only INDEX")
    if a.address and a.engine != "ray":
        return _fail("--address goes with --engine ray")
    if a.graph and a.only is not None:
        return _fail("--graph goes with a campaign, not --only (fly one run through the graph with bb2-launch)")
    if a.only is not None:  # one run, in this process, written to --out-run: a campaign's options are not read
        given = [opt for opt, on in (("--out", a.out), ("--resume", a.resume), ("--workers", a.workers),
                                     ("--batch", a.batch), ("--engine", a.engine != "local")) if on]
        if given:
            return _fail(f"{', '.join(given)} go{'es' if len(given) == 1 else ''} with a campaign, not --only "
                         "(one run, flown here, written to --out-run)")
    from bb2_tools.campaign.spec import load_spec
    from bb2_tools.campaign.worker import campaign_warnings, probe

    try:
        spec = load_spec(a.spec)
        probe(spec)
        for said in spec.notes:
            print(f"bb2-campaign: note: {a.spec}: {said}", file=sys.stderr)
        for said in campaign_warnings(spec):
            print(f"bb2-campaign: warning: {a.spec}: {said}", file=sys.stderr)
        if a.only is not None and a.only >= spec.n_runs:
            raise SpecError(f"--only {a.only}: the campaign has runs 0..{spec.n_runs - 1}")
    except SpecError as e:
        return _fail(f"{a.spec}: {e}")
    if a.only is not None:
        return _run_only(spec, a.only, Path(a.out_run))
    out = Path(a.out) if a.out else Path("out") / "campaigns" / spec.name
    if a.graph:
        if spec.target != "mission":
            return _fail(f"{a.spec}: --graph flies missions only (maneuvers have no graph)")
        spec.graph_dir = str((out / "graph").resolve())
    return _run_campaign(spec, out, a)


# ------------------------------------------------------------------------------------------ --only
def _run_only(spec: Any, index: int, out: Path) -> int:
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from bb2_sim.maneuvers import OUTPUT_COLUMNS, CsvWriter
    from bb2_tools.campaign.store import results_schema
    from bb2_tools.campaign.worker import run_one

    try:
        out.mkdir(parents=True, exist_ok=True)
        if spec.target == "mission":
            from bb2_mission import MISSION_COLUMNS

            run_name = plain_name(spec.document(index).get("name", spec.name), "the run's mission name")
            traj_file = out / f"{run_name}.csv"
            writer = CsvWriter(traj_file, MISSION_COLUMNS)
            on_row = writer.write
        else:
            traj_file = out / f"{spec.maneuver}.csv"
            writer = CsvWriter(traj_file, OUTPUT_COLUMNS)   # bb2-sim maneuver --out's columns
            on_row = writer.write
    except OSError as e:
        return _fail(f"cannot write into {out}: {e}")
    except ValueError as e:  # a varied name that is no plain name
        return _fail(f"run {index}: {e}")
    try:
        row, result = run_one(spec, index, on_row=on_row)
    finally:
        writer.close()
    pacsv.write_csv(pa.Table.from_pylist([row], schema=results_schema(spec)), str(out / "run.csv"))
    print(f"run {index} of campaign {spec.name} (seed {row['seed']}): {row['status']}"
          + (f" -- {row['message']}" if row["message"] else ""))
    for k in spec.input_columns:
        print(f"  {k} = {row[k]}")
    for k in spec.collect:
        print(f"  {k:<28s} {row.get(k)}")
    print(f"  trajectory: {traj_file}\n  row: {out / 'run.csv'}")
    figs = _plot_run(spec, index, result, out)
    if figs:
        print(f"  figures: {', '.join(str(f) for f in figs)}")
    return 0 if row["status"] == "ok" else 1


def _plot_run(spec: Any, index: int, result: Any, out: Path) -> list[Path]:
    if result is None or len(result.traj.get("t_s", [])) < 2:
        return []
    try:
        if spec.target == "mission":
            from bb2_tools.mission_plots import plot_mission

            figs = plot_mission(result.traj, result.path_native, out, terrain=result.mission.terrain,
                                title=f"{spec.name} run {index}")
            return [Path(f) for f in figs.values()]
        from dataclasses import asdict

        from bb2_sim.plots import plot_maneuver

        f = out / f"{spec.maneuver}.png"
        plot_maneuver(str(spec.maneuver), result.traj, str(f), settings=asdict(result.settings))
        return [f]
    except Exception as e:  # noqa: BLE001 -- figures are a convenience; the CSV and row are written
        print(f"  (no figures: {type(e).__name__}: {e})", file=sys.stderr)
        return []


# ------------------------------------------------------------------------------------------ campaign
def _run_campaign(spec: Any, out: Path, a: argparse.Namespace) -> int:
    from bb2_tools.campaign.engines import make_engine
    from bb2_tools.campaign.progress import Progress, format_duration
    from bb2_tools.campaign.store import (CAMPAIGN_YAML, JOURNAL, REPORT_HTML, RESULTS_CSV, RESULTS_PARQUET,
                                          Journal, check_campaign_yaml, write_campaign_yaml, write_results)

    journal = Journal(out / JOURNAL)
    try:
        engine = make_engine(a.engine, a.workers, a.address, **({"batch": a.batch} if a.batch else {}))
        engine.prepare()  # a cluster that cannot be reached: said before the folder is written
        if a.resume:
            check_campaign_yaml(out, spec)
            done = journal.recover()
        else:
            if (out / JOURNAL).exists() or (out / CAMPAIGN_YAML).exists():
                raise SpecError(f"{out} already holds a campaign: --resume to finish it, or another --out")
            out.mkdir(parents=True, exist_ok=True)
            write_campaign_yaml(out, spec)
            done = set()
    except SpecError as e:
        return _fail(e)
    except OSError as e:
        return _fail(f"cannot write into {out}: {e}")
    todo = [i for i in range(spec.n_runs) if i not in done]
    prog = Progress(spec.n_runs, already=spec.n_runs - len(todo), enabled=not a.quiet)
    seen = set(done)

    def on_row(row: dict[str, Any]) -> None:
        i = int(row["index"])
        if i in seen:           # never twice (a pool rebuilt after a worker died may deliver a run again)
            return
        seen.add(i)
        journal.append(row)
        prog.update(row.get("status", "error"))

    t0 = time.monotonic()
    interrupted = False
    try:
        if todo:
            engine.run(spec, todo, on_row, prog.flying_now)
    except KeyboardInterrupt:
        interrupted = True
    except SpecError as e:
        journal.close()
        return _fail(e)
    finally:
        journal.close()
        prog.close()
        if hasattr(engine, "shutdown"):
            engine.shutdown()
    wall = time.monotonic() - t0
    table = write_results(out, spec, journal)
    counts: dict[str, int] = {}
    for s in table.column("status").to_pylist():
        counts[s] = counts.get(s, 0) + 1
    report = None
    if not a.no_report:
        from bb2_tools.campaign.report import write_report

        report = write_report(out / REPORT_HTML, spec, table,
                              meta=f"{table.num_rows} of {spec.n_runs} runs; engine {engine.describe()}")
    flown = len(todo) if not interrupted else prog.done
    print(f"campaign {spec.name}: {table.num_rows}/{spec.n_runs} runs recorded "
          f"({', '.join(f'{k} {v}' for k, v in sorted(counts.items()))}); this session flew {flown} in "
          f"{format_duration(wall)} ({flown / wall if wall > 0 else 0:.2f} runs/s, {engine.describe()})")
    print(f"  results: {out / RESULTS_PARQUET}, {out / RESULTS_CSV}\n  campaign: {out / CAMPAIGN_YAML}"
          + (f"\n  report: {report}" if report else ""))
    if interrupted:
        print(f"{PROG}: interrupted; --resume finishes the {spec.n_runs - table.num_rows} missing runs",
              file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
