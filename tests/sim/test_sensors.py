"""Sensor models (bb2_sim.sensors): noise statistics from the Allan deviation, rates, DVL lock, GPS fixes only
while surfaced, faults, determinism per seed, the suite files' checks."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bb2_sim import frames
from bb2_sim.sensors import (SensorConfigError, SensorEnvironment, SensorSuite, load_suite_config,
                             truth_from_step)
from bb2_sim.sensors.allan import overlapping_adev
from bb2_sim.sensors.config import suite_config_from_mapping
from bb2_sim.sensors.imu import N_COLUMNS, ImuModel
from bb2_sim.sensors.truth import interpolate, rotations_enu_flu

PRESETS = ("tactical", "mems")
H = 0.05


def straight_run(duration=20.0, *, z=-60.0, speed=3.0, clearance=50.0, phi=0.0, theta=0.0, psi=0.3, h=H):
    """Truth of a boat on a straight level course (native frames: u < 0 ahead), at the ROM's steps."""
    out = []
    R = frames.rotation_native(phi, theta, psi)
    v_earth = R @ np.array([-speed, 0.0, 0.0])
    for n in range(int(round(duration / h)) + 1):
        t = n * h
        x = np.zeros(12)
        x[0:3] = np.array([0.0, 0.0, z]) + v_earth * t
        x[3:6] = phi, theta, psi
        x[6] = -speed
        out.append(truth_from_step(t, x, None, clearance))
    return out


def imu_record(cfg, n, seed=0):
    m = ImuModel(cfg, seed)
    W = m.rng.standard_normal((n, N_COLUMNS))
    return m.raw(np.zeros((n, 3)), np.zeros((n, 3)), W)


# ------------------------------------------------------------------------------------------ Allan deviation
def test_overlapping_adev_equals_allantools():
    allantools = pytest.importorskip("allantools")
    rng = np.random.default_rng(1)
    y = rng.standard_normal(20000) * 0.01 + np.cumsum(rng.standard_normal(20000)) * 1e-4
    tau, ad = overlapping_adev(y, 0.01, [1, 2, 4, 16, 64, 256])
    t2, ad2, _, _ = allantools.oadev(y, rate=100.0, data_type="freq", taus=tau)
    np.testing.assert_allclose(t2, tau)
    np.testing.assert_allclose(ad, ad2, rtol=1e-9)


@pytest.mark.parametrize("preset", PRESETS)
def test_white_noise_density_from_the_allan_deviation_at_short_tau(preset):
    """The full preset (biases, instability, random walk on): the Allan deviation at tau = 1..4 samples gives
    the configured gyro and accelerometer noise densities within 10 %."""
    cfg = load_suite_config(preset).imu
    dt = 1.0 / cfg.rate_hz
    gyro, acc = imu_record(cfg, 100_000, seed=5)
    for y, density in ((gyro, cfg.gyro.noise_density), (acc, cfg.accel.noise_density)):
        tau, ad = overlapping_adev(y, dt, [1, 2, 4])
        est = ad * np.sqrt(tau)[:, None]
        err = np.abs(est / density - 1.0)
        assert err.max() < 0.10, (preset, est / density)


@pytest.mark.parametrize("preset,which", [(p, w) for p in PRESETS for w in ("gyro", "accel")])
def test_bias_random_walk_from_the_allan_deviation_over_a_long_record(preset, which):
    """A long record (1000 crossover times of white noise and random walk; 1e6 samples at a rate chosen for
    it, the statistics being rate-free) with the bias instability off: the random walk from the Allan variance
    past the crossover, K^2 = 3 (AVAR - N^2 / tau) / tau averaged over tau and the axes, within 20 %."""
    base = load_suite_config(preset).imu
    c = getattr(base, which)
    N, K = c.noise_density, c.bias_random_walk
    tc = math.sqrt(3.0) * N / K
    n = 1_000_000
    rate = n / (1000.0 * tc)
    off = {"gyro": {"bias_instability_deg_h": 0.0}, "accel": {"bias_instability_ug": 0.0}}
    cfg = suite_config_from_mapping({"base": preset, "imu": {"rate_hz": rate, **off}}).imu
    gyro, acc = imu_record(cfg, n, seed=11)
    y = gyro if which == "gyro" else acc
    dt = 1.0 / rate
    m = np.unique(np.logspace(np.log10(5 * tc / dt), np.log10(n / 30), 8).astype(int))
    tau, ad = overlapping_adev(y, dt, m)
    k_est = np.sqrt(np.clip(3.0 * (ad ** 2 - N ** 2 / tau[:, None]) / tau[:, None], 0.0, None)).mean()
    assert abs(k_est / K - 1.0) < 0.20, (preset, which, k_est / K)


