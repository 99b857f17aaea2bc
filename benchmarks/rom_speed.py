#!/usr/bin/env python3
"""ROM speed: real-time factor (simulated s per wall s) on one core, and the cost of one model evaluation.

    python benchmarks/rom_speed.py [--hull-mesh DIR] [--repeat N] [--accuracy]

Cases (all with the full pressure integration over every panel at every ode3 stage):
  * 300 s open loop in calm water (planes 0, n = 1.2861 rps; the authors' compiled C code runs this case at about
    19x real time on this machine, per the issue);
  * 300 s self-propulsion in sea state 5 (waves: exp/sin at every integration point), autopilot on;
  * the same in a 64-component JONSWAP sea (Hs 3.25 m, Tp 9.7 s, gamma 3.3, cos-2s s = 4 about head seas),
    wave loads from the body-grid interpolation (bb2_sim.sea.pressure_grid).
Goal: >= 60x real time, never below 20x. The three runs are repeated --repeat times (default 3) in turn, so
that a loaded machine slows them alike; prints the median and best real-time factor of each, the irregular /
calm ratio of the medians and the load average, and the same per CPU second of the process (steadier on a
loaded machine). One core: the process is pinned to one CPU and BLAS runs
single-threaded (set before numpy is imported). ``--accuracy`` also compares the grid wave loads along the
irregular run with a direct full-resolution pressure integration every 0.5 s of it (slow: ~600 direct sums).
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

from bb2_sim.actuators import ActuatorOutputs  # noqa: E402
from bb2_sim.added_mass import DerivativeMemory  # noqa: E402
from bb2_sim.frames import rotation_native  # noqa: E402
from bb2_sim.integrator import Simulator  # noqa: E402
from bb2_sim.maneuvers import ManeuverCommander, build_model, maneuver_settings, run_maneuver  # noqa: E402
from bb2_sim.model import BB2Model  # noqa: E402
from bb2_sim.sea import ComponentSea, Cos2sSpreading, JonswapSpectrum, discretise  # noqa: E402
from bb2_sim.waves import Wave  # noqa: E402


def irregular_sea(n: int = 64) -> ComponentSea:
    return ComponentSea(discretise(JonswapSpectrum(3.25, 9.7, 3.3), n, seed=1, spreading=Cos2sSpreading(0.0, 4.0)))


def timed(fn):
    """(wall s, CPU s of this process, result); on a loaded machine the CPU time is the steadier figure."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out


def fly(model, s, every: int):
    """(t, x, actual plane deflections) every ``every`` major steps of maneuver ``s``."""
    sim, cmd = Simulator(model, s.initial_state()), ManeuverCommander(s)
    out = []
    for k in range(int(round(s.duration / sim.h))):
        planes, rps = cmd.step(sim.t, sim.x)
        rec = sim.step(planes, rps)
        if k % every == 0:
            out.append((rec.t, rec.x.copy(), rec.act.planes_deg.copy()))
    return out


