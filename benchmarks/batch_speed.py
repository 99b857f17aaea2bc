#!/usr/bin/env python3
"""Batch ROM speed: the cost per boat and step of N boats stepped together (bb2_sim.batch) against one boat alone.

    python benchmarks/batch_speed.py [--hull-mesh DIR] [--repeat R] [--sizes 1,10,100,1000] [--no-sea]

Cases, each a single boat (bb2_sim.integrator.Simulator) and batches of N boats (BatchSimulator):
  * open loop in calm water: constant planes and rps per boat (mixed headings, speeds, plane commands);
  * the v12 autopilot maneuvers in calm water (self-propulsion, turning circle, hzz, vzz in turn), commands from
    ManeuverCommander / BatchManeuverCommander every step;
  * open loop in calm water with ``exact=True`` (bit for bit the single runs), largest N only;
  * open loop in sea state 5 (information: the per-point wave pressure over 11 k hull points per boat and stage
    does not shrink with the batch), N up to 100 only.
Goal (issue): per-boat cost at N = 1000 <= 1/50 of one boat alone, i.e. single / per-boat(1000) >= 50, open loop
and the autopilot maneuvers. One core: the process is pinned to one CPU and BLAS runs single-threaded. The rounds
alternate single and batch runs so that a loaded machine slows them alike; the median over rounds is printed, in
wall time and in CPU time of the process (steadier on a loaded machine).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # one core: no BLAS threads
    os.environ.setdefault(_var, "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from bb2_sim.batch import BatchModel, BatchSimulator  # noqa: E402
from bb2_sim.batch.maneuvers import batch_for_maneuvers  # noqa: E402
from bb2_sim.integrator import Simulator  # noqa: E402
from bb2_sim.maneuvers import ManeuverCommander, maneuver_settings  # noqa: E402
from bb2_sim.model import BB2Model  # noqa: E402

GOAL = 50.0
AUTOPILOT_MANEUVERS = ("self-propulsion", "turning-circle", "hzz", "vzz")


def timed(fn) -> tuple[float, float]:
    """(wall s, CPU s of this process) of fn()."""
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def open_loop_boats(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Initial states (n, 12), plane commands (n, 5) deg and rps (n,) of a mixed open-loop fleet."""
    rng = np.random.default_rng(seed)
    x0 = np.zeros((n, 12))
    x0[:, 2] = rng.uniform(-100.0, -40.0, n)
    x0[:, 5] = rng.uniform(-np.pi, np.pi, n)
    x0[:, 6] = -rng.uniform(3.0, 5.5, n)
    return x0, rng.uniform(-5.0, 5.0, (n, 5)), rng.uniform(0.8, 1.4, n)


def open_loop_single(model: BB2Model, steps: int):
    x0, planes, rps = open_loop_boats(1)

    def run():
        sim = Simulator(model, x0[0])
        for _ in range(steps):
            sim.step(planes[0], rps[0])
    return run


def open_loop_batch(model: BB2Model, n: int, steps: int, sea_state: float = 0, exact: bool = False):
    x0, planes, rps = open_loop_boats(n)
    bm = BatchModel.from_sea_states(model, [sea_state] * n, exact=exact)

    def run():
        sim = BatchSimulator(bm, x0)
        for _ in range(steps):
            sim.step(planes, rps)
        assert not sim.diverged.any()
    return run


def maneuver_list(n: int):
    return [maneuver_settings(AUTOPILOT_MANEUVERS[i % len(AUTOPILOT_MANEUVERS)]) for i in range(n)]