def test_noise_streams_do_not_depend_on_the_chunking():
    cfg = load_suite_config("mems").imu
    one = imu_record(cfg, 1000, seed=3)
    m = ImuModel(cfg, 3)
    parts = [m.raw(np.zeros((k, 3)), np.zeros((k, 3)), m.rng.standard_normal((k, N_COLUMNS)))
             for k in (1, 7, 92, 400, 500)]
    np.testing.assert_array_equal(one[0], np.vstack([p[0] for p in parts]))
    np.testing.assert_array_equal(one[1], np.vstack([p[1] for p in parts]))


# ------------------------------------------------------------------------------------------ truth
def test_truth_frames_and_specific_force():
    R = rotations_enu_flu(np.array([0.1]), np.array([-0.2]), np.array([0.7]))[0]
    np.testing.assert_allclose(R, frames.rotation_enu_flu(-0.1, 0.2, 0.7), atol=1e-15)
    a = straight_run(1.0, phi=0.0, theta=0.0)[0]
    b = interpolate(a, None, [0.0])
    np.testing.assert_allclose(b.f_flu[0], [0.0, 0.0, 9.81], atol=1e-12)   # at rest, level: +g up
    np.testing.assert_allclose(b.v_flu[0], [3.0, 0.0, 0.0], atol=1e-12)    # ahead = +x in FLU


# ------------------------------------------------------------------------------------------ rates, determinism
def test_each_sensor_at_its_own_rate_independent_of_the_step():
    doc = {"base": "tactical", "pressure": {"rate_hz": 7.0}, "dvl": {"latency_s": 0.0},
           "altimeter": {"dropout_probability": 0.0}}
    suite = SensorSuite(suite_config_from_mapping(doc), seed=1)
    out = suite.run(straight_run(10.0))
    for name, rate in (("imu", 200.0), ("pressure", 7.0), ("dvl", 5.0), ("altimeter", 5.0), ("gps", 5.0)):
        t = np.array([s.t for s in out if s.sensor == name])
        assert t.size == math.ceil(10.0 * rate - 1e-9), (name, t.size)
        np.testing.assert_allclose(np.diff(t), 1.0 / rate, atol=1e-9)
        np.testing.assert_allclose(t, np.arange(t.size) / rate, atol=1e-9)


def _values(samples):
    return [(s.sensor, s.t, repr(np.ravel(getattr(s, f)).tolist()))
            for s in samples for f in ("angular_velocity", "pressure_pa", "velocity", "range_m", "latitude_deg")
            if hasattr(s, f)]


def test_same_seed_same_measurements_other_seed_others():
    truth = straight_run(5.0)
    cfg = load_suite_config("mems")
    a = _values(SensorSuite(cfg, seed=4).run(truth))
    b = _values(SensorSuite(cfg, seed=4).run(truth))
    c = _values(SensorSuite(cfg, seed=5).run(truth))
    assert a == b
    assert a != c


def test_latency_delays_the_delivery_not_the_stamp():
    suite = SensorSuite(load_suite_config("tactical"), seed=0)
    truth = straight_run(2.0)
    for a, b in zip(truth[:-1], truth[1:]):
        for s in suite.step(a, b):
            assert s.t_available < b.t + 1e-9
            if s.sensor == "dvl":
                assert s.t_available == pytest.approx(s.t + 0.1)