def wave_load_errors(model, samples) -> np.ndarray:
    """Max |grid - direct| per load (X..N) as a fraction of the range of the direct wave loads."""
    H, sea = model.hydro, model.sea
    d, g, c = [], [], []
    for t, x, defl in samples:
        R, pos = rotation_native(*x[3:6]), x[0:3]
        d.append(H.loads(pos, R, t, None, defl, sea=sea, wave_load_method="direct"))
        g.append(H.loads(pos, R, t, None, defl, sea=sea))
        c.append(H.loads(pos, R, t, Wave(), defl))
    d, g, c = np.array(d), np.array(g), np.array(c)
    return np.abs(g - d).max(axis=0) / np.ptp(d - c, axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hull-mesh", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--accuracy", action="store_true")
    a = ap.parse_args()
    try:
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    except (AttributeError, OSError):
        pass
    print(f"ROM speed benchmark (hull: {a.hull_mesh or 'generated from offsets'}, one core, {a.repeat} rounds, "
          f"load average {os.getloadavg()[0]:.2f} at start)")
    cases = []
    for label, name, extra in [("open loop, calm, 300 s", "open-loop", {"duration": 300.0}),
                               ("self-propulsion, sea state 5, 300 s", "self-propulsion",
                                {"duration": 300.0, "sea_state": 5}),
                               ("self-propulsion, 64-comp. irregular, 300 s", "self-propulsion",
                                {"duration": 300.0, "sea_state": "irregular"})]:
        if extra.get("sea_state") == "irregular":
            s = maneuver_settings(name, duration=300.0, sea_state=0)
            model = BB2Model(a.hull_mesh, profile=s.profile, sea=irregular_sea())
        else:
            s = maneuver_settings(name, **extra)
            model = build_model(s, a.hull_mesh)
        cases.append((label, s, model))
    walls = {label: [] for label, _, _ in cases}
    cpus = {label: [] for label, _, _ in cases}
    for _ in range(a.repeat):
        for label, s, model in cases:
            wall, cpu, res = timed(lambda s=s, model=model: run_maneuver(s, model))
            assert res.completed
            walls[label].append(wall)
            cpus[label].append(cpu)
    med, med_cpu = {}, {}
    for label, s, _ in cases:
        rtf = s.duration / float(np.median(walls[label]))
        med[label] = rtf
        med_cpu[label] = rtf_cpu = s.duration / float(np.median(cpus[label]))
        print(f"  {label:<42s} median wall {np.median(walls[label]):6.2f} s   real-time factor {rtf:6.1f}x "
              f"(best {s.duration / min(walls[label]):5.1f}x; per CPU second {rtf_cpu:5.1f}x; "
              f"{'meets' if rtf >= 60 else 'MISSES'} the 60x goal; {rtf / 19:.1f}x the authors' C code)")
    calm, irr = med[cases[0][0]], med[cases[2][0]]
    print(f"  irregular / calm real-time factor (medians): {irr / calm:.2f} wall, "
          f"{med_cpu[cases[2][0]] / med_cpu[cases[0][0]]:.2f} CPU "
          f"({'above' if irr >= 20 else 'BELOW'} the 20x floor)   load average now {os.getloadavg()[0]:.2f}")
    # one model evaluation, the three cases in turn, median of --repeat rounds
    evals = []
    for ss in (0, 5, "irregular (64)"):
        if isinstance(ss, str):
            model = BB2Model(a.hull_mesh, profile=maneuver_settings("open-loop").profile, sea=irregular_sea())
        else:
            model = build_model(maneuver_settings("open-loop", sea_state=ss), a.hull_mesh)
        evals.append((ss, model))
    x = np.array([0, 0, -15.4, 0.05, 0.02, 0.1, -5.0, 0.1, 0.05, 0.01, 0.005, -0.01])
    act = ActuatorOutputs(np.array([3.0, -2.0, 1.0, 4.0, -5.0]), 1.2)
    dm = DerivativeMemory()
    dm.store(-0.05, np.zeros((15, 3)))
    n = 1000
    per = {ss: [] for ss, _ in evals}
    per_cpu = {ss: [] for ss, _ in evals}
    for _ in range(a.repeat):
        for ss, model in evals:
            wall, cpu, _ = timed(lambda model=model: [model.evaluate(0.01 * i, x, act, dm) for i in range(n)])
            per[ss].append(wall / n * 1e6)
            per_cpu[ss].append(cpu / n * 1e6)
    for ss, model in evals:
        print(f"  one model evaluation, sea state {ss}: {np.median(per[ss]):7.1f} us median wall, "
              f"{np.median(per_cpu[ss]):7.1f} us CPU "
              f"({model.hydro.n_points} pressure points, {model.surfaces.n_triangles()} triangles)")
    if a.accuracy:
        label, s, model = cases[2]
        err = wave_load_errors(model, fly(model, s, every=10))
        print("  irregular run, grid vs direct wave loads, max error in % of each load's range over the run: "
              + "  ".join(f"{n} {100 * e:.3f}" for n, e in zip("XYZKMN", err)))


if __name__ == "__main__":
    main()
