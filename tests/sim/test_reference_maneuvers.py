"""Regression: the six maneuvers of ../shared/bb2_reference, flown by `bb2_sim.maneuvers`, reproduce the authors'
compiled model to <= 1e-6 relative on the authors' surfaces; with the project's own generated hull the maneuver
figures of REFERENCE.md section 4 agree within 0.5 %.
"""
from dataclasses import asdict

import numpy as np
import pytest

from bb2_sim.maneuvers import CSV_COLUMNS, build_model, maneuver_settings, run_maneuver
from bb2_sim.metrics import figures_for
from bb2_sim.model import BB2Model

pytestmark = pytest.mark.slow(seconds=110)  # started first (tests/conftest.py)

CASES = [
    ("self-propulsion", "ref_sp_calm", {}),
    ("turning-circle", "ref_tc20", {}),
    ("hzz", "ref_hzz20", {}),
    ("vzz", "ref_vzz10_mode4", {}),
    ("open-loop", "ref_openloop_planes0", {}),
    ("open-loop", "ref_openloop_rudder20_stbd", {"planes_deg": (-20, 20, 20, -20, 0)}),
]


def _load(path):
    return np.genfromtxt(path, delimiter=",", names=True)


@pytest.mark.parametrize("name,ref,extra", CASES, ids=[c[1] for c in CASES])
def test_maneuver_reproduces_reference(name, ref, extra, shared, authors_surfaces):
    R = _load(shared("bb2_reference", f"{ref}.csv"))
    s = maneuver_settings(name, **extra)
    model = BB2Model(authors_surfaces, sea_state=s.sea_state)
    assert not model.trimmed  # the authors' Mb is already trimmed to their surfaces
    res = run_maneuver(s, model)
    assert res.completed
    assert len(res.traj["t_s"]) == len(R)
    for c in CSV_COLUMNS:
        a, b = res.traj[c], R[c]
        scale = max(np.max(np.abs(b)), 1e-9)
        err = np.max(np.abs(a - b)) / scale
        assert err <= 1e-6, f"{ref}: column {c} differs by {err:.2e} of its range"


# (maneuver, reference run, figure rows to compare); the values are read from the reference CSV with the same
# metrics code, so the check is "our hull gives the authors' figures", independent of hand-copied numbers.
FIGURES = {
    "ref_tc20": ("turning-circle", {}, ["advance_90_m", "transfer_90_m", "tactical_diameter_m", "advance_180_m",
                                       "steady_radius_m", "steady_yaw_rate_rad_s", "steady_speed_m_s",
                                       "steady_roll_rad", "time_90_s", "time_180_s"]),
    "ref_hzz20": ("hzz", {}, ["time_to_first_check_s", "first_overshoot_rad", "second_overshoot_rad",
                              "first_period_s"]),
    "ref_vzz10_mode4": ("vzz", {}, ["time_to_first_check_s", "first_period_s", "first_peak_time_s"]),
    "ref_sp_calm": ("self-propulsion", {}, ["forward_speed_m_s", "advance_coefficient", "thrust_N", "torque_Nm",
                                            "z_m"]),
}


@pytest.mark.parametrize("ref", list(FIGURES))
def test_generated_hull_gives_reference_figures(ref, shared):
    name, extra, rows = FIGURES[ref]
    R = _load(shared("bb2_reference", f"{ref}.csv"))
    R = {c: R[c] for c in R.dtype.names}
    s = maneuver_settings(name, **extra)
    model = build_model(s)  # the hull generated from the table of offsets, weight trimmed to its buoyancy
    assert model.trimmed and model.surfaces.source.startswith("generated")
    res = run_maneuver(s, model)
    ours = figures_for(name, res.traj, **asdict(s))
    theirs = figures_for(name, R, **asdict(s))
    for row in rows:
        _, a, unit = ours.row(row)
        _, b, _ = theirs.row(row)
        assert np.isfinite(a) and np.isfinite(b), row
        assert abs(a - b) <= 0.005 * abs(b), f"{ref}: {row} = {a:.4f} {unit} vs reference {b:.4f} ({(a - b) / b:+.2%})"
