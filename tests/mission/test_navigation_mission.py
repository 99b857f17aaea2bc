"""Issue 12, point 3: the library runner flies the stack on the navigation filter with ``navigation: sensors``.

The state columns stay the truth, the stack's path errors are those of the estimate it flew on (the true vehicle's
are the closest-point figures), and the estimate's error is in its own columns; the run is a function of the
mission and the sensor seed alone."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bb2_mission import MISSIONS_DIR, MissionRunner, load_mission
from bb2_mission.summary import path_errors_closest

DURATION_S = 60.0


def canyon(tmp_path, sensors: str | None, seed: int = 1):
    f = tmp_path / f"canyon_{sensors or 'truth'}_{seed}.yaml"
    text = f"extends: {MISSIONS_DIR / 'canyon.yaml'}\nname: canyon_nav\nduration_s: {DURATION_S}\n"
    if sensors:
        text += f"sensors: {{suite: {sensors}, seed: {seed}}}\nnavigation: sensors\n"
    f.write_text(text)
    return load_mission(f)


def fly(m):
    return MissionRunner(m).run()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("nav")
    return {k: fly(canyon(tmp, k)) for k in (None, "tactical", "mems")}


def test_the_stack_flies_on_the_estimate_and_its_errors_are_said(runs):
    truth, tac, mems = runs[None], runs["tactical"], runs["mems"]
    for r in (tac, mems):
        s = r.summary
        assert not r.failed and s.end_reason == "duration" and s.mission_time_s == pytest.approx(DURATION_S)
        assert s.navigation == "sensors"
        # the stack flew on something else than the truth: the trajectory departs from the truth-fed run
        assert np.max(np.abs(r.traj["y_m"] - truth.traj["y_m"])) > 0.01
        # the stack's own path errors are those of the estimate it flew on; the true vehicle's are the
        # closest-point errors of the true positions: they differ by no more than the estimate's error
        e = r.traj["nav_position_error_m"]
        P = np.c_[r.traj["x_m"], r.traj["y_m"], r.traj["z_m"]]
        eh, ev = path_errors_closest(r.path_native, P)
        d = np.hypot(r.traj["e_horizontal_m"] - eh, r.traj["e_vertical_m"] - ev)
        assert 0.01 < np.max(d) and np.all(d < e + 0.05)
        assert s.rms_horizontal_closest_m == pytest.approx(math.sqrt(np.mean(eh ** 2)))
        assert np.all(np.isfinite(e)) and e[0] == 0.0      # started at the mission's initial state
        assert s.rms_nav_error_m == pytest.approx(math.sqrt(np.mean(e ** 2)))
        assert any(line.startswith("  navigation: sensors; position estimate error RMS") for line in s.lines())
    # the MEMS suite navigates worse than the tactical one, and it shows in the true path error
    assert mems.summary.rms_nav_error_m > 2.0 * tac.summary.rms_nav_error_m
    assert tac.summary.rms_nav_error_m < 1.0
    assert mems.summary.max_nav_heading_error_deg > tac.summary.max_nav_heading_error_deg
    assert mems.summary.rms_horizontal_closest_m > tac.summary.rms_horizontal_closest_m
    # on the truth: the paper's loop, no navigation columns
    assert truth.summary.navigation == "truth"
    assert np.all(np.isnan(truth.traj["nav_position_error_m"])) and np.isnan(truth.summary.rms_nav_error_m)
    assert not any("navigation" in line for line in truth.summary.lines())


def test_a_run_on_sensors_is_a_function_of_the_mission_and_the_seed(tmp_path, runs):
    again = fly(dataclasses.replace(canyon(tmp_path, "tactical"), duration_s=20.0))
    first = runs["tactical"].traj
    n = again.traj["t_s"].size
    for c in ("x_m", "y_m", "z_m", "psi_deg", "nav_position_error_m", "cmd_d1_deg"):
        assert np.array_equal(again.traj[c], first[c][:n]), c      # bit for bit
    other = fly(dataclasses.replace(canyon(tmp_path, "tactical", seed=2), duration_s=20.0))
    assert not np.array_equal(other.traj["nav_position_error_m"], again.traj["nav_position_error_m"])
