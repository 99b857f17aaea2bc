"""Mission files with a sea: and a current: block (issue 11): parsed into the ROM the runner and the nodes build,
clear one-line errors for bad values, the authors' table unchanged, the shipped sea-state-5 mission."""
from pathlib import Path

import numpy as np
import pytest

from bb2_mission import MissionError, MissionRunner, build_model, load_mission, mission_from_dict
from bb2_sim.environment import Environment, sea_from_mapping
from bb2_sim.sea import ComponentSea

REPO = Path(__file__).resolve().parents[2]


def _mission(tmp_path, text: str):
    f = tmp_path / "m.yaml"
    f.write_text("path: straight_line_x4000\n" + text)
    return load_mission(f)


def test_sea_and_current_blocks_reach_the_model(tmp_path):
    m = _mission(tmp_path, "sea: {spectrum: jonswap, hs: 2.0, tp: 8.5, heading_deg: 45, spreading_s: 6,"
                           " components: 12, seed: 9}\n"
                           "current: {speed_mps: 0.4, heading_deg: 90, profile: {water_depth_m: 120}}\n")
    assert m.sea_state == 0 and not m.environment.sea.authors_table
    model = build_model(m)
    assert isinstance(model.sea, ComponentSea) and len(model.sea.components) == 12
    ref = sea_from_mapping({"spectrum": "jonswap", "hs": 2.0, "tp": 8.5, "heading_deg": 45, "spreading_s": 6,
                            "components": 12, "seed": 9}).wave_components()
    assert np.array_equal(model.sea.components.phase, ref.phase)
    assert model.current.speed == 0.4 and model.current.direction_deg == 90
    assert model.current.profile[0] == "power"


def test_sea_state_alone_and_sea_block_sea_state_are_the_same_table(tmp_path):
    a = _mission(tmp_path, "sea_state: 5\n")
    b = _mission(tmp_path, "sea: {sea_state: 5}\n")
    assert a.sea_state == b.sea_state == 5
    ma, mb = build_model(a), build_model(b)
    assert ma.wave == mb.wave and ma.sea is None and mb.sea is None and not ma.wave.calm


def test_calm_mission_builds_the_model_as_before(tmp_path):
    m = _mission(tmp_path, "")
    assert m.environment == Environment()
    model = build_model(m)
    assert model.sea is None and model.current is None and model.wave.calm


def test_component_file_beside_the_mission(tmp_path):
    (tmp_path / "waves.csv").write_text("amplitude_m,omega_rad_s,direction_deg,phase_deg\n0.8,0.7,30,10\n")
    m = _mission(tmp_path, "sea: {components: waves.csv}\n")
    model = build_model(m)
    assert model.sea.components.amplitude[0] == 0.8


@pytest.mark.parametrize("text,needle", [
    ("sea: {spectrum: jonswap, hs: -1, tp: 9}\n", "sea.hs must be >= 0"),
    ("sea: {spectrum: jonswap, hs: 3, tp: 0}\n", "sea.tp must be > 0"),
    ("sea: {spectrum: jonswap, hs: 3, tp: 9, gamma: 0.5}\n", "sea.gamma must be >= 1"),
    ("sea: {spectrum: jonswap, hs: 3, tp: 9, components: 0}\n", "components"),
    ("sea: {spectrum: jonswap, hs: .nan, tp: 9}\n", "finite"),
    ("sea: {spectrum: jonswap, hs: 3, tp: 9, wind: 20}\n", "unknown key(s) in sea"),
    ("sea: {components: missing.csv}\n", "not found"),
    ("sea_state: 5\nsea: {spectrum: jonswap, hs: 3, tp: 9}\n", "either sea_state"),
    ("sea: jonswap\n", "sea must be a mapping"),
    ("current: {speed_mps: -0.5}\n", "current.speed_mps must be >= 0"),
    ("current: {speed_mps: 0.5, heading_deg: .inf}\n", "finite"),
    ("current: {speed_mps: 0.5, direction: 3}\n", "unknown key(s) in current"),
])
def test_bad_sea_or_current_one_clear_line(tmp_path, text, needle):
    with pytest.raises(MissionError) as e:
        _mission(tmp_path, text)
    msg = str(e.value)
    assert needle in msg and str(tmp_path / "m.yaml") in msg and "\n" not in msg


def test_shipped_periscope_ss5_mission():
    m = load_mission(REPO / "missions" / "canyon_periscope_ss5.yaml")
    s = m.environment.sea
    assert s.spectrum == "jonswap" and s.effective_hs_tp == (3.25, 9.7) and s.spreading_s == 10
    assert m.environment.current.speed_mps == 0.3
    z = m.path.to_frame("native")(np.linspace(m.path.t0, m.path.tf, 11))[:, 2] if m.path.frame != "native" \
        else m.path(np.linspace(m.path.t0, m.path.tf, 11))[:, 2]
    assert np.allclose(z, -18.0)


def test_runner_in_waves_moves_differently_from_calm(tmp_path):
    """10 s of the straight mission in a sea-state-5 JONSWAP beam sea: the boat rolls, in calm water not."""
    base = {"path": "straight_line_x4000", "duration_s": 10.0}
    calm = MissionRunner(mission_from_dict(base))
    wavy = MissionRunner(mission_from_dict({**base, "sea": {"spectrum": "jonswap", "sea_state": 5,
                                                            "heading_deg": 90, "components": 8}}))
    roll = {}
    for name, r in (("calm", calm), ("wavy", wavy)):
        phi = []
        while not r.done:
            r.step()
            phi.append(r.sim.x[3])
        roll[name] = np.ptp(phi)
    assert roll["wavy"] > 5 * roll["calm"]
