"""Issue 12, point 3: the navigation filter (bb2_control.navigation) on the sensor suite's own samples, no ROS.

The truth is a boat on a straight level course (native frames, as the ROM steps it); the samples come from the
real :class:`bb2_sim.sensors.SensorSuite` of each preset, so every noise is the suite's."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bb2_control.errors import ControlConfigError
from bb2_control.navigation import NavigationFilter, NavigationSettings, load_navigation_settings
from bb2_sim import frames
from bb2_sim.sensors import SensorSuite, load_suite_config, truth_from_step
from bb2_sim.sensors.config import FaultSpec

H = 0.05


def course(duration: float, *, z: float = -60.0, speed: float = 3.0, psi: float = 0.3, clearance: float = 50.0):
    """Truth at the ROM's steps of a straight level course (u < 0 ahead in the native body frame)."""
    v_earth = frames.rotation_native(0.0, 0.0, psi) @ np.array([-speed, 0.0, 0.0])
    out = []
    for n in range(int(round(duration / H)) + 1):
        x = np.zeros(12)
        x[0:3] = np.array([0.0, 0.0, z]) + v_earth * n * H
        x[5], x[6] = psi, -speed
        out.append(truth_from_step(n * H, x, None, clearance))
    return out


def fly(preset: str, truths, *, seed: int = 1, faults=(), x0=None, settings=None):
    """The filter fed tick by tick as the runner feeds it; (filter, estimates at every step)."""
    suite = SensorSuite(load_suite_config(preset), seed=seed, faults=tuple(faults))
    nav = NavigationFilter(suite.config, truths[0].x12 if x0 is None else x0, settings=settings)
    est = [nav.state(truths[0].t)]
    for a, b in zip(truths[:-1], truths[1:]):
        nav.update(suite.step(a, b))
        est.append(nav.state(b.t))
    return nav, est


def position_errors(truths, est) -> np.ndarray:
    return np.array([e.p_native - t.x12[0:3] for t, e in zip(truths, est)])


@pytest.mark.parametrize("preset,bound_m", [("tactical", 1.0), ("mems", 6.0)])
def test_dead_reckoning_on_the_dvl_stays_within_its_own_covariance(preset, bound_m):
    truths = course(120.0)
    nav, est = fly(preset, truths)
    err = position_errors(truths, est)
    sigma = nav.position_sigma_m                        # ENU axes; native x, y are -E, -N: same magnitudes
    assert np.all(np.abs(err[-1]) < 4.0 * sigma), (err[-1], sigma)   # consistent, not overconfident
    assert np.linalg.norm(err[-1]) < bound_m
    assert abs(err[-1][2]) < 0.2                        # depth from the pressure sensor
    assert nav.stats.used["dvl"] > 0.9 * 120 * load_suite_config(preset).dvl.rate_hz
    assert nav.stats.used["imu"] == pytest.approx(120 * load_suite_config(preset).imu.rate_hz, abs=2)
    # the attitude and rates the stack gets are the sensors' (heading unwrapped next to the truth)
    psi_err = np.array([e.euler_native[2] - t.x12[5] for t, e in zip(truths, est)])
    assert np.max(np.abs(psi_err)) < math.radians(5.0 if preset == "mems" else 0.2)
    speed = np.array([e.v_body_native[0] for e in est[100:]])
    assert np.max(np.abs(speed + 3.0)) < 0.1


def test_without_the_dvl_the_covariance_grows_and_says_so():
    truths = course(120.0)
    nav_dvl, _ = fly("tactical", truths)
    nav_none, est = fly("tactical", truths, faults=[FaultSpec("dvl", "dropout", 20.0)])
    assert "dvl" not in nav_none.stats.rejected
    assert np.all(nav_none.position_sigma_m[:2] > 3.0 * nav_dvl.position_sigma_m[:2])
    err = position_errors(truths, est)[-1]
    assert np.all(np.abs(err) < 4.0 * nav_none.position_sigma_m)


def test_a_filter_started_off_position_converges_on_the_gps_at_the_surface():
    truths = course(60.0, z=-5.0)                       # the sail top well above the calm surface: fixes
    x0 = truths[0].x12.copy()
    x0[0] += 30.0
    nav, est = fly("tactical", truths, x0=x0)
    assert nav.stats.used["gps"] > 200                  # never gated, whatever the distance
    err = position_errors(truths, est)
    assert np.linalg.norm(err[0][:2]) == pytest.approx(30.0)
    assert np.linalg.norm(err[-1][:2]) < 2.0


def test_a_dvl_bias_step_is_rejected_by_the_gate():
    truths = course(90.0)
    step = FaultSpec("dvl", "bias_step", 40.0, 70.0, (1.0, 0.0, 0.0), "velocity")
    nav, est = fly("tactical", truths, faults=[step])
    assert nav.stats.rejected["dvl"] > 100              # 30 s at 5 Hz, nearly all of them
    assert np.linalg.norm(position_errors(truths, est)[-1]) < 3.0   # a 1 m/s bias taken in: tens of metres


def test_bad_settings_and_suites_are_refused_with_the_reason():
    s = load_navigation_settings()
    assert s.gate_probability < 1 and s.position_sigma_m > 0
    for bad in ({"gate_probability": 1.0}, {"position_sigma_m": 0.0}, {"extra_accel_noise": -1.0},
                {"current_sigma_m_s": math.nan}):
        with pytest.raises(ControlConfigError, match="navigation"):
            dataclasses.replace(s, **bad)
    with pytest.raises(ControlConfigError, match="needs an IMU"):
        NavigationFilter(dataclasses.replace(load_suite_config("tactical"), imu=None), np.zeros(12))
    with pytest.raises(ControlConfigError, match="12 finite numbers"):
        NavigationFilter(load_suite_config("tactical"), np.full(12, math.nan))
    with pytest.raises(ControlConfigError, match="missing key 'gating'"):
        NavigationSettings.from_mapping({"initial": {"position_sigma_m": 1, "velocity_sigma_m_s": 1},
                                         "process": {"extra_accel_noise_m_s2_sqrt_hz": 0},
                                         "water_track": {"current_sigma_m_s": 1}})
