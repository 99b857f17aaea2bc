"""Mixer signs (SPEC 6.1 and the ROM geometry) and the baseline autopilots (SPEC 4)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bb2_control.autopilots import CommandLimiter, DepthHeadingPD, RateAutopilot
from bb2_control.config import load_data
from bb2_control.errors import ControlConfigError, NonFiniteInputError
from bb2_control.mixer import PlaneMixer, from_rom_commands, to_rom_commands


def test_mixer_rows_match_spec():
    m = PlaneMixer.from_config()
    dV, dH = 2.0, 0.5
    np.testing.assert_array_equal(m.step(dV, dH), [-dV + dH, -dV - dH, dV - dH, dV + dH, dV])


def test_mixer_equals_rom_mixer_in_rom_convention():
    """ROM convention (bb2_rom SPEC 9.1): d1 = dV-dH, d2 = dV+dH, d3 = -dV+dH, d4 = -dV-dH, d5 = -dV."""
    m = PlaneMixer.from_config()
    for dV_rom, dH_rom in [(1.0, 0.0), (0.0, 1.0), (3.0, -2.0)]:
        planes = m.step(*from_rom_commands(dV_rom, dH_rom))
        expect = [dV_rom - dH_rom, dV_rom + dH_rom, -dV_rom + dH_rom, -dV_rom - dH_rom, -dV_rom]
        np.testing.assert_array_equal(planes, expect)
        assert to_rom_commands(*from_rom_commands(dV_rom, dH_rom)) == (dV_rom, dH_rom)


def _plane_moments_native(shared, planes_deg):
    """Moment per plane (native body: x aft, y stbd, z up) of a unit lift along d_i per degree at r_i."""
    geo = json.loads(shared("bb2_rom", "data", "geometry.json").read_text())
    out = []
    for i, delta in enumerate(planes_deg, start=1):
        r = np.array(geo["planes"][str(i)]["position_m"], float)
        d = np.array(geo["lift_direction_for_positive_deflection"][str(i)], float)
        out.append(np.cross(r, d) * delta)
    return np.array(out)


def test_mixer_signs_against_rom_geometry(shared):
    """Controller dV > 0: every plane pitches the bow up (native +M_y); dH > 0: stern planes yaw bow to port.

    Equivalently, in the ROM convention dV_rom > 0 pitches the bow down and dH_rom > 0 turns it to starboard.
    """
    m = PlaneMixer.from_config()
    mom = _plane_moments_native(shared, m.step(1.0, 0.0))
    assert np.all(mom[:, 1] > 0), mom[:, 1]          # native y = starboard: +M_y raises the bow (-x)
    mom = _plane_moments_native(shared, m.step(0.0, 1.0))
    assert np.all(mom[:4, 2] > 0), mom[:, 2]         # native z up: +M_z swings the bow (-x) to port (-y)
    assert mom[4, 2] == 0.0
    mom = _plane_moments_native(shared, m.step(*from_rom_commands(1.0, 0.0)))
    assert mom[:, 1].sum() < 0                       # ROM dV > 0: bow down
    mom = _plane_moments_native(shared, m.step(*from_rom_commands(0.0, 1.0)))
    assert mom[:, 2].sum() < 0                       # ROM dH > 0: bow to starboard


def test_mixer_sail_sign_and_saturation_options():
    cfg = load_data("mixer")
    paper = PlaneMixer.from_config({**cfg, "sail_sign": -1})
    assert paper.step(1.0, 0.0)[4] == -1.0
    clipped = PlaneMixer.from_config({**cfg, "saturation_deg": 30.0})
    assert np.max(np.abs(clipped.step(25.0, 25.0))) == 30.0
    assert np.max(np.abs(PlaneMixer.from_config().step(25.0, 25.0))) == 50.0  # no clip by default (ROM does it)
    with pytest.raises(ControlConfigError):
        PlaneMixer.from_config({**cfg, "sail_sign": 2})
    with pytest.raises(NonFiniteInputError):
        PlaneMixer.from_config().step(float("nan"), 0.0)


def test_rate_autopilot_gain_and_sign():
    ap = RateAutopilot()
    dV, dH = ap.step(u_q=0.01, u_r=-0.002, q_up=0.0, r_left=0.0)
    assert dV == pytest.approx(30.0) and dH == pytest.approx(-6.0)   # 3000 deg per rad/s
    dV, _ = ap.step(u_q=0.0, u_r=0.0, q_up=0.01, r_left=0.0)
    assert dV < 0                                                     # too much bow-up rate -> bow-down command


def test_rate_autopilot_unlimited_by_default_and_limited_when_configured():
    assert RateAutopilot().step(1.0, 0.0, 0.0, 0.0)[0] == pytest.approx(3000.0)   # SPEC 4.1: no limit
    lim = load_data("autopilots")["rom_manoeuvre_limits"]
    cfg = {**load_data("autopilots")["rate_P_2022"],
           "command_saturation_deg": lim["command_saturation_deg"],
           "command_rate_limit_deg_per_s": lim["command_rate_limit_deg_per_s"]}
    ap = RateAutopilot(cfg)
    first = ap.step(1.0, -1.0, 0.0, 0.0)
    assert first == (30.0, -30.0)                    # saturation on the first tick (no rate memory yet)
    out = ap.step(-1.0, 1.0, 0.0, 0.0)
    assert out[0] == pytest.approx(30.0 - 7.11 * 0.05) and out[1] == pytest.approx(-30.0 + 7.11 * 0.05)


def test_command_limiter_sequence():
    lim = CommandLimiter(0.05, rate_limit_deg_per_s=10.0, saturation_deg=1.0)
    ys = [lim.step(x) for x in (0.0, 5.0, 5.0, -5.0)]
    np.testing.assert_allclose(ys, [0.0, 0.5, 1.0, 0.5])


def test_depth_heading_pd_signs_and_units():
    pd = DepthHeadingPD()
    # vehicle 1 m above the reference depth, level, on heading: dive command (bow-down, dV < 0)
    dV, dH = pd.step(z_ref=-100.0, z=-99.0, theta=0.0, psi_ref=0.0, psi=0.0)
    assert dV == pytest.approx(-3.0) and dH == 0.0     # no derivative kick on the first tick
    # next tick the error grew by 0.1 m: D term 3 deg/(m/s) * (-0.1/0.05)
    dV, _ = pd.step(z_ref=-100.0, z=-98.9, theta=0.0, psi_ref=0.0, psi=0.0)
    assert dV == pytest.approx(3 * -1.1 + 3 * (-0.1 / 0.05))
    pd.reset()
    # heading reference 1 deg to port of the bow: dH > 0 (bow-to-port moment)
    _, dH = pd.step(-100.0, -100.0, 0.0, math.radians(1.0), 0.0)
    assert dH == pytest.approx(3.0)
    # bow-up pitch: dV < 0
    pd.reset()
    dV, _ = pd.step(-100.0, -100.0, math.radians(2.0), 0.0, 0.0)
    assert dV == pytest.approx(-6.0)


def test_depth_heading_pd_authors_zero_initial_error_option():
    cfg = {**load_data("autopilots")["depth_pitch_yaw_PD_2023"], "initial_previous_error": "zero"}
    dV, _ = DepthHeadingPD(cfg).step(-100.0, -99.0, 0.0, 0.0, 0.0)
    assert dV == pytest.approx(-3.0 + 3.0 * (-1.0 / 0.05))


def test_autopilot_non_finite_input_raises_and_keeps_state():
    ap = RateAutopilot()
    ap.step(0.01, 0.0, 0.0, 0.0)
    with pytest.raises(NonFiniteInputError, match="q_up"):
        ap.step(0.0, 0.0, float("nan"), 0.0)
    pd = DepthHeadingPD()
    with pytest.raises(ValueError, match="psi"):
        pd.step(0.0, 0.0, 0.0, 0.0, float("inf"))


def test_autopilot_bad_config():
    with pytest.raises(ControlConfigError, match="K_q_deg_per_radps"):
        RateAutopilot({"Ts_s": 0.05, "K_r_deg_per_radps": 1.0})
    with pytest.raises(ControlConfigError, match="initial_previous_error"):
        DepthHeadingPD({**load_data("autopilots")["depth_pitch_yaw_PD_2023"], "initial_previous_error": "x"})


def test_autopilot_gains_carried_from_shared(shared):
    params = json.loads(shared("bb2_control", "params.json").read_text())["autopilot"]
    own = load_data("autopilots")
    assert own["rate_P_2022"]["K_q_deg_per_radps"] == params["rate_P_2022"]["K_q_deg_per_radps"]
    assert own["rate_P_2022"]["K_r_deg_per_radps"] == params["rate_P_2022"]["K_r_deg_per_radps"]
    pd_src, pd_own = params["depth_pitch_yaw_PD_2023"], own["depth_pitch_yaw_PD_2023"]
    for a, b in [("KP_z_deg_per_m", "KP_z_deg_per_m"), ("KD_z_deg_per_mps", "KD_z_deg_per_mps"),
                 ("KP_theta", "KP_theta_deg_per_deg"), ("KD_theta_s", "KD_theta_s"),
                 ("KP_psi", "KP_psi_deg_per_deg"), ("KD_psi_s", "KD_psi_s")]:
        assert pd_own[b] == pd_src[a], b
    mix = json.loads(shared("bb2_control", "params.json").read_text())["mixer"]
    from bb2_sim.xplane import mixing_matrix  # the vehicle's geometry, which the controllers' mixer uses

    assert mixing_matrix().tolist() == mix["matrix_rows_d1_to_d5_cols_dV_dH"]
    assert PlaneMixer.from_config().matrix.tolist() == mix["matrix_rows_d1_to_d5_cols_dV_dH"]