# ------------------------------------------------------------------------------------------ DVL
def _dvl(truth, preset="tactical", **over):
    suite = SensorSuite(suite_config_from_mapping({"base": preset, "dvl": over}) if over
                        else load_suite_config(preset), seed=2)
    return [s for s in suite.run(truth) if s.sensor == "dvl"]


def test_dvl_bottom_track_within_range_water_track_beyond():
    near = _dvl(straight_run(4.0, clearance=50.0))
    assert near and all(s.bottom_lock for s in near)
    v = np.mean([s.velocity for s in near], axis=0)
    np.testing.assert_allclose(v, [3.0, 0.0, 0.0], atol=0.05)           # over ground, dvl frame (FLU axes)
    cov = near[0].covariance
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    far = _dvl(straight_run(4.0, clearance=400.0))                     # slant range > 200 m
    assert far and not any(s.bottom_lock for s in far)
    assert all(np.all(np.isinf(s.beam_ranges_m)) for s in far)
    edge = _dvl(straight_run(4.0, clearance=170.0 + 4.5))              # 170 m / cos 30 = 196 m: in range
    assert all(s.bottom_lock for s in edge)


@pytest.mark.parametrize("attitude", [{"phi": math.radians(50)}, {"theta": math.radians(-45)},
                                      {"phi": math.radians(40), "theta": math.radians(40)}])
def test_dvl_loses_lock_at_large_roll_or_pitch(attitude):
    lost = _dvl(straight_run(3.0, clearance=30.0, **attitude))
    assert lost and not any(s.bottom_lock for s in lost)
    ok = _dvl(straight_run(3.0, clearance=30.0, phi=math.radians(10), theta=math.radians(8)))
    assert all(s.bottom_lock for s in ok)


def test_dvl_three_beam_solution_when_one_beam_is_lost():
    """Roll and pitch 35 deg: one beam leans past 60 deg from the vertical; the other three still solve."""
    samples = _dvl(straight_run(3.0, clearance=30.0, phi=math.radians(35), theta=math.radians(35)))
    assert samples and all(s.beam_valid.sum() == 3 and s.bottom_lock for s in samples)
    assert all(np.isinf(s.beam_ranges_m[~s.beam_valid]).all() for s in samples)
    v = np.mean([s.velocity for s in samples], axis=0)
    np.testing.assert_allclose(v, [3.0, 0.0, 0.0], atol=0.05)


# ------------------------------------------------------------------------------------------ GPS
class _Swell:
    """A regular long-crested swell: elevation A cos(k x - w t); no pressure (the GPS looks at eta only)."""

    def __init__(self, amplitude, period):
        self.A, self.w = amplitude, 2 * math.pi / period
        self.k = self.w ** 2 / 9.81

    def elevation(self, x, y, t):
        return self.A * np.cos(self.k * np.asarray(x) - self.w * t)

    def pressure_head(self, points, t):
        return np.zeros(np.shape(points)[:-1])


def _gps(truth, env=None, preset="tactical"):
    suite = SensorSuite(suite_config_from_mapping({"base": preset, "imu": None}), seed=0, environment=env)
    return [s for s in suite.run(truth) if s.sensor == "gps"]


def test_gps_fixes_only_while_surfaced_after_the_time_to_first_fix():
    # submerged: the sail top (11.4 m above the CG) below the calm surface
    deep = _gps(straight_run(20.0, z=-20.0))
    assert deep and not any(s.fix for s in deep)
    # surfaced (CG 8 m deep: sail top 3.4 m up): no fix for the first 5 s, then every sample
    up = _gps(straight_run(20.0, z=-8.0))
    t_fix = [s.t for s in up if s.fix]
    assert t_fix and min(t_fix) == pytest.approx(5.0)
    assert all(s.fix == (s.t >= 5.0 - 1e-9) for s in up)
    fix = [s for s in up if s.fix]
    assert np.all(np.isfinite([s.latitude_deg for s in fix]))
    p_true = np.array([frames.earth_native_to_enu(np.array([-8.763 * math.cos(0.3) - 3.0 * math.cos(0.3) * s.t,
                                                             -8.763 * math.sin(0.3) - 3.0 * math.sin(0.3) * s.t,
                                                             -8.0 + 11.401])) for s in fix])
    err = np.array([s.position_enu for s in fix]) - p_true
    np.testing.assert_allclose(err.std(axis=0), [1.0, 1.0, 2.0], rtol=0.35)
    assert np.all(np.abs(err.mean(axis=0)) < [0.5, 0.5, 1.0])


