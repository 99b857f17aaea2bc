"""Regression: the ROM reproduces the authors' compiled model (../shared/bb2_rom/data/reference) step by step.

Each reference run was produced by the authors' v12.1 generated C code with its own autopilot; every row
gives the state at t_k, the total load F at that major step and the actuator outputs. We fly the same
autopilot (bb2_sim.autopilot_v12) on the authors' surfaces and compare every step.
"""
import json

import numpy as np
import pytest

from bb2_sim.autopilot_v12 import V12Autopilot
from bb2_sim.integrator import Simulator
from bb2_sim.model import BB2Model

STATE = ["x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"]
RUNS = ["ref1_calm_z60_hold.csv", "ref2_ss5_depth_heading_change.csv", "ref3_ss3_deep_turn.csv"]


@pytest.mark.parametrize("run", RUNS)
def test_reference_run_states_and_forces(run, shared, authors_surfaces):
    ref_dir = shared("bb2_rom", "data", "reference")
    cfg = json.loads((ref_dir / "README.json").read_text())
    settings = cfg["runs"][run]
    ref = np.genfromtxt(ref_dir / run, delimiter=",", names=True)
    model = BB2Model(authors_surfaces, sea_state=settings["Seastate"])
    x0 = np.zeros(12)
    x0[2] = settings["z0_m"]
    x0[6:12] = cfg["common_settings"]["Bv_0"]
    sim = Simulator(model, x0)
    ap = V12Autopilot(z_ref=settings["z_ref_m"], psi_ref=settings["psi_ref_rad"])
    from bb2_control.mixer import PlaneMixer
    mixer = PlaneMixer.from_config()
    rps = 5.14444 / 4  # n = -v_ref / 4 with v_ref = -5.14444
    X = np.empty((len(ref), 12))
    F = np.empty((len(ref), 6))
    D = np.empty((len(ref), 6))
    for k in range(len(ref)):
        dv, dh = ap.step(sim.x[2], sim.x[4], sim.x[5])
        rec = sim.step(mixer.step(dv, dh), rps)
        X[k], F[k] = rec.x, rec.ev.forces
        D[k] = [*rec.act.planes_deg, rec.act.rps]
    Xr = np.column_stack([ref[c] for c in STATE])
    Fr = np.column_stack([ref[c] for c in "XYZKMN"])
    Dr = np.column_stack([ref[c] for c in ["d1", "d2", "d3", "d4", "d5", "n"]])
    assert np.allclose(ref["t"], np.arange(len(ref)) * 0.05)
    # relative to each column's range: the files carry 13 significant digits
    for name, a, b, tol in [("state", X, Xr, 1e-8), ("forces", F, Fr, 1e-8), ("actuators", D, Dr, 1e-8)]:
        scale = np.maximum(np.max(np.abs(b), axis=0), 1e-12)
        err = np.max(np.abs(a - b), axis=0) / scale
        assert np.all(err < tol), f"{run}: {name} relative error {err.max():.2e} > {tol}"
