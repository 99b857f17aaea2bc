"""Campaign throughput (issue 14): local pool with 1 and 2 workers, Ray on K = 1 and 2 raylets, and the
one-process-per-run baseline; plus the memory of building the results of a 100,000-run journal.

    .venv/bin/python benchmarks/campaign_speed.py [--mission missions/canyon.yaml] [--runs 8]
        [--duration S] [--no-baseline] [--no-ray] [--store-rows 100000] [--maneuvers 256] [--only-maneuvers]
        [--mission-batch-runs 64] [--mission-batches 128] [--mission-sea-states 0,3,5]
        [--mission-spectrum-seas 3,4,5,6] [--no-one-by-one]

Every campaign is the same SPEC (the mission with the guidance look-ahead ``stack.guidance.d_m`` drawn uniform in
[200, 300] m and ``adaptation`` on/off): runs/s is runs / wall time of the engine (pool or cluster start-up
included), and "1000 runs" is the projection 1000 / (runs/s).  Goals: 1,000 canyon runs (500 s each) in
<= 10 min on this 2-core machine; on Ray, K nodes >= 0.9 K x one node's throughput -- measured here with
Ray's own multi-node test cluster (``ray.cluster_utils.Cluster``: K raylets of 1 CPU each on this machine,
reported as such).  The baseline is today's way: one ``bb2-sim mission`` process per run, two at a time.  The
engines are compared flying one run per task (``--batch 1``).

``--mission-batch-runs N``: the mission campaign of N runs (sea state drawn from ``--mission-sea-states``, default
0/3/5, too) by the local pool of 2
workers, one by one and flown together (``--mission-batches``: the ``--batch`` values, default 128): each worker
flies the missions of its chunk with one exact batch ROM (bb2_mission.batch), each mission's stack alone; the
goal line takes the faster way.  ``--mission-spectrum-seas 3,4,5,6``: short-crested JONSWAP seas of these sea states
and four wave headings drawn instead, each run its own wave phases (e.g. on ``missions/canyon_periscope_ss5.yaml``).

``--maneuvers N``: a campaign of N turning circles (60 s; rudder, sea state (``--maneuver-sea-states``, default
0/3/5) and speed drawn) flown by the
local pool with 2 workers, each worker flying its runs together in the batch ROM (``--maneuver-batches``: the
``--batch`` values, default 128, the default of bb2-campaign) and one by one (``--batch 1``): maneuver runs per
second, the ratio, and whether the tables are equal.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bb2_tools.campaign.engines import LocalEngine, RayEngine  # noqa: E402
from bb2_tools.campaign.spec import parse_spec  # noqa: E402
from bb2_tools.campaign.worker import probe  # noqa: E402


def make_spec(mission: str, runs: int, duration: float | None, sea_states: list[int] | None = None,
              spectrum_seas: list[int] | None = None):
    """The benchmark's SPEC; ``sea_states``: the authors' regular sea states drawn; ``spectrum_seas``: short-crested
    JONSWAP seas of these sea states (the table's Hs and Tp, 32 components, spreading s = 10) drawn, with the wave
    heading (0/90/180/270 deg) and each run's own wave phases (``seed_key: sea.seed``)."""
    vary: dict = {"stack.guidance.d_m": {"uniform": [200.0, 300.0]}, "adaptation": [True, False]}
    extra: dict = {}
    if spectrum_seas:
        vary.update({"sea.spectrum": "jonswap", "sea.components": 32, "sea.spreading_s": 10.0,
                     "sea.sea_state": {"choice": spectrum_seas}, "sea.heading_deg": {"choice": [0, 90, 180, 270]}})
        extra["seed_key"] = "sea.seed"
    elif sea_states:
        vary["sea_state"] = {"choice": sea_states}
    if duration is not None:
        vary["duration_s"] = duration
    spec = parse_spec({"name": "campaign_speed", "mission": mission, "seed": 1, "samples": max(1, (runs + 1) // 2),
                       "vary": vary, "collect": ["rms_vertical", "rms_horizontal", "min_clearance", "mission_time_s"],
                       **extra})
    probe(spec)
    return spec


def timed(engine, spec, n: int) -> tuple[float, list[dict]]:
    rows: list[dict] = []
    t0 = time.perf_counter()
    engine.run(spec, range(n), rows.append)
    return time.perf_counter() - t0, rows


def key(rows: list[dict]) -> list[tuple]:
    return sorted(tuple(sorted((k, v) for k, v in r.items() if k != "wall_time_s")) for r in rows)


def line(label: str, n: int, wall: float, base: float | None = None, rows: list[dict] | None = None) -> str:
    rate = n / wall
    s = f"  {label:<44s} {n:4d} runs in {wall:7.1f} s  {rate:6.3f} runs/s  1000 runs: {1000 / rate / 60:6.1f} min"
    if rows:
        sim = sum(r.get("mission_time_s") or 0.0 for r in rows)
        s += f"  ({sim / wall:5.1f} simulated s per s"
        s += f"; 1000 canyon runs of 475 s: {1000 * 475.15 / (sim / wall) / 60:5.1f} min)" if sim else ")"
    if base:
        s += f"  ({rate / base:.2f}x)"
    return s


def ray_cluster_rate(spec, n: int, k: int) -> tuple[float, list[dict]]:
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")   # a test cluster on this machine only
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    try:
        for _ in range(k - 1):
            cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        eng = RayEngine(address=cluster.address, batch=1)
        eng._connect()
        return timed(eng, spec, n)
    finally:
        ray.shutdown()
        cluster.shutdown()


def baseline(mission: str, n: int, duration: float | None) -> float:
    """One ``bb2-sim mission`` process per run, two at a time (the mission file as is)."""
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "m.yaml"
        f.write_text(f"extends: {Path(mission).resolve()}\n" + (f"duration_s: {duration}\n" if duration else ""))
        t0 = time.perf_counter()
        running: list[subprocess.Popen] = []
        for _ in range(n):
            while len(running) >= 2:
                running = [p for p in running if p.poll() is None]
                time.sleep(0.05)
            running.append(subprocess.Popen([str(Path(sys.executable).parent / "bb2-sim"), "mission", str(f),
                                              "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        for p in running:
            p.wait()
        return time.perf_counter() - t0


def store_memory(rows: int) -> str:
    """Peak RSS growth while results.parquet/csv are built from a synthetic journal of ``rows`` runs."""
    import json

    from bb2_tools.campaign.store import Journal, write_results

    spec = parse_spec({"mission": "circle", "samples": rows, "vary": {"stack.guidance.d_m": {"uniform": [0, 1]}}})
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        with open(out / "runs.jsonl", "w") as fh:
            for i in range(rows):
                r = {"index": i, "seed": spec.run_seed(i), "stack.guidance.d_m": 0.5, "status": "ok", "message": "",
                     "wall_time_s": 1.0}
                r.update({c: 1.5 for c in spec.collect})
                r.update(completed=True, end_reason="finished")
                fh.write(json.dumps(r) + "\n")
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        t0 = time.perf_counter()
        table = write_results(out, spec, Journal(out / "runs.jsonl"))
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        size = (out / "results.parquet").stat().st_size
    return (f"  results of a {rows}-run journal ({table.num_columns} columns): built in {wall:.1f} s, peak RSS "
            f"+{(after - before) / 1024:.0f} MB, results.parquet {size / 1e6:.1f} MB")


def maneuver_batches(n: int, sea_states: list[float], batches: list[int]) -> None:
    spec = parse_spec({"name": "batch_speed", "maneuver": {"name": "turning-circle", "options": {"duration": 60}},
                       "seed": 2, "samples": n,
                       "vary": {"rudder_deg": {"uniform": [15.0, 35.0]}, "sea_state": {"choice": sea_states},
                                "speed_mps": {"uniform": [3.0, 6.0]}},
                       "collect": ["tactical_diameter_m", "peak_roll_rad", "z_change_m"]})
    probe(spec)
    print(f"maneuver campaign: {n} turning circles of 60 s (sea states {'/'.join(f'{x:g}' for x in sea_states)}), "
          "local pool of 2 workers")
    w1, r1 = timed(LocalEngine(2, batch=1), spec, n)
    print(line("one by one (--batch 1)", n, w1))
    for b in batches:
        wb, rb = timed(LocalEngine(2, batch=b), spec, n)
        print(line(f"together in the batch ROM (--batch {b})", n, wb, n / w1))
        print(f"  batch / one-by-one throughput: {w1 / wb:.2f}; tables equal to the last digit: {key(r1) == key(rb)}")


def mission_batches(mission: str, n: int, duration: float | None, batches: list[int], sea_states: list[int],
                    one_by_one: bool = True, spectrum_seas: list[int] | None = None) -> float:
    """The mission campaign of ``n`` runs (the sea state drawn from ``sea_states`` too, or a spectrum sea of
    ``spectrum_seas``: :func:`make_spec`) by the local pool of 2 workers, one by one (unless ``one_by_one`` is
    False) and flown together (``--batch B``); returns the best simulated seconds per second."""
    spec = make_spec(mission, n, duration, sea_states=sea_states, spectrum_seas=spectrum_seas)
    n = min(n, spec.n_runs)
    seas = (f"JONSWAP seas of sea states {'/'.join(map(str, spectrum_seas))} and four headings" if spectrum_seas
            else f"sea states {'/'.join(map(str, sea_states))}")
    print(f"mission campaign: {n} runs of {'%g s' % duration if duration else 'the whole mission'} ({seas} drawn), "
          f"local pool of 2 workers")
    w1 = r1 = None
    best = 0.0
    if one_by_one:
        w1, r1 = timed(LocalEngine(2, batch=1), spec, n)
        print(line("one by one (--batch 1)", n, w1, rows=r1))
        best = sum(r.get("mission_time_s") or 0.0 for r in r1) / w1
    for b in batches:
        wb, rb = timed(LocalEngine(2, batch=b), spec, n)
        print(line(f"together (--batch {b})", n, wb, n / w1 if w1 else None, rb))
        if w1:
            print(f"  together / one-by-one throughput: {w1 / wb:.2f}; tables equal to the last digit: "
                  f"{key(r1) == key(rb)}")
        best = max(best, sum(r.get("mission_time_s") or 0.0 for r in rb) / wb)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mission", default=str(REPO / "missions" / "canyon.yaml"))
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--duration", type=float, default=None, help="duration_s of every run (default: the mission's)")
    ap.add_argument("--no-baseline", action="store_true")
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--store-rows", type=int, default=100_000)
    ap.add_argument("--maneuvers", type=int, default=256, help="turning circles of the batch comparison (0: skip)")
    ap.add_argument("--only-maneuvers", action="store_true", help="only the maneuver batch comparison")
    ap.add_argument("--maneuver-sea-states", default="0,3,5", help="sea states drawn for the turning circles")
    ap.add_argument("--maneuver-batches", default="128", help="--batch values compared with one by one")
    ap.add_argument("--mission-batch-runs", type=int, default=64,
                    help="runs of the mission batch comparison (0: skip)")
    ap.add_argument("--mission-batches", default="128", help="--batch values of the mission batch comparison")
    ap.add_argument("--mission-sea-states", default="0,3,5", help="sea states drawn in the mission batch comparison")
    ap.add_argument("--mission-spectrum-seas", default="", metavar="S,S,...",
                    help="instead: short-crested JONSWAP seas of these sea states (and four wave headings) drawn in "
                         "the mission batch comparison, e.g. 3,4,5,6 with --mission missions/canyon_periscope_ss5.yaml")
    ap.add_argument("--no-one-by-one", action="store_true",
                    help="the mission campaign flown together only (e.g. 128 whole canyon runs: the one-by-one pass "
                         "would take ~7 min more)")
    a = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    if a.only_maneuvers:
        maneuver_batches(a.maneuvers, [float(x) for x in a.maneuver_sea_states.split(',')],
                         [int(x) for x in a.maneuver_batches.split(',')])
        return 0
    spec = make_spec(a.mission, a.runs, a.duration)
    n = min(a.runs, spec.n_runs)
    print(f"campaign_speed: {n} runs of {a.mission} ({'duration ' + str(a.duration) + ' s' if a.duration else 'full'}"
          f"), {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at start")
    w1, r1 = timed(LocalEngine(1, batch=1), spec, n)        # the engines compared one run per task
    print(line("local, 1 worker", n, w1, rows=r1))
    w2, r2 = timed(LocalEngine(2, batch=1), spec, n)
    print(line("local, 2 workers", n, w2, n / w1, r2))
    assert key(r1) == key(r2), "local 1 and 2 workers differ"
    if not a.no_ray:
        try:
            import ray  # noqa: F401
        except ImportError:
            print("  ray: not installed")
        else:
            k1, q1 = ray_cluster_rate(spec, n, 1)
            print(line("ray test cluster, K = 1 raylet x 1 CPU", n, k1, rows=q1))
            k2, q2 = ray_cluster_rate(spec, n, 2)
            print(line("ray test cluster, K = 2 raylets x 1 CPU", n, k2, n / k1, q2))
            ratio = (n / k2) / (n / k1)
            print(f"  Ray scaling: K = 2 throughput = {ratio:.2f} x K = 1 (goal >= 1.8) -> "
                  f"{'MET' if ratio >= 1.8 else 'NOT MET'}; results equal to local: {key(q1) == key(r1) == key(q2)}")
    if not a.no_baseline:
        nb = min(n, 4)
        wb = baseline(a.mission, nb, a.duration)
        mean_t = sum(r.get("mission_time_s") or 0.0 for r in r2) / max(1, len(r2))
        print(line("baseline: one bb2-sim process per run, 2 at a time", nb, wb,
                   rows=[{"mission_time_s": mean_t}] * nb))
    sim_rate = sum(r.get("mission_time_s") or 0.0 for r in r2) / w2
    how = "2 local workers, one by one"
    if a.mission_batch_runs:
        rate = mission_batches(a.mission, a.mission_batch_runs, a.duration,
                               [int(x) for x in a.mission_batches.split(",")],
                               [int(x) for x in a.mission_sea_states.split(",")], not a.no_one_by_one,
                               [int(x) for x in a.mission_spectrum_seas.split(",") if x])
        if rate > sim_rate:
            sim_rate, how = rate, "2 local workers, missions flown together"
    minutes = 1000 * 475.15 / sim_rate / 60 if sim_rate else float("nan")
    print(f"GOAL 1000 canyon runs (475 s simulated each) <= 10 min on this machine: {minutes:.1f} min with {how} "
          f"-> {'MET' if minutes <= 10 else 'NOT MET'}  (load average {os.getloadavg()[0]:.1f} at the end)")
    if a.store_rows:
        print(store_memory(a.store_rows))
    if a.maneuvers:
        maneuver_batches(a.maneuvers, [float(x) for x in a.maneuver_sea_states.split(',')],
                         [int(x) for x in a.maneuver_batches.split(',')])
    return 0


if __name__ == "__main__":
    sys.exit(main())