def test_gps_loses_the_fix_under_a_wave_crest():
    """Sail top 1.4 m above the calm surface in a 3 m, 10 s swell: out of the water 6.4 s of each 10 s, so fixes
    come in the troughs only (after the 5 s to first fix), and the crests take them away."""
    swell = _Swell(amplitude=3.0, period=10.0)
    samples = _gps(straight_run(60.0, z=-10.0, speed=0.0), SensorEnvironment(sea=swell))
    fix = np.array([s.fix for s in samples])
    assert 0 < fix.sum() < 0.3 * fix.size
    assert np.any(fix[:-1] & ~fix[1:])                       # lost again after a fix
    x_native = -8.763 * math.cos(0.3)                        # the antenna 8.763 m forward of the CG, psi 0.3
    for s in samples:
        if s.fix:                                            # out of the water for the last 5 s
            for tt in np.arange(s.t - 5.0, s.t + 1e-9, 0.2):
                assert 1.4011 - float(swell.elevation(x_native, 0.0, tt)) >= 0.1 - 1e-6
    calm = _gps(straight_run(60.0, z=-10.0, speed=0.0))
    assert sum(s.fix for s in calm) == sum(1 for s in calm if s.t >= 5.0 - 1e-9)
    # the sail top 0.5 m under the calm surface: a 3 m swell bares it 4.4 s per period, never 5 s in a row
    assert not any(s.fix for s in _gps(straight_run(60.0, z=-11.9, speed=0.0), SensorEnvironment(sea=swell)))


# ------------------------------------------------------------------------------------------ pressure, altimeter
def test_pressure_depth_offset_and_waves():
    cfg = suite_config_from_mapping({"base": "tactical", "pressure": {"offset_pa": 0.0, "resolution_pa": 0.0,
                                                                      "atmospheric_pressure_pa": 100000.0}})
    p = [s.pressure_pa for s in SensorSuite(cfg, seed=0).run(straight_run(20.0, z=-60.0)) if s.sensor == "pressure"]
    expect = 100000.0 + 1025.0 * 9.81 * (60.0 + 4.0)              # the sensor is 4 m below the CG
    assert np.mean(p) == pytest.approx(expect, abs=3 * 10.0 / math.sqrt(len(p)) + 1e-6)
    assert np.std(p) == pytest.approx(10.0, rel=0.25)
    quant = load_suite_config("mems")
    q = [s.pressure_pa for s in SensorSuite(quant, seed=0).run(straight_run(2.0)) if s.sensor == "pressure"]
    assert all(abs(v / 100.0 - round(v / 100.0)) < 1e-9 for v in q)   # 100 Pa resolution


def test_altimeter_range_max_range_and_dropouts():
    cfg = suite_config_from_mapping({"base": "mems", "imu": None, "altimeter": {"dropout_probability": 0.2}})
    s = [x for x in SensorSuite(cfg, seed=0).run(straight_run(200.0, clearance=40.0)) if x.sensor == "altimeter"]
    assert 0.7 * 400 < len(s) < 0.9 * 400                                 # 2 Hz, 20 % lost
    r = np.array([x.range_m for x in s])
    assert np.mean(r) == pytest.approx(40.0 - 4.5, abs=0.05)
    far = [x for x in SensorSuite(cfg, seed=0).run(straight_run(20.0, clearance=300.0)) if x.sensor == "altimeter"]
    assert far and all(x.range_m == math.inf for x in far)


