"""Build the synthetic canyon and its thalweg path; print the figures; ``--write`` refreshes the shipped path.

    .venv/bin/python benchmarks/planner_canyon.py [--write]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from bb2_planner.paths import DATA_DIR, read_path_metadata, save_path
from bb2_planner.terrain import canyon_path, synthetic_canyon


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--write", action="store_true", help="rewrite bb2_planner/data/paths/synthetic_canyon.json")
    args = ap.parse_args()
    t_start = time.perf_counter()
    cy = synthetic_canyon()
    P = canyon_path(cy)
    elapsed = time.perf_counter() - t_start
    t = np.linspace(P.t0, P.tf, 2001)
    z = P(t)[:, 2]
    facts = {"curve_length_m": round(P.arc_length(), 2),
             "path_speed_min_mps": round(float(P.speed(t).min()), 3),
             "path_speed_max_mps": round(float(P.speed(t).max()), 3),
             "min_radius_of_curvature_m": round(float(1 / P.curvature(t).max()), 1),
             "min_clearance_m": round(cy.terrain.min_clearance(P)[0], 2),
             "z_range_m": [round(float(z.min()), 1), round(float(z.max()), 1)]}
    print(cy.terrain)
    print(f"canyon + thalweg + fit: {elapsed:.2f} s; path degree {P.degree}, Tf {P.tf} s")
    for k, v in facts.items():
        print(f"  {k}: {v}")
    if args.write:
        meta = read_path_metadata("synthetic_canyon")
        f = save_path(P, DATA_DIR / "synthetic_canyon.json", description=meta["description"],
                      provenance=meta["provenance"], facts=facts)
        print(f"wrote {f}")


if __name__ == "__main__":
    main()
