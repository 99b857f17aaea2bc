"""Where the ROM's fixed step holds: the fastest steady cruise each number of sub-steps flies.

    .venv/bin/python benchmarks/substeps_stability.py [--substeps 1 2 3 4] [--duration 120] [--jobs 2]

For each ``substeps`` K, the boat is started straight ahead at 20 m depth at the speed of the propeller rule
(u = 4.2 n m/s, near its cruise) with the planes at 0 and the propeller held at n rps, n = 3.00, 3.25 ... 5.50
(about 12.6 to 23 m/s), and flown open loop for ``--duration`` s of simulation (``Simulator(..., substeps=K)``).
Printed per K: the fastest cruise that flew the whole duration (its speed at the end) and the slowest that
diverged (the speed it started at), and each run's end.  Above these speeds the explicit ode3 step of 0.05 s / K
is numerically unstable (more sub-steps fly on and agree: see ``tests/sim/test_substeps.py``).  The hull tables
themselves span 1.54 to 5.14 m/s in u; at these speeds their forces are the authors' clamps or linear
extrapolations.
"""
from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bb2_sim.integrator import NonFiniteStateError, Simulator  # noqa: E402
from bb2_sim.model import BB2Model  # noqa: E402

RPS = tuple(2.5 + 0.25 * k for k in range(13))
M_S_PER_RPS = 4.2  # the cruise speed the ROM reaches per propeller rps, about (8.6 m/s at 2 rps, 17.2 at 4)


def cruise(substeps: int, rps: float, duration_s: float) -> tuple[bool, float, float]:
    """(flew the whole duration, the time it ended at, its speed then or, diverged, the speed it started at)."""
    x0 = np.zeros(12)
    x0[2], x0[6] = -20.0, -M_S_PER_RPS * rps  # native: z up, u < 0 ahead
    sim = Simulator(BB2Model(), x0, substeps=substeps)
    try:
        while sim.t < duration_s - 1e-9:
            sim.step(np.zeros(5), rps)
    except NonFiniteStateError:
        return False, sim.t, M_S_PER_RPS * rps
    return True, sim.t, float(np.linalg.norm(sim.x[6:9]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--substeps", type=int, nargs="+", default=[1, 2, 3, 4])
    p.add_argument("--duration", type=float, default=120.0, help="simulated s of each cruise (default 120)")
    p.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    a = p.parse_args(argv)
    cases = [(k, n) for k in a.substeps for n in RPS]
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        ends = dict(zip(cases, pool.map(cruise, *zip(*cases), [a.duration] * len(cases))))
    print(f"steady cruise, planes 0, {a.duration:g} s each (ode3, 0.05 s major step):")
    print("substeps  fastest flown       slowest diverged")
    for k in a.substeps:
        flown = [(n, ends[k, n]) for n in RPS if ends[k, n][0]]
        lost = [(n, ends[k, n]) for n in RPS if not ends[k, n][0]]
        best = f"{flown[-1][1][2]:5.1f} m/s ({flown[-1][0]:.2f} rps)" if flown else "none"
        worst = f"{lost[0][1][2]:5.1f} m/s ({lost[0][0]:.2f} rps, at t = {lost[0][1][1]:.1f} s)" if lost else "none"
        print(f"{k:8d}  {best:18s}  {worst}")
    per_rps = [e[2] / n for (k, n), e in ends.items() if e[0]]
    if per_rps:  # the data file's cruise_m_s_per_rps
        print(f"steady speed per rps of the cruises flown: {min(per_rps):.3f} .. {max(per_rps):.3f} m/s")
    print("each run: " + "; ".join(f"K={k} {n:.2f} rps " + ("ok" if e[0] else f"diverged at {e[1]:.1f} s")
                                   for (k, n), e in ends.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