# ------------------------------------------------------------------------------------------ faults
def test_faults_dropout_stuck_and_bias_step():
    faults = [{"sensor": "dvl", "kind": "dropout", "start_s": 2.0, "end_s": 4.0},
              {"sensor": "pressure", "kind": "stuck", "start_s": 3.0, "duration_s": 2.0},
              {"sensor": "imu", "kind": "bias_step", "start_s": 5.0, "field": "gyro", "bias": [0.1, 0.0, 0.0]},
              {"sensor": "gps", "kind": "dropout", "start_s": 6.0, "end_s": 7.0},
              {"sensor": "altimeter", "kind": "bias_step", "start_s": 1.0, "end_s": 2.0, "bias": 10.0}]
    cfg = suite_config_from_mapping({"base": "tactical", "faults": faults, "altimeter": {"dropout_probability": 0}})
    out = SensorSuite(cfg, seed=0).run(straight_run(10.0, z=-8.0))
    dvl_t = [s.t for s in out if s.sensor == "dvl"]
    assert dvl_t and not any(2.0 <= t < 4.0 for t in dvl_t) and any(t >= 4.0 for t in dvl_t)
    pr = [(s.t, s.pressure_pa) for s in out if s.sensor == "pressure"]
    held = [p for t, p in pr if 3.0 <= t < 5.0]
    before = [p for t, p in pr if t < 3.0][-1]
    assert held and all(p == before for p in held)
    assert len({p for t, p in pr if t >= 5.0}) > 1
    gx = np.array([(s.t, s.angular_velocity[0]) for s in out if s.sensor == "imu"])
    assert np.mean(gx[gx[:, 0] >= 5.0, 1]) == pytest.approx(0.1, abs=1e-3)
    assert abs(np.mean(gx[gx[:, 0] < 5.0, 1])) < 1e-3
    assert not any(6.0 <= s.t < 7.0 for s in out if s.sensor == "gps")
    alt = [(s.t, s.range_m) for s in out if s.sensor == "altimeter"]
    assert all((r > 50.0) == (1.0 <= t < 2.0) for t, r in alt)


# ------------------------------------------------------------------------------------------ configuration
@pytest.mark.parametrize("doc,msg", [
    ({"base": "tactical", "imu": {"rate_hz": 0}}, "imu.rate_hz must be > 0"),
    ({"base": "tactical", "imu": {"gyro": {"angle_random_walk_deg_sqrt_h": -1}}}, "must be >= 0"),
    ({"base": "tactical", "dvl": {"beam_noise_mps": float("nan")}}, "must be finite"),
    ({"base": "tactical", "dvl": {"beams": 4}}, "unknown key(s) in dvl: ['beams']"),
    ({"base": "tactical", "gps": {"rate_hz": "fast"}}, "gps.rate_hz must be a number"),
    ({"base": "tactical", "altimeter": {"max_range_m": 0.1}}, "max_range_m must exceed min_range_m"),
    ({"base": "nosuch"}, "neither a preset"),
    ({"base": "tactical", "gps": None, "faults": [{"sensor": "gps", "kind": "dropout", "start_s": 1}]},
     "does not have"),
    ({"base": "tactical", "faults": [{"sensor": "imu", "kind": "melt", "start_s": 1}]}, "kind must be one of"),
    ({"base": "tactical", "faults": [{"sensor": "imu", "kind": "bias_step", "start_s": 1, "bias": 1.0}]},
     "list of 3 numbers"),
    ({"base": "tactical", "sonar": {}}, "unknown key(s) ['sonar']"),
])
def test_clear_errors_for_bad_values(doc, msg):
    with pytest.raises(SensorConfigError) as e:
        suite_config_from_mapping(doc)
    assert msg in str(e.value)


def test_presets_load_and_a_sensor_can_be_removed():
    for p in PRESETS:
        c = load_suite_config(p)
        assert set(c.sensors()) == {"imu", "pressure", "dvl", "altimeter", "gps"}
    c = suite_config_from_mapping({"base": "mems", "gps": None, "dvl": {"enabled": False}})
    assert set(c.sensors()) == {"imu", "pressure", "altimeter"}