def autopilot_single(model: BB2Model, steps: int):
    settings = maneuver_list(len(AUTOPILOT_MANEUVERS))

    def run():   # one boat per maneuver in turn: the mean single cost of the mix
        for s in settings:
            sim, cmd = Simulator(model, s.initial_state()), ManeuverCommander(s)
            for _ in range(steps // len(settings)):
                sim.step(*cmd.step(sim.t, sim.x))
    return run


def autopilot_batch(model: BB2Model, n: int, steps: int):
    settings = maneuver_list(n)

    def run():
        sim, cmd = batch_for_maneuvers(settings, model)
        for _ in range(steps):
            sim.step(*cmd.step(sim.t, sim.x))
        assert not sim.diverged.any()
    return run


def measure(label: str, single, single_steps: int, batches: dict[int, tuple], repeat: int) -> None:
    """Median per-step costs (us) over ``repeat`` alternating rounds; prints single, per boat, ratio."""
    walls = {"single": []} | {n: [] for n in batches}
    cpus = {"single": []} | {n: [] for n in batches}
    single()                                   # warm-up (first-call caches, page faults)
    for fn, _ in batches.values():
        fn()
    for _ in range(repeat):
        w, c = timed(single)
        walls["single"].append(w / single_steps)
        cpus["single"].append(c / single_steps)
        for n, (fn, steps) in batches.items():
            w, c = timed(fn)
            walls[n].append(w / steps / n)
            cpus[n].append(c / steps / n)
    s_w, s_c = float(np.median(walls["single"])), float(np.median(cpus["single"]))
    print(f"{label}\n  one boat alone: {1e6 * s_w:8.1f} us per step wall, {1e6 * s_c:8.1f} us CPU")
    for n in batches:
        w, c = float(np.median(walls[n])), float(np.median(cpus[n]))
        print(f"  batch N = {n:5d}: {1e6 * w:8.1f} us per boat and step wall, {1e6 * c:8.1f} us CPU   "
              f"(single / per boat: {s_w / w:6.1f} wall, {s_c / c:6.1f} CPU)")
    n_max = max(batches)
    ratio_w = s_w / float(np.median(walls[n_max]))
    ratio_c = s_c / float(np.median(cpus[n_max]))
    verdict = "meets" if min(ratio_w, ratio_c) >= GOAL else ("MISSES" if max(ratio_w, ratio_c) < GOAL else
                                                               "meets in one measure, not the other:")
    print(f"  -> single / per-boat(N = {n_max}) = {ratio_w:.1f} wall, {ratio_c:.1f} CPU: {verdict} the goal "
          f">= {GOAL:g}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hull-mesh", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sizes", default="1,10,100,1000")
    ap.add_argument("--no-sea", action="store_true", help="skip the sea-state 5 case")
    a = ap.parse_args()
    try:
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    except (AttributeError, OSError):
        pass
    sizes = [int(s) for s in a.sizes.split(",")]
    print(f"Batch ROM speed (hull: {a.hull_mesh or 'generated from offsets'}, one core, {a.repeat} rounds, "
          f"load average {os.getloadavg()[0]:.2f} at start)")
    model = BB2Model(a.hull_mesh)

    def steps_for(n: int) -> int:      # about 0.2-1 s of work per run
        return max(10, min(100, 20000 // n))

    t_start = time.perf_counter()
    measure("open loop, calm water", open_loop_single(model, 100), 100,
            {n: (open_loop_batch(model, n, steps_for(n)), steps_for(n)) for n in sizes}, a.repeat)
    measure("v12 autopilot maneuvers, calm water (" + ", ".join(AUTOPILOT_MANEUVERS) + ")",
            autopilot_single(model, 100), 100,
            {n: (autopilot_batch(model, n, steps_for(n)), steps_for(n)) for n in sizes}, a.repeat)
    n_max = max(sizes)
    measure(f"open loop, calm water, exact=True (bit for bit the single runs; N = {n_max} only)",
            open_loop_single(model, 100), 100,
            {n_max: (open_loop_batch(model, n_max, steps_for(n_max), exact=True), steps_for(n_max))}, a.repeat)
    if not a.no_sea:
        sea_sizes = [n for n in sizes if n <= 100]
        sea_model = BB2Model(model.surfaces, sea_state=5)
        measure("open loop, sea state 5 (information; N <= 100)", open_loop_single(sea_model, 40), 40,
                {n: (open_loop_batch(model, n, 10, sea_state=5), 10) for n in sea_sizes}, a.repeat)
    print(f"(benchmark wall time {time.perf_counter() - t_start:.0f} s, load average now {os.getloadavg()[0]:.2f})")


if __name__ == "__main__":
    main()
